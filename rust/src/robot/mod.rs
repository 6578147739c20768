//! Robot models behind one interface, generic in the joint count.
//!
//! Joint space has `N` dimensions (`JointVector<N>`); the task space is the tip position in
//! the world frame (`TaskVector`, 3-D), so the Jacobian is 3×N. Controllers, the plant and
//! the simulation are written against [`RobotModel`], never against a concrete arm: the
//! closed-form three-link arm of SPEC §1 is one implementation, and a general serial chain
//! plugs in beside it.

use nalgebra::{DMatrix, DVector, SMatrix, SVector, Vector3};

use crate::contact::{Contact, KnownTip, Surface};
use crate::scalar::Real;

pub mod chain;
pub mod three_link;

pub use three_link::{MassModel, RobotParams, ThreeLinkArm};

/// A joint-space vector (q, q̇, q̈, τ) of an `N`-joint arm.
pub type JointVector<const N: usize> = SVector<f64, N>;
/// An `N`×`N` joint-space matrix (the inertia D).
pub type JointMatrix<const N: usize> = SMatrix<f64, N, N>;
/// A task-space vector: tip position, velocity, force [world frame].
pub type TaskVector = Vector3<f64>;
/// The tip's translational Jacobian, 3×N.
pub type Jacobian<const N: usize> = SMatrix<f64, 3, N>;

/// A controller's friction model error: viscous and Coulomb coefficients scaled alike
/// (`with_model_error` of every arm's parameters).
pub(crate) fn scale_friction(viscous: &mut [f64], coulomb: &mut [f64], scale: f64) {
    viscous
        .iter_mut()
        .chain(coulomb.iter_mut())
        .for_each(|f| *f *= scale);
}

/// Tip position, Jacobian and the velocity-product acceleration J̇q̇ at one state.
/// Over `f64` by default; over lanes (`crate::scalar::F64x4`) for runs advancing together.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kinematics<const N: usize, T: Real = f64> {
    pub position: Vector3<T>,
    pub jacobian: SMatrix<T, 3, N>,
    pub jdot_qd: Vector3<T>,
}

/// How a general arm's task is solved (SPEC §11): the damping λ of J⁺ = Jᵀ(J Jᵀ + λ² I)⁻¹
/// and, for a pose task, (K_P, K_D) of the orientation (`None`: the controller's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskOptions {
    pub orientation_gains: Option<(f64, f64)>,
    pub damping: f64,
}

impl Default for TaskOptions {
    fn default() -> Self {
        Self {
            orientation_gains: None,
            damping: 1e-3,
        }
    }
}

/// The tip's orientation terms for a pose task (SPEC §11): rotation R (tip axes in the
/// world), the angular Jacobian (3×N, world frame) and its J̇q̇ (angular acceleration at q̈ = 0).
/// Over `f64` by default; over lanes for runs advancing together.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orientation<const N: usize, T: Real = f64> {
    pub rotation: nalgebra::Matrix3<T>,
    pub jacobian: SMatrix<T, 3, N>,
    pub jdot_qd: Vector3<T>,
}

/// D(q), C(q, q̇) q̇ and G(q) of eq. (1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dynamics<const N: usize, T: Real = f64> {
    pub inertia: SMatrix<T, N, N>,
    /// The Coriolis and centrifugal torque C(q, q̇) (already multiplied by q̇).
    pub coriolis: SVector<T, N>,
    pub gravity: SVector<T, N>,
}

/// What controllers and the plant need from an arm.
///
/// `Config` holds whatever the arm computes once per configuration and shares between
/// terms (the three-link arm's sines and cosines); the plant keeps one per RK4 stage.
pub trait RobotModel<const N: usize>: Clone + Send + Sync {
    type Config: Copy + Send + Sync + std::fmt::Debug;

    /// Per-configuration values of `q`.
    fn configure(&self, q: &JointVector<N>) -> Self::Config;

    /// The values at `shifted` = q + `delta`, given those at q, written into `out` (RK4's
    /// stages reuse one buffer: a chain's frames are kilobytes). Arms that can update
    /// cheaply for a small step (angle addition), or fill in place, override this.
    #[inline(always)]
    fn configure_shifted(
        &self,
        _at_q: &Self::Config,
        _delta: &JointVector<N>,
        shifted: &JointVector<N>,
        out: &mut Self::Config,
    ) {
        *out = self.configure(shifted);
    }

    /// Tip position (forward kinematics).
    fn tip_position(&self, c: &Self::Config) -> TaskVector;

    /// Tip position, Jacobian and J̇q̇.
    fn kinematics(&self, c: &Self::Config, qd: &JointVector<N>) -> Kinematics<N>;

    /// D, C q̇ and G.
    fn dynamics(&self, c: &Self::Config, qd: &JointVector<N>) -> Dynamics<N>;

    /// Joint friction τ_f(q̇).
    fn friction(&self, qd: &JointVector<N>) -> JointVector<N>;

    /// q̈ of eq. (1) with a Cartesian force on the tip:
    /// D q̈ = τ + Jᵀ F_tip − C q̇ − G − τ_f.
    fn forward_dynamics(
        &self,
        c: &Self::Config,
        qd: &JointVector<N>,
        tau: &JointVector<N>,
        tip_force: &TaskVector,
    ) -> JointVector<N> {
        let k = self.kinematics(c, qd);
        let d = self.dynamics(c, qd);
        let rhs =
            tau + k.jacobian.transpose() * tip_force - d.coriolis - d.gravity - self.friction(qd);
        // Arms with a structured D override this; the general path solves by LU.
        let lu = DMatrix::from_column_slice(N, N, d.inertia.as_slice()).lu();
        match lu.solve(&DVector::from_column_slice(rhs.as_slice())) {
            Some(qdd) => JointVector::<N>::from_column_slice(qdd.as_slice()),
            // A singular inertia has no acceleration; NaN makes the plant report divergence.
            None => JointVector::<N>::repeat(f64::NAN),
        }
    }

    /// q̈ with the surface's contact evaluated at this same state: one RK4 stage of the
    /// plant. The surface reads the tip's motion; the arm feels its force F through Jᵀ.
    /// Returns (q̈, the contact). Arms with a faster form of the tip's motion override this.
    #[inline(always)]
    fn accelerate(
        &self,
        c: &Self::Config,
        qd: &JointVector<N>,
        tau: &JointVector<N>,
        surface: &impl Surface<f64>,
    ) -> (JointVector<N>, Contact<f64>) {
        let k = self.kinematics(c, qd);
        let contact = surface.contact(&KnownTip {
            position: &k.position,
            jacobian: &k.jacobian,
            qd,
        });
        (self.forward_dynamics(c, qd, tau, &contact.force()), contact)
    }

    /// The model a controller believes in: masses (and inertias) scaled by `mass_scale`,
    /// friction by `friction_scale`; geometry shared with the plant.
    fn with_model_error(&self, mass_scale: f64, friction_scale: f64) -> Self;

    /// The initial joint positions q0.
    fn initial_position(&self) -> JointVector<N>;

    /// The orientation terms when the arm's task includes the tip orientation (SPEC §11
    /// `task = "pose"`); `None` for a position task (the three-link arm).
    #[inline(always)]
    fn orientation(&self, _c: &Self::Config, _qd: &JointVector<N>) -> Option<Orientation<N>> {
        None
    }

    /// J⁺'s damping and the orientation gains.
    fn task_options(&self) -> TaskOptions {
        TaskOptions::default()
    }

    /// Joint position limits (lower, upper), if the arm has any.
    fn position_limits(&self) -> Option<(JointVector<N>, JointVector<N>)> {
        None
    }
}
