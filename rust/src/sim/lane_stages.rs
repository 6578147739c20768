//! Stages 1–8 of a period in lanes (SPEC §10, §13): four runs' sensors, filters, task
//! frames, control laws and actuators packed into [`F64x4`] and stepped once per period by
//! the same generic stage code the scalar pipeline runs (`ForceSensor::read`,
//! `ForceControl::step`, `TaskFrame::force_reference`, `PositionGains::command`, the square
//! laws `computed_torque` / `model_free` / `time_delay` and the general task path
//! `TaskTerms` of SPEC §11, `Actuator::apply_lanes`).
//!
//! One orchestration, [`LaneStages`], serves every arm; an arm brings what differs through
//! [`StageArm`]: its kinematics in lanes (the three-link closed form here; URDF chains'
//! frames, 6×N Jacobian and tip rotation in `sim::chain_stages`) and its controller model
//! for computed torque. The law takes the square path (J⁻¹, three joints, position task,
//! scalar D̄) or the general task path (damped J⁺, orientation, posture, matrix D̄) exactly
//! where `Controller::step` does.
//!
//! What stays per lane, and why: each run's noise draw (its own seeded generator at its own
//! sample index), its references (a run's signals may be of different kinds, each a
//! function of that lane's own t), and the record and online metrics (each lane's
//! `Simulation::close_sample`, so the bookkeeping exists once). The orchestration below
//! mirrors `Simulation::step_to_plant`, which it cannot call: that one reads and writes one
//! run's state; this one packs four. It holds no physics or control law of its own.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use simba::simd::{AutoBoolx4, SimdBool, SimdValue};

use crate::control::controller::{
    computed_torque, constant_inertia, model_free, time_delay, Controller, OrientationTask,
    PositionGains, TaskInputs, TaskTerms, TdcLaw,
};
use crate::control::filter::ForceControl;
use crate::control::reference::Sample;
use crate::control::task::TaskFrame;
use crate::robot::chain::arm::rotation_vector;
use crate::robot::three_link::{ClosedForm, Trig};
use crate::robot::{Dynamics, Kinematics, ThreeLinkArm};
use crate::scalar::{
    finite, lane, lane_of, mask_from, pack_vector, put, put_vector, F64x4, Real, LANES,
};
use crate::sim::lanes::{Front, LaneArm, PackedPlant};
use crate::sim::outcome::Divergence;
use crate::sim::simulation::Simulation;
use crate::sim::trace::Row;
use crate::world::actuator::Actuator;
use crate::world::sensor::ForceSensor;

/// A pose task's tip terms in lanes: the rotation R, the angular Jacobian and its J̇q̇.
pub type TipRotation<const N: usize> = (Matrix3<F64x4>, SMatrix<F64x4, 3, N>, Vector3<F64x4>);

/// What an arm brings to the lane stages besides its plant.
pub trait StageArm<const N: usize>: LaneArm<N> {
    /// Four controllers' models (computed torque's D̂, Ĉ, Ĝ, τ̂_f) in lanes.
    type Model;
    /// What the lanes' kinematics leave for the model (the three-link arm's trig).
    type At;

    fn pack_model(arms: [&Self; LANES]) -> Self::Model;

    /// Lane `l` takes the model `arm`.
    fn put_model(model: &mut Self::Model, l: usize, arm: &Self);

    /// Tip position, 3×N Jacobian and J̇q̇ at the lanes' state (q, q̇), and, for a pose
    /// task (`pose`), the tip rotation terms.
    fn lane_kinematics(
        plant: &PackedPlant<Self::Lanes>,
        lanes: [&Simulation<Self, N>; LANES],
        q: &SVector<F64x4, N>,
        qd: &SVector<F64x4, N>,
        pose: bool,
    ) -> (Kinematics<N, F64x4>, Option<TipRotation<N>>, Self::At);

    /// The model's (D̂, Ĉ q̇, Ĝ) and τ̂_f at the lanes' state.
    fn model_terms(
        model: &Self::Model,
        at: &Self::At,
        q: &SVector<F64x4, N>,
        qd: &SVector<F64x4, N>,
    ) -> (Dynamics<N, F64x4>, SVector<F64x4, N>);
}

/// The kind of law, with its own memory. One per lane group, built once and never moved in
/// the loop: its size does not matter.
#[allow(clippy::large_enum_variant)]
enum LawKind<M, const N: usize> {
    /// Eq. (7); the controllers' own models (with their model errors) packed.
    ComputedTorque { compensation: bool, model: M },
    /// Eq. (18) without the delay estimate.
    ModelFree,
    /// Eqs. (17) and (18) with their memory.
    TimeDelay(TdcLanes<N>),
}

/// TDC's law, period and memory τ_{k−1}, q̇_{k−1} in lanes (`started`: the lanes that have a
/// q̇_{k−1}).
struct TdcLanes<const N: usize> {
    period: F64x4,
    law: TdcLaw,
    tau_prev: SVector<F64x4, N>,
    qd_prev: SVector<F64x4, N>,
    started: AutoBoolx4,
}

/// The general task's per-lane terms (SPEC §11): R0 for a pose task with its orientation
/// (K_P, K_D), q0 for a redundant arm's posture, J⁺'s damping λ.
struct TaskLanes<const N: usize> {
    start_rotation: Option<Matrix3<F64x4>>,
    orientation_gains: (F64x4, F64x4),
    posture: Option<SVector<F64x4, N>>,
    damping: F64x4,
}

impl<const N: usize> TaskLanes<N> {
    /// The four runs' task terms (their structure checked by `LaneLaw::pack`).
    fn pack<R: StageArm<N>>(sims: [&Simulation<R, N>; LANES]) -> Self {
        let mut task = TaskLanes {
            start_rotation: sims[0].start_rotation().map(|_| Matrix3::zeros()),
            orientation_gains: (F64x4::splat(0.0), F64x4::splat(0.0)),
            posture: sims[0].posture().map(|_| SVector::zeros()),
            damping: F64x4::splat(0.0),
        };
        for (l, s) in sims.iter().enumerate() {
            task.put_lane(l, s);
        }
        task
    }

    fn put_lane<R: StageArm<N>>(&mut self, l: usize, sim: &Simulation<R, N>) {
        if let (Some(r), Some(r0)) = (&mut self.start_rotation, sim.start_rotation()) {
            put_vector(r, l, r0);
        }
        if let (Some(p), Some(q0)) = (&mut self.posture, sim.posture()) {
            put_vector(p, l, q0);
        }
        let gains = sim.controller().gains();
        let options = sim.task_options();
        let (kp, kd) = options.orientation_gains.unwrap_or((gains.kp, gains.kd));
        put(&mut self.orientation_gains.0, l, kp);
        put(&mut self.orientation_gains.1, l, kd);
        put(&mut self.damping, l, options.damping);
    }
}

/// Whether `Controller::step` takes the general task path for this run.
fn takes_task_path<R: StageArm<N>, const N: usize>(s: &Simulation<R, N>) -> bool {
    N != 3
        || s.start_rotation().is_some()
        || s.posture().is_some()
        || s.controller().joint_inertia().is_some()
}

/// The control laws of one kind in lanes, on the square path or the general task path.
struct LaneLaw<M, const N: usize> {
    kind: LawKind<M, N>,
    /// D̄ = α I's α (square path; computed torque: unused).
    inertia: F64x4,
    /// D̄ as a matrix, α I or the per-joint D̄ (task path).
    dbar: SMatrix<F64x4, N, N>,
    torque_constant: F64x4,
    /// `None`: the square path.
    task: Option<TaskLanes<N>>,
}

impl<M, const N: usize> LaneLaw<M, N> {
    /// The laws of four runs' controllers of one kind; `None` if their kinds, structure or
    /// path differ.
    fn pack<R: StageArm<N, Model = M>>(sims: [&Simulation<R, N>; LANES]) -> Option<Self> {
        let task_path = takes_task_path(sims[0]);
        if sims.iter().any(|s| {
            takes_task_path(*s) != task_path
                || s.start_rotation().is_some() != sims[0].start_rotation().is_some()
                || s.posture().is_some() != sims[0].posture().is_some()
        }) {
            return None;
        }
        let kind = match sims[0].controller() {
            Controller::ComputedTorque { params, .. } => LawKind::ComputedTorque {
                compensation: params.contact_compensation,
                // A lane of another kind takes its plant's arm here and fails `put_lane`.
                model: R::pack_model(sims.map(|s| match s.controller() {
                    Controller::ComputedTorque { model, .. } => model,
                    _ => s.plant().arm(),
                })),
            },
            Controller::ModelFree(_) => LawKind::ModelFree,
            Controller::TimeDelay { params, .. } => LawKind::TimeDelay(TdcLanes {
                period: F64x4::splat(0.0),
                law: params.law,
                tau_prev: SVector::zeros(),
                qd_prev: SVector::zeros(),
                started: AutoBoolx4::splat(false),
            }),
        };
        let mut law = LaneLaw {
            kind,
            inertia: F64x4::splat(0.0),
            dbar: SMatrix::zeros(),
            torque_constant: F64x4::splat(0.0),
            task: task_path.then(|| TaskLanes::pack(sims)),
        };
        for (l, s) in sims.iter().enumerate() {
            if !law.put_lane(l, s) {
                return None;
            }
        }
        Some(law)
    }

    /// Lane `l` takes the run `sim`; false if its kind or structure differs.
    fn put_lane<R: StageArm<N, Model = M>>(&mut self, l: usize, sim: &Simulation<R, N>) -> bool {
        if let Some(task) = &mut self.task {
            task.put_lane(l, sim);
        }
        let (inertia, joint, torque_constant) = match sim.controller() {
            Controller::ComputedTorque { .. } => (1.0, None, 0.0),
            Controller::ModelFree(p) => (p.inertia, p.joint_inertia, p.torque_constant),
            Controller::TimeDelay { params, .. } => {
                (params.inertia, params.joint_inertia, params.torque_constant)
            }
        };
        put(&mut self.inertia, l, inertia);
        put_vector(&mut self.dbar, l, &constant_inertia::<N>(inertia, &joint));
        put(&mut self.torque_constant, l, torque_constant);
        match (&mut self.kind, sim.controller()) {
            (
                LawKind::ComputedTorque {
                    compensation,
                    model,
                },
                Controller::ComputedTorque { params, model: m },
            ) if *compensation == params.contact_compensation => R::put_model(model, l, m),
            (LawKind::ModelFree, Controller::ModelFree(_)) => {}
            (
                LawKind::TimeDelay(m),
                Controller::TimeDelay {
                    params,
                    period,
                    tau_prev,
                    qd_prev,
                    ..
                },
            ) if m.law == params.law => {
                put(&mut m.period, l, *period);
                put_vector(&mut m.tau_prev, l, tau_prev);
                put_vector(&mut m.qd_prev, l, &qd_prev.unwrap_or_else(SVector::zeros));
                m.started.replace(l, qd_prev.is_some());
            }
            _ => return false,
        }
        true
    }

    /// Stage 6: the commanded torque and the lanes whose Jacobian failed (J⁻¹ singular, or
    /// J⁺'s Cholesky or J⁺ itself not finite), as `Controller::step`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn torque<R: StageArm<N, Model = M>>(
        &self,
        kin: &Kinematics<N, F64x4>,
        rotation: Option<&TipRotation<N>>,
        at: &R::At,
        (q, qd): (&SVector<F64x4, N>, &SVector<F64x4, N>),
        v: &Vector3<F64x4>,
        gains: &PositionGains<F64x4>,
        contact: (&Vector3<F64x4>, F64x4),
    ) -> (SVector<F64x4, N>, AutoBoolx4) {
        let Some(task) = &self.task else {
            return self.square::<R>(kin, at, (q, qd), v, contact);
        };
        // e_o = log(R0 Rᵀ), generic with its small-angle branch a lane select.
        let orientation = match (&task.start_rotation, rotation) {
            (Some(r0), Some((r, jacobian, jdot_qd))) => Some(OrientationTask {
                error: rotation_vector(&(r0 * r.transpose())),
                jacobian: *jacobian,
                jdot_qd: *jdot_qd,
            }),
            _ => None,
        };
        let input = TaskInputs {
            q,
            qd,
            orientation: orientation.as_ref().map(|o| (o, task.orientation_gains)),
            posture: task.posture.as_ref(),
            gains: (gains.ka, gains.kd, gains.kp),
            damping: task.damping,
        };
        let (terms, failed) = TaskTerms::new(kin, v, &input);
        let tau = match &self.kind {
            LawKind::ComputedTorque {
                compensation,
                model,
            } => {
                if failed.all() {
                    return (SVector::zeros(), failed);
                }
                terms.computed_torque(
                    R::model_terms(model, at, q, qd),
                    &kin.jacobian,
                    compensation.then_some(contact),
                )
            }
            LawKind::ModelFree => terms.model_free(&self.dbar, self.torque_constant),
            LawKind::TimeDelay(m) => terms.time_delay(
                qd,
                &self.dbar,
                (self.torque_constant, m.period),
                m.law,
                &m.tau_prev,
                &m.qd_prev,
                m.started,
            ),
        };
        (tau, failed)
    }

    /// The square path (three joints, position task, D̄ = α I): J⁻¹ as the paper writes it.
    #[inline(always)]
    fn square<R: StageArm<N, Model = M>>(
        &self,
        kin: &Kinematics<N, F64x4>,
        at: &R::At,
        (q, qd): (&SVector<F64x4, N>, &SVector<F64x4, N>),
        v: &Vector3<F64x4>,
        contact: (&Vector3<F64x4>, F64x4),
    ) -> (SVector<F64x4, N>, AutoBoolx4) {
        match &self.kind {
            LawKind::ComputedTorque {
                compensation,
                model,
            } => computed_torque(
                kin,
                v,
                || R::model_terms(model, at, q, qd),
                compensation.then_some(contact),
            ),
            LawKind::ModelFree => (
                model_free(kin, v, self.inertia, self.torque_constant),
                AutoBoolx4::splat(false),
            ),
            LawKind::TimeDelay(m) => time_delay(
                kin,
                v,
                qd,
                (self.inertia, self.torque_constant, m.period),
                m.law,
                &m.tau_prev,
                &m.qd_prev,
                m.started,
            ),
        }
    }

    /// Whether the task holds the tip's orientation (a pose task).
    fn pose(&self) -> bool {
        self.task
            .as_ref()
            .is_some_and(|t| t.start_rotation.is_some())
    }

    /// Stage 7's write-back: TDC remembers the applied torque and q̇_k.
    #[inline(always)]
    fn applied(&mut self, tau: &SVector<F64x4, N>, qd: &SVector<F64x4, N>) {
        if let LawKind::TimeDelay(m) = &mut self.kind {
            m.tau_prev = *tau;
            m.qd_prev = *qd;
            m.started = AutoBoolx4::splat(true);
        }
    }
}

/// Four runs' stages 1–8 in lanes, for any arm with a [`StageArm`].
pub struct LaneStages<R: StageArm<N>, const N: usize> {
    sensor: ForceSensor<F64x4>,
    force_control: Option<ForceControl<F64x4>>,
    frame: TaskFrame<F64x4>,
    gains: PositionGains<F64x4>,
    law: LaneLaw<R::Model, N>,
    actuator: Actuator<N, F64x4>,
}

/// The three-link arm's lane stages.
pub type ThreeLinkStages = LaneStages<ThreeLinkArm, 3>;

impl StageArm<3> for ThreeLinkArm {
    type Model = ClosedForm<F64x4>;
    type At = Trig<F64x4>;

    fn pack_model(arms: [&Self; LANES]) -> ClosedForm<F64x4> {
        ClosedForm::pack(arms.map(|a| a.closed_form()))
    }

    fn put_model(model: &mut ClosedForm<F64x4>, l: usize, arm: &Self) {
        model.put_lane(l, arm.closed_form());
    }

    #[inline(always)]
    fn lane_kinematics(
        plant: &PackedPlant<ClosedForm<F64x4>>,
        lanes: [&Simulation<Self, 3>; LANES],
        _: &Vector3<F64x4>,
        qd: &Vector3<F64x4>,
        _: bool,
    ) -> (Kinematics<3, F64x4>, Option<TipRotation<3>>, Trig<F64x4>) {
        // Each lane's fresh trig of q, as the scalar plant holds it.
        let trig = Trig::pack(lanes.map(|s| s.plant().config()));
        (plant.arm.kinematics(&trig, qd), None, trig)
    }

    #[inline(always)]
    fn model_terms(
        model: &ClosedForm<F64x4>,
        trig: &Trig<F64x4>,
        _: &Vector3<F64x4>,
        qd: &Vector3<F64x4>,
    ) -> (Dynamics<3, F64x4>, Vector3<F64x4>) {
        (model.dynamics(trig, qd), model.friction(qd))
    }
}

impl<R: StageArm<N>, const N: usize> Front<R, N> for LaneStages<R, N> {
    fn pack(sims: [&Simulation<R, N>; LANES]) -> Option<Self> {
        // The lane key (`sweep::lane_key`) groups runs of one structure; checked again
        // here so that a group that is not uniform still runs, per lane.
        let s0 = sims[0];
        let uniform = sims.iter().all(|s| {
            s.sensor().latency() == s0.sensor().latency()
                && s.actuator().delay() == s0.actuator().delay()
                && s.controller().gains().scale_feedforward
                    == s0.controller().gains().scale_feedforward
        });
        if !uniform {
            return None;
        }
        let force_control = match s0.force_control() {
            None if sims.iter().all(|s| s.force_control().is_none()) => None,
            None => return None,
            Some(_) => {
                let f: Option<Vec<_>> = sims.iter().map(|s| s.force_control()).collect();
                let f = f?;
                Some(ForceControl::pack([f[0], f[1], f[2], f[3]])?)
            }
        };
        Some(Self {
            sensor: ForceSensor::pack(sims.map(|s| s.sensor())),
            force_control,
            frame: TaskFrame::pack(sims.map(|s| s.frame())),
            gains: PositionGains::pack(sims.map(|s| s.controller().gains())),
            law: LaneLaw::pack(sims)?,
            actuator: Actuator::pack(sims.map(|s| s.actuator())),
        })
    }

    fn put_lane(&mut self, l: usize, sim: &Simulation<R, N>) {
        self.sensor.put_lane(l, sim.sensor());
        if let (Some(f), Some(g)) = (&mut self.force_control, sim.force_control()) {
            f.put_lane(l, g);
        }
        self.frame.put_lane(l, sim.frame());
        let g = sim.controller().gains();
        put(&mut self.gains.ka, l, g.ka);
        put(&mut self.gains.kd, l, g.kd);
        put(&mut self.gains.kp, l, g.kp);
        self.law.put_lane(l, sim);
        self.actuator.put_lane(l, sim.actuator());
    }

    #[inline(always)]
    fn step(
        &mut self,
        plant: &PackedPlant<R::Lanes>,
        sims: &mut [Simulation<R, N>],
        slot: &[Option<usize>; LANES],
        run: &[usize; LANES],
    ) -> [Option<SVector<f64, N>>; LANES] {
        let lanes = run.map(|i| &sims[i]);
        let k = lanes.map(|s| s.sample());
        let t = F64x4::from_lanes(|l| k[l] as f64 * lanes[l].config().period);
        let first = mask_from::<F64x4>(|l| k[l] == 0);
        // 1. plant state (the encoders)
        let states = lanes.map(|s| *s.plant().state());
        let q = pack_vector(states.each_ref().map(|s| &s.q));
        let qd = pack_vector(states.each_ref().map(|s| &s.qd));
        let (kin, rotation, at) = R::lane_kinematics(plant, lanes, &q, &qd, self.law.pose());
        // 2. environment: the true force along n
        let (force, penetration) = match &plant.wall {
            Some(w) => {
                let velocity = if plant.needs_rate {
                    kin.jacobian * qd
                } else {
                    Vector3::zeros()
                };
                (
                    w.force(&kin.position, &velocity),
                    w.penetration(&kin.position),
                )
            }
            None => (F64x4::splat(0.0), F64x4::splat(f64::NAN)),
        };
        // 3. force sensor; each run draws its own noise at its own sample
        let noise = F64x4::from_lanes(|l| lanes[l].sensor().noise_draw(k[l]));
        let measured = self.sensor.read(first, force, noise);
        // 4. references, each run's signals at its own t
        let f_d: [Sample; LANES] =
            std::array::from_fn(|l| lanes[l].config().force_reference.at(lane(t, l)));
        let s: [Sample; LANES] =
            std::array::from_fn(|l| lanes[l].config().z_reference.at(lane(t, l)));
        let (f_d, s) = (Sample::pack(f_d.each_ref()), Sample::pack(s.each_ref()));
        // 5. force control, fed by the measured force
        let (x_a, desired) = match &mut self.force_control {
            Some(fc) => {
                let x_a = fc.step(&f_d, measured);
                (x_a, self.frame.force_reference(&x_a, &s))
            }
            None => (Sample::default(), self.frame.motion_reference(&s)),
        };
        // 6. control law (eq. 39's V, then the square or the general task path)
        let velocity = kin.jacobian * qd;
        let v = self.gains.command(&desired, &kin.position, &velocity);
        let (command, singular) = self.law.torque::<R>(
            &kin,
            rotation.as_ref(),
            &at,
            (&q, &qd),
            &v,
            &self.gains,
            (&self.frame.normal, measured),
        );
        let finite_command = command
            .iter()
            .fold(AutoBoolx4::splat(true), |m, c| m & finite(*c));
        // 7. actuator; TDC remembers what was applied
        let tau = self.actuator.apply_lanes(first, &command);
        self.law.applied(&tau, &qd);
        // 8. record sample k, per lane (a lane whose law failed ends its run instead)
        std::array::from_fn(|l| {
            let i = slot[l]?;
            let sim = &mut sims[i];
            let time = lane(t, l);
            if singular.extract(l) {
                sim.stop(time, Divergence::SingularJacobian);
                return None;
            }
            if !finite_command.extract(l) {
                sim.stop(time, Divergence::NonFiniteTorque);
                return None;
            }
            let (p, reference) = (lane_of(&kin.position, l), lane_of(&desired.position, l));
            let (tau_l, command_l) = (lane_of(&tau, l), lane_of(&command, l));
            let st = &states[l];
            let more = sim.close_sample(&Row {
                t: time,
                q: st.q.as_slice(),
                qd: st.qd.as_slice(),
                position: [p[0], p[1], p[2]],
                reference: [reference[0], reference[1], reference[2]],
                f: lane(force, l),
                f_measured: lane(measured, l),
                f_d: lane(f_d.value, l),
                penetration: lane(penetration, l),
                x_a: lane(x_a.value, l),
                xa_dot: lane(x_a.rate, l),
                tau: tau_l.as_slice(),
                tau_cmd: command_l.as_slice(),
            });
            more.then_some(tau_l)
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    type Sim = Simulation<ThreeLinkArm, 3>;
    use crate::control::controller::{ControllerParams, TimeDelayParams};
    use crate::sim::lanes::run_lanes;
    use crate::sim::simulation::{RunResult, ScenarioConfig};
    use crate::world::actuator::ActuatorParams;
    use crate::world::environment::WallParams;
    use crate::world::sensor::SensorParams;

    /// Run `i` of a ragged group: its own wall, seed, sensor (noise, cut-off, resolution)
    /// and actuator limits; one sensor latency (the lane key).
    pub(crate) fn varied(i: usize, controller: ControllerParams) -> ScenarioConfig {
        let f = i as f64;
        ScenarioConfig {
            seed: 3 + i as u64,
            wall: Some(WallParams {
                stiffness: 1e4 * (1.0 + f),
                ..WallParams::default()
            }),
            controller,
            sensor: SensorParams {
                noise_std: 0.05 * f,
                cutoff: i.is_multiple_of(2).then_some(80.0),
                resolution: if i == 3 { 0.05 } else { 0.0 },
                latency: 1,
                ..SensorParams::default()
            },
            actuator: ActuatorParams {
                torque_limit: (i % 3 == 1).then(|| vec![100.0]),
                rate_limit: (i == 2).then_some(5e4),
                ..ActuatorParams::default()
            },
            ..ScenarioConfig::default()
        }
    }

    /// The worst gap between a lane run's trace and `simulate`'s, column by column relative
    /// to the column's largest value (at least `floor`); asserts it is within 1e-9.
    pub(crate) fn worst_trace_gap(alone: &RunResult, lanes: &RunResult, floor: f64) -> f64 {
        assert_eq!(lanes.trace.len(), alone.trace.len());
        let mut worst_of_all = 0.0_f64;
        for ((name, x), (_, y)) in alone
            .trace
            .clone()
            .into_named_columns()
            .into_iter()
            .zip(lanes.trace.clone().into_named_columns())
        {
            let scale = x.iter().fold(floor, |m, v| m.max(v.abs()));
            let worst = x
                .iter()
                .zip(&y)
                .filter(|(p, _)| !p.is_nan())
                .fold(0.0_f64, |m, (p, q)| m.max((p - q).abs()));
            assert!(worst <= 1e-9 * scale, "{name}: {worst:e} of {scale:e}");
            worst_of_all = worst_of_all.max(worst / scale);
        }
        worst_of_all
    }

    /// Six TDC runs (a ragged group).
    fn configs() -> Vec<ScenarioConfig> {
        (0..6)
            .map(|i| ScenarioConfig {
                duration: 0.3,
                ..varied(
                    i,
                    ControllerParams::TimeDelay(TimeDelayParams {
                        inertia: 0.1 + 0.01 * i as f64,
                        ..TimeDelayParams::default()
                    }),
                )
            })
            .collect()
    }

    fn lanes(configs: &[ScenarioConfig]) -> Vec<RunResult> {
        let mut sims: Vec<Sim> = configs.iter().map(|c| Sim::new(c).unwrap()).collect();
        run_lanes(&mut sims)
    }

    /// Runs in lanes agree with `simulate` to 1e-9 (only `exp` differs), and a run's bits
    /// do not depend on which runs share its lanes.
    #[test]
    fn lane_stages_agree_with_simulate_and_do_not_mix() {
        let c = configs();
        let all = lanes(&c);
        for (cfg, r) in c.iter().zip(&all) {
            let alone = crate::sim::simulation::simulate(cfg).unwrap();
            assert_eq!(r.outcome, alone.outcome);
            worst_trace_gap(&alone, r, 1e-12);
        }
        // The last run with other neighbours, and alone: the same bits.
        let other = lanes(&[c[1].clone(), c[5].clone()]);
        assert_eq!(other[1].trace, all[5].trace);
        assert_eq!(lanes(&c[5..])[0].trace, all[5].trace);
    }

    /// A three-link arm with a per-joint D̄ takes the general task path (as
    /// `Controller::step` does), in lanes too: the same runs as `simulate`.
    #[test]
    fn per_joint_inertia_takes_the_task_path_in_lanes() {
        use crate::control::controller::{ModelFreeParams, PerJoint, TdcLaw};
        let runs: Vec<Vec<ScenarioConfig>> = [false, true]
            .into_iter()
            .map(|tdc| {
                (0..5)
                    .map(|i| {
                        let joint = PerJoint::from_slice(&[0.1, 0.08 + 0.01 * i as f64, 0.05]);
                        let controller = if tdc {
                            ControllerParams::TimeDelay(TimeDelayParams {
                                joint_inertia: joint,
                                law: TdcLaw::InverseJacobian,
                                ..TimeDelayParams::default()
                            })
                        } else {
                            ControllerParams::ModelFree(ModelFreeParams {
                                joint_inertia: joint,
                                ..ModelFreeParams::default()
                            })
                        };
                        ScenarioConfig {
                            duration: 0.3,
                            ..varied(i, controller)
                        }
                    })
                    .collect()
            })
            .collect();
        for c in runs {
            let sims: Vec<Sim> = c.iter().map(|c| Sim::new(c).unwrap()).collect();
            let packed = LaneStages::pack([&sims[0], &sims[1], &sims[2], &sims[3]]);
            assert!(packed.is_some_and(|p| p.law.task.is_some()));
            for (cfg, r) in c.iter().zip(lanes(&c)) {
                let alone = crate::sim::simulation::simulate(cfg).unwrap();
                assert_eq!(r.outcome, alone.outcome);
                worst_trace_gap(&alone, &r, 1e-12);
            }
        }
    }
}
