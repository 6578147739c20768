//! AVX2: four f64 lanes in a ymm register, conditions as all-ones / all-zeros lanes of
//! another. See the parent module's safety note: every function here executes AVX (and, for
//! the 64-bit integer steps of e^x, AVX2; for its multiply-adds, FMA) instructions.

use std::arch::x86_64::{
    __m256d, _mm256_add_epi64, _mm256_add_pd, _mm256_and_pd, _mm256_andnot_pd, _mm256_blendv_pd,
    _mm256_castpd_si256, _mm256_castsi256_pd, _mm256_cmp_pd, _mm256_div_pd, _mm256_fmadd_pd,
    _mm256_max_pd, _mm256_min_pd, _mm256_movemask_pd, _mm256_mul_pd, _mm256_or_pd,
    _mm256_set1_epi64x, _mm256_set1_pd, _mm256_setr_pd, _mm256_slli_epi64, _mm256_sqrt_pd,
    _mm256_sub_epi64, _mm256_sub_pd, _mm256_xor_pd, _CMP_EQ_OQ, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ,
    _CMP_LT_OQ, _CMP_NEQ_UQ, _CMP_UNORD_Q,
};

use simba::simd::{AutoF64x4, AutoSimd};

use super::Isa;

/// The AVX2 instruction set (ymm registers, vector masks).
#[derive(Debug, Clone, Copy)]
pub struct Avx2;

/// One AVX / AVX2 operation: the module's safety note is the caller's guarantee.
macro_rules! avx2 {
    ($e:expr) => {
        // SAFETY: AVX2 is present wherever these lane types run (module note).
        unsafe { $e }
    };
}

/// Only the sign bit set, in every lane.
#[inline(always)]
fn sign_bit() -> __m256d {
    avx2!(_mm256_castsi256_pd(_mm256_set1_epi64x(i64::MIN)))
}

impl Isa<4> for Avx2 {
    type V = __m256d;
    type M = __m256d;
    type Auto = AutoF64x4;

    #[inline(always)]
    fn to_array(v: __m256d) -> [f64; 4] {
        // SAFETY: four f64 either way; by value, so no alignment requirement.
        unsafe { std::mem::transmute::<__m256d, [f64; 4]>(v) }
    }

    #[inline(always)]
    fn from_array(a: [f64; 4]) -> __m256d {
        // SAFETY: as in `to_array`.
        unsafe { std::mem::transmute::<[f64; 4], __m256d>(a) }
    }

    #[inline(always)]
    fn set(a: [f64; 4]) -> __m256d {
        avx2!(_mm256_setr_pd(a[0], a[1], a[2], a[3]))
    }

    #[inline(always)]
    fn auto(a: [f64; 4]) -> AutoF64x4 {
        AutoSimd(a)
    }

    #[inline(always)]
    fn auto_array(a: AutoF64x4) -> [f64; 4] {
        a.0
    }

    #[inline(always)]
    fn splat(x: f64) -> __m256d {
        avx2!(_mm256_set1_pd(x))
    }

    #[inline(always)]
    fn add(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_add_pd(a, b))
    }

    #[inline(always)]
    fn sub(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_sub_pd(a, b))
    }

    #[inline(always)]
    fn mul(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_mul_pd(a, b))
    }

    #[inline(always)]
    fn div(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_div_pd(a, b))
    }

    #[inline(always)]
    fn fma(a: __m256d, b: __m256d, c: __m256d) -> __m256d {
        avx2!(_mm256_fmadd_pd(a, b, c))
    }

    #[inline(always)]
    fn sqrt(a: __m256d) -> __m256d {
        avx2!(_mm256_sqrt_pd(a))
    }

    #[inline(always)]
    fn abs(a: __m256d) -> __m256d {
        avx2!(_mm256_andnot_pd(sign_bit(), a))
    }

    #[inline(always)]
    fn neg(a: __m256d) -> __m256d {
        avx2!(_mm256_xor_pd(a, sign_bit()))
    }

    #[inline(always)]
    fn copysign(a: __m256d, sign: __m256d) -> __m256d {
        avx2!(_mm256_or_pd(
            _mm256_andnot_pd(sign_bit(), a),
            _mm256_and_pd(sign_bit(), sign)
        ))
    }

    #[inline(always)]
    fn max(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_max_pd(a, b))
    }

    #[inline(always)]
    fn min(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_min_pd(a, b))
    }

    #[inline(always)]
    fn pow2_of_rounded(t: __m256d, round: f64) -> __m256d {
        avx2!(_mm256_castsi256_pd(_mm256_slli_epi64::<52>(
            _mm256_add_epi64(
                _mm256_sub_epi64(
                    _mm256_castpd_si256(t),
                    _mm256_set1_epi64x(round.to_bits() as i64)
                ),
                _mm256_set1_epi64x(1023),
            )
        )))
    }

    #[inline(always)]
    fn lt(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_cmp_pd::<_CMP_LT_OQ>(a, b))
    }

    #[inline(always)]
    fn gt(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_cmp_pd::<_CMP_GT_OQ>(a, b))
    }

    #[inline(always)]
    fn le(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_cmp_pd::<_CMP_LE_OQ>(a, b))
    }

    #[inline(always)]
    fn ge(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_cmp_pd::<_CMP_GE_OQ>(a, b))
    }

    #[inline(always)]
    fn eq(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_cmp_pd::<_CMP_EQ_OQ>(a, b))
    }

    #[inline(always)]
    fn ne(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_cmp_pd::<_CMP_NEQ_UQ>(a, b))
    }

    #[inline(always)]
    fn unordered(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_cmp_pd::<_CMP_UNORD_Q>(a, b))
    }

    #[inline(always)]
    fn blend(mask: __m256d, no: __m256d, yes: __m256d) -> __m256d {
        // blendv takes its second operand where the mask lane's sign bit is set.
        avx2!(_mm256_blendv_pd(no, yes, mask))
    }

    #[inline(always)]
    fn mask_bits(m: __m256d) -> u8 {
        avx2!(_mm256_movemask_pd(m)) as u8
    }

    #[inline(always)]
    fn mask_from_bits(bits: u8) -> __m256d {
        let lane = |i: usize| if (bits >> i) & 1 == 1 { -1i64 } else { 0 };
        // SAFETY: four 64-bit lanes either way; by value.
        unsafe { std::mem::transmute::<[i64; 4], __m256d>(std::array::from_fn(lane)) }
    }

    #[inline(always)]
    fn mask_and(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_and_pd(a, b))
    }

    #[inline(always)]
    fn mask_or(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_or_pd(a, b))
    }

    #[inline(always)]
    fn mask_xor(a: __m256d, b: __m256d) -> __m256d {
        avx2!(_mm256_xor_pd(a, b))
    }

    #[inline(always)]
    fn mask_not(a: __m256d) -> __m256d {
        avx2!(_mm256_xor_pd(
            a,
            _mm256_castsi256_pd(_mm256_set1_epi64x(-1))
        ))
    }
}
