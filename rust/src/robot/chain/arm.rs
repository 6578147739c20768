//! [`UrdfArm`]: a serial chain loaded from a URDF as a [`RobotModel`] of `N` joints
//! (SPEC §11). Friction and gravity are the block's parameters (as for the three-link arm);
//! geometry, inertias and limits come from the URDF.

use crate::contact::{Contact, Surface, TipMotion};
use nalgebra::{Matrix3, SVector, Vector3};

use super::kinematics::Frames;
use super::model::{ChainModel, SerialChain};
use super::{unsupported_joints, urdf, with_joints, JointCount};

use crate::error::{check, Error, Result};
use crate::robot::chain::spatial::Real;
use crate::robot::three_link::friction_sign;
use crate::robot::{ArmModel, Dynamics, JointVector, Kinematics, Orientation, RobotModel};
use crate::scalar::{put, put_vector, zeros, Wide};

/// What the task space holds.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum TaskKind {
    /// The tip position (3-D).
    Position,
    /// Tip position and orientation (6-D); the orientation is held at its start value.
    Pose,
}

/// What a pose task holds the tip's orientation at (SPEC §11, §15).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    Hash,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum OrientationMode {
    /// Its start value R0.
    #[default]
    Hold,
    /// R0 turned as the estimated surface's normal turns under the tip.
    Surface,
}

/// The parameters of `ar.UrdfArm`. Defaults: no friction, g = 9.81, q0 = 0 clipped into the
/// limits, `task` by joint count (position below 6 joints, pose from 6).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct UrdfArmParams {
    /// The URDF document (read from ``path`` when not given).
    pub urdf: String,
    /// The link whose origin is the tip (contact point and task frame).
    pub tip_link: String,
    /// The chain's base link; ``None``: the URDF's root link.
    pub base_link: Option<String>,
    /// Initial joint positions [rad or m], one per joint; ``None``: zero, clipped into the
    /// URDF's position limits.
    pub q0: Option<Vec<f64>>,
    /// Viscous friction [N·m·s/rad]: one number for every joint or one per joint.
    #[serde(with = "crate::schema::fields::numbers")]
    #[schemars(with = "crate::schema::fields::Numbers")]
    pub viscous_friction: Vec<f64>,
    /// Coulomb friction [N·m]: one number for every joint or one per joint.
    #[serde(with = "crate::schema::fields::numbers")]
    #[schemars(with = "crate::schema::fields::Numbers")]
    pub coulomb_friction: Vec<f64>,
    /// ε [rad/s] of sgn(q̇) ≈ tanh(q̇/ε); ε ≤ 0 uses the exact sign.
    pub friction_smoothing: f64,
    /// Gravity along -z of the base frame [m/s²].
    pub gravity: f64,
    /// Task space: ``"position"`` (tip position) or ``"pose"`` (position and orientation,
    /// held at its start); ``None``: position below 6 joints, pose from 6.
    pub task: Option<TaskKind>,
    /// (K_P [1/s²], K_D [1/s]) of the orientation in a pose task; ``None``: the controller's
    /// kp, kd (both divided by its command_divisor K_A, as in eq. 39).
    pub orientation_gains: Option<(f64, f64)>,
    /// λ of the damped pseudo-inverse J⁺ = Jᵀ(J Jᵀ + λ² I)⁻¹ of eqs. 7 and 17.
    pub damping: f64,
    /// A pose task's orientation: ``"hold"`` (its start value R0) or ``"surface"`` (R0 turned by the rotation that takes the estimated surface's normal at the start to its normal at the tip, so the tool stays normal to the part as it curves; SPEC §15).
    pub orientation: OrientationMode,
}

impl Default for UrdfArmParams {
    fn default() -> Self {
        Self {
            urdf: String::new(),
            tip_link: String::new(),
            base_link: None,
            q0: None,
            viscous_friction: vec![0.0],
            coulomb_friction: vec![0.0],
            friction_smoothing: 0.01,
            gravity: 9.81,
            task: None,
            orientation_gains: None,
            damping: 1e-3,
            orientation: OrientationMode::Hold,
        }
    }
}

/// One value per joint from a list of 1 or `n` values.
fn per_joint(field: &str, v: &[f64], n: usize) -> Result<Vec<f64>> {
    match v.len() {
        1 => Ok(vec![v[0]; n]),
        len if len == n => Ok(v.to_vec()),
        len => Err(Error::parameter(
            field,
            format!("{len} values"),
            &format!("one value or {n} (one per joint)"),
        )),
    }
}

impl UrdfArmParams {
    /// Parses the URDF and checks every field; returns the chain.
    pub fn load(&self) -> Result<ChainModel> {
        check::non_negative("gravity", self.gravity)?;
        check::finite("friction_smoothing", self.friction_smoothing)?;
        check::non_negative("damping", self.damping)?;
        if let Some((kp, kd)) = self.orientation_gains {
            check::non_negative("orientation_gains[0]", kp)?;
            check::non_negative("orientation_gains[1]", kd)?;
        }
        let model = urdf::parse(&self.urdf, self.base_link.as_deref(), &self.tip_link)?;
        let n = model.dof();
        if self.orientation == OrientationMode::Surface && self.task_kind(n) != TaskKind::Pose {
            return Err(Error::parameter(
                "orientation",
                "'surface'",
                &format!(
                    "'hold' for a position task (orientation='surface' needs task='pose', \
                     the default from 6 joints; this chain has {n})"
                ),
            ));
        }
        for (field, v) in [
            ("viscous_friction", &self.viscous_friction),
            ("coulomb_friction", &self.coulomb_friction),
        ] {
            for (i, x) in per_joint(field, v, n)?.iter().enumerate() {
                check::non_negative(&format!("{field}[{i}]"), *x)?;
            }
        }
        if let Some(q0) = &self.q0 {
            if q0.len() != n {
                return Err(Error::parameter(
                    "q0",
                    format!("{} values", q0.len()),
                    &format!(
                        "{n} values, one per joint from '{}' to '{}'",
                        model.base_link, model.tip_link
                    ),
                ));
            }
            for (i, x) in q0.iter().enumerate() {
                check::finite(&format!("q0[{i}]"), *x)?;
            }
        }
        Ok(model)
    }

    /// The task of a chain of `n` joints: `task`, else position below 6 joints, pose from 6.
    pub fn task_kind(&self, n: usize) -> TaskKind {
        self.task.unwrap_or(if n >= 6 {
            TaskKind::Pose
        } else {
            TaskKind::Position
        })
    }

    /// The joint count, parsing the URDF.
    pub fn dof(&self) -> Result<usize> {
        Ok(self.load()?.dof())
    }

    pub fn with_model_error(&self, friction_scale: f64) -> Self {
        let mut p = self.clone();
        crate::robot::scale_friction(
            &mut p.viscous_friction,
            &mut p.coulomb_friction,
            friction_scale,
        );
        p
    }
}

/// Viscous plus Coulomb joint friction, τ_f = f_v q̇ + f_c sgn(q̇), over any scalar.
#[derive(Debug, Clone, PartialEq)]
pub struct JointFriction<T: Real, const N: usize> {
    pub fv: SVector<T, N>,
    pub fc: SVector<T, N>,
    /// ε of sgn(q̇) ≈ tanh(q̇/ε); ε ≤ 0: the exact sign.
    pub eps: T,
}

impl<T: Real, const N: usize> JointFriction<T, N> {
    ///
    /// A joint without Coulomb friction (the URDF arms' default) skips sgn's `exp`: its
    /// term f_c sgn(q̇) would be ±0. (A loop, not `from_fn`: the lanes' AVX2 code must
    /// inline it; measured out of line at 5 % of a Panda sweep.)
    #[inline(always)]
    pub fn torque(&self, qd: &SVector<T, N>) -> SVector<T, N> {
        let mut tau = zeros::<T, N, 1>();
        for i in 0..N {
            let viscous = self.fv[i] * qd[i];
            let none = self.fc[i].simd_eq(T::zero());
            tau[i] = if T::all(none) {
                viscous
            } else {
                let coulomb =
                    viscous + self.fc[i] * friction_sign(qd[i], qd[i] / self.eps, self.eps);
                // A lane without Coulomb friction keeps its bits (viscous + 0 would turn
                // −0 into +0), whatever its neighbours: 4- and 8-wide groups agree.
                if T::none(none) {
                    coulomb
                } else {
                    viscous.select(none, coulomb)
                }
            };
        }
        tau
    }
}

impl<W: Real, const N: usize> JointFriction<W, N> {
    /// Lane `l` takes the friction `f`.
    pub fn put_lane(&mut self, l: usize, f: &JointFriction<f64, N>) {
        put_vector(&mut self.fv, l, &f.fv);
        put_vector(&mut self.fc, l, &f.fc);
        put(&mut self.eps, l, f.eps);
    }

    /// Four arms' friction in four lanes.
    pub fn pack<const L: usize>(f: [&JointFriction<f64, N>; L]) -> Self
    where
        W: Wide<L>,
    {
        let v = |g: fn(&JointFriction<f64, N>) -> &SVector<f64, N>| {
            SVector::<W, N>::from_fn(|j, _| W::from_lanes(|l| g(f[l])[j]))
        };
        Self {
            fv: v(|f| &f.fv),
            fc: v(|f| &f.fc),
            eps: W::from_lanes(|l| f[l].eps),
        }
    }
}

/// A URDF chain's equations over any scalar: the bodies, the joint friction, and whether
/// the task holds the tip's orientation (SPEC §11 `task = "pose"`, which adds the
/// orientation rows to the measurement). One arm in `f64`, four in lanes.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain<T: Real, const N: usize> {
    pub chain: SerialChain<T, N>,
    pub friction: JointFriction<T, N>,
    pub pose: bool,
}

impl<W: Real, const N: usize> Chain<W, N> {
    /// Four chains of one structure (joint kinds and task) in four lanes.
    pub fn pack<const L: usize>(c: [&Chain<f64, N>; L]) -> Self
    where
        W: Wide<L>,
    {
        Self {
            chain: SerialChain::pack(c.map(|c| &c.chain)),
            friction: JointFriction::pack(c.map(|c| &c.friction)),
            pose: c[0].pose,
        }
    }

    /// Lane `l` takes the chain `c` (of this structure).
    pub fn put_lane(&mut self, l: usize, c: &Chain<f64, N>) {
        self.chain.put_lane(l, &c.chain);
        self.friction.put_lane(l, &c.friction);
    }
}

impl<T: Real, const N: usize> ArmModel<T, N> for Chain<T, N> {
    type Config = Frames<T, N>;

    #[inline(always)]
    fn configure(&self, q: &SVector<T, N>) -> Frames<T, N> {
        self.chain.frames(q)
    }

    /// The frames afresh, in place (they are kilobytes).
    #[inline(always)]
    fn configure_shifted(
        &self,
        _: &Frames<T, N>,
        _: &SVector<T, N>,
        shifted: &SVector<T, N>,
        out: &mut Frames<T, N>,
    ) {
        self.chain.frames_into(shifted, out);
    }

    #[inline(always)]
    fn tip_position(&self, c: &Frames<T, N>) -> Vector3<T> {
        c.tip.pos
    }

    #[inline(always)]
    fn tip_rotation(&self, c: &Frames<T, N>) -> nalgebra::Matrix3<T> {
        c.tip.rot
    }

    #[inline(always)]
    fn kinematics(&self, c: &Frames<T, N>, qd: &SVector<T, N>) -> Kinematics<N, T> {
        self.measure(c, qd, false).0
    }

    #[inline(always)]
    fn orientation(&self, c: &Frames<T, N>, qd: &SVector<T, N>) -> Option<Orientation<N, T>> {
        self.measure(c, qd, true).1
    }

    /// One 6×N Jacobian for both the position and the orientation rows.
    #[inline(always)]
    fn measure(
        &self,
        c: &Frames<T, N>,
        qd: &SVector<T, N>,
        pose: bool,
    ) -> (Kinematics<N, T>, Option<Orientation<N, T>>) {
        let (j, jdq) = self.chain.jacobian(c, qd);
        let kinematics = Kinematics {
            position: c.tip.pos,
            jacobian: j.fixed_rows::<3>(0).into_owned(),
            jdot_qd: jdq.fixed_rows::<3>(0).into_owned(),
        };
        let orientation = (pose && self.pose).then(|| Orientation {
            rotation: c.tip.rot,
            jacobian: j.fixed_rows::<3>(3).into_owned(),
            jdot_qd: jdq.fixed_rows::<3>(3).into_owned(),
        });
        (kinematics, orientation)
    }

    #[inline(always)]
    fn dynamics(&self, c: &Frames<T, N>, qd: &SVector<T, N>) -> Dynamics<N, T> {
        let (coriolis, gravity) = self.chain.bias(c, qd);
        Dynamics {
            inertia: self.chain.crba(c),
            coriolis,
            gravity,
        }
    }

    #[inline(always)]
    fn friction(&self, qd: &SVector<T, N>) -> SVector<T, N> {
        self.friction.torque(qd)
    }

    /// ABA (Featherstone Table 7.1) with the tip force as a wrench on the last body.
    #[inline(always)]
    fn forward_dynamics(
        &self,
        c: &Frames<T, N>,
        qd: &SVector<T, N>,
        tau: &SVector<T, N>,
        tip_force: &Vector3<T>,
    ) -> SVector<T, N> {
        let wrench = self.chain.tip_wrench(c, tip_force);
        self.chain
            .aba(c, qd, &(tau - self.friction.torque(qd)), &wrench)
    }

    /// ABA with the surface's contact evaluated at the same state, its force F applied as
    /// a wrench on the last body (τ_ext = Jᵀ F).
    #[inline(always)]
    fn accelerate(
        &self,
        c: &Frames<T, N>,
        qd: &SVector<T, N>,
        tau: &SVector<T, N>,
        surface: &impl Surface<T>,
    ) -> (SVector<T, N>, Contact<T>) {
        let contact = surface.contact(&ChainTip {
            chain: &self.chain,
            frames: c,
            qd,
        });
        (self.forward_dynamics(c, qd, tau, &contact.force()), contact)
    }
}

/// A chain's tip motion at one state, from its frames: n·X from the tip's origin, n·Ẋ from
/// its velocity (only when asked).
struct ChainTip<'a, T: Real, const N: usize> {
    chain: &'a SerialChain<T, N>,
    frames: &'a Frames<T, N>,
    qd: &'a SVector<T, N>,
}

impl<T: Real, const N: usize> TipMotion<T> for ChainTip<'_, T, N> {
    #[inline(always)]
    fn along(&self, n: &Vector3<T>, rate: bool) -> (T, T) {
        let rate = if rate {
            n.dot(&self.chain.tip_velocity(self.frames, self.qd))
        } else {
            T::zero()
        };
        (n.dot(&self.frames.tip.pos), rate)
    }

    #[inline(always)]
    fn position(&self) -> Vector3<T> {
        self.frames.tip.pos
    }

    #[inline(always)]
    fn velocity(&self) -> Vector3<T> {
        self.chain.tip_velocity(self.frames, self.qd)
    }
}

/// A URDF chain of `N` joints as a [`RobotModel`].
#[derive(Debug, Clone, PartialEq)]
pub struct UrdfArm<const N: usize> {
    /// Its equations (the chain, its friction, its task's orientation rows).
    pub model: Chain<f64, N>,
    q0: JointVector<N>,
    pub task: TaskKind,
    pub options: crate::robot::TaskOptions,
    /// Position limits [rad or m] (±∞ where none) and effort limits (∞ where none).
    pub lower: JointVector<N>,
    pub upper: JointVector<N>,
    pub effort: JointVector<N>,
    pub joint_names: Vec<String>,
    /// A tool's mass at the tip [kg] (SPEC §15), folded into the last body's inertia.
    pub tool: f64,
}

impl<const N: usize> UrdfArm<N> {
    /// The arm of `params`, whose chain must have `N` joints (see [`UrdfArmParams::dof`]).
    pub fn new(params: &UrdfArmParams) -> Result<Self> {
        let model = params.load()?;
        Self::from_model(params, &model)
    }

    pub fn from_model(params: &UrdfArmParams, model: &ChainModel) -> Result<Self> {
        if model.dof() != N {
            return Err(Error::parameter(
                "tip_link",
                format!("'{}' ({} joints)", params.tip_link, model.dof()),
                &format!("a chain of {N} joints"),
            ));
        }
        let v = |f: fn(&crate::robot::chain::JointSpec) -> f64| {
            JointVector::<N>::from_fn(|i, _| f(&model.joints[i]))
        };
        let (lower, upper) = (v(|j| j.lower), v(|j| j.upper));
        let q0 = match &params.q0 {
            Some(q) => JointVector::<N>::from_column_slice(q),
            None => JointVector::<N>::from_fn(|i, _| 0f64.clamp(lower[i], upper[i])),
        };
        let fv = per_joint("viscous_friction", &params.viscous_friction, N)?;
        let fc = per_joint("coulomb_friction", &params.coulomb_friction, N)?;
        let task = params.task_kind(N);
        Ok(Self {
            model: Chain {
                chain: SerialChain::from_model(model, params.gravity),
                friction: JointFriction {
                    fv: JointVector::<N>::from_column_slice(&fv),
                    fc: JointVector::<N>::from_column_slice(&fc),
                    eps: params.friction_smoothing,
                },
                pose: task == TaskKind::Pose,
            },
            q0,
            task,
            options: crate::robot::TaskOptions {
                orientation_gains: params.orientation_gains,
                damping: params.damping,
                follow_surface: params.orientation == OrientationMode::Surface,
            },
            lower,
            upper,
            effort: v(|j| j.effort),
            joint_names: model.joints.iter().map(|j| j.name.clone()).collect(),
            tool: 0.0,
        })
    }

    /// The 6×N Jacobian and 6-D J̇q̇ (rows 0–2 linear, 3–5 angular).
    pub fn jacobian6(
        &self,
        c: &Frames<f64, N>,
        qd: &JointVector<N>,
    ) -> (nalgebra::SMatrix<f64, 6, N>, SVector<f64, 6>) {
        self.model.chain.jacobian(c, qd)
    }

    /// The largest excursion of `q` beyond the position limits (0 if within).
    pub fn limit_excursion(&self, q: &[f64]) -> f64 {
        q.iter()
            .enumerate()
            .map(|(i, &v)| (self.lower[i] - v).max(v - self.upper[i]).max(0.0))
            .fold(0.0, f64::max)
    }
}

impl<const N: usize> RobotModel<N> for UrdfArm<N> {
    type Model = Chain<f64, N>;
    type Lanes<W: Real> = Chain<W, N>;

    /// The arms users sweep: six joints (UR, xArm 6, Kinova Gen3 lite) and seven (Panda, iiwa,
    /// Gen3). Other joint counts run sweeps one run at a time: the lane loop compiled for each
    /// of the eight counts and three lane builds took two thirds of the build.
    const LANES: bool = N == 6 || N == 7;

    #[inline(always)]
    fn model(&self) -> &Chain<f64, N> {
        &self.model
    }

    fn same_structure(&self, other: &Self) -> bool {
        self.model.chain.same_structure(&other.model.chain) && self.task == other.task
    }

    fn pack<W: Wide<L>, const L: usize>(models: [&Chain<f64, N>; L]) -> Chain<W, N> {
        Chain::pack(models)
    }

    fn put_lane<W: Real>(lanes: &mut Chain<W, N>, l: usize, model: &Chain<f64, N>) {
        lanes.put_lane(l, model);
    }

    fn with_model_error(&self, mass_scale: f64, friction_scale: f64) -> Self {
        let mut a = self.clone();
        // The tool's mass is believed on its own: it is not scaled with the arm's.
        a.model.chain = if self.tool > 0.0 {
            let bare = self.model.chain.with_tip_mass(-self.tool);
            bare.with_mass_scale(mass_scale).with_tip_mass(self.tool)
        } else {
            self.model.chain.with_mass_scale(mass_scale)
        };
        a.model.friction.fv *= friction_scale;
        a.model.friction.fc *= friction_scale;
        a
    }

    fn with_tool(&self, mass: f64) -> Self {
        let mut a = self.clone();
        if mass != self.tool {
            a.model.chain = self.model.chain.with_tip_mass(mass - self.tool);
            a.tool = mass;
        }
        a
    }

    fn gravity(&self) -> f64 {
        self.model.chain.gravity
    }

    fn initial_position(&self) -> JointVector<N> {
        self.q0
    }

    fn position_limits(&self) -> Option<(JointVector<N>, JointVector<N>)> {
        Some((self.lower, self.upper))
    }

    fn task_options(&self) -> crate::robot::TaskOptions {
        self.options
    }
}

/// The rotation vector θ a of a rotation matrix (log map), for orientation errors; over
/// any scalar, with no data-dependent branch.
///
/// With v = (R − Rᵀ)∨ = 2 sin θ a and tr R − 1 = 2 cos θ, θ = atan2(|v|, tr R − 1) and
/// θ a = v θ/|v| (→ v/2 as θ → 0). Why not acos((tr R − 1)/2), as nalgebra's
/// `scaled_axis`: near the identity, rounding puts its argument above 1 — acos gives NaN
/// (an arm whose orientation error was 1e-16 stopped with a non-finite torque) — and for
/// θ below ~1e-8 it returns rounding noise. Like any log map it is ill-conditioned near
/// θ = π, where v vanishes too; an orientation error that large has left the task long
/// before.
#[inline(always)]
pub fn rotation_vector<T: Real>(r: &Matrix3<T>) -> Vector3<T> {
    let v = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    );
    let sin2 = v.norm();
    let cos2 = r[(0, 0)] + r[(1, 1)] + r[(2, 2)] - T::one();
    let angle = sin2.simd_atan2(cos2);
    // θ/|v| at |v| = 0 is its limit 1/2 (the identity gives v = 0 either way).
    let zero = sin2.simd_eq(T::zero());
    let ratio = T::splat(0.5).select(zero, angle / sin2);
    v * ratio
}

/// Every term of a URDF arm at one state, in plain vectors (row-major matrices): for the
/// Python layer and tests, at any joint count.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainTerms {
    pub joints: usize,
    /// D, n×n.
    pub inertia: Vec<f64>,
    pub coriolis: Vec<f64>,
    pub gravity: Vec<f64>,
    /// The 6×n tip Jacobian (rows 0–2 linear).
    pub jacobian: Vec<f64>,
    pub jdot_qd: Vec<f64>,
    pub position: Vec<f64>,
    /// The tip rotation, 3×3.
    pub rotation: Vec<f64>,
    pub friction: Vec<f64>,
    /// q̈ for the given torque and tip force (ABA), when asked for.
    pub acceleration: Option<Vec<f64>>,
}

/// The chain's static description: joint names, limits, the default q0 and the task.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainInfo {
    pub joint_names: Vec<String>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub effort: Vec<f64>,
    pub q0: Vec<f64>,
    pub task: TaskKind,
}

fn row_major<const R: usize, const C: usize>(m: &nalgebra::SMatrix<f64, R, C>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

fn terms_n<const N: usize>(
    p: &UrdfArmParams,
    model: &ChainModel,
    q: &[f64],
    qd: &[f64],
    forward: Option<(&[f64], [f64; 3])>,
) -> Result<ChainTerms> {
    let arm = UrdfArm::<N>::from_model(p, model)?;
    for (name, v) in [("q", q), ("qd", qd)] {
        if v.len() != N {
            return Err(Error::parameter(
                name,
                format!("{} values", v.len()),
                &format!("{N} values, one per joint"),
            ));
        }
    }
    let q = JointVector::<N>::from_column_slice(q);
    let qd = JointVector::<N>::from_column_slice(qd);
    let c = arm.model.configure(&q);
    let d = arm.model.dynamics(&c, &qd);
    let (j, jdq) = arm.jacobian6(&c, &qd);
    let acceleration = match forward {
        Some((tau, force)) => {
            if tau.len() != N {
                return Err(Error::parameter(
                    "tau",
                    format!("{} values", tau.len()),
                    &format!("{N} values, one per joint"),
                ));
            }
            let tau = JointVector::<N>::from_column_slice(tau);
            Some(
                arm.model
                    .forward_dynamics(&c, &qd, &tau, &Vector3::from(force))
                    .as_slice()
                    .to_vec(),
            )
        }
        None => None,
    };
    Ok(ChainTerms {
        joints: N,
        inertia: row_major(&d.inertia),
        coriolis: d.coriolis.as_slice().to_vec(),
        gravity: d.gravity.as_slice().to_vec(),
        jacobian: row_major(&j),
        jdot_qd: jdq.as_slice().to_vec(),
        position: c.tip.pos.as_slice().to_vec(),
        rotation: row_major(&c.tip.rot),
        friction: arm.model.friction(&qd).as_slice().to_vec(),
        acceleration,
    })
}

fn info_n<const N: usize>(p: &UrdfArmParams, model: &ChainModel) -> Result<ChainInfo> {
    let arm = UrdfArm::<N>::from_model(p, model)?;
    Ok(ChainInfo {
        joint_names: arm.joint_names.clone(),
        lower: arm.lower.as_slice().to_vec(),
        upper: arm.upper.as_slice().to_vec(),
        effort: arm.effort.as_slice().to_vec(),
        q0: arm.q0.as_slice().to_vec(),
        task: arm.task,
    })
}

/// D, C q̇, G, J, J̇q̇, tip pose, friction (and q̈ with `forward` = (τ, tip force)) at (q, q̇).
pub fn chain_terms(
    p: &UrdfArmParams,
    q: &[f64],
    qd: &[f64],
    forward: Option<(&[f64], [f64; 3])>,
) -> Result<ChainTerms> {
    let model = p.load()?;
    struct Terms<'a>(
        &'a UrdfArmParams,
        &'a ChainModel,
        (&'a [f64], &'a [f64]),
        Option<(&'a [f64], [f64; 3])>,
    );
    impl JointCount for Terms<'_> {
        type Output = Result<ChainTerms>;
        fn visit<const N: usize>(self) -> Result<ChainTerms> {
            terms_n::<N>(self.0, self.1, self.2 .0, self.2 .1, self.3)
        }
    }
    with_joints(model.dof(), Terms(p, &model, (q, qd), forward))
        .unwrap_or_else(|| Err(unsupported_joints(model.dof())))
}

/// Joint names, limits, q0 and task of the chain of `p`.
pub fn chain_info(p: &UrdfArmParams) -> Result<ChainInfo> {
    let model = p.load()?;
    struct Info<'a>(&'a UrdfArmParams, &'a ChainModel);
    impl JointCount for Info<'_> {
        type Output = Result<ChainInfo>;
        fn visit<const N: usize>(self) -> Result<ChainInfo> {
            info_n::<N>(self.0, self.1)
        }
    }
    with_joints(model.dof(), Info(p, &model))
        .unwrap_or_else(|| Err(unsupported_joints(model.dof())))
}

#[cfg(test)]
mod tests {
    use super::*;

    const PANDA: &str = include_str!("../../../../examples/data/panda.urdf");

    fn panda(gravity: f64) -> UrdfArm<7> {
        UrdfArm::<7>::new(&UrdfArmParams {
            urdf: PANDA.to_owned(),
            tip_link: "panda_hand_tcp".to_owned(),
            gravity,
            ..UrdfArmParams::default()
        })
        .unwrap()
    }

    fn kinetic_energy(arm: &UrdfArm<7>, q: &JointVector<7>, qd: &JointVector<7>) -> f64 {
        let d = arm.model.dynamics(&arm.model.configure(q), qd).inertia;
        0.5 * qd.dot(&(d * qd))
    }

    /// Relative kinetic-energy drift of a free 1-s motion (no gravity, friction or torque)
    /// integrated by RK4 with step `h`.
    fn energy_drift(h: f64) -> f64 {
        let arm = panda(0.0);
        let mut q =
            JointVector::<7>::from_column_slice(&[0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]);
        let mut qd = JointVector::<7>::from_column_slice(&[0.8, -0.5, 0.6, 0.7, -0.9, 0.5, 1.0]);
        let e0 = kinetic_energy(&arm, &q, &qd);
        let tau = JointVector::<7>::zeros();
        let f = |q: &JointVector<7>, qd: &JointVector<7>| {
            arm.model
                .forward_dynamics(&arm.model.configure(q), qd, &tau, &Vector3::zeros())
        };
        let steps = (1.0 / h).round() as usize;
        for _ in 0..steps {
            let k1 = (qd, f(&q, &qd));
            let k2 = (
                qd + k1.1 * (h / 2.0),
                f(&(q + k1.0 * (h / 2.0)), &(qd + k1.1 * (h / 2.0))),
            );
            let k3 = (
                qd + k2.1 * (h / 2.0),
                f(&(q + k2.0 * (h / 2.0)), &(qd + k2.1 * (h / 2.0))),
            );
            let k4 = (qd + k3.1 * h, f(&(q + k3.0 * h), &(qd + k3.1 * h)));
            q += (k1.0 + k2.0 * 2.0 + k3.0 * 2.0 + k4.0) * (h / 6.0);
            qd += (k1.1 + k2.1 * 2.0 + k3.1 * 2.0 + k4.1) * (h / 6.0);
        }
        ((kinetic_energy(&arm, &q, &qd) - e0) / e0).abs()
    }

    /// Energy is conserved to RK4 accuracy. RK4's global error is C h⁴, so the relative
    /// drift falls 16× per halving of h (asserted within [10, 24]). Measured: 1.69e-10 at
    /// h = 4e-3 s and 1.08e-11 at 2e-3 s (ratio 15.7), so C ≈ 0.66 s⁻⁴; the bound
    /// asserted at h = 1e-3 s is 2 C h⁴ ≈ 1.3e-12, and at the simulator's substep
    /// h = 1e-4 s the same law gives 7e-17, below the rounding floor (~1e-13).
    #[test]
    fn panda_free_motion_conserves_kinetic_energy() {
        let (coarse, fine) = (energy_drift(4e-3), energy_drift(2e-3));
        eprintln!("energy drift: h=4e-3 {coarse:e}, h=2e-3 {fine:e}");
        let ratio = coarse / fine;
        assert!((10.0..24.0).contains(&ratio), "{coarse} {fine} {ratio}");
        let at_1ms = energy_drift(1e-3);
        assert!(at_1ms < 2.0 * 0.66 * 1e-12, "{at_1ms:e}");
    }

    #[test]
    fn errors_name_the_element() {
        let p = |urdf: &str, tip: &str| UrdfArmParams {
            urdf: urdf.to_owned(),
            tip_link: tip.to_owned(),
            ..UrdfArmParams::default()
        };
        let e = UrdfArm::<7>::new(&p(PANDA, "nowhere"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("tip_link = 'nowhere'"), "{e}");
        let e = UrdfArm::<7>::new(&UrdfArmParams {
            q0: Some(vec![0.0; 3]),
            ..p(PANDA, "panda_hand_tcp")
        })
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("q0 = 3 values"), "{e}");
        let floating = PANDA.replace(
            r#"name="panda_joint3" type="revolute""#,
            r#"name="panda_joint3" type="floating""#,
        );
        let e = UrdfArm::<7>::new(&p(&floating, "panda_hand_tcp"))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("urdf joint 'panda_joint3' = type floating"),
            "{e}"
        );
    }
}
