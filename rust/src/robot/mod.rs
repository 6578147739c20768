//! Robot models behind one interface, generic in the joint count.
//!
//! Joint space has `N` dimensions (`JointVector<N>`); the task space is the tip position in
//! the world frame (`TaskVector`, 3-D), so the Jacobian is 3×N. Controllers, the plant,
//! the stages and the lanes are written against [`ArmModel`] (an arm's equations over any
//! scalar) and [`RobotModel`] (an arm as a scenario builds it), never against a concrete
//! arm: the closed-form three-link arm of SPEC §1 is one implementation, and a general
//! serial chain plugs in beside it.

use nalgebra::{SMatrix, SVector, Vector3};

use crate::contact::{Contact, Surface};
use crate::scalar::{Real, Wide};

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
    /// A pose task keeps the tool normal to the estimated surface (SPEC §15).
    pub follow_surface: bool,
}

impl Default for TaskOptions {
    fn default() -> Self {
        Self {
            orientation_gains: None,
            damping: 1e-3,
            follow_surface: false,
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

/// An arm's equations over a scalar `T`: `f64` for one arm, a lane type
/// ([`crate::scalar::F64x4`], [`crate::scalar::F64x8`]) for four or eight arms of
/// one structure advancing in SIMD lanes (SPEC §13, §14). The three-link closed form
/// (`three_link::ClosedForm`) and a URDF chain (`chain::Chain`) implement it once; the
/// plant, the controllers, the stages and the lanes are written against it.
///
/// `Config` holds whatever the arm computes once per configuration and shares between
/// terms (the three-link arm's sines and cosines, a chain's frames); the plant keeps one
/// per RK4 stage.
pub trait ArmModel<T: Real, const N: usize>: Clone + Send + Sync + std::fmt::Debug {
    type Config: Copy + Send + Sync + std::fmt::Debug;

    /// Per-configuration values of `q`.
    fn configure(&self, q: &SVector<T, N>) -> Self::Config;

    /// The values at `shifted` = q + `delta`, given those at q, written into `out` (RK4's
    /// stages reuse one buffer: a chain's frames are kilobytes). Arms that can update
    /// cheaply for a small step (angle addition), or fill in place, override this.
    #[inline(always)]
    fn configure_shifted(
        &self,
        _at_q: &Self::Config,
        _delta: &SVector<T, N>,
        shifted: &SVector<T, N>,
        out: &mut Self::Config,
    ) {
        *out = self.configure(shifted);
    }

    /// Tip position (forward kinematics).
    fn tip_position(&self, c: &Self::Config) -> Vector3<T>;

    /// The tip frame's rotation R (its axes in the world): what a tip-frame force sensor
    /// is rotated by (SPEC §15).
    fn tip_rotation(&self, c: &Self::Config) -> nalgebra::Matrix3<T>;

    /// Tip position, Jacobian and J̇q̇.
    fn kinematics(&self, c: &Self::Config, qd: &SVector<T, N>) -> Kinematics<N, T>;

    /// The tip's orientation terms when the arm's task includes the tip orientation (SPEC
    /// §11 `task = "pose"`); `None` for a position task (the three-link arm).
    #[inline(always)]
    fn orientation(&self, _c: &Self::Config, _qd: &SVector<T, N>) -> Option<Orientation<N, T>> {
        None
    }

    /// Stage 1 of a period (what the encoders give the controller): the kinematics and,
    /// when `pose`, the orientation terms. Arms whose two share a Jacobian override this.
    #[inline(always)]
    fn measure(
        &self,
        c: &Self::Config,
        qd: &SVector<T, N>,
        pose: bool,
    ) -> (Kinematics<N, T>, Option<Orientation<N, T>>) {
        let orientation = if pose { self.orientation(c, qd) } else { None };
        (self.kinematics(c, qd), orientation)
    }

    /// D, C q̇ and G.
    fn dynamics(&self, c: &Self::Config, qd: &SVector<T, N>) -> Dynamics<N, T>;

    /// Joint friction τ_f(q̇).
    fn friction(&self, qd: &SVector<T, N>) -> SVector<T, N>;

    /// q̈ of eq. (1) with a Cartesian force on the tip:
    /// D q̈ = τ + Jᵀ F_tip − C q̇ − G − τ_f.
    fn forward_dynamics(
        &self,
        c: &Self::Config,
        qd: &SVector<T, N>,
        tau: &SVector<T, N>,
        tip_force: &Vector3<T>,
    ) -> SVector<T, N>;

    /// q̈ with the surface's contact evaluated at this same state: one RK4 stage of the
    /// plant. The surface reads the tip's motion; the arm feels its force F through Jᵀ.
    /// Returns (q̈, the contact).
    fn accelerate(
        &self,
        c: &Self::Config,
        qd: &SVector<T, N>,
        tau: &SVector<T, N>,
        surface: &impl Surface<T>,
    ) -> (SVector<T, N>, Contact<T>);
}

/// The configuration values of robot `R`'s model.
pub type ConfigOf<R, const N: usize> = <<R as RobotModel<N>>::Model as ArmModel<f64, N>>::Config;
/// The configuration values of robot `R`'s models in lanes of `W`.
pub type LaneConfigOf<R, W, const N: usize> =
    <<R as RobotModel<N>>::Lanes<W> as ArmModel<W, N>>::Config;

/// An arm as a scenario builds it: its [`ArmModel`] in `f64` (what the plant integrates
/// and a controller believes in), its start, limits and task options, the model a
/// controller with a model error believes in, and how four of its models pack into lanes.
pub trait RobotModel<const N: usize>: Clone + Send + Sync + std::fmt::Debug + 'static {
    /// The arm's equations for one run.
    type Model: ArmModel<f64, N> + 'static;
    /// Runs' equations in lanes of `W` (four or eight runs).
    type Lanes<W: Real>: ArmModel<W, N>;

    /// Whether sweeps run this arm in SIMD lanes (SPEC §13). Each arm that does compiles the
    /// whole lane loop once per lane build (three), most of the extension's build time
    /// (docs/performance.md, "Build and install time"); an arm that does not runs its sweeps
    /// one run at a time, with the same results but for `exp`'s last bits.
    const LANES: bool = true;

    /// The arm's equations.
    fn model(&self) -> &Self::Model;

    /// Whether `other` can share lanes with this arm (same joint structure).
    fn same_structure(&self, other: &Self) -> bool;

    /// `L` models of one structure in lanes.
    fn pack<W: Wide<L>, const L: usize>(models: [&Self::Model; L]) -> Self::Lanes<W>;

    /// Lane `l` takes the model `model` (a new run's).
    fn put_lane<W: Real>(lanes: &mut Self::Lanes<W>, l: usize, model: &Self::Model);

    /// The model a controller believes in: masses (and inertias) scaled by `mass_scale`,
    /// friction by `friction_scale`; geometry shared with the plant.
    fn with_model_error(&self, mass_scale: f64, friction_scale: f64) -> Self;

    /// The arm with a point mass `mass` [kg] at the tip origin (a tool, SPEC §15): in its
    /// inertia, its gravity and so in its dynamics, the plant's or a controller's model.
    /// Not scaled by a later `with_model_error` (the tool's mass is believed on its own).
    fn with_tool(&self, mass: f64) -> Self;

    /// Gravity along −z [m/s²].
    fn gravity(&self) -> f64;

    /// The initial joint positions q0.
    fn initial_position(&self) -> JointVector<N>;

    /// J⁺'s damping and the orientation gains.
    fn task_options(&self) -> TaskOptions {
        TaskOptions::default()
    }

    /// Joint position limits (lower, upper), if the arm has any.
    fn position_limits(&self) -> Option<(JointVector<N>, JointVector<N>)> {
        None
    }
}
