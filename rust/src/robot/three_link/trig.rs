//! The three-link arm's sines and cosines (SPEC §1): one `sincos` per joint and period,
//! the rest by angle addition.

use nalgebra::Vector3;

use crate::scalar::Real;

/// Sines and cosines of one configuration, computed once and shared by every term.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trig<T: Real = f64> {
    pub(super) s1: T,
    pub(super) c1: T,
    pub(super) s2: T,
    pub(super) c2: T,
    pub(super) s3: T,
    pub(super) c3: T,
    pub(super) s23: T,
    pub(super) c23: T,
}

impl<T: Real> Trig<T> {
    #[inline(always)]
    pub fn new(q: &Vector3<T>) -> Self {
        // libm's sincos shares one range reduction between sin and cos; std's sin_cos
        // makes two calls. A run calls this once per control period (`shifted` serves
        // the RK4 stages).
        Self::from_joints(
            q[0].sin_cos_each(),
            q[1].sin_cos_each(),
            q[2].sin_cos_each(),
        )
    }

    /// Completes the joints' (sin, cos) pairs with those of q2 + q3, by angle addition:
    /// no extra transcendental call.
    #[inline(always)]
    fn from_joints((s1, c1): (T, T), (s2, c2): (T, T), (s3, c3): (T, T)) -> Self {
        Self {
            s1,
            c1,
            s2,
            c2,
            s3,
            c3,
            s23: s2 * c3 + c2 * s3,
            c23: c2 * c3 - s2 * s3,
        }
    }

    /// The trig of `q + delta` from this one (the trig of `q`) by angle addition, with
    /// sin δ and cos δ from their Taylor series while every |δ| ≤ 1/128 (truncation below
    /// 4e-19); otherwise from scratch at `shifted` (= q + δ), lane by lane. An RK4 stage
    /// moves a joint by h q̇, about 1e-5 rad in the paper's runs, so the series is the rule
    /// and saves 9 of the 12 `sincos` calls of a substep.
    #[inline(always)]
    pub fn shifted(&self, delta: &Vector3<T>, shifted: &Vector3<T>) -> Self {
        let limit = T::splat(1.0 / 128.0);
        let far = delta[0].simd_abs().simd_gt(limit)
            | delta[1].simd_abs().simd_gt(limit)
            | delta[2].simd_abs().simd_gt(limit);
        if T::all(far) {
            return Self::new(shifted);
        }
        let near = Self::from_joints(
            T::rotate_small(self.s1, self.c1, delta[0]),
            T::rotate_small(self.s2, self.c2, delta[1]),
            T::rotate_small(self.s3, self.c3, delta[2]),
        );
        if T::none(far) {
            return near;
        }
        // Lanes disagree: each takes its own branch's value.
        let fresh = Self::new(shifted);
        let pick = |a: T, b: T| a.select(far, b);
        Self {
            s1: pick(fresh.s1, near.s1),
            c1: pick(fresh.c1, near.c1),
            s2: pick(fresh.s2, near.s2),
            c2: pick(fresh.c2, near.c2),
            s3: pick(fresh.s3, near.s3),
            c3: pick(fresh.c3, near.c3),
            s23: pick(fresh.s23, near.s23),
            c23: pick(fresh.c23, near.c23),
        }
    }
}
