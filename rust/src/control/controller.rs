//! The inner position loop as one state machine over a scalar `T` (SPEC §4, §11, §14):
//! `f64` for one run, a lane type for four runs of one structure. It owns what the laws of
//! `control::laws` need between periods and across a run: the law's kind, the gains of
//! eq. (39), D̄ and K_t, TDC's memory τ_{k−1}, q̇_{k−1}, and the task's reference state (R0 of a
//! pose task, q0 of a redundant arm's posture, J⁺'s damping). Computed torque's model is any
//! [`ArmModel`] over the same scalar: a scalar run is `Controller<f64, M, N>` (`M` an arm's
//! `f64` equations); a lane group packs four of them into `Controller<F64x4, M, N>` (`M`
//! the four models in lanes). There is no second copy.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use simba::simd::SimdValue;

use crate::control::laws::{
    computed_torque, model_free, time_delay, OrientationTask, TaskInputs, TaskTerms,
};
use crate::control::params::{constant_inertia, ControllerParams, PositionGains, TdcLaw};
use crate::control::task::Desired;
use crate::robot::chain::arm::rotation_vector;
use crate::robot::{ArmModel, JointVector, Kinematics, Orientation, RobotModel, TaskOptions};
use crate::scalar::{
    cross, finite, mask_from, mat_mul, mat_vec, no_lane, put, put_vector, zeros, Real, Wide,
};

/// What the controller reads at t_k: the encoders' state, the tip kinematics the plant
/// evaluated once, the tip orientation terms when the task holds the orientation, and the
/// measured contact force along the wall normal.
#[derive(Debug, Clone, Copy)]
pub struct Measured<'a, T: Real, const N: usize> {
    pub q: &'a SVector<T, N>,
    pub qd: &'a SVector<T, N>,
    pub kinematics: &'a Kinematics<N, T>,
    /// The tip's rotation terms; read only by a pose task (`Controller::pose`).
    pub orientation: Option<&'a Orientation<N, T>>,
    /// Contact force along the wall normal, as the sensor reads it [N].
    pub force: T,
    /// The wall normal n (the force direction).
    pub normal: &'a Vector3<T>,
}

/// TDC's memory (eq. 14): τ_{k−1}, the torque *applied* in the previous period (anti-windup,
/// SPEC §10), and q̇_{k−1}; `started`: the lanes that have a q̇_{k−1}.
#[derive(Debug, Clone, PartialEq)]
pub struct TdcMemory<T: Real, const N: usize> {
    pub law: TdcLaw,
    period: T,
    /// τ_{−1} = Ĝ(q0).
    initial_torque: SVector<T, N>,
    tau_prev: SVector<T, N>,
    qd_prev: SVector<T, N>,
    started: T::SimdBool,
}

/// The law's kind with what it keeps.
#[derive(Debug, Clone, PartialEq)]
pub enum Law<T: Real, M, const N: usize> {
    /// Eq. (7), with the model the controller believes in.
    ComputedTorque { compensation: bool, model: M },
    /// Eq. (18) without the delay estimate.
    ModelFree,
    /// Eqs. (17) and (18) with their memory.
    TimeDelay(TdcMemory<T, N>),
}

/// The general task's reference state (SPEC §11): R0 of a pose task with its orientation
/// (K_P, K_D), q0 of a redundant arm's posture and J⁺'s damping λ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskSetup<T: Real, const N: usize> {
    start_rotation: Option<Matrix3<T>>,
    /// n̂ at the start, for a pose task that keeps the tool normal to the estimated surface
    /// (`UrdfArm(orientation="surface")`, SPEC §15): R_d turns R0 as n̂ turns.
    start_normal: Option<Vector3<T>>,
    orientation_gains: (T, T),
    posture: Option<SVector<T, N>>,
    damping: T,
}

/// The arm's task as one run sees it at q0: R0 for a pose task, q0 for a redundant arm's
/// posture, and the arm's J⁺ damping and orientation gains.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskAtStart<const N: usize> {
    pub start_rotation: Option<Matrix3<f64>>,
    /// The estimated normal at the start, when the orientation follows the surface.
    pub start_normal: Option<Vector3<f64>>,
    pub posture: Option<JointVector<N>>,
    pub options: TaskOptions,
}

impl<const N: usize> TaskAtStart<N> {
    /// What `robot`'s task holds: R0 (a pose task), q0 where N exceeds the task's dimension.
    pub fn of<R: RobotModel<N>>(robot: &R) -> Self {
        let (q0, model) = (robot.initial_position(), robot.model());
        let start_rotation = model
            .orientation(&model.configure(&q0), &JointVector::zeros())
            .map(|o| o.rotation);
        let task_dimension = if start_rotation.is_some() { 6 } else { 3 };
        Self {
            start_rotation,
            start_normal: None,
            posture: (N > task_dimension).then_some(q0),
            options: robot.task_options(),
        }
    }

    /// The task with the estimated normal at the start, `normal`, which a pose task whose
    /// arm asks for it (`TaskOptions::follow_surface`) keeps the tool normal to.
    pub fn with_surface_normal(mut self, normal: &Vector3<f64>) -> Self {
        if self.options.follow_surface && self.start_rotation.is_some() {
            self.start_normal = Some(*normal);
        }
        self
    }
}

/// A position controller: one of the three laws, on the square path or the general task
/// path, with its memory. Over `f64` (one run, model `M` an arm) or lanes.
#[derive(Debug, Clone, PartialEq)]
pub struct Controller<T: Real, M, const N: usize> {
    law: Law<T, M, N>,
    gains: PositionGains<T>,
    /// D̄ = α I's α (the square path; computed torque: unused).
    inertia: T,
    /// D̄ as a matrix: α I or the per-joint D̄ (the task path).
    dbar: SMatrix<T, N, N>,
    torque_constant: T,
    /// `None`: the paper's square path (three joints, position task, D̄ = α I, J⁻¹).
    task: Option<TaskSetup<T, N>>,
}

impl<M: ArmModel<f64, N>, const N: usize> Controller<f64, M, N> {
    /// The controller for the plant's arm `robot` (computed torque's model: `robot`'s
    /// with the controller's model error), whose task is `task`.
    pub fn new<R: RobotModel<N, Model = M>>(
        params: &ControllerParams,
        robot: &R,
        period: f64,
        task: &TaskAtStart<N>,
    ) -> Self {
        let (gains, inertia, joint_inertia, torque_constant) = match params {
            ControllerParams::ComputedTorque(p) => (p.gains, 1.0, None, 0.0),
            ControllerParams::ModelFree(p) => {
                (p.gains, p.inertia, p.joint_inertia, p.torque_constant)
            }
            ControllerParams::TimeDelay(p) => {
                (p.gains, p.inertia, p.joint_inertia, p.torque_constant)
            }
        };
        let law = match params {
            ControllerParams::ComputedTorque(p) => Law::ComputedTorque {
                compensation: p.contact_compensation,
                model: p.model.arm(robot),
            },
            ControllerParams::ModelFree(_) => Law::ModelFree,
            ControllerParams::TimeDelay(p) => {
                let model = p.model.arm(robot);
                let q0 = robot.initial_position();
                let g0 = model
                    .dynamics(&model.configure(&q0), &JointVector::zeros())
                    .gravity;
                Law::TimeDelay(TdcMemory {
                    law: p.law,
                    period,
                    initial_torque: g0,
                    tau_prev: g0,
                    qd_prev: JointVector::zeros(),
                    started: false,
                })
            }
        };
        // The paper's square 3×3 path (J⁻¹) stays as it was; every other task goes through
        // the general one (J⁺ with the arm's damping).
        let task_path = N != 3
            || task.start_rotation.is_some()
            || task.posture.is_some()
            || joint_inertia.is_some();
        Self {
            law,
            gains,
            inertia,
            dbar: constant_inertia::<N>(inertia, &joint_inertia),
            torque_constant,
            task: task_path.then(|| TaskSetup {
                start_rotation: task.start_rotation,
                start_normal: task.start_normal,
                orientation_gains: task
                    .options
                    .orientation_gains
                    .unwrap_or((gains.kp, gains.kd)),
                posture: task.posture,
                damping: task.options.damping,
            }),
        }
    }

    /// Labels of the controller's memory, in the order of `state`.
    pub fn state_labels(&self) -> Vec<String> {
        match self.law {
            Law::TimeDelay(_) => (1..=N)
                .map(|j| format!("controller.tau_prev{j}"))
                .chain((1..=N).map(|j| format!("controller.qd_prev{j}")))
                .collect(),
            _ => Vec::new(),
        }
    }

    pub fn state(&self, out: &mut Vec<f64>) {
        if let Law::TimeDelay(m) = &self.law {
            out.extend_from_slice(m.tau_prev.as_slice());
            let qd_prev = if m.started {
                m.qd_prev
            } else {
                JointVector::zeros()
            };
            out.extend_from_slice(qd_prev.as_slice());
        }
    }

    /// Reads the memory written by `state`. `started`: whether a sample has been taken (so
    /// q̇_{k−1} exists). Returns the number of values used.
    pub fn set_state(&mut self, values: &[f64], started: bool) -> usize {
        if let Law::TimeDelay(m) = &mut self.law {
            m.tau_prev = JointVector::<N>::from_column_slice(&values[..N]);
            m.qd_prev = JointVector::<N>::from_column_slice(&values[N..2 * N]);
            m.started = started;
        }
        self.state_len()
    }

    pub fn state_len(&self) -> usize {
        match self.law {
            Law::TimeDelay(_) => 2 * N,
            _ => 0,
        }
    }
}

impl<T: Real, M, const N: usize> Controller<T, M, N> {
    pub fn gains(&self) -> &PositionGains<T> {
        &self.gains
    }

    /// Whether the task holds the tip's orientation (a pose task): the caller then passes
    /// the tip's rotation terms in `Measured::orientation`.
    pub fn pose(&self) -> bool {
        self.task.is_some_and(|t| t.start_rotation.is_some())
    }

    /// Whether the law runs the general task path (J⁺) rather than the square one (J⁻¹).
    pub fn task_path(&self) -> bool {
        self.task.is_some()
    }

    pub fn law(&self) -> &Law<T, M, N> {
        &self.law
    }

    pub fn reset(&mut self) {
        if let Law::TimeDelay(m) = &mut self.law {
            m.tau_prev = m.initial_torque;
            m.qd_prev = SVector::zeros();
            m.started = no_lane::<T>();
        }
    }

    /// The commanded joint torque τ_k for the measurement at t_k, with the lanes whose
    /// Jacobian failed (J⁻¹ singular, or J⁺'s Cholesky or J⁺ itself not finite). The memory
    /// moves on in `applied`, once the actuator has said what it applied.
    #[inline(always)]
    pub fn command(
        &self,
        m: &Measured<T, N>,
        at: &M::Config,
        desired: &Desired<T>,
    ) -> (SVector<T, N>, T::SimdBool)
    where
        M: ArmModel<T, N>,
    {
        let k = m.kinematics;
        // J q̇ written out (nalgebra's sums, the same bits): nalgebra's generic product stays
        // out of line in the native lane builds, each vector operation a call (§24).
        let velocity = mat_vec(&k.jacobian, m.qd);
        // eq. (39)
        let v = self.gains.command(desired, &k.position, &velocity);
        let Some(task) = &self.task else {
            return self.square(m, at, &v);
        };
        // e_o = log(R_d Rᵀ): the orientation is held at its start R0, or (following the
        // surface) at R0 turned by the rotation that takes n̂ at the start to n̂ now.
        let orientation = match (&task.start_rotation, m.orientation) {
            (Some(r0), Some(o)) => {
                let target = match &task.start_normal {
                    Some(n0) => mat_mul(&shortest_turn(n0, m.normal), r0),
                    None => *r0,
                };
                Some(OrientationTask {
                    error: rotation_vector(&mat_mul(&target, &o.rotation.transpose())),
                    jacobian: o.jacobian,
                    jdot_qd: o.jdot_qd,
                })
            }
            _ => None,
        };
        let gains = &self.gains;
        let input = TaskInputs {
            q: m.q,
            qd: m.qd,
            orientation: orientation.as_ref().map(|o| (o, task.orientation_gains)),
            posture: task.posture.as_ref(),
            gains: (gains.ka, gains.kd, gains.kp),
            damping: task.damping,
        };
        let (terms, failed) = TaskTerms::new(k, &v, &input);
        if T::all(failed) {
            return (SVector::zeros(), failed);
        }
        let tau = match &self.law {
            Law::ComputedTorque {
                compensation,
                model,
            } => terms.computed_torque(
                (model.dynamics(at, m.qd), model.friction(m.qd)),
                &k.jacobian,
                compensation.then_some((m.normal, m.force)),
            ),
            Law::ModelFree => terms.model_free(&self.dbar, self.torque_constant),
            Law::TimeDelay(mem) => terms.time_delay(
                m.qd,
                &self.dbar,
                (self.torque_constant, mem.period),
                mem.law,
                &mem.tau_prev,
                &mem.qd_prev,
                mem.started,
            ),
        };
        (tau, failed)
    }

    /// The square path (three joints, position task, D̄ = α I): J⁻¹ as the paper writes it.
    #[inline(always)]
    fn square(
        &self,
        m: &Measured<T, N>,
        at: &M::Config,
        v: &Vector3<T>,
    ) -> (SVector<T, N>, T::SimdBool)
    where
        M: ArmModel<T, N>,
    {
        let k = m.kinematics;
        match &self.law {
            Law::ComputedTorque {
                compensation,
                model,
            } => computed_torque(
                k,
                v,
                || (model.dynamics(at, m.qd), model.friction(m.qd)),
                compensation.then_some((m.normal, m.force)),
            ),
            Law::ModelFree => (
                model_free(k, v, self.inertia, self.torque_constant),
                no_lane::<T>(),
            ),
            Law::TimeDelay(mem) => time_delay(
                k,
                v,
                m.qd,
                (self.inertia, self.torque_constant, mem.period),
                mem.law,
                &mem.tau_prev,
                &mem.qd_prev,
                mem.started,
            ),
        }
    }

    /// Tells the controller the torque the actuator applied for its command at the state
    /// with joint rates `qd`: TDC's τ_{k−1} is the applied torque (identical to the command
    /// when nothing limits it), its q̇_{k−1} this q̇_k.
    #[inline(always)]
    pub fn applied(&mut self, tau: &SVector<T, N>, qd: &SVector<T, N>) {
        if let Law::TimeDelay(m) = &mut self.law {
            m.tau_prev = *tau;
            m.qd_prev = *qd;
            m.started = !no_lane::<T>();
        }
    }
}

/// What runs must share for their controllers to advance in one lane group: the law's kind
/// with its structural switch, the path with the task terms present, and
/// `scale_feedforward`. Everything else (gains, D̄, K_t, λ, R0, q0, the memory) is a number
/// a lane carries. A new law kind adds a variant here, or `Controller::lane_key` does not
/// compile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ControllerKey {
    pub law: LawKey,
    /// `None`: the square path; else the general task path with (pose, posture).
    pub task: Option<TaskKey>,
    pub scale_feedforward: bool,
}

/// The law's kind with what changes its code path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LawKey {
    ComputedTorque { contact_compensation: bool },
    ModelFree,
    TimeDelay(TdcLaw),
}

/// The general task path's terms: orientation rows (a pose task) and a posture term.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TaskKey {
    pub pose: bool,
    pub posture: bool,
    /// The orientation follows the estimated surface's normal.
    pub follow_surface: bool,
}

impl<T: Real, M, const N: usize> Controller<T, M, N> {
    /// This controller's structure (see [`ControllerKey`]).
    pub fn lane_key(&self) -> ControllerKey {
        ControllerKey {
            law: match &self.law {
                Law::ComputedTorque { compensation, .. } => LawKey::ComputedTorque {
                    contact_compensation: *compensation,
                },
                Law::ModelFree => LawKey::ModelFree,
                Law::TimeDelay(m) => LawKey::TimeDelay(m.law),
            },
            task: self.task.as_ref().map(|t| TaskKey {
                pose: t.start_rotation.is_some(),
                posture: t.posture.is_some(),
                follow_surface: t.start_normal.is_some(),
            }),
            scale_feedforward: self.gains.scale_feedforward,
        }
    }
}

impl<W: Real, M, const N: usize> Controller<W, M, N> {
    /// Four runs' controllers of one structure in lanes (`None` if their structures differ);
    /// `models` packs computed torque's four models.
    pub fn pack<R, const L: usize>(
        c: [&Controller<f64, R, N>; L],
        models: impl FnOnce([&R; L]) -> M,
    ) -> Option<Self>
    where
        W: Wide<L>,
    {
        if !c.iter().all(|x| x.lane_key() == c[0].lane_key()) {
            return None;
        }
        let law = match &c[0].law {
            Law::ComputedTorque { compensation, .. } => Law::ComputedTorque {
                compensation: *compensation,
                model: models(c.map(|x| match &x.law {
                    Law::ComputedTorque { model, .. } => model,
                    _ => unreachable!("one structure: every lane is computed torque"),
                })),
            },
            Law::ModelFree => Law::ModelFree,
            Law::TimeDelay(m) => Law::TimeDelay(TdcMemory {
                law: m.law,
                period: W::splat(0.0),
                initial_torque: SVector::zeros(),
                tau_prev: SVector::zeros(),
                qd_prev: SVector::zeros(),
                started: mask_from::<W>(|_| false),
            }),
        };
        let mut packed = Self {
            law,
            gains: PositionGains::pack(c.map(|x| &x.gains)),
            inertia: W::splat(0.0),
            dbar: SMatrix::zeros(),
            torque_constant: W::splat(0.0),
            task: c[0].task.map(|t| TaskSetup {
                start_rotation: t.start_rotation.map(|_| Matrix3::zeros()),
                start_normal: t.start_normal.map(|_| Vector3::zeros()),
                orientation_gains: (W::splat(0.0), W::splat(0.0)),
                posture: t.posture.map(|_| SVector::zeros()),
                damping: W::splat(0.0),
            }),
        };
        for (l, x) in c.iter().enumerate() {
            packed.put_numbers(l, x);
        }
        Some(packed)
    }

    /// Lane `l` takes the run's controller `c` (of this structure, else false and nothing
    /// changes); `model` puts computed torque's model into its lane.
    pub fn put_lane<R>(
        &mut self,
        l: usize,
        c: &Controller<f64, R, N>,
        model: impl FnOnce(&mut M, &R),
    ) -> bool {
        if self.lane_key() != c.lane_key() {
            return false;
        }
        if let (Law::ComputedTorque { model: m, .. }, Law::ComputedTorque { model: r, .. }) =
            (&mut self.law, &c.law)
        {
            model(m, r);
        }
        self.put_numbers(l, c);
        true
    }

    /// Lane `l`'s numbers and memory from `c`.
    fn put_numbers<R>(&mut self, l: usize, c: &Controller<f64, R, N>) {
        put(&mut self.gains.ka, l, c.gains.ka);
        put(&mut self.gains.kd, l, c.gains.kd);
        put(&mut self.gains.kp, l, c.gains.kp);
        put(&mut self.inertia, l, c.inertia);
        put_vector(&mut self.dbar, l, &c.dbar);
        put(&mut self.torque_constant, l, c.torque_constant);
        if let (Some(t), Some(theirs)) = (&mut self.task, &c.task) {
            if let (Some(r), Some(r0)) = (&mut t.start_rotation, &theirs.start_rotation) {
                put_vector(r, l, r0);
            }
            if let (Some(p), Some(q0)) = (&mut t.posture, &theirs.posture) {
                put_vector(p, l, q0);
            }
            if let (Some(n), Some(n0)) = (&mut t.start_normal, &theirs.start_normal) {
                put_vector(n, l, n0);
            }
            put(&mut t.orientation_gains.0, l, theirs.orientation_gains.0);
            put(&mut t.orientation_gains.1, l, theirs.orientation_gains.1);
            put(&mut t.damping, l, theirs.damping);
        }
        if let (Law::TimeDelay(m), Law::TimeDelay(theirs)) = (&mut self.law, &c.law) {
            put(&mut m.period, l, theirs.period);
            put_vector(&mut m.initial_torque, l, &theirs.initial_torque);
            put_vector(&mut m.tau_prev, l, &theirs.tau_prev);
            put_vector(&mut m.qd_prev, l, &theirs.qd_prev);
            m.started.replace(l, theirs.started);
        }
    }
}

/// The rotation that takes the unit vector `a` to the unit vector `b` about a × b, by the
/// least angle: I + [v]× + [v]×² / (1 + c), v = a × b, c = a·b (Rodrigues). Exact I when
/// a = b; 1 + c is kept from 0 (a normal turned by π names no one rotation).
#[inline(always)]
pub(crate) fn shortest_turn<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> Matrix3<T> {
    let v = cross(a, b);
    let c = a.dot(b);
    let k = Matrix3::new(
        T::zero(),
        -v[2],
        v[1],
        v[2],
        T::zero(),
        -v[0],
        -v[1],
        v[0],
        T::zero(),
    );
    let scale = T::one() / (T::one() + c).simd_max(T::splat(1e-12));
    // (I + K) + K² · scale entry by entry, as nalgebra's operators sum it (the same bits,
    // −0 entries of K included), inlined (`mat_mul`).
    let k2 = mat_mul(&k, &k);
    let mut turn = zeros::<T, 3, 3>();
    for col in 0..3 {
        for row in 0..3 {
            let identity = if row == col { T::one() } else { T::zero() };
            turn[(row, col)] = identity + k[(row, col)] + k2[(row, col)] * scale;
        }
    }
    turn
}

/// The lanes where any entry of `v` is not finite.
#[inline(always)]
pub(crate) fn not_finite<T: Real, const N: usize>(v: &SVector<T, N>) -> T::SimdBool {
    !v.iter().fold(!no_lane::<T>(), |m, c| m & finite(*c))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::params::{ComputedTorqueParams, ModelFreeParams, TimeDelayParams};
    use crate::robot::three_link::{ClosedForm, Kinematics, Trig, Vec3};
    use crate::robot::{RobotParams, TaskVector, ThreeLinkArm};
    use crate::scalar::F64x4;
    use crate::scalar::{lane_of, pack_vector};

    type Ctl = Controller<f64, ClosedForm, 3>;
    const X: TaskVector = TaskVector::new(1.0, 0.0, 0.0);
    const REST: Vec3 = Vec3::new(0.0, 0.0, 0.0);

    fn at_q0() -> (ThreeLinkArm, Vec3, Kinematics) {
        let arm = ThreeLinkArm::new(&RobotParams::default());
        let q = arm.initial_position();
        let k = arm
            .model()
            .kinematics(&arm.model().configure(&q), &Vec3::zeros());
        (arm, q, k)
    }

    fn controller(params: ControllerParams, arm: &ThreeLinkArm) -> Ctl {
        Ctl::new(&params, arm, 1e-3, &TaskAtStart::of(arm))
    }

    /// The paper's TDC at q0, its set point 1 cm along x from the tip.
    fn tdc_pulled_along_x() -> (ThreeLinkArm, Vec3, Kinematics, Ctl, Desired) {
        let (r, q, k) = at_q0();
        let c = controller(ControllerParams::TimeDelay(TimeDelayParams::default()), &r);
        let d = Desired {
            position: k.position + Vec3::new(0.01, 0.0, 0.0),
            ..Desired::default()
        };
        (r, q, k, c, d)
    }

    /// The measurement of a controller test: no contact force, the paper's wall normal.
    fn measured<'a>(q: &'a Vec3, qd: &'a Vec3, k: &'a Kinematics) -> Measured<'a, f64, 3> {
        Measured {
            q,
            qd,
            kinematics: k,
            orientation: None,
            force: 0.0,
            normal: &X,
        }
    }

    /// One period: the command, then (nothing limiting it) the memory moves on.
    fn step(c: &mut Ctl, m: &Measured<f64, 3>, d: &Desired) -> Option<Vec3> {
        let (tau, singular) = c.command(m, &Trig::new(m.q), d);
        if singular {
            return None;
        }
        c.applied(&tau, m.qd);
        Some(tau)
    }

    fn gravity(arm: &ThreeLinkArm, q: &Vec3) -> Vec3 {
        arm.model()
            .dynamics(&arm.model().configure(q), &Vec3::zeros())
            .gravity
    }

    /// The rotation taking a to b (Rodrigues), written out entry by entry, equals
    /// nalgebra's operator form I + K + K² / (1 + c) to the bit, and turns a onto b.
    #[test]
    fn shortest_turn_is_the_operator_form() {
        let pairs = [
            (
                TaskVector::new(0.0, 0.0, -1.0),
                TaskVector::new(0.1, -0.2, -0.97),
            ),
            (
                TaskVector::new(0.3, 0.4, 0.5),
                TaskVector::new(-0.2, 0.9, 0.1),
            ),
            (
                TaskVector::new(1.0, 0.0, 0.0),
                TaskVector::new(1.0, 0.0, 0.0),
            ),
        ];
        for (a, b) in pairs {
            let (a, b) = (a.normalize(), b.normalize());
            let v = a.cross(&b);
            let k = Matrix3::new(0.0, -v[2], v[1], v[2], 0.0, -v[0], -v[1], v[0], 0.0);
            let scale = 1.0 / (1.0 + a.dot(&b)).max(1e-12);
            let operators = Matrix3::identity() + k + k * k * scale;
            let turn = shortest_turn(&a, &b);
            let bits = |m: &Matrix3<f64>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&turn), bits(&operators));
            assert!((turn * a - b).norm() < 1e-15, "{a} to {b}");
        }
    }

    #[test]
    fn computed_torque_holds_still_with_gravity_compensation() {
        let (r, q, k) = at_q0();
        let mut c = controller(
            ControllerParams::ComputedTorque(ComputedTorqueParams::default()),
            &r,
        );
        let m = measured(&q, &REST, &k);
        let d = Desired {
            position: k.position,
            ..Desired::default()
        };
        let tau = step(&mut c, &m, &d).unwrap();
        assert!((tau - gravity(&r, &q)).abs().max() < 1e-12);
    }

    #[test]
    fn tdc_first_step_is_gravity_plus_transpose_term() {
        let (r, q, k, mut c, d) = tdc_pulled_along_x();
        let qd = Vec3::zeros();
        let m = measured(&q, &qd, &k);
        let tau0 = step(&mut c, &m, &d).unwrap();
        let g = gravity(&r, &q);
        // V = 100·0.01/5 = 0.2 along x; D̄ K_t = 20.
        let expected = g + k.jacobian.transpose() * Vec3::new(0.2, 0.0, 0.0) * 20.0;
        assert!((tau0 - expected).abs().max() < 1e-12);
        // Next step: q̇ changed by 0.001 rad/s on joint 2 ⇒ q̈_{k−1} = 1 rad/s².
        let qd1 = Vec3::new(0.0, 0.001, 0.0);
        let m1 = Measured { qd: &qd1, ..m };
        let tau1 = step(&mut c, &m1, &d).unwrap();
        let v1 = k.jacobian.transpose() * (Vec3::new(0.2, 0.0, 0.0) - k.jacobian * qd1 * 4.0);
        let expected1 = tau0 + v1 * 20.0 - Vec3::new(0.0, 0.1, 0.0);
        assert!((tau1 - expected1).abs().max() < 1e-12);
        c.reset();
        assert!((step(&mut c, &m, &d).unwrap() - tau0).abs().max() < 1e-15);
    }

    #[test]
    fn singular_jacobian_is_reported() {
        let r = ThreeLinkArm::new(&RobotParams::default());
        let q = Vec3::new(0.0, 0.3, 0.0);
        let k = r
            .model()
            .kinematics(&r.model().configure(&q), &Vec3::zeros());
        let mut c = controller(
            ControllerParams::ComputedTorque(ComputedTorqueParams::default()),
            &r,
        );
        let m = measured(&q, &REST, &k);
        assert_eq!(step(&mut c, &m, &Desired::default()), None);
    }

    /// TDC's τ_{k−1} is the torque the actuator applied, not the one commanded.
    #[test]
    fn tdc_remembers_the_applied_torque() {
        let (r, q, k, mut c, d) = tdc_pulled_along_x();
        let m = measured(&q, &REST, &k);
        let (tau0, _) = c.command(&m, &Trig::new(m.q), &d);
        let applied = tau0.map(|t| t.clamp(-20.0, 20.0));
        c.applied(&applied, &REST);
        let mut state = Vec::new();
        c.state(&mut state);
        assert_eq!(&state[..3], applied.as_slice());
        // Same measurement again: u is unchanged, ĥ = τ_{k−1} − 0 is the applied torque.
        let (tau1, _) = c.command(&m, &Trig::new(m.q), &d);
        assert!((tau1 - (tau0 - gravity(&r, &q) + applied)).abs().max() < 1e-12);
    }

    /// Four controllers packed into lanes (each with its own gains, D̄ and TDC memory) give
    /// the four scalar controllers' torques bit for bit, over several periods, and a lane
    /// that takes a new controller gives that controller's torques; a controller of another
    /// structure does not pack.
    #[test]
    fn controllers_in_lanes_equal_four_scalar_controllers() {
        let (r, _, _) = at_q0();
        let qs: [Vec3; 4] = std::array::from_fn(|i| Vec3::new(0.05 * i as f64, 0.8, -0.9));
        let tdc = |i: usize| {
            ControllerParams::TimeDelay(TimeDelayParams {
                inertia: 0.1 + 0.01 * i as f64,
                gains: PositionGains::new(5.0, 20.0 + i as f64, 100.0),
                ..TimeDelayParams::default()
            })
        };
        let mut scalar: Vec<Ctl> = (0..5).map(|i| controller(tdc(i), &r)).collect();
        let models = |arms: [&ClosedForm; 4]| ClosedForm::pack(arms);
        let mut lanes = Controller::<F64x4, ClosedForm<F64x4>, 3>::pack(
            std::array::from_fn(|i| &scalar[i]),
            models,
        )
        .unwrap();
        let other = controller(ControllerParams::ModelFree(ModelFreeParams::default()), &r);
        assert!(Controller::<F64x4, ClosedForm<F64x4>, 3>::pack(
            [&scalar[0], &scalar[1], &scalar[2], &other],
            models
        )
        .is_none());
        assert!(!lanes.put_lane(0, &other, |_, _| ()));
        let d = Desired {
            position: Vec3::new(0.3, 0.0, 0.5),
            ..Desired::default()
        };
        for period in 0..6 {
            if period == 3 {
                // Lane 2 takes the fifth controller, fresh.
                assert!(lanes.put_lane(2, &scalar[4], |_, _| ()));
                scalar.swap(2, 4);
            }
            let qd: [Vec3; 4] =
                std::array::from_fn(|i| Vec3::new(0.01 * (period + i) as f64, -0.02, 0.0));
            let kins: [Kinematics; 4] =
                std::array::from_fn(|i| r.model().kinematics(&r.model().configure(&qs[i]), &qd[i]));
            let expected: [Vec3; 4] = std::array::from_fn(|i| {
                step(&mut scalar[i], &measured(&qs[i], &qd[i], &kins[i]), &d).unwrap()
            });
            let (q4, qd4) = (pack_vector(qs.each_ref()), pack_vector(qd.each_ref()));
            let kin = crate::robot::Kinematics::<3, F64x4> {
                position: pack_vector(kins.each_ref().map(|k| &k.position)),
                jacobian: pack_vector(kins.each_ref().map(|k| &k.jacobian)),
                jdot_qd: pack_vector(kins.each_ref().map(|k| &k.jdot_qd)),
            };
            let normal = pack_vector([&X; 4]);
            let m = Measured {
                q: &q4,
                qd: &qd4,
                kinematics: &kin,
                orientation: None,
                force: F64x4::splat(0.0),
                normal: &normal,
            };
            let d4 = Desired {
                position: pack_vector([&d.position; 4]),
                ..Desired::default()
            };
            // The lanes' trig as the lane loop evaluates it (libm's bits in every lane).
            let (tau, singular) = lanes.command(&m, &Trig::<F64x4>::new(&q4), &d4);
            assert!(!simba::simd::SimdBool::any(singular));
            lanes.applied(&tau, &qd4);
            for (i, e) in expected.iter().enumerate() {
                assert_eq!(&lane_of(&tau, i), e, "period {period} lane {i}");
            }
        }
    }
}
