//! Stages 1–8 of a period in lanes for the three-link arm (SPEC §10, §13): four runs'
//! sensors, filters, task frames, control laws and actuators packed into [`F64x4`] and
//! stepped once per period by the same generic stage code the scalar pipeline runs
//! (`ForceSensor::read`, `ForceControl::step`, `TaskFrame::force_reference`,
//! `PositionGains::command`, `computed_torque` / `model_free` / `time_delay`,
//! `Actuator::apply_lanes`).
//!
//! What stays per lane, and why: each run's noise draw (its own seeded generator at its own
//! sample index), its references (a run's signals may be of different kinds, each a
//! function of that lane's own t), and the record and online metrics (each lane's
//! `Simulation::close_sample`, so the bookkeeping exists once). The orchestration below
//! mirrors `Simulation::step_to_plant`, which it cannot call: that one reads and writes one
//! run's state; this one packs four. It holds no physics or control law of its own.

use nalgebra::Vector3;
use simba::simd::{AutoBoolx4, SimdValue};

use crate::control::controller::{
    computed_torque, model_free, time_delay, Controller, PositionGains, TdcLaw,
};
use crate::control::filter::ForceControl;
use crate::control::reference::Sample;
use crate::control::task::TaskFrame;
use crate::robot::three_link::{ClosedForm, Trig};
use crate::robot::ThreeLinkArm;
use crate::scalar::{
    finite, lane, lane_of, mask_from, pack_vector, put, put_vector, F64x4, Real, LANES,
};
use crate::sim::lanes::{Front, PackedPlant};
use crate::sim::outcome::Divergence;
use crate::sim::simulation::Simulation;
use crate::sim::trace::Row;
use crate::world::actuator::Actuator;
use crate::world::sensor::ForceSensor;

type Sim = Simulation<ThreeLinkArm, 3>;

/// The three-link control laws of one kind in lanes (the square path: J⁻¹, no posture).
/// One per lane group, built once and never moved in the loop: its size does not matter.
#[allow(clippy::large_enum_variant)]
enum LaneLaw {
    /// Eq. (7); the controllers' own models (with their model errors) packed.
    ComputedTorque {
        compensation: bool,
        model: ClosedForm<F64x4>,
    },
    /// Eq. (18) without the delay estimate.
    ModelFree {
        inertia: F64x4,
        torque_constant: F64x4,
    },
    /// Eqs. (17) and (18) with their memory.
    TimeDelay {
        inertia: F64x4,
        torque_constant: F64x4,
        period: F64x4,
        law: TdcLaw,
        tau_prev: Vector3<F64x4>,
        qd_prev: Vector3<F64x4>,
        started: AutoBoolx4,
    },
}

impl LaneLaw {
    /// The laws of four controllers of one kind; `None` if the kinds or their structure
    /// differ, or a law takes the general task path (a per-joint D̄).
    fn pack(c: [&Controller<ThreeLinkArm, 3>; LANES]) -> Option<Self> {
        if c.iter().any(|c| c.joint_inertia().is_some()) {
            return None;
        }
        let mut law = match c[0] {
            Controller::ComputedTorque { params, model } => LaneLaw::ComputedTorque {
                compensation: params.contact_compensation,
                model: ClosedForm::pack([model.closed_form(); LANES]),
            },
            Controller::ModelFree(p) => LaneLaw::ModelFree {
                inertia: F64x4::splat(p.inertia),
                torque_constant: F64x4::splat(p.torque_constant),
            },
            Controller::TimeDelay { params, period, .. } => LaneLaw::TimeDelay {
                inertia: F64x4::splat(params.inertia),
                torque_constant: F64x4::splat(params.torque_constant),
                period: F64x4::splat(*period),
                law: params.law,
                tau_prev: Vector3::zeros(),
                qd_prev: Vector3::zeros(),
                started: AutoBoolx4::splat(false),
            },
        };
        for (l, c) in c.iter().enumerate() {
            if !law.put_lane(l, c) {
                return None;
            }
        }
        Some(law)
    }

    /// Lane `l` takes the controller `c`; false if its kind or structure differs.
    fn put_lane(&mut self, l: usize, c: &Controller<ThreeLinkArm, 3>) -> bool {
        match (self, c) {
            (
                LaneLaw::ComputedTorque {
                    compensation,
                    model,
                },
                Controller::ComputedTorque { params, model: m },
            ) if *compensation == params.contact_compensation => {
                model.put_lane(l, m.closed_form());
            }
            (
                LaneLaw::ModelFree {
                    inertia,
                    torque_constant,
                },
                Controller::ModelFree(p),
            ) => {
                put(inertia, l, p.inertia);
                put(torque_constant, l, p.torque_constant);
            }
            (
                LaneLaw::TimeDelay {
                    inertia,
                    torque_constant,
                    period,
                    law,
                    tau_prev,
                    qd_prev,
                    started,
                },
                Controller::TimeDelay {
                    params,
                    period: p,
                    tau_prev: t,
                    qd_prev: q,
                    ..
                },
            ) if *law == params.law => {
                put(inertia, l, params.inertia);
                put(torque_constant, l, params.torque_constant);
                put(period, l, *p);
                put_vector(tau_prev, l, t);
                put_vector(qd_prev, l, &q.unwrap_or_else(Vector3::zeros));
                started.replace(l, q.is_some());
            }
            _ => return false,
        }
        true
    }
}

/// Four three-link runs' stages 1–8 in lanes.
pub struct ThreeLinkStages {
    sensor: ForceSensor<F64x4>,
    force_control: Option<ForceControl<F64x4>>,
    frame: TaskFrame<F64x4>,
    gains: PositionGains<F64x4>,
    law: LaneLaw,
    actuator: Actuator<3, F64x4>,
}

impl Front<ThreeLinkArm, 3> for ThreeLinkStages {
    fn pack(sims: [&Sim; LANES]) -> Option<Self> {
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
            law: LaneLaw::pack(sims.map(|s| s.controller()))?,
            actuator: Actuator::pack(sims.map(|s| s.actuator())),
        })
    }

    fn put_lane(&mut self, l: usize, sim: &Sim) {
        self.sensor.put_lane(l, sim.sensor());
        if let (Some(f), Some(g)) = (&mut self.force_control, sim.force_control()) {
            f.put_lane(l, g);
        }
        self.frame.put_lane(l, sim.frame());
        let g = sim.controller().gains();
        put(&mut self.gains.ka, l, g.ka);
        put(&mut self.gains.kd, l, g.kd);
        put(&mut self.gains.kp, l, g.kp);
        self.law.put_lane(l, sim.controller());
        self.actuator.put_lane(l, sim.actuator());
    }

    #[inline(always)]
    fn step(
        &mut self,
        plant: &PackedPlant<ClosedForm<F64x4>>,
        sims: &mut [Sim],
        slot: &[Option<usize>; LANES],
        run: &[usize; LANES],
    ) -> [Option<Vector3<f64>>; LANES] {
        let lanes = run.map(|i| &sims[i]);
        let k = lanes.map(|s| s.sample());
        let t = F64x4::from_lanes(|l| k[l] as f64 * lanes[l].config().period);
        let first = mask_from::<F64x4>(|l| k[l] == 0);
        // 1. plant state (the encoders), with each lane's fresh trig of q
        let states = lanes.map(|s| *s.plant().state());
        let qd = pack_vector(states.each_ref().map(|s| &s.qd));
        let trig = Trig::pack(lanes.map(|s| s.plant().config()));
        let kin = plant.arm.kinematics(&trig, &qd);
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
        // 6. control law (square path, eq. 39's V)
        let velocity = kin.jacobian * qd;
        let v = self.gains.command(&desired, &kin.position, &velocity);
        let (command, singular) = match &mut self.law {
            LaneLaw::ComputedTorque {
                compensation,
                model,
            } => computed_torque(
                &kin,
                &v,
                || (model.dynamics(&trig, &qd), model.friction(&qd)),
                compensation.then_some((&self.frame.normal, measured)),
            ),
            LaneLaw::ModelFree {
                inertia,
                torque_constant,
            } => (
                model_free(&kin, &v, *inertia, *torque_constant),
                AutoBoolx4::splat(false),
            ),
            LaneLaw::TimeDelay {
                inertia,
                torque_constant,
                period,
                law,
                tau_prev,
                qd_prev,
                started,
            } => time_delay(
                &kin,
                &v,
                &qd,
                (*inertia, *torque_constant, *period),
                *law,
                tau_prev,
                qd_prev,
                *started,
            ),
        };
        let finite_command = finite(command[0]) & finite(command[1]) & finite(command[2]);
        // 7. actuator; TDC remembers what was applied
        let tau = self.actuator.apply_lanes(first, &command);
        if let LaneLaw::TimeDelay {
            tau_prev,
            qd_prev,
            started,
            ..
        } = &mut self.law
        {
            *tau_prev = tau;
            *qd_prev = qd;
            *started = AutoBoolx4::splat(true);
        }
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
mod tests {
    use super::*;
    use crate::control::controller::{ControllerParams, TimeDelayParams};
    use crate::sim::lanes::run_lanes;
    use crate::sim::simulation::{RunResult, ScenarioConfig};
    use crate::world::actuator::ActuatorParams;
    use crate::world::environment::WallParams;
    use crate::world::sensor::SensorParams;

    /// Six TDC runs (a ragged group) with their own wall, sensor, actuator and gains.
    fn configs() -> Vec<ScenarioConfig> {
        (0..6)
            .map(|i| {
                let f = i as f64;
                ScenarioConfig {
                    duration: 0.3,
                    seed: 3 + i as u64,
                    wall: Some(WallParams {
                        stiffness: 1e4 * (1.0 + f),
                        ..WallParams::default()
                    }),
                    controller: ControllerParams::TimeDelay(TimeDelayParams {
                        inertia: 0.1 + 0.01 * f,
                        ..TimeDelayParams::default()
                    }),
                    sensor: SensorParams {
                        noise_std: 0.1 * f,
                        cutoff: (i % 2 == 0).then_some(60.0),
                        resolution: if i == 3 { 0.05 } else { 0.0 },
                        latency: 1,
                        ..SensorParams::default()
                    },
                    actuator: ActuatorParams {
                        torque_limit: (i % 3 == 1).then(|| vec![120.0]),
                        rate_limit: (i == 4).then_some(3e4),
                        ..ActuatorParams::default()
                    },
                    ..ScenarioConfig::default()
                }
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
            for ((name, x), (_, y)) in alone
                .trace
                .clone()
                .into_named_columns()
                .into_iter()
                .zip(r.trace.clone().into_named_columns())
            {
                let scale = x.iter().fold(1e-12_f64, |m, v| m.max(v.abs()));
                let worst = x
                    .iter()
                    .zip(&y)
                    .filter(|(p, _)| !p.is_nan())
                    .fold(0.0_f64, |m, (p, q)| m.max((p - q).abs()));
                assert!(worst <= 1e-9 * scale, "{name}: {worst:e} of {scale:e}");
            }
        }
        // The last run with other neighbours, and alone: the same bits.
        let other = lanes(&[c[1].clone(), c[5].clone()]);
        assert_eq!(other[1].trace, all[5].trace);
        assert_eq!(lanes(&c[5..])[0].trace, all[5].trace);
    }
}
