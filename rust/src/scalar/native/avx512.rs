//! AVX-512 F: eight f64 lanes in a zmm register, conditions in a `k` mask (`__mmask8`).
//! See the parent module's safety note: every function here executes AVX-512 F instructions (and
//! FMA in e^x's multiply-adds).

use std::arch::x86_64::{
    __m512d, __mmask8, _mm512_abs_pd, _mm512_add_epi64, _mm512_add_pd, _mm512_and_si512,
    _mm512_andnot_si512, _mm512_castpd_si512, _mm512_castsi512_pd, _mm512_cmp_pd_mask,
    _mm512_div_pd, _mm512_fmadd_pd, _mm512_mask_blend_pd, _mm512_max_pd, _mm512_min_pd,
    _mm512_mul_pd, _mm512_or_si512, _mm512_set1_epi64, _mm512_set1_pd, _mm512_setr_pd,
    _mm512_slli_epi64, _mm512_sqrt_pd, _mm512_sub_epi64, _mm512_sub_pd, _mm512_xor_si512,
    _CMP_EQ_OQ, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_NEQ_UQ, _CMP_UNORD_Q,
};

use simba::simd::{AutoF64x8, AutoSimd};

use super::Isa;

/// The AVX-512 F instruction set (zmm registers, `k` masks).
#[derive(Debug, Clone, Copy)]
pub struct Avx512;

/// One AVX-512 F operation: the module's safety note is the caller's guarantee.
macro_rules! avx512 {
    ($e:expr) => {
        // SAFETY: AVX-512 F is present wherever these lane types run (module note).
        unsafe { $e }
    };
}

impl Isa<8> for Avx512 {
    type V = __m512d;
    type M = __mmask8;
    type Auto = AutoF64x8;

    #[inline(always)]
    fn to_array(v: __m512d) -> [f64; 8] {
        // SAFETY: eight f64 either way; by value, so no alignment requirement.
        unsafe { std::mem::transmute::<__m512d, [f64; 8]>(v) }
    }

    #[inline(always)]
    fn from_array(a: [f64; 8]) -> __m512d {
        // SAFETY: as in `to_array`.
        unsafe { std::mem::transmute::<[f64; 8], __m512d>(a) }
    }

    #[inline(always)]
    fn set(a: [f64; 8]) -> __m512d {
        avx512!(_mm512_setr_pd(
            a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7]
        ))
    }

    #[inline(always)]
    fn auto(a: [f64; 8]) -> AutoF64x8 {
        AutoSimd(a)
    }

    #[inline(always)]
    fn auto_array(a: AutoF64x8) -> [f64; 8] {
        a.0
    }

    #[inline(always)]
    fn splat(x: f64) -> __m512d {
        avx512!(_mm512_set1_pd(x))
    }

    #[inline(always)]
    fn add(a: __m512d, b: __m512d) -> __m512d {
        avx512!(_mm512_add_pd(a, b))
    }

    #[inline(always)]
    fn sub(a: __m512d, b: __m512d) -> __m512d {
        avx512!(_mm512_sub_pd(a, b))
    }

    #[inline(always)]
    fn mul(a: __m512d, b: __m512d) -> __m512d {
        avx512!(_mm512_mul_pd(a, b))
    }

    #[inline(always)]
    fn div(a: __m512d, b: __m512d) -> __m512d {
        avx512!(_mm512_div_pd(a, b))
    }

    #[inline(always)]
    fn fma(a: __m512d, b: __m512d, c: __m512d) -> __m512d {
        avx512!(_mm512_fmadd_pd(a, b, c))
    }

    #[inline(always)]
    fn sqrt(a: __m512d) -> __m512d {
        avx512!(_mm512_sqrt_pd(a))
    }

    #[inline(always)]
    fn abs(a: __m512d) -> __m512d {
        avx512!(_mm512_abs_pd(a))
    }

    #[inline(always)]
    fn neg(a: __m512d) -> __m512d {
        avx512!(_mm512_castsi512_pd(_mm512_xor_si512(
            _mm512_castpd_si512(a),
            _mm512_set1_epi64(i64::MIN),
        )))
    }

    #[inline(always)]
    fn copysign(a: __m512d, sign: __m512d) -> __m512d {
        avx512!({
            let bit = _mm512_set1_epi64(i64::MIN);
            _mm512_castsi512_pd(_mm512_or_si512(
                _mm512_andnot_si512(bit, _mm512_castpd_si512(a)),
                _mm512_and_si512(bit, _mm512_castpd_si512(sign)),
            ))
        })
    }

    #[inline(always)]
    fn max(a: __m512d, b: __m512d) -> __m512d {
        avx512!(_mm512_max_pd(a, b))
    }

    #[inline(always)]
    fn min(a: __m512d, b: __m512d) -> __m512d {
        avx512!(_mm512_min_pd(a, b))
    }

    #[inline(always)]
    fn pow2_of_rounded(t: __m512d, round: f64) -> __m512d {
        avx512!(_mm512_castsi512_pd(_mm512_slli_epi64::<52>(
            _mm512_add_epi64(
                _mm512_sub_epi64(
                    _mm512_castpd_si512(t),
                    _mm512_set1_epi64(round.to_bits() as i64)
                ),
                _mm512_set1_epi64(1023),
            )
        )))
    }

    #[inline(always)]
    fn lt(a: __m512d, b: __m512d) -> __mmask8 {
        avx512!(_mm512_cmp_pd_mask::<_CMP_LT_OQ>(a, b))
    }

    #[inline(always)]
    fn gt(a: __m512d, b: __m512d) -> __mmask8 {
        avx512!(_mm512_cmp_pd_mask::<_CMP_GT_OQ>(a, b))
    }

    #[inline(always)]
    fn le(a: __m512d, b: __m512d) -> __mmask8 {
        avx512!(_mm512_cmp_pd_mask::<_CMP_LE_OQ>(a, b))
    }

    #[inline(always)]
    fn ge(a: __m512d, b: __m512d) -> __mmask8 {
        avx512!(_mm512_cmp_pd_mask::<_CMP_GE_OQ>(a, b))
    }

    #[inline(always)]
    fn eq(a: __m512d, b: __m512d) -> __mmask8 {
        avx512!(_mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a, b))
    }

    #[inline(always)]
    fn ne(a: __m512d, b: __m512d) -> __mmask8 {
        avx512!(_mm512_cmp_pd_mask::<_CMP_NEQ_UQ>(a, b))
    }

    #[inline(always)]
    fn unordered(a: __m512d, b: __m512d) -> __mmask8 {
        avx512!(_mm512_cmp_pd_mask::<_CMP_UNORD_Q>(a, b))
    }

    #[inline(always)]
    fn blend(mask: __mmask8, no: __m512d, yes: __m512d) -> __m512d {
        // The blend takes its second operand where the mask bit is set.
        avx512!(_mm512_mask_blend_pd(mask, no, yes))
    }

    #[inline(always)]
    fn mask_bits(m: __mmask8) -> u8 {
        m
    }

    #[inline(always)]
    fn mask_from_bits(bits: u8) -> __mmask8 {
        bits
    }

    #[inline(always)]
    fn mask_and(a: __mmask8, b: __mmask8) -> __mmask8 {
        a & b
    }

    #[inline(always)]
    fn mask_or(a: __mmask8, b: __mmask8) -> __mmask8 {
        a | b
    }

    #[inline(always)]
    fn mask_xor(a: __mmask8, b: __mmask8) -> __mmask8 {
        a ^ b
    }

    #[inline(always)]
    fn mask_not(a: __mmask8) -> __mmask8 {
        !a
    }
}
