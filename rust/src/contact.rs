//! Contact between the tool tip and its environment (SPEC §14): the one interface between
//! an arm and a surface, over any scalar (one run, or runs in SIMD lanes).
//!
//! A [`Surface`] reads the tip's motion through [`TipMotion`] (the arm answers with its
//! fastest form: the three-link closed form computes n·X and Jᵀn from its trigonometry, a
//! chain reads its frames) and returns a [`Contact`]: the force F on the tip, the normal and
//! the penetration. The arm applies Jᵀ F inside every RK4 stage. Neither side knows the
//! other's type: a new surface implements [`Surface`]; a new arm implements [`TipMotion`].

use nalgebra::{SMatrix, SVector, Vector3};

use crate::scalar::{mat_vec, Real};

/// What a surface may ask of the tip at one state.
pub trait TipMotion<T: Real> {
    /// (n·X, n·Ẋ) for a unit direction n: the tip's position and velocity along n. n·Ẋ is
    /// computed only when `rate` (a damped contact reads it); otherwise it is 0.
    fn along(&self, n: &Vector3<T>, rate: bool) -> (T, T);

    /// The tip position X (a curved surface's distance, a height field's coordinates).
    fn position(&self) -> Vector3<T>;

    /// The tip velocity Ẋ = J q̇ (friction's slip, a curved surface's δ̇).
    fn velocity(&self) -> Vector3<T>;
}

/// The contact at the tip: the surface pushes the tip with F = −f n + F_t (its normal force
/// f ≥ 0 along the unit normal n pointing into the surface, and Coulomb friction F_t in the
/// tangent plane). The penetration δ is positive inside the surface. A torque joins F here
/// when a surface produces one; an arm applies [`Contact::force`] through Jᵀ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact<T: Real> {
    pub normal: Vector3<T>,
    pub normal_force: T,
    pub penetration: T,
    /// F_t [N], world frame; `None` for a frictionless surface (never computed, so a
    /// frictionless run's bits do not depend on friction's code).
    pub friction: Option<Vector3<T>>,
}

impl<T: Real> Contact<T> {
    /// F = −f n + F_t [N], world frame.
    #[inline(always)]
    pub fn force(&self) -> Vector3<T> {
        let normal = self.normal * -self.normal_force;
        match &self.friction {
            Some(ft) => normal + ft,
            None => normal,
        }
    }
}

/// An environment the tip can touch.
pub trait Surface<T: Real> {
    /// The contact for the tip's motion `tip`.
    fn contact(&self, tip: &impl TipMotion<T>) -> Contact<T>;
}

/// No environment: no force (the normal is e_x, the penetration NaN).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FreeSpace;

impl<T: Real> Surface<T> for FreeSpace {
    #[inline(always)]
    fn contact(&self, _: &impl TipMotion<T>) -> Contact<T> {
        Contact {
            normal: Vector3::x().map(T::splat),
            normal_force: T::zero(),
            penetration: T::splat(f64::NAN),
            friction: None,
        }
    }
}

/// A tip whose kinematics are known (the encoders' reading at t_k): n·X by a dot product,
/// n·Ẋ = n·(J q̇) only when asked.
#[derive(Debug, Clone, Copy)]
pub struct KnownTip<'a, T: Real, const N: usize> {
    pub position: &'a Vector3<T>,
    pub jacobian: &'a SMatrix<T, 3, N>,
    pub qd: &'a SVector<T, N>,
}

impl<T: Real, const N: usize> TipMotion<T> for KnownTip<'_, T, N> {
    #[inline(always)]
    fn along(&self, n: &Vector3<T>, rate: bool) -> (T, T) {
        let rate = if rate {
            n.dot(&mat_vec(self.jacobian, self.qd))
        } else {
            T::zero()
        };
        (n.dot(self.position), rate)
    }

    #[inline(always)]
    fn position(&self) -> Vector3<T> {
        *self.position
    }

    #[inline(always)]
    fn velocity(&self) -> Vector3<T> {
        mat_vec(self.jacobian, self.qd)
    }
}
