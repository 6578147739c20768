//! libm's `sincos` (the `libm` crate's, FreeBSD's msun by way of musl) in every lane at once,
//! bit for bit.
//!
//! The three-link arm's scalar run takes its trig once per control period from
//! `libm::sincos`, and its runs in lanes must give the same bits. Until session 32 each lane
//! called `libm::sincos` on its own, three times per period: about 12 % of a fig. 19 sweep's
//! time at one substep (docs/performance-history.md §34). Here the same operations run on the lane
//! type, so a vector of lanes costs about what one call did.
//!
//! libm reduces x by π/2 (`rem_pio2`) and evaluates its kernels `k_sin` and `k_cos` on the
//! remainder y0 + y1. Every path it takes for |x| < 2²⁰·π/2 is the same arithmetic:
//! - |x| ≤ π/4: no reduction, y0 = x, y1 = 0 (and `k_sin`'s other form);
//! - |x| ≤ 9π/4, away from a multiple of π/2: r = x − k·π/2₁, w = k·π/2₁ₜ with k = ±1…±4
//!   fixed by ranges of x's high word, not by rounding;
//! - otherwise ("medium"): the same with k = round(2x/π), and a second, finer round when the
//!   first cancels (the remainder's exponent 17 or more below x's).
//!
//! k·π/2₁ is exact, and k·π/2₁ₜ rounds as libm's constant `3.0 * PIO2_1T` does, so one
//! formula gives every path's bits. The ranges are tests on |x| (for a positive double, its
//! high word is at most h exactly when it is below the double whose high word is h + 1).
//! Lanes that would take the second round (which a conservative test finds), lie beyond
//! 2²⁰·π/2, or are not finite take `libm::sincos` itself, so every lane is libm's.

use simba::simd::SimdValue;

use super::Real;

/// The double whose high word is `h` and low word 0.
const fn high(h: u64) -> f64 {
    f64::from_bits(h << 32)
}

/// 1.5·2⁵²: adding it rounds to an integer held in the low mantissa bits.
const TO_INT: f64 = 1.5 / f64::EPSILON;
/// 53 bits of 2/π.
const INV_PIO2: f64 = f64::from_bits(0x3fe4_5f30_6dc9_c883);
/// The first 33 bits of π/2, and π/2 minus them.
const PIO2_1: f64 = f64::from_bits(0x3ff9_21fb_5440_0000);
const PIO2_1T: f64 = f64::from_bits(0x3dd0_b461_1a62_6331);

/// `k_sin`'s and `k_cos`'s coefficients, as libm writes their bits.
const S1: f64 = f64::from_bits(0xbfc5_5555_5555_5549);
const S2: f64 = f64::from_bits(0x3f81_1111_1110_f8a6);
const S3: f64 = f64::from_bits(0xbf2a_01a0_19c1_61d5);
const S4: f64 = f64::from_bits(0x3ec7_1de3_57b1_fe7d);
const S5: f64 = f64::from_bits(0xbe5a_e5e6_8a2b_9ceb);
const S6: f64 = f64::from_bits(0x3de5_d93a_5acf_d57c);
const C1: f64 = f64::from_bits(0x3fa5_5555_5555_554c);
const C2: f64 = f64::from_bits(0xbf56_c16c_16c1_5177);
const C3: f64 = f64::from_bits(0x3efa_01a0_19cb_1590);
const C4: f64 = f64::from_bits(0xbe92_7e4f_809c_52ad);
const C5: f64 = f64::from_bits(0x3e21_ee9e_bdb4_b1c4);
const C6: f64 = f64::from_bits(0xbda8_fae9_be88_38d4);

/// `libm::sincos(x)` in every lane: (sin x, cos x), the same bits.
#[inline(always)]
pub fn sincos<T: Real>(x: T) -> (T, T) {
    let c = T::splat;
    let a = x.simd_abs();
    let below = |h: u64| a.simd_lt(c(high(h + 1)));
    let window = |h: u64| a.simd_ge(c(high(h))) & a.simd_lt(c(high(h + 1)));
    // libm's branches, by x's high word.
    let tiny = a.simd_lt(c(high(0x3e46_a09e)));
    let direct = below(0x3fe9_21fb);
    let near_axis = window(0x3ff9_21fb) | window(0x4009_21fb) | window(0x4012_d97c);
    let fixed = below(0x401c_463b) & !(near_axis | window(0x4019_21fb));
    let k = choose(
        below(0x400f_6a7a),
        choose(below(0x4002_d97c), c(1.0), c(2.0)),
        choose(below(0x4015_fdbc), c(3.0), c(4.0)),
    );
    let k = choose(x.simd_lt(T::zero()), -k, k);
    let rounded = (x * c(INV_PIO2) + c(TO_INT)) - c(TO_INT);
    let f_n = choose(fixed, k, rounded);
    let r = x - f_n * c(PIO2_1);
    let w = f_n * c(PIO2_1T);
    let y0 = r - w;
    // The medium path's second round: needed where y0's exponent is 17 or more below x's,
    // so only where |y0| < 2⁻¹⁶|x|; those lanes (and the huge and the non-finite) are
    // libm's own.
    let medium = !(direct | fixed);
    let cancels = medium & y0.simd_abs().simd_lt(a * c(1.0 / 65536.0));
    let beyond = !below(0x4139_21fa);
    if !T::none(cancels | beyond) {
        return per_lane(x);
    }
    let y1 = (r - y0) - w;
    let (y0, y1) = (choose(direct, x, y0), choose(direct, T::zero(), y1));
    // k_sin, in its two forms (y = 0 unreduced, y0 + y1 reduced), and k_cos.
    let z = y0 * y0;
    let zz = z * z;
    let rs = c(S2) + z * (c(S3) + z * c(S4)) + z * zz * (c(S5) + z * c(S6));
    let v = z * y0;
    let sin_direct = y0 + v * (c(S1) + z * rs);
    let sin_reduced = y0 - ((z * (c(0.5) * y1 - v * rs) - y1) - v * c(S1));
    let sin = choose(direct, sin_direct, sin_reduced);
    let rc = z * (c(C1) + z * (c(C2) + z * c(C3))) + zz * zz * (c(C4) + z * (c(C5) + z * c(C6)));
    let hz = c(0.5) * z;
    let one_minus = c(1.0) - hz;
    let cos = one_minus + (((c(1.0) - one_minus) - hz) + (z * rc - y0 * y1));
    // The quadrant n mod 4, from n's integer value: odd n swaps sin and cos; n mod 4 in
    // {2, 3} negates sin, in {1, 2} cos.
    let n = choose(direct, T::zero(), f_n);
    let round = |v: T| (v + c(TO_INT)) - c(TO_INT);
    let half = n * c(0.5);
    let odd = half.simd_ne(round(half));
    let floor_half = choose(odd, half - c(0.5), half);
    let upper = (floor_half * c(0.5)).simd_ne(round(floor_half * c(0.5)));
    let (s, co) = (choose(odd, cos, sin), choose(odd, sin, cos));
    let s = choose(upper, -s, s);
    let co = choose(odd ^ upper, -co, co);
    (choose(tiny, x, s), choose(tiny, T::one(), co))
}

/// `yes` where `mask` holds, else `no`.
#[inline(always)]
fn choose<T: SimdValue>(mask: T::SimdBool, yes: T, no: T) -> T {
    yes.select(mask, no)
}

/// Every lane by `libm::sincos` itself: a lane near a multiple of π/2, huge or not finite.
#[cold]
#[inline(never)]
fn per_lane<T: Real>(x: T) -> (T, T) {
    (
        T::from_lanes(|i| libm::sincos(x.extract(i)).0),
        T::from_lanes(|i| libm::sincos(x.extract(i)).1),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scalar::{F64x4, F64x8};
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    /// Every lane of `T` against `libm::sincos`, bit for bit (NaN for NaN).
    fn same_as_libm<T: Real>(values: &[f64]) -> usize {
        let mut checked = 0;
        for chunk in values.chunks(<T as Real>::LANES) {
            let x = T::from_lanes(|i| chunk[i % chunk.len()]);
            let (s, c) = sincos(x);
            for (i, &v) in chunk.iter().enumerate() {
                let (ws, wc) = libm::sincos(v);
                let same =
                    |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
                assert!(
                    same(s.extract(i), ws) && same(c.extract(i), wc),
                    "x = {v:e} ({:#018x}): ({:e}, {:e}) against libm's ({ws:e}, {wc:e})",
                    v.to_bits(),
                    s.extract(i),
                    c.extract(i)
                );
                checked += 1;
            }
        }
        checked
    }

    /// Inputs over every branch: a dense grid of joint angles, each branch's boundary ±
    /// a few ulp, the multiples of π/2 and their neighbours, and the edges.
    fn inputs() -> Vec<f64> {
        let mut out = vec![];
        let mut x = -30.0;
        while x < 30.0 {
            out.push(x);
            x += 0.000_913;
        }
        let mut x = 1e-12;
        while x < 1e7 {
            out.extend([x, -x]);
            x *= 1.013;
        }
        let highs = [
            0x3e46_a09e,
            0x3fe9_21fb,
            0x3ff9_21fb,
            0x4002_d97c,
            0x4009_21fb,
            0x400f_6a7a,
            0x4012_d97c,
            0x4015_fdbc,
            0x4019_21fb,
            0x401c_463b,
            0x4139_21fb,
        ];
        for h in highs {
            for base in [(h as u64) << 32, ((h as u64 + 1) << 32) - 1] {
                for d in -3i64..=3 {
                    let v = f64::from_bits(base.wrapping_add_signed(d));
                    out.extend([v, -v]);
                }
            }
        }
        // Random doubles, uniform in [−8, 8] and with random exponents up to 2²¹.
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        for _ in 0..50_000 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            out.push(16.0 * u - 8.0);
            let bits = (state & 0x800f_ffff_ffff_ffff) | ((0x3c0 + (state >> 52) % 0x55) << 52);
            out.push(f64::from_bits(bits));
        }
        for k in -12..=12 {
            let m = k as f64 * FRAC_PI_2;
            for d in -40i64..=40 {
                out.push(f64::from_bits(m.to_bits().wrapping_add_signed(d)));
            }
            out.extend([m + 1e-6, m - 1e-6, m + 2e-5, m - 2e-5, m + FRAC_PI_4]);
        }
        out.extend([
            0.0,
            -0.0,
            1e-300,
            -5e-324,
            PI,
            -PI,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MAX,
        ]);
        out
    }

    #[test]
    fn every_lane_is_libm_s_sincos() {
        let x = inputs();
        assert!(x.len() > 170_000);
        assert_eq!(same_as_libm::<f64>(&x), x.len());
        same_as_libm::<F64x4>(&x);
        same_as_libm::<F64x8>(&x);
        #[cfg(target_arch = "x86_64")]
        {
            use crate::sim::lanes::LanePath;
            if LanePath::Avx2.available() {
                same_as_libm::<crate::scalar::F64x4Avx2>(&x);
            }
            if LanePath::Avx512.available() {
                same_as_libm::<crate::scalar::F64x8Avx512>(&x);
            }
        }
    }

    /// A lane that needs libm's own path leaves its neighbours' bits as they were.
    #[test]
    fn a_slow_lane_does_not_change_its_neighbours() {
        let plain = sincos(F64x4::from_lanes(|i| 0.3 + i as f64));
        for edge in [FRAC_PI_2, f64::NAN, 1e300] {
            let mixed = sincos(F64x4::from_lanes(|i| {
                if i == 2 {
                    edge
                } else {
                    0.3 + i as f64
                }
            }));
            for i in [0, 1, 3] {
                assert_eq!(plain.0.extract(i).to_bits(), mixed.0.extract(i).to_bits());
                assert_eq!(plain.1.extract(i).to_bits(), mixed.1.extract(i).to_bits());
            }
        }
    }
}
