//! [`F64x8Avx512`]: eight f64 lanes held in one AVX-512 register, for the AVX-512 build of
//! the lane loop (issue #25).
//!
//! Why not simba's array-backed `AutoF64x8` there: its element-wise loops are left to LLVM's
//! SLP vectoriser, which at eight wide assembled zmm registers from xmm pieces and unpacked
//! every lane mask bit by bit (`kshiftrb`): 170k extra instructions in the 8-wide build,
//! which ran 27 % slower than the 4-wide one (docs/performance.md §22). Here each arithmetic
//! operation is one AVX-512 instruction and a mask is one `k` register (`__mmask8`).
//!
//! Bits: the arithmetic (+ − × ÷ √, |x|, −x) is the same IEEE operation per lane, never
//! contracted into an FMA; comparisons are the ordered ones f64's `<`, `>`, `<=`, `>=`,
//! `==` use (`!=` unordered). Every other operation (trig, powers, min/max, ...) is taken
//! lane by lane through `AutoF64x8`, so it gives that type's bits exactly. The lane loop's
//! tests check the AVX-512 build against the portable 8-wide and 4-wide ones bit for bit.
//!
//! Safety: every method may execute AVX-512 F instructions. The
//! type is only instantiated inside `sim::lanes::lanes_avx512`, which is entered after
//! `LanePath::Avx512.available()` detected AVX-512 F, DQ and VL; nothing else may use it.

use std::arch::x86_64::{
    __m512d, __m512i, _mm512_abs_pd, _mm512_add_epi64, _mm512_add_pd, _mm512_and_si512,
    _mm512_andnot_si512, _mm512_castpd_si512, _mm512_castsi512_pd, _mm512_cmp_pd_mask,
    _mm512_div_pd, _mm512_mask_blend_pd, _mm512_max_pd, _mm512_min_pd, _mm512_mul_pd,
    _mm512_or_si512, _mm512_set1_epi64, _mm512_set1_pd, _mm512_slli_epi64, _mm512_sqrt_pd,
    _mm512_sub_epi64, _mm512_sub_pd, _mm512_xor_si512, _CMP_EQ_OQ, _CMP_GE_OQ, _CMP_GT_OQ,
    _CMP_LE_OQ, _CMP_LT_OQ, _CMP_NEQ_UQ, _CMP_UNORD_Q,
};
use std::fmt;
use std::ops::{
    Add, AddAssign, BitAnd, BitOr, BitXor, Div, DivAssign, Mul, MulAssign, Neg, Not, Rem,
    RemAssign, Sub, SubAssign,
};

use nalgebra::{Matrix3, Vector3};
use num_traits::{Num, One, Zero};
use simba::scalar::{Field, SubsetOf};
use simba::simd::{
    AutoF64x8, AutoSimd, PrimitiveSimdValue, SimdBool, SimdComplexField, SimdPartialOrd,
    SimdRealField, SimdSigned, SimdValue,
};

use super::{rotate_small_in, sin_cos_lanes, Real, Wide};

/// One bit per lane: an AVX-512 `k` mask.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mask8(u8);

/// Eight f64 lanes in one AVX-512 register (see the module's safety note).
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct F64x8Avx512(__m512d);

impl F64x8Avx512 {
    #[inline(always)]
    fn to_array(self) -> [f64; 8] {
        // SAFETY: __m512d is eight f64 (64 bytes); transmuting by value has no alignment
        // requirement.
        unsafe { std::mem::transmute::<__m512d, [f64; 8]>(self.0) }
    }

    #[inline(always)]
    fn from_array(a: [f64; 8]) -> Self {
        // SAFETY: as in `to_array`.
        Self(unsafe { std::mem::transmute::<[f64; 8], __m512d>(a) })
    }

    #[inline(always)]
    fn auto(self) -> AutoF64x8 {
        AutoSimd(self.to_array())
    }

    #[inline(always)]
    fn from_auto(a: AutoF64x8) -> Self {
        Self::from_array(a.0)
    }

    #[inline(always)]
    fn cmp<const P: i32>(self, other: Self) -> Mask8 {
        // SAFETY: AVX-512 F, present wherever this type is used (module note).
        Mask8(unsafe { _mm512_cmp_pd_mask::<P>(self.0, other.0) })
    }
}

impl F64x8Avx512 {
    #[inline(always)]
    fn bits(self) -> __m512i {
        // SAFETY: AVX-512 F (module note); a cast, no instruction.
        unsafe { _mm512_castpd_si512(self.0) }
    }

    #[inline(always)]
    fn from_bits(b: __m512i) -> Self {
        // SAFETY: as in `bits`.
        Self(unsafe { _mm512_castsi512_pd(b) })
    }

    /// e^x: [`super::exp_lanes`]' steps, one instruction each, in its order (so its bits;
    /// tested). Written here because the array version's element loops stayed out of line
    /// in this build.
    #[inline(always)]
    fn exp_native(self) -> Self {
        use super::exp_consts::{HIGH, LN2_HI, LN2_LO, LOG2_E, LOW, ROUND};
        let c = Self::splat;
        // SAFETY: AVX-512 F (module note). max then min is f64::clamp wherever x is not
        // NaN; a NaN lane is replaced by x at the end.
        let xc = Self(unsafe { _mm512_min_pd(_mm512_max_pd(self.0, c(LOW).0), c(HIGH).0) });
        let t = xc * c(LOG2_E) + c(ROUND);
        let n = t - c(ROUND);
        let r = (xc - n * c(LN2_HI)) - n * c(LN2_LO);
        let r2 = r * r;
        let r4 = r2 * r2;
        let r8 = r4 * r4;
        let p01 = c(1.0) + r;
        let p23 = c(1.0 / 2.0) + r * c(1.0 / 6.0);
        let p45 = c(1.0 / 24.0) + r * c(1.0 / 120.0);
        let p67 = c(1.0 / 720.0) + r * c(1.0 / 5040.0);
        let p89 = c(1.0 / 40320.0) + r * c(1.0 / 362_880.0);
        let p1011 = c(1.0 / 3_628_800.0) + r * c(1.0 / 39_916_800.0);
        let p1213 = c(1.0 / 479_001_600.0) + r * c(1.0 / 6_227_020_800.0);
        let p03 = p01 + r2 * p23;
        let p47 = p45 + r2 * p67;
        let p811 = p89 + r2 * p1011;
        let p07 = p03 + r4 * p47;
        let p813 = p811 + r4 * p1213;
        let poly = p07 + r8 * p813;
        let t1 = n * c(0.5) + c(ROUND);
        let t2 = (n - (t1 - c(ROUND))) + c(ROUND);
        // SAFETY: AVX-512 F (module note). (bits − ROUND's bits + 1023) << 52, wrapping.
        let pow2 = |t: Self| {
            Self::from_bits(unsafe {
                _mm512_slli_epi64::<52>(_mm512_add_epi64(
                    _mm512_sub_epi64(t.bits(), _mm512_set1_epi64(ROUND.to_bits() as i64)),
                    _mm512_set1_epi64(1023),
                ))
            })
        };
        let y = poly * pow2(t1) * pow2(t2);
        let y = c(0.0).select(self.cmp::<_CMP_LT_OQ>(c(LOW)), y);
        let y = c(f64::INFINITY).select(self.cmp::<_CMP_GT_OQ>(c(HIGH)), y);
        self.select(self.cmp::<_CMP_UNORD_Q>(self), y)
    }
}

impl fmt::Debug for F64x8Avx512 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.to_array().fmt(f)
    }
}

impl Default for F64x8Avx512 {
    #[inline(always)]
    fn default() -> Self {
        Self::from_array([0.0; 8])
    }
}

impl PartialEq for F64x8Avx512 {
    #[inline(always)]
    fn eq(&self, other: &Self) -> bool {
        self.to_array() == other.to_array()
    }
}

// Mask8: plain bit operations, no intrinsics needed.

impl Not for Mask8 {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        Mask8(!self.0)
    }
}

impl BitAnd for Mask8 {
    type Output = Self;
    #[inline(always)]
    fn bitand(self, rhs: Self) -> Self {
        Mask8(self.0 & rhs.0)
    }
}

impl BitOr for Mask8 {
    type Output = Self;
    #[inline(always)]
    fn bitor(self, rhs: Self) -> Self {
        Mask8(self.0 | rhs.0)
    }
}

impl BitXor for Mask8 {
    type Output = Self;
    #[inline(always)]
    fn bitxor(self, rhs: Self) -> Self {
        Mask8(self.0 ^ rhs.0)
    }
}

impl SimdValue for Mask8 {
    const LANES: usize = 8;
    type Element = bool;
    type SimdBool = Self;

    #[inline(always)]
    fn splat(val: bool) -> Self {
        Mask8(if val { 0xff } else { 0 })
    }

    #[inline(always)]
    fn extract(&self, i: usize) -> bool {
        assert!(i < 8, "lane {i} of 8");
        (self.0 >> i) & 1 == 1
    }

    #[inline(always)]
    unsafe fn extract_unchecked(&self, i: usize) -> bool {
        (self.0 >> i) & 1 == 1
    }

    #[inline(always)]
    fn replace(&mut self, i: usize, val: bool) {
        assert!(i < 8, "lane {i} of 8");
        // SAFETY: i < 8, checked above.
        unsafe { self.replace_unchecked(i, val) }
    }

    #[inline(always)]
    unsafe fn replace_unchecked(&mut self, i: usize, val: bool) {
        self.0 = (self.0 & !(1 << i)) | (u8::from(val) << i);
    }

    #[inline(always)]
    fn select(self, cond: Self, other: Self) -> Self {
        Mask8((self.0 & cond.0) | (other.0 & !cond.0))
    }
}

impl SimdBool for Mask8 {
    #[inline(always)]
    fn bitmask(self) -> u64 {
        u64::from(self.0)
    }

    #[inline(always)]
    fn and(self) -> bool {
        self.0 == 0xff
    }

    #[inline(always)]
    fn or(self) -> bool {
        self.0 != 0
    }

    #[inline(always)]
    fn xor(self) -> bool {
        self.0.count_ones() % 2 == 1
    }

    #[inline(always)]
    fn all(self) -> bool {
        self.and()
    }

    #[inline(always)]
    fn any(self) -> bool {
        self.or()
    }

    #[inline(always)]
    fn none(self) -> bool {
        self.0 == 0
    }

    #[inline(always)]
    fn if_else<Res: SimdValue<SimdBool = Self>>(
        self,
        if_value: impl FnOnce() -> Res,
        else_value: impl FnOnce() -> Res,
    ) -> Res {
        let a = if_value();
        a.select(self, else_value())
    }

    #[inline(always)]
    fn if_else2<Res: SimdValue<SimdBool = Self>>(
        self,
        if_value: impl FnOnce() -> Res,
        else_if: (impl FnOnce() -> Self, impl FnOnce() -> Res),
        else_value: impl FnOnce() -> Res,
    ) -> Res {
        let a = if_value();
        let b = else_if.1();
        let c = else_value();
        a.select(self, b.select(else_if.0(), c))
    }

    #[inline(always)]
    fn if_else3<Res: SimdValue<SimdBool = Self>>(
        self,
        if_value: impl FnOnce() -> Res,
        else_if: (impl FnOnce() -> Self, impl FnOnce() -> Res),
        else_else_if: (impl FnOnce() -> Self, impl FnOnce() -> Res),
        else_value: impl FnOnce() -> Res,
    ) -> Res {
        let a = if_value();
        let b = else_if.1();
        let c = else_else_if.1();
        let d = else_value();
        let inner = c.select(else_else_if.0(), d);
        a.select(self, b.select(else_if.0(), inner))
    }
}

impl SimdValue for F64x8Avx512 {
    const LANES: usize = 8;
    type Element = f64;
    type SimdBool = Mask8;

    #[inline(always)]
    fn splat(val: f64) -> Self {
        // SAFETY: AVX-512 F (module note).
        Self(unsafe { _mm512_set1_pd(val) })
    }

    #[inline(always)]
    fn extract(&self, i: usize) -> f64 {
        self.to_array()[i]
    }

    #[inline(always)]
    unsafe fn extract_unchecked(&self, i: usize) -> f64 {
        // SAFETY: the caller promises i < 8.
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
        // SAFETY: the caller promises i < 8.
        unsafe { *a.get_unchecked_mut(i) = val };
        *self = Self::from_array(a);
    }

    #[inline(always)]
    fn select(self, cond: Mask8, other: Self) -> Self {
        // SAFETY: AVX-512 F. The blend takes its second operand where the mask bit is set.
        Self(unsafe { _mm512_mask_blend_pd(cond.0, other.0, self.0) })
    }
}

impl PrimitiveSimdValue for F64x8Avx512 {}

/// The IEEE operations, one instruction each.
macro_rules! arithmetic {
    ($($op:ident $f:ident $assign:ident $fa:ident $intr:ident),*) => {$(
        impl $op for F64x8Avx512 {
            type Output = Self;
            #[inline(always)]
            fn $f(self, rhs: Self) -> Self {
                // SAFETY: AVX-512 F (module note).
                Self(unsafe { $intr(self.0, rhs.0) })
            }
        }

        impl $assign for F64x8Avx512 {
            #[inline(always)]
            fn $fa(&mut self, rhs: Self) {
                *self = $op::$f(*self, rhs);
            }
        }
    )*};
}

arithmetic!(
    Add add AddAssign add_assign _mm512_add_pd,
    Sub sub SubAssign sub_assign _mm512_sub_pd,
    Mul mul MulAssign mul_assign _mm512_mul_pd,
    Div div DivAssign div_assign _mm512_div_pd
);

impl Rem for F64x8Avx512 {
    type Output = Self;
    #[inline(always)]
    fn rem(self, rhs: Self) -> Self {
        Self::from_auto(self.auto() % rhs.auto())
    }
}

impl RemAssign for F64x8Avx512 {
    #[inline(always)]
    fn rem_assign(&mut self, rhs: Self) {
        *self = *self % rhs;
    }
}

impl Neg for F64x8Avx512 {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        // The sign bit flipped, as f64's `-x` (0 − x would turn −0 into +0).
        // SAFETY: AVX-512 F (module note).
        Self(unsafe {
            _mm512_castsi512_pd(_mm512_xor_si512(
                _mm512_castpd_si512(self.0),
                _mm512_set1_epi64(i64::MIN),
            ))
        })
    }
}

impl Zero for F64x8Avx512 {
    #[inline(always)]
    fn zero() -> Self {
        Self::splat(0.0)
    }

    #[inline(always)]
    fn is_zero(&self) -> bool {
        *self == Self::zero()
    }
}

impl One for F64x8Avx512 {
    #[inline(always)]
    fn one() -> Self {
        Self::splat(1.0)
    }
}

impl Num for F64x8Avx512 {
    type FromStrRadixErr = <f64 as Num>::FromStrRadixErr;

    fn from_str_radix(str: &str, radix: u32) -> Result<Self, Self::FromStrRadixErr> {
        f64::from_str_radix(str, radix).map(Self::splat)
    }
}

impl Field for F64x8Avx512 {}

impl SubsetOf<F64x8Avx512> for F64x8Avx512 {
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
        impl SubsetOf<F64x8Avx512> for $t {
            #[inline(always)]
            fn to_superset(&self) -> F64x8Avx512 {
                F64x8Avx512::from_auto(SubsetOf::<AutoF64x8>::to_superset(self))
            }

            #[inline(always)]
            fn from_superset_unchecked(element: &F64x8Avx512) -> Self {
                <$t as SubsetOf<AutoF64x8>>::from_superset_unchecked(&element.auto())
            }

            #[inline(always)]
            fn is_in_subset(element: &F64x8Avx512) -> bool {
                <$t as SubsetOf<AutoF64x8>>::is_in_subset(&element.auto())
            }
        }
    )*};
}

scalar_subset!(f32, f64);

impl SimdPartialOrd for F64x8Avx512 {
    #[inline(always)]
    fn simd_gt(self, other: Self) -> Mask8 {
        self.cmp::<_CMP_GT_OQ>(other)
    }

    #[inline(always)]
    fn simd_lt(self, other: Self) -> Mask8 {
        self.cmp::<_CMP_LT_OQ>(other)
    }

    #[inline(always)]
    fn simd_ge(self, other: Self) -> Mask8 {
        self.cmp::<_CMP_GE_OQ>(other)
    }

    #[inline(always)]
    fn simd_le(self, other: Self) -> Mask8 {
        self.cmp::<_CMP_LE_OQ>(other)
    }

    #[inline(always)]
    fn simd_eq(self, other: Self) -> Mask8 {
        self.cmp::<_CMP_EQ_OQ>(other)
    }

    #[inline(always)]
    fn simd_ne(self, other: Self) -> Mask8 {
        self.cmp::<_CMP_NEQ_UQ>(other)
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

impl SimdSigned for F64x8Avx512 {
    #[inline(always)]
    fn simd_abs(&self) -> Self {
        // SAFETY: AVX-512 F (module note). Clears the sign bit, as f64::abs.
        Self(unsafe { _mm512_abs_pd(self.0) })
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
    fn is_simd_positive(&self) -> Mask8 {
        Mask8(self.auto().is_simd_positive().bitmask() as u8)
    }

    #[inline(always)]
    fn is_simd_negative(&self) -> Mask8 {
        Mask8(self.auto().is_simd_negative().bitmask() as u8)
    }
}

/// Methods taken lane by lane through `AutoF64x8` (its bits exactly): `self` → `Self`.
macro_rules! by_auto_unary {
    ($tr:ident: $($f:ident),*) => {$(
        #[inline(always)]
        fn $f(self) -> Self {
            Self::from_auto(<AutoF64x8 as $tr>::$f(self.auto()))
        }
    )*};
}

/// As [`by_auto_unary`], for `(self, other)` → `Self`.
macro_rules! by_auto_binary {
    ($tr:ident: $($f:ident),*) => {$(
        #[inline(always)]
        fn $f(self, other: Self) -> Self {
            Self::from_auto(<AutoF64x8 as $tr>::$f(self.auto(), other.auto()))
        }
    )*};
}

/// As [`by_auto_unary`], for constants.
macro_rules! by_auto_const {
    ($($f:ident),*) => {$(
        #[inline(always)]
        fn $f() -> Self {
            Self::from_auto(<AutoF64x8 as SimdRealField>::$f())
        }
    )*};
}

impl SimdRealField for F64x8Avx512 {
    by_auto_binary!(SimdRealField: simd_atan2);

    #[inline(always)]
    fn simd_copysign(self, sign: Self) -> Self {
        // |self| with sign's sign bit, as f64::copysign (NaN included).
        // SAFETY: AVX-512 F (module note).
        Self::from_bits(unsafe {
            let mask = _mm512_set1_epi64(i64::MIN);
            _mm512_or_si512(
                _mm512_andnot_si512(mask, self.bits()),
                _mm512_and_si512(mask, sign.bits()),
            )
        })
    }
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
}

impl SimdComplexField for F64x8Avx512 {
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
        // SAFETY: AVX-512 F (module note). Correctly rounded, as f64::sqrt.
        Self(unsafe { _mm512_sqrt_pd(self.0) })
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

impl Real for F64x8Avx512 {
    const LANES: usize = 8;

    #[inline(always)]
    fn exp_fast(self) -> Self {
        self.exp_native()
    }

    #[inline(always)]
    fn sin_cos_each(self) -> (Self, Self) {
        let sc = self.to_array().map(libm::sincos);
        (
            Self::from_array(sc.map(|p| p.0)),
            Self::from_array(sc.map(|p| p.1)),
        )
    }

    #[inline(always)]
    fn sin_cos_fast(self) -> (Self, Self) {
        let (s, c) = sin_cos_lanes(self.to_array());
        (Self::from_array(s), Self::from_array(c))
    }

    #[inline(always)]
    fn from_lanes(f: impl FnMut(usize) -> f64) -> Self {
        Self::from_array(std::array::from_fn(f))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scalar::F64x8;
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

    fn pairs() -> impl Iterator<Item = ([f64; 8], [f64; 8])> {
        (0..SPECIAL.len()).flat_map(|i| {
            (0..SPECIAL.len()).map(move |j| {
                (
                    std::array::from_fn(|l| SPECIAL[(i + l) % 16]),
                    std::array::from_fn(|l| SPECIAL[(j + 3 * l) % 16]),
                )
            })
        })
    }

    fn bits(x: [f64; 8]) -> [u64; 8] {
        x.map(f64::to_bits)
    }

    fn native(a: F64x8Avx512) -> [u64; 8] {
        bits(a.to_array())
    }

    fn auto(a: F64x8) -> [u64; 8] {
        bits(a.0)
    }

    /// Every native operation against simba's array-backed type, bit for bit, on every pair
    /// of awkward values (the lane loop's tests cover them as the stages use them).
    #[test]
    fn native_lanes_equal_array_lanes_bit_for_bit() {
        if !LanePath::Avx512.available() {
            eprintln!("skipped: this CPU has no AVX-512");
            return;
        }
        for (x, y) in pairs() {
            let (a, b) = (F64x8Avx512::from_array(x), F64x8Avx512::from_array(y));
            let (p, q) = (AutoSimd(x), AutoSimd(y));
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
            }
            let (s, c) = F64x8Avx512::rotate_small(a, b, a * F64x8Avx512::splat(1e-3));
            let (t, d) = F64x8::rotate_small(p, q, p * F64x8::splat(1e-3));
            assert_eq!((native(s), native(c)), (auto(t), auto(d)));
        }
    }

    /// e^x over its whole range, the edges (±745.2, 709.78) and the subnormal results.
    #[test]
    fn native_exp_equals_exp_lanes_bit_for_bit() {
        if !LanePath::Avx512.available() {
            eprintln!("skipped: this CPU has no AVX-512");
            return;
        }
        let mut x = -760.0;
        while x < 720.0 {
            let v: [f64; 8] = std::array::from_fn(|l| x + 0.173 * l as f64);
            let w = v.map(|v| v / 97.0);
            for v in [v, w] {
                assert_eq!(
                    native(F64x8Avx512::from_array(v).exp_fast()),
                    bits(crate::scalar::exp_lanes(v)),
                    "{v:?}"
                );
            }
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
            let v = [
                edge,
                edge.next_up(),
                edge.next_down(),
                -edge,
                0.0,
                1e-300,
                -1e-300,
                f64::NAN,
            ];
            assert_eq!(
                native(F64x8Avx512::from_array(v).exp_fast()),
                bits(crate::scalar::exp_lanes(v)),
                "{v:?}"
            );
        }
    }

    #[test]
    fn lanes_are_set_and_read_one_at_a_time() {
        if !LanePath::Avx512.available() {
            eprintln!("skipped: this CPU has no AVX-512");
            return;
        }
        let mut a = F64x8Avx512::from_lanes(|i| i as f64);
        a.replace(5, -1.5);
        assert_eq!(a.to_array(), [0.0, 1.0, 2.0, 3.0, 4.0, -1.5, 6.0, 7.0]);
        assert_eq!(a.extract(7), 7.0);
        let mut m = Mask8::splat(false);
        m.replace(2, true);
        m.replace(6, true);
        assert_eq!(m.bitmask(), 0b0100_0100);
        assert!(m.extract(6) && !m.extract(5));
        assert_eq!((m.any(), m.all(), (!m).any()), (true, false, true));
        assert_eq!(
            F64x8Avx512::splat(1.0).select(m, a).to_array(),
            [0.0, 1.0, 1.0, 3.0, 4.0, -1.5, 1.0, 7.0]
        );
    }
}
