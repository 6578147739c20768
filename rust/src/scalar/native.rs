//! Lane types held in native x86 vector registers (issue #25): [`Lanes`] over an [`Isa`],
//! [`F64x8Avx512`] (one zmm register, a `k` mask) for the AVX-512 build of the lane loop and
//! [`F64x4Avx2`] (one ymm register, a ymm mask) for the AVX2 build.
//!
//! Why not simba's array-backed `AutoSimd` there: its element-wise loops are left to LLVM's
//! SLP vectoriser, which at eight wide assembled zmm registers from xmm pieces and unpacked
//! every lane mask bit by bit: 170k extra instructions, and the 8-wide build ran 27 % slower
//! than the 4-wide one (docs/performance-history.md §22). Here each arithmetic operation is one
//! instruction and a condition stays in a mask register.
//!
//! Bits: the arithmetic (+ − × ÷ √, |x|, −x, copysign) is the same IEEE operation per lane,
//! never contracted into an FMA; comparisons are the ordered ones f64's `<`, `>`, `<=`,
//! `>=`, `==` use (`!=` unordered); e^x repeats [`super::exp_lanes`]' steps in its order,
//! its fused multiply-adds included (`Isa::fma` here, `mul_add` there: one rounding each).
//! Every other operation (trig, powers, min/max, ...) is taken lane by lane through the
//! matching `AutoSimd`, so it gives that type's bits. The tests below compare each operation
//! with `AutoSimd` bit for bit; the lane loop's tests compare whole runs on every build.
//!
//! Safety: every method may execute the ISA's instructions (AVX-512 F; AVX and AVX2; FMA in e^x,
//! which both builds are compiled for and `LanePath::available` checks). A lane type is only
//! instantiated inside the lane-loop build compiled for its ISA (`sim::lanes::builds::avx512::run`,
//! `builds::avx2::run`), which is entered after `LanePath::available` detected the features;
//! nothing else may use it. Code the build does not inline calls each intrinsic as a function:
//! correct, but slow, so the hot paths are `inline(always)`.

use std::fmt;
use std::ops::{
    Add, AddAssign, BitAnd, BitOr, BitXor, Div, DivAssign, Mul, MulAssign, Neg, Not, Rem,
    RemAssign, Sub, SubAssign,
};

use nalgebra::{Matrix3, Vector3};
use num_traits::{Num, One, Zero};
use simba::scalar::{Field, SubsetOf};
use simba::simd::{
    PrimitiveSimdValue, SimdBool, SimdComplexField, SimdPartialOrd, SimdRealField, SimdSigned,
    SimdValue,
};

use super::{rotate_small_in, sin_cos_lanes, Real, Wide};

mod avx2;
mod avx512;
mod mask;

pub use avx2::Avx2;
pub use avx512::Avx512;

/// Eight f64 lanes in one AVX-512 register, for the AVX-512 build of the lane loop.
pub type F64x8Avx512 = Lanes<Avx512, 8>;

/// Four f64 lanes in one AVX2 (ymm) register, for the AVX2 build of the lane loop.
pub type F64x4Avx2 = Lanes<Avx2, 4>;

/// An instruction set's `L`-lane f64 register: the few primitive operations [`Lanes`] is
/// built from. Each is one instruction (or a short fixed sequence) of the ISA.
pub trait Isa<const L: usize>: Copy + Send + Sync + 'static {
    /// The vector register.
    type V: Copy + Send + Sync + 'static;
    /// A condition per lane.
    type M: Copy + Send + Sync + 'static;
    /// simba's array-backed type of the same width, for the operations taken lane by lane.
    type Auto: SimdRealField<Element = f64> + Copy;

    fn to_array(v: Self::V) -> [f64; L];
    fn from_array(a: [f64; L]) -> Self::V;
    /// The vector of `L` values held one by one (in registers), built by register moves:
    /// `from_array` of an array just written one value at a time is a wide load of
    /// narrow stores, which the CPU cannot forward (a stall per gather).
    fn set(a: [f64; L]) -> Self::V;
    fn auto(a: [f64; L]) -> Self::Auto;
    fn auto_array(a: Self::Auto) -> [f64; L];

    fn splat(x: f64) -> Self::V;
    fn add(a: Self::V, b: Self::V) -> Self::V;
    fn sub(a: Self::V, b: Self::V) -> Self::V;
    fn mul(a: Self::V, b: Self::V) -> Self::V;
    fn div(a: Self::V, b: Self::V) -> Self::V;
    /// a·b + c rounded once (the FMA instruction), for e^x only (see the module note).
    fn fma(a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    fn sqrt(a: Self::V) -> Self::V;
    /// The sign bit cleared.
    fn abs(a: Self::V) -> Self::V;
    /// The sign bit flipped.
    fn neg(a: Self::V) -> Self::V;
    /// `a`'s magnitude bits with `sign`'s sign bit.
    fn copysign(a: Self::V, sign: Self::V) -> Self::V;
    /// The hardware's max / min: `b` when either is NaN or they are equal.
    fn max(a: Self::V, b: Self::V) -> Self::V;
    fn min(a: Self::V, b: Self::V) -> Self::V;
    /// (bits(t) − bits(ROUND) + 1023) << 52 per lane, wrapping: 2ⁿ from `exp_lanes`' n.
    fn pow2_of_rounded(t: Self::V, round: f64) -> Self::V;

    fn lt(a: Self::V, b: Self::V) -> Self::M;
    fn gt(a: Self::V, b: Self::V) -> Self::M;
    fn le(a: Self::V, b: Self::V) -> Self::M;
    fn ge(a: Self::V, b: Self::V) -> Self::M;
    fn eq(a: Self::V, b: Self::V) -> Self::M;
    /// Unordered not-equal (true when either is NaN), as f64's `!=`.
    fn ne(a: Self::V, b: Self::V) -> Self::M;
    /// Either is NaN.
    fn unordered(a: Self::V, b: Self::V) -> Self::M;
    /// `yes` in the lanes of `mask`, `no` elsewhere.
    fn blend(mask: Self::M, no: Self::V, yes: Self::V) -> Self::V;

    /// Bit i holds lane i's condition.
    fn mask_bits(m: Self::M) -> u8;
    fn mask_from_bits(bits: u8) -> Self::M;
    fn mask_and(a: Self::M, b: Self::M) -> Self::M;
    fn mask_or(a: Self::M, b: Self::M) -> Self::M;
    fn mask_xor(a: Self::M, b: Self::M) -> Self::M;
    fn mask_not(a: Self::M) -> Self::M;
}

/// `L` f64 lanes in one register of the ISA `I` (see the module's safety note).
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct Lanes<I: Isa<L>, const L: usize>(I::V);

/// A condition per lane of [`Lanes`], in the ISA's mask form.
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct LaneMask<I: Isa<L>, const L: usize>(I::M);

/// All `L` lanes' bits set.
const fn full(l: usize) -> u8 {
    ((1u16 << l) - 1) as u8
}

impl<I: Isa<L>, const L: usize> Lanes<I, L> {
    #[inline(always)]
    fn to_array(self) -> [f64; L] {
        I::to_array(self.0)
    }

    #[inline(always)]
    fn from_array(a: [f64; L]) -> Self {
        Self(I::from_array(a))
    }

    #[inline(always)]
    fn auto(self) -> I::Auto {
        I::auto(self.to_array())
    }

    #[inline(always)]
    fn from_auto(a: I::Auto) -> Self {
        Self::from_array(I::auto_array(a))
    }

    #[inline(always)]
    fn mask_of_auto(m: <I::Auto as SimdValue>::SimdBool) -> LaneMask<I, L> {
        LaneMask(I::mask_from_bits(m.bitmask() as u8))
    }

    /// e^x: [`super::exp_lanes`]' steps, one instruction each, in its order (so its bits;
    /// tested). Written here because the array version's element loops stayed out of line
    /// in the native builds.
    #[inline(always)]
    fn exp_native(self) -> Self {
        use super::exp_consts::{HIGH, LN2_HI, LN2_LO, LOG2_E, LOW, ROUND};
        let c = Self::splat;
        let f = |a: Self, b: Self, d: Self| Self(I::fma(a.0, b.0, d.0));
        let x = self;
        let t = f(x, c(LOG2_E), c(ROUND));
        let n = t - c(ROUND);
        let r = f(-n, c(LN2_LO), f(-n, c(LN2_HI), x));
        let r2 = r * r;
        let r4 = r2 * r2;
        let r8 = r4 * r4;
        let p01 = c(1.0) + r;
        let p23 = f(r, c(1.0 / 6.0), c(1.0 / 2.0));
        let p45 = f(r, c(1.0 / 120.0), c(1.0 / 24.0));
        let p67 = f(r, c(1.0 / 5040.0), c(1.0 / 720.0));
        let p89 = f(r, c(1.0 / 362_880.0), c(1.0 / 40320.0));
        let p1011 = f(r, c(1.0 / 39_916_800.0), c(1.0 / 3_628_800.0));
        let p1213 = f(r, c(1.0 / 6_227_020_800.0), c(1.0 / 479_001_600.0));
        let p03 = f(r2, p23, p01);
        let p47 = f(r2, p67, p45);
        let p811 = f(r2, p1011, p89);
        let p07 = f(r4, p47, p03);
        let p813 = f(r4, p1213, p811);
        let poly = f(r8, p813, p07);
        let t1 = f(n, c(0.5), c(ROUND));
        let t2 = (n - (t1 - c(ROUND))) + c(ROUND);
        let pow2 = |t: Self| Self(I::pow2_of_rounded(t.0, ROUND));
        let y = poly * pow2(t1) * pow2(t2);
        let y = c(0.0).select(self.simd_lt(c(LOW)), y);
        let y = c(f64::INFINITY).select(self.simd_gt(c(HIGH)), y);
        self.select(LaneMask(I::unordered(self.0, self.0)), y)
    }
}

impl<I: Isa<L>, const L: usize> fmt::Debug for Lanes<I, L> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.to_array().fmt(f)
    }
}

impl<I: Isa<L>, const L: usize> Default for Lanes<I, L> {
    #[inline(always)]
    fn default() -> Self {
        Self::from_array([0.0; L])
    }
}

impl<I: Isa<L>, const L: usize> PartialEq for Lanes<I, L> {
    #[inline(always)]
    fn eq(&self, other: &Self) -> bool {
        self.to_array() == other.to_array()
    }
}

impl<I: Isa<L>, const L: usize> SimdValue for Lanes<I, L> {
    const LANES: usize = L;
    type Element = f64;
    type SimdBool = LaneMask<I, L>;

    #[inline(always)]
    fn splat(val: f64) -> Self {
        Self(I::splat(val))
    }

    #[inline(always)]
    fn extract(&self, i: usize) -> f64 {
        self.to_array()[i]
    }

    #[inline(always)]
    unsafe fn extract_unchecked(&self, i: usize) -> f64 {
        // SAFETY: the caller promises i < L.
        unsafe { *self.to_array().get_unchecked(i) }
    }

    #[inline(always)]
    fn replace(&mut self, i: usize, val: f64) {
        let mut a = self.to_array();
        a[i] = val;
        *self = Self::from_array(a);
    }

    #[inline(always)]
    unsafe fn replace_unchecked(&mut self, i: usize, val: f64) {
        let mut a = self.to_array();
        // SAFETY: the caller promises i < L.
        unsafe { *a.get_unchecked_mut(i) = val };
        *self = Self::from_array(a);
    }

    #[inline(always)]
    fn select(self, cond: Self::SimdBool, other: Self) -> Self {
        Self(I::blend(cond.0, other.0, self.0))
    }
}

impl<I: Isa<L>, const L: usize> PrimitiveSimdValue for Lanes<I, L> {}

/// The IEEE operations, one instruction each.
macro_rules! arithmetic {
    ($($op:ident $f:ident $assign:ident $fa:ident),*) => {$(
        impl<I: Isa<L>, const L: usize> $op for Lanes<I, L> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, rhs: Self) -> Self {
                Self(I::$f(self.0, rhs.0))
            }
        }

        impl<I: Isa<L>, const L: usize> $assign for Lanes<I, L> {
            #[inline(always)]
            fn $fa(&mut self, rhs: Self) {
                *self = $op::$f(*self, rhs);
            }
        }
    )*};
}

arithmetic!(
    Add add AddAssign add_assign,
    Sub sub SubAssign sub_assign,
    Mul mul MulAssign mul_assign,
    Div div DivAssign div_assign
);

impl<I: Isa<L>, const L: usize> Rem for Lanes<I, L> {
    type Output = Self;
    #[inline(always)]
    fn rem(self, rhs: Self) -> Self {
        Self::from_auto(self.auto() % rhs.auto())
    }
}

impl<I: Isa<L>, const L: usize> RemAssign for Lanes<I, L> {
    #[inline(always)]
    fn rem_assign(&mut self, rhs: Self) {
        *self = *self % rhs;
    }
}

impl<I: Isa<L>, const L: usize> Neg for Lanes<I, L> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        // The sign bit flipped, as f64's `-x` (0 − x would turn −0 into +0).
        Self(I::neg(self.0))
    }
}

impl<I: Isa<L>, const L: usize> Zero for Lanes<I, L> {
    #[inline(always)]
    fn zero() -> Self {
        Self::splat(0.0)
    }

    #[inline(always)]
    fn is_zero(&self) -> bool {
        *self == Self::zero()
    }
}

impl<I: Isa<L>, const L: usize> One for Lanes<I, L> {
    #[inline(always)]
    fn one() -> Self {
        Self::splat(1.0)
    }
}

impl<I: Isa<L>, const L: usize> Num for Lanes<I, L> {
    type FromStrRadixErr = <f64 as Num>::FromStrRadixErr;

    fn from_str_radix(str: &str, radix: u32) -> Result<Self, Self::FromStrRadixErr> {
        f64::from_str_radix(str, radix).map(Self::splat)
    }
}

impl<I: Isa<L>, const L: usize> Field for Lanes<I, L> {}

impl<I: Isa<L>, const L: usize> SubsetOf<Lanes<I, L>> for Lanes<I, L> {
    #[inline(always)]
    fn to_superset(&self) -> Self {
        *self
    }

    #[inline(always)]
    fn from_superset_unchecked(element: &Self) -> Self {
        *element
    }

    #[inline(always)]
    fn is_in_subset(_: &Self) -> bool {
        true
    }
}

/// f64 and f32 as every lane of the lane type, as simba embeds them in its own lane types.
macro_rules! scalar_subset {
    ($($t:ty),*) => {$(
        impl<I: Isa<L>, const L: usize> SubsetOf<Lanes<I, L>> for $t {
            #[inline(always)]
            fn to_superset(&self) -> Lanes<I, L> {
                Lanes::splat(f64::from(*self))
            }

            #[inline(always)]
            fn from_superset_unchecked(element: &Lanes<I, L>) -> Self {
                // simba's own lane types take lane 0 the same way.
                element.extract(0) as $t
            }

            #[inline(always)]
            fn is_in_subset(element: &Lanes<I, L>) -> bool {
                let a = element.to_array();
                a.iter().all(|v| *v == a[0])
            }
        }
    )*};
}

scalar_subset!(f32, f64);

impl<I: Isa<L>, const L: usize> SimdPartialOrd for Lanes<I, L> {
    #[inline(always)]
    fn simd_gt(self, other: Self) -> Self::SimdBool {
        LaneMask(I::gt(self.0, other.0))
    }

    #[inline(always)]
    fn simd_lt(self, other: Self) -> Self::SimdBool {
        LaneMask(I::lt(self.0, other.0))
    }

    #[inline(always)]
    fn simd_ge(self, other: Self) -> Self::SimdBool {
        LaneMask(I::ge(self.0, other.0))
    }

    #[inline(always)]
    fn simd_le(self, other: Self) -> Self::SimdBool {
        LaneMask(I::le(self.0, other.0))
    }

    #[inline(always)]
    fn simd_eq(self, other: Self) -> Self::SimdBool {
        LaneMask(I::eq(self.0, other.0))
    }

    #[inline(always)]
    fn simd_ne(self, other: Self) -> Self::SimdBool {
        LaneMask(I::ne(self.0, other.0))
    }

    #[inline(always)]
    fn simd_max(self, other: Self) -> Self {
        Self::from_auto(self.auto().simd_max(other.auto()))
    }

    #[inline(always)]
    fn simd_min(self, other: Self) -> Self {
        Self::from_auto(self.auto().simd_min(other.auto()))
    }

    #[inline(always)]
    fn simd_clamp(self, min: Self, max: Self) -> Self {
        Self::from_auto(self.auto().simd_clamp(min.auto(), max.auto()))
    }

    #[inline(always)]
    fn simd_horizontal_min(self) -> f64 {
        self.auto().simd_horizontal_min()
    }

    #[inline(always)]
    fn simd_horizontal_max(self) -> f64 {
        self.auto().simd_horizontal_max()
    }
}

impl<I: Isa<L>, const L: usize> SimdSigned for Lanes<I, L> {
    #[inline(always)]
    fn simd_abs(&self) -> Self {
        Self(I::abs(self.0))
    }

    #[inline(always)]
    fn simd_abs_sub(&self, other: &Self) -> Self {
        Self::from_auto(self.auto().simd_abs_sub(&other.auto()))
    }

    #[inline(always)]
    fn simd_signum(&self) -> Self {
        Self::from_auto(SimdSigned::simd_signum(&self.auto()))
    }

    #[inline(always)]
    fn is_simd_positive(&self) -> Self::SimdBool {
        Self::mask_of_auto(self.auto().is_simd_positive())
    }

    #[inline(always)]
    fn is_simd_negative(&self) -> Self::SimdBool {
        Self::mask_of_auto(self.auto().is_simd_negative())
    }
}

/// Methods taken lane by lane through the array-backed type (its bits exactly):
/// `self` → `Self`.
macro_rules! by_auto_unary {
    ($tr:ident: $($f:ident),*) => {$(
        #[inline(always)]
        fn $f(self) -> Self {
            Self::from_auto(<I::Auto as $tr>::$f(self.auto()))
        }
    )*};
}

/// As [`by_auto_unary`], for `(self, other)` → `Self`.
macro_rules! by_auto_binary {
    ($tr:ident: $($f:ident),*) => {$(
        #[inline(always)]
        fn $f(self, other: Self) -> Self {
            Self::from_auto(<I::Auto as $tr>::$f(self.auto(), other.auto()))
        }
    )*};
}

/// As [`by_auto_unary`], for constants.
macro_rules! by_auto_const {
    ($($f:ident),*) => {$(
        #[inline(always)]
        fn $f() -> Self {
            Self::from_auto(<I::Auto as SimdRealField>::$f())
        }
    )*};
}

impl<I: Isa<L>, const L: usize> SimdRealField for Lanes<I, L> {
    by_auto_binary!(SimdRealField: simd_atan2);
    by_auto_const!(
        simd_default_epsilon,
        simd_pi,
        simd_two_pi,
        simd_frac_pi_2,
        simd_frac_pi_3,
        simd_frac_pi_4,
        simd_frac_pi_6,
        simd_frac_pi_8,
        simd_frac_1_pi,
        simd_frac_2_pi,
        simd_frac_2_sqrt_pi,
        simd_e,
        simd_log2_e,
        simd_log10_e,
        simd_ln_2,
        simd_ln_10
    );

    #[inline(always)]
    fn simd_copysign(self, sign: Self) -> Self {
        Self(I::copysign(self.0, sign.0))
    }
}

impl<I: Isa<L>, const L: usize> SimdComplexField for Lanes<I, L> {
    type SimdRealField = Self;

    by_auto_unary!(SimdComplexField:
        simd_floor, simd_ceil, simd_round, simd_trunc, simd_fract, simd_recip,
        simd_signum, simd_sin, simd_cos, simd_tan, simd_asin, simd_acos, simd_atan,
        simd_sinh, simd_cosh, simd_tanh, simd_asinh, simd_acosh, simd_atanh,
        simd_log2, simd_log10, simd_ln, simd_ln_1p, simd_exp, simd_exp2, simd_exp_m1,
        simd_cbrt, simd_argument, simd_norm1
    );
    by_auto_binary!(SimdComplexField: simd_powf, simd_powc, simd_log, simd_hypot);

    #[inline(always)]
    fn from_simd_real(re: Self) -> Self {
        re
    }

    #[inline(always)]
    fn simd_real(self) -> Self {
        self
    }

    #[inline(always)]
    fn simd_imaginary(self) -> Self {
        Self::zero()
    }

    #[inline(always)]
    fn simd_conjugate(self) -> Self {
        self
    }

    #[inline(always)]
    fn simd_modulus(self) -> Self {
        SimdSigned::simd_abs(&self)
    }

    #[inline(always)]
    fn simd_abs(self) -> Self {
        SimdSigned::simd_abs(&self)
    }

    #[inline(always)]
    fn simd_modulus_squared(self) -> Self {
        self * self
    }

    #[inline(always)]
    fn simd_scale(self, factor: Self) -> Self {
        self * factor
    }

    #[inline(always)]
    fn simd_unscale(self, factor: Self) -> Self {
        self / factor
    }

    #[inline(always)]
    fn simd_sqrt(self) -> Self {
        // Correctly rounded, as f64::sqrt.
        Self(I::sqrt(self.0))
    }

    #[inline(always)]
    fn simd_to_exp(self) -> (Self, Self) {
        let (m, u) = self.auto().simd_to_exp();
        (Self::from_auto(m), Self::from_auto(u))
    }

    #[inline(always)]
    fn simd_mul_add(self, a: Self, b: Self) -> Self {
        Self::from_auto(self.auto().simd_mul_add(a.auto(), b.auto()))
    }

    #[inline(always)]
    fn simd_powi(self, n: i32) -> Self {
        Self::from_auto(self.auto().simd_powi(n))
    }

    #[inline(always)]
    fn simd_sin_cos(self) -> (Self, Self) {
        let (s, c) = self.auto().simd_sin_cos();
        (Self::from_auto(s), Self::from_auto(c))
    }

    #[inline(always)]
    fn simd_horizontal_sum(self) -> f64 {
        self.auto().simd_horizontal_sum()
    }

    #[inline(always)]
    fn simd_horizontal_product(self) -> f64 {
        self.auto().simd_horizontal_product()
    }
}

impl<I: Isa<L>, const L: usize> Real for Lanes<I, L> {
    const LANES: usize = L;

    #[inline(always)]
    fn exp_fast(self) -> Self {
        self.exp_native()
    }

    #[inline(always)]
    fn sin_cos_each(self) -> (Self, Self) {
        super::libm_sincos::sincos(self)
    }

    #[inline(always)]
    fn sin_cos_fast(self) -> (Self, Self) {
        let (s, c) = sin_cos_lanes(self.to_array());
        (Self::from_array(s), Self::from_array(c))
    }

    #[inline(always)]
    fn from_lanes(f: impl FnMut(usize) -> f64) -> Self {
        Self(I::set(std::array::from_fn(f)))
    }

    #[inline(always)]
    fn rotate_small(s: Self, c: Self, d: Self) -> (Self, Self) {
        rotate_small_in(s, c, d)
    }

    #[inline(always)]
    fn mat3_vec(a: &Matrix3<Self>, v: &Vector3<Self>) -> Vector3<Self> {
        Vector3::new(
            a[(0, 0)] * v[0] + a[(0, 1)] * v[1] + a[(0, 2)] * v[2],
            a[(1, 0)] * v[0] + a[(1, 1)] * v[1] + a[(1, 2)] * v[2],
            a[(2, 0)] * v[0] + a[(2, 1)] * v[1] + a[(2, 2)] * v[2],
        )
    }
}

impl Wide<8> for F64x8Avx512 {}
impl Wide<4> for F64x4Avx2 {}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::lanes::LanePath;

    /// Awkward values: signed zeros, subnormals, infinities, NaN, huge and tiny numbers.
    const SPECIAL: [f64; 16] = [
        0.0,
        -0.0,
        1.0,
        -2.5,
        f64::MIN_POSITIVE / 4.0,
        -f64::MIN_POSITIVE,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NAN,
        1e300,
        -1e-300,
        3.0e-3,
        -7.25,
        0.5,
        f64::MAX,
        -1.0,
    ];

    fn bits<const L: usize>(x: [f64; L]) -> [u64; L] {
        x.map(f64::to_bits)
    }

    /// Whether this CPU runs the ISA's lane type (else the test says so and passes).
    fn runs(path: LanePath) -> bool {
        let ok = path.available();
        if !ok {
            eprintln!("skipped: this CPU cannot run the {} lane type", path.name());
        }
        ok
    }

    /// Every native operation against simba's array-backed type, bit for bit, on every
    /// pair of awkward values (the lane loop's tests cover them as the stages use them).
    fn ops_equal_array_lanes<I: Isa<L>, const L: usize>()
    where
        I::Auto: Real,
    {
        let native = |a: Lanes<I, L>| bits(a.to_array());
        let auto = |a: I::Auto| bits(I::auto_array(a));
        for i in 0..SPECIAL.len() {
            for j in 0..SPECIAL.len() {
                let x: [f64; L] = std::array::from_fn(|l| SPECIAL[(i + l) % 16]);
                let y: [f64; L] = std::array::from_fn(|l| SPECIAL[(j + 3 * l) % 16]);
                let (a, b) = (Lanes::<I, L>::from_array(x), Lanes::<I, L>::from_array(y));
                let (p, q) = (I::auto(x), I::auto(y));
                assert_eq!(native(a + b), auto(p + q), "{x:?} + {y:?}");
                assert_eq!(native(a - b), auto(p - q), "{x:?} - {y:?}");
                assert_eq!(native(a * b), auto(p * q), "{x:?} * {y:?}");
                assert_eq!(native(a / b), auto(p / q), "{x:?} / {y:?}");
                assert_eq!(native(a % b), auto(p % q), "{x:?} % {y:?}");
                assert_eq!(native(-a), auto(-p));
                assert_eq!(
                    native(SimdSigned::simd_abs(&a)),
                    auto(SimdSigned::simd_abs(&p))
                );
                assert_eq!(native(a.simd_sqrt()), auto(p.simd_sqrt()));
                assert_eq!(native(a.simd_max(b)), auto(p.simd_max(q)));
                assert_eq!(native(a.simd_min(b)), auto(p.simd_min(q)));
                assert_eq!(native(a.exp_fast()), auto(p.exp_fast()));
                assert_eq!(native(a.simd_copysign(b)), auto(p.simd_copysign(q)));
                assert_eq!(native(a.simd_sin()), auto(p.simd_sin()));
                let masks = [
                    (a.simd_lt(b), p.simd_lt(q)),
                    (a.simd_gt(b), p.simd_gt(q)),
                    (a.simd_le(b), p.simd_le(q)),
                    (a.simd_ge(b), p.simd_ge(q)),
                    (a.simd_eq(b), p.simd_eq(q)),
                    (a.simd_ne(b), p.simd_ne(q)),
                ];
                for (k, (m, n)) in masks.into_iter().enumerate() {
                    assert_eq!(m.bitmask(), n.bitmask(), "comparison {k} of {x:?}, {y:?}");
                    assert_eq!(native(a.select(m, b)), auto(p.select(n, q)));
                    assert_eq!((m.all(), m.any(), m.none()), (n.all(), n.any(), n.none()));
                    assert_eq!((!m).bitmask(), (!n).bitmask());
                }
                let d = Lanes::<I, L>::splat(1e-3);
                let (s, c) = Lanes::<I, L>::rotate_small(a, b, a * d);
                let (t, e) = I::Auto::rotate_small(p, q, p * I::Auto::splat(1e-3));
                assert_eq!((native(s), native(c)), (auto(t), auto(e)));
            }
        }
    }

    /// e^x over its whole range, the edges (−745.2, 709.78) and the subnormal results.
    fn exp_equals_exp_lanes<I: Isa<L>, const L: usize>() {
        let check = |v: [f64; L]| {
            let native = Lanes::<I, L>::from_array(v).exp_fast().to_array();
            assert_eq!(bits(native), bits(crate::scalar::exp_lanes(v)), "{v:?}");
        };
        let mut x = -760.0;
        while x < 720.0 {
            let v: [f64; L] = std::array::from_fn(|l| x + 0.173 * l as f64);
            check(v);
            check(v.map(|v| v / 97.0));
            x += 1.37;
        }
        for edge in [
            -745.2,
            -745.1,
            -708.4,
            709.782_712_893_384,
            709.79,
            f64::MIN,
            -0.0,
        ] {
            let around = [
                edge,
                edge.next_up(),
                edge.next_down(),
                -edge,
                0.0,
                1e-300,
                -1e-300,
                f64::NAN,
            ];
            check(std::array::from_fn(|l| around[l]));
            check(std::array::from_fn(|l| around[8 - L + l]));
        }
    }

    fn lanes_are_set_and_read_one_at_a_time<I: Isa<L>, const L: usize>() {
        let mut a = Lanes::<I, L>::from_lanes(|i| i as f64);
        a.replace(L - 1, -1.5);
        assert_eq!(a.extract(L - 1), -1.5);
        assert_eq!(a.extract(1), 1.0);
        let mut m = LaneMask::<I, L>::splat(false);
        m.replace(1, true);
        m.replace(L - 1, true);
        assert_eq!(m.bitmask(), 0b10 | 1 << (L - 1));
        assert!(m.extract(L - 1) && !m.extract(0));
        assert_eq!((m.any(), m.all(), (!m).any()), (true, false, true));
        let picked = Lanes::<I, L>::splat(9.0).select(m, a).to_array();
        let expected: [f64; L] = std::array::from_fn(|i| match i {
            1 => 9.0,
            i if i == L - 1 => 9.0,
            i => i as f64,
        });
        assert_eq!(picked, expected);
    }

    #[test]
    fn avx512_lanes_equal_array_lanes_bit_for_bit() {
        if runs(LanePath::Avx512) {
            ops_equal_array_lanes::<Avx512, 8>();
            exp_equals_exp_lanes::<Avx512, 8>();
            lanes_are_set_and_read_one_at_a_time::<Avx512, 8>();
        }
    }

    #[test]
    fn avx2_lanes_equal_array_lanes_bit_for_bit() {
        if runs(LanePath::Avx2) {
            ops_equal_array_lanes::<Avx2, 4>();
            exp_equals_exp_lanes::<Avx2, 4>();
            lanes_are_set_and_read_one_at_a_time::<Avx2, 4>();
        }
    }
}
