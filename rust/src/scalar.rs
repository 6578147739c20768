//! The scalar the stage math is written over (SPEC §13): `f64` for one run, or a lane type,
//! four or eight runs advancing together in SIMD lanes: simba's array-backed [`F64x4`] and
//! [`F64x8`] in the portable builds of the lane loop, the native-register [`F64x4Avx2`] and
//! [`F64x8Avx512`] (`native`) in the AVX2 and AVX-512 builds. One source serves them all
//! (lane code is generic over [`Wide`]), with the same bits on each; data-dependent
//! branches become lane selects (`SimdValue::select`), with the scalar branch kept where all
//! lanes agree (see [`Real::all`]).
//!
//! Lanes are independent: no operation mixes lanes, so a lane's result never depends on
//! what runs share its group. Lane and scalar results differ only where `exp` differs
//! (a polynomial here, libm's for `f64`): within a few ulp per call.

use nalgebra::{Matrix3, SMatrix, SVector, SimdRealField, Vector3};
use simba::simd::SimdBool;
use simba::simd::SimdValue;

mod libm_exp;
pub mod libm_sincos;
#[cfg(target_arch = "x86_64")]
mod native;
#[cfg(target_arch = "x86_64")]
pub use native::{F64x4Avx2, F64x8Avx512};

/// Four f64 lanes. simba's array-backed type, for the portable build of the lane loop
/// (its element-wise loops become SSE2, or the target's own vector instructions).
pub type F64x4 = simba::simd::AutoF64x4;

/// Lanes in an [`F64x4`].
pub const LANES: usize = 4;

/// Eight f64 lanes, the same array-backed type as [`F64x4`]: the portable 8-wide build of
/// the lane loop, which any CPU runs, so the 8-wide grouping is tested everywhere.
pub type F64x8 = simba::simd::AutoF64x8;

/// A lane type carrying `L` runs: [`F64x4`] (`L` = 4) or [`F64x8`] (`L` = 8). The lane
/// code is written once over it; `L` sizes the arrays of runs a group packs from, so a
/// width that does not match its lane type does not compile.
pub trait Wide<const L: usize>: Real {}

impl Wide<4> for F64x4 {}
impl Wide<8> for F64x8 {}

/// A scalar for the stage math: nalgebra's `SimdRealField` over `f64` elements, plus the
/// few operations whose lane version is written here.
pub trait Real:
    SimdRealField<Element = f64, SimdBool: std::fmt::Debug + PartialEq + SimdValue<Element = bool>>
    + Copy
    + Default
{
    /// Number of runs this scalar carries.
    const LANES: usize;

    /// e^x. `f64::exp`'s bits for one run (libm's, without its errno wrapper: `libm_exp`);
    /// lanes evaluate [`exp_lanes`] in every lane at once.
    fn exp_fast(self) -> Self;

    /// (sin x, cos x) per lane with libm's `sincos`'s bits (one range reduction for both):
    /// `libm::sincos` for one run, [`libm_sincos::sincos`] in every lane at once.
    fn sin_cos_each(self) -> (Self, Self);

    /// (sin x, cos x): `f64::sin_cos` for one run; lanes evaluate [`sin_cos_lanes`] in
    /// every lane at once. For the chain's frames, four times per RK4 substep and joint.
    fn sin_cos_fast(self) -> (Self, Self);

    /// A value from one f64 per lane.
    fn from_lanes(f: impl FnMut(usize) -> f64) -> Self;

    /// (sin(a + d), cos(a + d)) from s = sin a, c = cos a and a small d, by [`rotate_small`]
    /// in every lane. Lanes evaluate it over their arrays, as [`exp_lanes`] does: written on
    /// the lane type, LLVM split the 8-wide series into narrower pieces
    /// (docs/performance-history.md §22). Element-wise, so the bits are the same either way.
    fn rotate_small(s: Self, c: Self, d: Self) -> (Self, Self);

    /// a v for a 3×3 matrix, each row's sum taken left to right (the same bits either way).
    /// `f64` takes nalgebra's product, which LLVM vectorises across the three rows; lanes
    /// write it out, as nalgebra's generic product is not inlined into their AVX2 loop
    /// (each way measured the faster for its path, by 10 % and 3 % of a Panda sweep).
    fn mat3_vec(a: &Matrix3<Self>, v: &Vector3<Self>) -> Vector3<Self>;

    /// Whether the condition holds in every lane (for a scalar: whether it holds).
    #[inline(always)]
    fn all(mask: Self::SimdBool) -> bool {
        mask.all()
    }

    /// Whether the condition holds in no lane.
    #[inline(always)]
    fn none(mask: Self::SimdBool) -> bool {
        mask.none()
    }
}

impl Real for f64 {
    const LANES: usize = 1;

    #[inline(always)]
    fn exp_fast(self) -> Self {
        libm_exp::exp(self)
    }

    #[inline(always)]
    fn sin_cos_each(self) -> (Self, Self) {
        libm::sincos(self)
    }

    #[inline(always)]
    fn sin_cos_fast(self) -> (Self, Self) {
        self.sin_cos()
    }

    #[inline(always)]
    fn from_lanes(mut f: impl FnMut(usize) -> f64) -> Self {
        f(0)
    }

    #[inline(always)]
    fn rotate_small(s: f64, c: f64, d: f64) -> (f64, f64) {
        rotate_small(s, c, d)
    }

    #[inline(always)]
    fn mat3_vec(a: &Matrix3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
        a * v
    }
}

/// The lane types' `Real`: one body for every width (element-wise array code).
macro_rules! real_lanes {
    ($t:ty, $l:literal) => {
        impl Real for $t {
            const LANES: usize = $l;

            #[inline(always)]
            fn exp_fast(self) -> Self {
                simba::simd::AutoSimd(exp_lanes(self.0))
            }

            #[inline(always)]
            fn sin_cos_each(self) -> (Self, Self) {
                libm_sincos::sincos(self)
            }

            #[inline(always)]
            fn sin_cos_fast(self) -> (Self, Self) {
                let (s, c) = sin_cos_lanes(self.0);
                (simba::simd::AutoSimd(s), simba::simd::AutoSimd(c))
            }

            #[inline(always)]
            fn from_lanes(f: impl FnMut(usize) -> f64) -> Self {
                simba::simd::AutoSimd(std::array::from_fn(f))
            }

            #[inline(always)]
            fn rotate_small(s: Self, c: Self, d: Self) -> (Self, Self) {
                let r: [(f64, f64); $l] =
                    std::array::from_fn(|i| rotate_small(s.0[i], c.0[i], d.0[i]));
                (
                    simba::simd::AutoSimd(r.map(|p| p.0)),
                    simba::simd::AutoSimd(r.map(|p| p.1)),
                )
            }

            #[inline(always)]
            fn mat3_vec(a: &Matrix3<$t>, v: &Vector3<$t>) -> Vector3<$t> {
                Vector3::new(
                    a[(0, 0)] * v[0] + a[(0, 1)] * v[1] + a[(0, 2)] * v[2],
                    a[(1, 0)] * v[0] + a[(1, 1)] * v[1] + a[(1, 2)] * v[2],
                    a[(2, 0)] * v[0] + a[(2, 1)] * v[1] + a[(2, 2)] * v[2],
                )
            }
        }
    };
}

real_lanes!(F64x4, 4);
real_lanes!(F64x8, 8);

/// (sin(a + d), cos(a + d)) from s = sin a and c = cos a by angle addition, with sin d and
/// cos d from their Taylor series to d⁵ and d⁶: for |d| ≤ 1/128 the truncation is below
/// 4e-19, under half an ulp of 1.
#[inline(always)]
pub fn rotate_small(s: f64, c: f64, d: f64) -> (f64, f64) {
    rotate_small_in(s, c, d)
}

/// [`rotate_small`] written on any [`Real`]: the same operations in the same order, so
/// the same bits per lane. For `f64` and for lane types whose arithmetic is one vector
/// instruction per operation ([`F64x8Avx512`]).
#[inline(always)]
pub fn rotate_small_in<T: Real>(s: T, c: T, d: T) -> (T, T) {
    let one = T::one();
    // A joint at rest (d = ±0 in every lane: the yaw joint of every planar task): the series
    // below gives cd = 1 and sd = d exactly, so this is its result, bit for bit, without
    // the series' 15 operations.
    if T::all(d.simd_eq(T::zero())) {
        return (s + c * d, c - s * d);
    }
    let d2 = d * d;
    let sd = d * (one - d2 * T::splat(1.0 / 6.0) * (one - d2 * T::splat(1.0 / 20.0)));
    let cd = one
        - d2 * T::splat(0.5)
            * (one - d2 * T::splat(1.0 / 12.0) * (one - d2 * T::splat(1.0 / 30.0)));
    (s * cd + c * sd, c * cd - s * sd)
}

/// Lane `i` of `x` (lane 0 of a scalar).
#[inline(always)]
pub fn lane<T: Real>(x: T, i: usize) -> f64 {
    x.extract(i)
}

/// An all-zero R×C matrix (vector), built in place. nalgebra's `zeros()` fills its buffer
/// from an iterator of `Option<T>`; in the lanes' AVX2 loop each 32-byte item was stored
/// and then reloaded at an offset, a stalled store-to-load forward per entry (a 6×7 lane
/// Jacobian spent half its time there, measured).
#[inline(always)]
pub fn zeros<T: Real, const R: usize, const C: usize>() -> SMatrix<T, R, C> {
    SMatrix::from_array_storage(nalgebra::ArrayStorage([[T::zero(); R]; C]))
}

/// a × b, the same products and differences as nalgebra's `cross` (so the same bits),
/// written out so that it inlines: the release build left nalgebra's `cross` out of line in
/// the lanes' AVX2 loop (47 call sites, the URDF chain's spatial algebra among them), each
/// of its lane products and differences a call (docs/performance-history.md §25).
#[inline(always)]
pub fn cross<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    Vector3::new(
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )
}

/// m v, summed as nalgebra's `*` sums it (column by column, so the same bits), written out
/// so that it inlines: in the lanes' AVX2 loop LLVM left nalgebra's generic product out of
/// line, where it ran as baseline x86-64 code.
#[inline(always)]
pub fn mat_vec<T: Real, const R: usize, const C: usize>(
    m: &SMatrix<T, R, C>,
    v: &SVector<T, C>,
) -> SVector<T, R> {
    // The first column's products start the sums, as nalgebra's gemv starts them (not
    // 0 + m₀v₀, which would turn a −0 sum into +0).
    let mut y = zeros::<T, R, 1>();
    for r in 0..R {
        y[r] = m[(r, 0)] * v[0];
    }
    for k in 1..C {
        for r in 0..R {
            y[r] += m[(r, k)] * v[k];
        }
    }
    y
}

/// a b, summed as nalgebra's `*` sums it (each column of the product as [`mat_vec`] sums
/// a b_c, so the same bits), written out so that it inlines: the lanes' AVX2 loop called
/// nalgebra's 3×3 product out of line in the URDF pose task (docs/performance-history.md §26).
/// `K` ≥ 1.
#[inline(always)]
pub fn mat_mul<T: Real, const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<T, R, K>,
    b: &SMatrix<T, K, C>,
) -> SMatrix<T, R, C> {
    let mut y = zeros::<T, R, C>();
    for c in 0..C {
        for r in 0..R {
            y[(r, c)] = a[(r, 0)] * b[(0, c)];
        }
        for k in 1..K {
            for r in 0..R {
                y[(r, c)] += a[(r, k)] * b[(k, c)];
            }
        }
    }
    y
}

/// mᵀ v, summed as nalgebra's `m.transpose() * v` sums it; see [`mat_vec`].
#[inline(always)]
pub fn mat_t_vec<T: Real, const R: usize, const C: usize>(
    m: &SMatrix<T, R, C>,
    v: &SVector<T, R>,
) -> SVector<T, C> {
    let mut y = zeros::<T, C, 1>();
    for c in 0..C {
        y[c] = m[(0, c)] * v[0];
    }
    for k in 1..R {
        for c in 0..C {
            y[c] += m[(k, c)] * v[k];
        }
    }
    y
}

/// `x` as a `T` (every lane `x`).
#[inline(always)]
pub fn splat<T: Real>(x: f64) -> T {
    T::splat(x)
}

/// `yes()` in the lanes where `mask` holds, `no()` elsewhere. A scalar (or lanes that all
/// agree) evaluates only its branch, so the `f64` instantiation keeps the scalar code's
/// branch and its bits; mixed lanes evaluate both and select.
#[inline(always)]
pub fn choose<T: Real>(mask: T::SimdBool, yes: impl FnOnce() -> T, no: impl FnOnce() -> T) -> T {
    if T::all(mask) {
        yes()
    } else if T::none(mask) {
        no()
    } else {
        yes().select(mask, no())
    }
}

/// [`choose`] for vectors (one mask for every component).
#[inline(always)]
pub fn choose_vector<T: Real, const N: usize>(
    mask: T::SimdBool,
    yes: impl FnOnce() -> SVector<T, N>,
    no: impl FnOnce() -> SVector<T, N>,
) -> SVector<T, N> {
    if T::all(mask) {
        yes()
    } else if T::none(mask) {
        no()
    } else {
        // Built in place: nalgebra's `zip_map` stayed out of line in the lane builds.
        let (a, b) = (yes(), no());
        let mut out = a;
        for i in 0..N {
            out[i] = a[i].select(mask, b[i]);
        }
        out
    }
}

/// The lanes where `x` is finite (|x| < ∞ is false for ±∞ and NaN).
#[inline(always)]
pub fn finite<T: Real>(x: T) -> T::SimdBool {
    x.simd_abs().simd_lt(T::splat(f64::INFINITY))
}

/// The mask that holds in no lane.
#[inline(always)]
pub fn no_lane<T: Real>() -> T::SimdBool {
    T::zero().simd_ne(T::zero())
}

/// A mask from one bool per lane.
#[inline(always)]
pub fn mask_from<T: Real>(f: impl FnMut(usize) -> bool) -> T::SimdBool {
    let mut f = f;
    let ones = T::from_lanes(|i| if f(i) { 1.0 } else { 0.0 });
    ones.simd_gt(T::zero())
}

/// Sets lane `l` of `x` to `v`: how a lane takes a new run's parameters and state.
#[inline(always)]
pub fn put<T: Real>(x: &mut T, l: usize, v: f64) {
    x.replace(l, v);
}

/// [`put`] for each component of a vector.
#[inline(always)]
pub fn put_vector<T: Real, const R: usize, const C: usize>(
    x: &mut SMatrix<T, R, C>,
    l: usize,
    v: &SMatrix<f64, R, C>,
) {
    x.zip_apply(v, |a, b| a.replace(l, b));
}

/// Every lane's value, if every lane has one (how a group packs its optional stages).
#[inline]
pub fn every<T: Copy, const L: usize>(a: [Option<T>; L]) -> Option<[T; L]> {
    let first = a.iter().flatten().next().copied()?;
    a.iter()
        .all(Option::is_some)
        .then(|| a.map(|x| x.unwrap_or(first)))
}

/// Lane `l` of a vector.
#[inline(always)]
pub fn lane_of<T: Real, const R: usize, const C: usize>(
    x: &SMatrix<T, R, C>,
    l: usize,
) -> SMatrix<f64, R, C> {
    x.map(|v| v.extract(l))
}

/// A vector of lanes from one vector per lane.
#[inline(always)]
pub fn pack_vector<W: Wide<L>, const L: usize, const R: usize, const C: usize>(
    v: [&SMatrix<f64, R, C>; L],
) -> SMatrix<W, R, C> {
    SMatrix::<W, R, C>::from_fn(|r, c| W::from_lanes(|i| v[i][(r, c)]))
}

/// [`exp_lanes`]' constants (shared with the AVX-512 lane type's copy of its steps).
mod exp_consts {
    pub const LOG2_E: f64 = std::f64::consts::LOG2_E;
    /// 1.5·2⁵²: adding it rounds to an integer held in the low mantissa bits.
    pub const ROUND: f64 = 6_755_399_441_055_744.0;
    /// 0.693147180369123816490: ln 2's high part, with trailing zero bits.
    pub const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
    /// ln 2 − LN2_HI.
    pub const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    /// Beyond these e^x rounds to 0 or overflows.
    pub const LOW: f64 = -745.2;
    pub const HIGH: f64 = 709.782_712_893_384;
}

/// e^x in `L` lanes at once, with no branch and no table, so it vectorises. Element-wise:
/// a lane's bits do not depend on `L` nor on the other lanes.
///
/// x = n ln 2 + r with n = round(x / ln 2) (by the 1.5·2⁵² rounding trick) and
/// |r| ≤ ln 2 / 2 (Cody–Waite: ln 2 split in a high part with trailing zero bits, exact
/// in n·hi, and a low part); e^r by its Taylor series to r¹³ (truncation below 2e-17
/// relative), in Estrin's scheme for a short dependency chain; 2ⁿ by building the exponent
/// bits. Within 2 ulp of libm's e^x over the normal range (tested); 0 below −745.2,
/// +∞ above 709.78, NaN for NaN.
///
/// Each a·b + c is one fused multiply-add (`f64::mul_add`: one rounding, the same bits on
/// every CPU). In the lane builds that is one FMA instruction, and it shortens the chain
/// an RK4 stage waits on (joint friction's tanh starts here): fig. 19 sweeps about 4 % faster
/// on AVX-512 and 7 % on AVX2 (docs/performance-history.md §30). Where the CPU has no FMA (before
/// AVX2, where the portable lane loop runs) libm computes it exactly in software: the same
/// bits, more slowly. x is not clamped before the reduction: inside [−745.2, 709.78] a
/// clamp changes nothing, and outside it the selects at the end replace whatever the
/// reduction made, so leaving it out takes two steps off the chain and no bit changes.
#[inline(always)]
pub fn exp_lanes<const L: usize>(x: [f64; L]) -> [f64; L] {
    use exp_consts::{HIGH, LN2_HI, LN2_LO, LOG2_E, LOW, ROUND};
    // Written as whole-array steps with no branch, so each becomes one vector instruction.
    let t = x.map(|v| v.mul_add(LOG2_E, ROUND));
    let n = t.map(|v| v - ROUND);
    let r: [f64; L] =
        std::array::from_fn(|i| (-n[i]).mul_add(LN2_LO, (-n[i]).mul_add(LN2_HI, x[i])));
    // Estrin: e^r = Σ rᵏ/k!, k ≤ 13, paired so independent products run side by side.
    let poly = r.map(|r| {
        let r2 = r * r;
        let r4 = r2 * r2;
        let r8 = r4 * r4;
        let p01 = 1.0 + r;
        let p23 = r.mul_add(1.0 / 6.0, 1.0 / 2.0);
        let p45 = r.mul_add(1.0 / 120.0, 1.0 / 24.0);
        let p67 = r.mul_add(1.0 / 5040.0, 1.0 / 720.0);
        let p89 = r.mul_add(1.0 / 362_880.0, 1.0 / 40320.0);
        let p1011 = r.mul_add(1.0 / 39_916_800.0, 1.0 / 3_628_800.0);
        let p1213 = r.mul_add(1.0 / 6_227_020_800.0, 1.0 / 479_001_600.0);
        let p03 = r2.mul_add(p23, p01);
        let p47 = r2.mul_add(p67, p45);
        let p811 = r2.mul_add(p1011, p89);
        let p07 = r4.mul_add(p47, p03);
        let p813 = r4.mul_add(p1213, p811);
        r8.mul_add(p813, p07)
    });
    // 2ⁿ as 2^n1 · 2^n2 with n1 = round(n/2), each built from its exponent bits (an integer
    // k sits in the low bits of k + ROUND, two's complement), so both stay normal for x in
    // [LOW, HIGH] and a subnormal result rounds once, in the last product (outside that
    // range the selects below decide).
    let t1 = n.map(|v| v.mul_add(0.5, ROUND));
    let t2: [f64; L] = std::array::from_fn(|i| (n[i] - (t1[i] - ROUND)) + ROUND);
    let pow2 = |t: [f64; L]| {
        t.map(|v| {
            f64::from_bits(v.to_bits().wrapping_sub(ROUND.to_bits()).wrapping_add(1023) << 52)
        })
    };
    let (s1, s2) = (pow2(t1), pow2(t2));
    std::array::from_fn(|i| {
        let y = poly[i] * s1[i] * s2[i];
        let y = if x[i] < LOW { 0.0 } else { y };
        let y = if x[i] > HIGH { f64::INFINITY } else { y };
        if x[i].is_nan() {
            x[i]
        } else {
            y
        }
    })
}

/// (sin x, cos x) in `L` lanes at once, with no branch and no table, so it vectorises.
///
/// x = n π/2 + r with n = round(2x/π) and |r| ≤ π/4 (Cody–Waite: π/2 split in three parts,
/// the first two with 33 bits so n·part is exact for |n| < 2²⁰); sin r and cos r by their
/// Taylor series to r¹⁷ and r¹⁸ (truncation below 1e-19), Horner in r²; the quadrant n mod 4
/// swaps and negates them. Within 2 ulp of libm over the range joint angles take (tested).
/// A lane beyond ±2¹⁹ or not finite takes `f64::sin_cos` instead, alone: every lane's bits
/// are its own, whatever `L` and its neighbours (a 4-wide and an 8-wide table agree).
#[inline(always)]
pub fn sin_cos_lanes<const L: usize>(x: [f64; L]) -> ([f64; L], [f64; L]) {
    if !x.iter().all(|v| v.abs() <= SIN_COS_LIMIT) {
        return sin_cos_beyond(x);
    }
    sin_cos_reduced(x)
}

/// Beyond the reduction's limit (a diverging run): libm in the lanes beyond it, the
/// polynomial in the others (at 0 in the lanes replaced, then overwritten).
#[cold]
#[inline(never)]
fn sin_cos_beyond<const L: usize>(x: [f64; L]) -> ([f64; L], [f64; L]) {
    let inside = x.map(|v| v.abs() <= SIN_COS_LIMIT);
    let (mut s, mut c) =
        sin_cos_reduced(std::array::from_fn(|i| if inside[i] { x[i] } else { 0.0 }));
    for i in (0..L).filter(|&i| !inside[i]) {
        (s[i], c[i]) = x[i].sin_cos();
    }
    (s, c)
}

/// 2¹⁹: below it n·PIO2_1 and n·PIO2_2 are exact.
const SIN_COS_LIMIT: f64 = 524_288.0;

/// [`sin_cos_lanes`] for |x| ≤ 2¹⁹ in every lane.
#[inline(always)]
fn sin_cos_reduced<const L: usize>(x: [f64; L]) -> ([f64; L], [f64; L]) {
    const FRAC_2_PI: f64 = std::f64::consts::FRAC_2_PI;
    // 1.5·2⁵²: adding it rounds to an integer held in the low mantissa bits.
    const ROUND: f64 = 6_755_399_441_055_744.0;
    const PIO2_1: f64 = f64::from_bits(0x3ff9_21fb_5440_0000); // 1.5707963267341256
    const PIO2_2: f64 = f64::from_bits(0x3dd0_b461_1a60_0000); // 6.077100506303966e-11
    const PIO2_3: f64 = f64::from_bits(0x3ba3_198a_2e03_7073); // 2.0222662487959506e-21
    let t = x.map(|v| v * FRAC_2_PI + ROUND);
    let n = t.map(|v| v - ROUND);
    let r: [f64; L] =
        std::array::from_fn(|i| ((x[i] - n[i] * PIO2_1) - n[i] * PIO2_2) - n[i] * PIO2_3);
    let z = r.map(|r| r * r);
    // sin r = r + r z S(z), S = Σ (−1)ᵏ z^(k−1) / (2k+1)!, k = 1…8.
    let sin_r: [f64; L] = std::array::from_fn(|i| {
        let z = z[i];
        let s = 1.0 / 355_687_428_096_000.0;
        let s = -1.0 / 1_307_674_368_000.0 + z * s;
        let s = 1.0 / 6_227_020_800.0 + z * s;
        let s = -1.0 / 39_916_800.0 + z * s;
        let s = 1.0 / 362_880.0 + z * s;
        let s = -1.0 / 5040.0 + z * s;
        let s = 1.0 / 120.0 + z * s;
        let s = -1.0 / 6.0 + z * s;
        // At r = ±0 the sum would lose the sign of zero.
        if z == 0.0 {
            r[i]
        } else {
            r[i] + r[i] * z * s
        }
    });
    // cos r = 1 − z/2 + z² C(z), C = Σ (−1)ᵏ z^(k−2) / (2k)!, k = 2…9.
    let cos_r = z.map(|z| {
        let c = -1.0 / 6_402_373_705_728_000.0;
        let c = 1.0 / 20_922_789_888_000.0 + z * c;
        let c = -1.0 / 87_178_291_200.0 + z * c;
        let c = 1.0 / 479_001_600.0 + z * c;
        let c = -1.0 / 3_628_800.0 + z * c;
        let c = 1.0 / 40320.0 + z * c;
        let c = -1.0 / 720.0 + z * c;
        let c = 1.0 / 24.0 + z * c;
        1.0 - (0.5 * z - z * z * c)
    });
    // The quadrant q = n mod 4 from the integer's low bits: sin x = (s, c, −s, −c)[q],
    // cos x = (c, −s, −c, s)[q].
    let q = t.map(|v| v.to_bits().wrapping_sub(ROUND.to_bits()));
    let flip = |v: f64, sign: u64| f64::from_bits(v.to_bits() ^ (sign << 63));
    let sin = std::array::from_fn(|i| {
        let v = if q[i] & 1 == 1 { cos_r[i] } else { sin_r[i] };
        flip(v, (q[i] >> 1) & 1)
    });
    let cos = std::array::from_fn(|i| {
        let v = if q[i] & 1 == 1 { sin_r[i] } else { cos_r[i] };
        flip(v, (q[i].wrapping_add(1) >> 1) & 1)
    });
    (sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ulps(a: f64, b: f64) -> u64 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    /// A joint at rest takes the short form; it must be the series' value at d = ±0 bit for
    /// bit (signed zeros included), in `f64` and in the portable lane type (which rotates
    /// lane by lane). The native lane types are held to the same bits by the every-path
    /// comparisons of `sim::lanes::paths`.
    #[test]
    fn a_joint_at_rest_rotates_as_the_series_does() {
        // The series of `rotate_small_in`, written out here as the oracle.
        let series = |s: f64, c: f64, d: f64| {
            let d2 = d * d;
            let sd = d * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0)));
            let cd = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0)));
            (s * cd + c * sd, c * cd - s * sd)
        };
        let angles = [
            0.0,
            -0.0,
            0.3,
            -2.9,
            std::f64::consts::FRAC_PI_2,
            1e-300,
            3.0,
        ];
        for a in angles {
            let (s, c) = (libm::sin(a), libm::cos(a));
            for (s, c) in [(s, c), (-0.0, 1.0), (0.0, -1.0), (-0.0, -1.0)] {
                for d in [0.0, -0.0] {
                    let want = series(s, c, d);
                    let got = rotate_small(s, c, d);
                    assert_eq!(
                        (got.0.to_bits(), got.1.to_bits()),
                        (want.0.to_bits(), want.1.to_bits()),
                        "s {s:e}, c {c:e}, d {d:e}"
                    );
                    let lanes =
                        F64x4::rotate_small(F64x4::splat(s), F64x4::splat(c), F64x4::splat(d));
                    assert_eq!(lanes.0.extract(2).to_bits(), want.0.to_bits());
                    assert_eq!(lanes.1.extract(2).to_bits(), want.1.to_bits());
                }
            }
        }
        // A group where one lane moves: every lane is the series at its own d.
        let d = F64x4::from_lanes(|i| if i == 1 { 1e-3 } else { 0.0 });
        let (s, c) = F64x4::rotate_small(F64x4::splat(0.3), F64x4::splat(0.9), d);
        let want = series(0.3, 0.9, 1e-3);
        assert_eq!((s.extract(1), c.extract(1)), want);
        assert_eq!((s.extract(0), c.extract(0)), series(0.3, 0.9, 0.0));
    }

    /// Against libm's exp over the whole range, densely near 0 where friction evaluates it.
    #[test]
    fn exp_lanes_within_two_ulp_of_libm() {
        let mut worst = 0;
        let mut x: f64 = -708.0;
        while x < 709.2 {
            for d in [0.0, 1e-3, 0.25, 0.5] {
                let v = [
                    x + d,
                    -(x + d) * 1e-3,
                    (x + d) * 1e-6,
                    -(x + d).abs() * 0.05,
                ];
                let e = exp_lanes(v);
                for i in 0..4 {
                    worst = worst.max(ulps(e[i], libm::exp(v[i])));
                }
            }
            x += 0.37;
        }
        assert!(worst <= 2, "worst {worst} ulp");
    }

    #[test]
    fn exp_lanes_edges() {
        let e = exp_lanes([0.0, -800.0, 800.0, f64::NAN]);
        assert_eq!(e[0], 1.0);
        assert_eq!(e[1], 0.0);
        assert_eq!(e[2], f64::INFINITY);
        assert!(e[3].is_nan());
        let e = exp_lanes([f64::NEG_INFINITY, f64::INFINITY, -1e300, 1.0]);
        assert_eq!(e[..3], [0.0, f64::INFINITY, 0.0]);
        assert!(ulps(e[3], std::f64::consts::E) <= 1);
    }

    /// Against libm's sin and cos: densely over the angles joints take, sparsely out to the
    /// reduction's limit; the edges (±0, the limit, ±∞, NaN) take or match libm's values.
    #[test]
    fn sin_cos_lanes_within_two_ulp_of_libm() {
        let mut worst = 0;
        let mut check = |v: [f64; 4]| {
            let (s, c) = sin_cos_lanes(v);
            for i in 0..4 {
                worst = worst.max(ulps(s[i], v[i].sin()));
                worst = worst.max(ulps(c[i], v[i].cos()));
            }
        };
        let mut x: f64 = -20.0;
        while x < 20.0 {
            check([x, x + 1e-3, -(x * 0.01), x * 1e-7]);
            x += 0.000_731;
        }
        let mut x: f64 = 20.0;
        while x < 5e5 {
            check([x, -x, x * 1.000_1, -x * 0.999_9]);
            x *= 1.001;
        }
        assert!(worst <= 2, "worst {worst} ulp");
        let (s, c) = sin_cos_lanes([0.0, -0.0, 1e-300, std::f64::consts::FRAC_PI_2]);
        assert_eq!(s[..3], [0.0, -0.0, 1e-300]);
        assert!(s[1].is_sign_negative());
        assert_eq!(c[..3], [1.0, 1.0, 1.0]);
        assert!(ulps(s[3], 1.0) <= 1 && c[3].abs() < 1e-16);
        // A lane beyond the limit takes libm alone; its neighbours keep their own bits.
        let inside = sin_cos_lanes([0.5, 1.0, -0.5, 2.0]);
        for edge in [f64::INFINITY, f64::NAN, 1e300, -6e5] {
            let (s, c) = sin_cos_lanes([0.5, edge, -0.5, 2.0]);
            let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
            assert!(same(s[1], edge.sin()) && same(c[1], edge.cos()), "{edge}");
            for i in [0, 2, 3] {
                assert_eq!((s[i], c[i]), (inside.0[i], inside.1[i]), "{edge}");
            }
        }
    }

    /// Four lanes and eight give a lane the same bits: the polynomials are element-wise.
    #[test]
    fn four_and_eight_lanes_agree() {
        let x8: [f64; 8] = std::array::from_fn(|i| -3.7 + 1.3 * i as f64);
        let e8 = exp_lanes(x8);
        let (s8, c8) = sin_cos_lanes(x8);
        for half in 0..2 {
            let x4: [f64; 4] = std::array::from_fn(|i| x8[4 * half + i]);
            let (s4, c4) = sin_cos_lanes(x4);
            for i in 0..4 {
                assert_eq!(exp_lanes(x4)[i].to_bits(), e8[4 * half + i].to_bits());
                assert_eq!(s4[i].to_bits(), s8[4 * half + i].to_bits());
                assert_eq!(c4[i].to_bits(), c8[4 * half + i].to_bits());
            }
        }
        let a = F64x8::from_lanes(|i| x8[i]);
        assert_eq!(
            lane(a.exp_fast(), 5),
            lane(F64x4::from_lanes(|i| x8[4 + i]).exp_fast(), 1)
        );
    }

    /// Lanes are independent: a lane's value does not depend on its neighbours.
    #[test]
    fn lanes_do_not_mix() {
        let a = F64x4::from_lanes(|i| -0.3 * i as f64);
        let b = F64x4::from_lanes(|i| if i == 2 { -0.6 } else { 5.0 });
        assert_eq!(lane(a.exp_fast(), 2), lane(b.exp_fast(), 2));
        let (s, c) = a.sin_cos_each();
        assert_eq!((lane(s, 3), lane(c, 3)), libm::sincos(-0.3 * 3.0));
    }

    /// The written-out products are nalgebra's to the bit: a rounding-sensitive spread of
    /// magnitudes, and ±0 entries (a sum starting at +0 would turn −0 into +0).
    #[test]
    fn written_out_products_are_nalgebra_s_bits() {
        let entry = |i: usize| {
            let x = (i as f64 * 0.7548).sin() * 10f64.powi((i % 7) as i32 - 3);
            if i.is_multiple_of(5) {
                -0.0 * x.signum()
            } else {
                x
            }
        };
        let a = SMatrix::<f64, 3, 4>::from_fn(|r, c| entry(3 * c + r));
        let b = SMatrix::<f64, 4, 2>::from_fn(|r, c| entry(17 + 4 * c + r));
        let v = SVector::<f64, 4>::from_fn(|r, _| -entry(31 + r));
        let bits = |m: &[f64]| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(mat_mul(&a, &b).as_slice()), bits((a * b).as_slice()));
        assert_eq!(bits(mat_vec(&a, &v).as_slice()), bits((a * v).as_slice()));
        let r = a.fixed_rows::<3>(0).fixed_columns::<3>(0).into_owned();
        let bt = b.fixed_rows::<3>(0).into_owned();
        let w = Vector3::new(bt[0], bt[1], bt[2]);
        let u = Vector3::new(bt[3], bt[4], bt[5]);
        assert_eq!(bits(cross(&w, &u).as_slice()), bits(w.cross(&u).as_slice()));
        assert_eq!(
            bits(mat_mul(&r, &r.transpose()).as_slice()),
            bits((r * r.transpose()).as_slice())
        );
    }
}
