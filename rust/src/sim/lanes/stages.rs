//! Stages 1–8 of a period in lanes (SPEC §10, §13, §14): `L` runs' stages 2–7 packed into
//! one [`Pipeline`] over a lane type `W` (`F64x4`, `F64x8`), the same code a scalar run steps
//! as `Pipeline<f64>`, with computed torque's models packed as the plant's are
//! ([`RobotModel::pack`]). What is here is only what is per lane: gathering the runs' noise
//! draws (each run's own seeded generator at its own sample index) and references (each a
//! function of that lane's own t), and closing each lane's sample in its own `Simulation`
//! (`close_sample`: the record and online metrics exist once). Stage 1 is the arm's
//! `ArmModel::measure` over `W`, at the lanes' configuration values ([`LaneStart`], which
//! the lane loop gathers once for stages 1 and 9), as a scalar run's is over `f64`.

use nalgebra::SVector;
use simba::simd::SimdValue;

use crate::control::reference::LaneSignal;
use crate::robot::{ArmModel, RobotModel};
use crate::scalar::{lane, lane_of, mask_from, Real, Wide};
use crate::sim::lanes::{LaneStart, PackedPlant};
use crate::sim::outcome::Divergence;
use crate::sim::pipeline::{Inputs, Pipeline};
use crate::sim::simulation::Simulation;
use crate::sim::trace::Row;

/// Runs' stages 1–8 in lanes of `W`, for any arm.
pub struct LaneStages<W: Real, R: RobotModel<N>, const N: usize> {
    pub(crate) stages: Pipeline<W, R::Lanes<W>, N>,
    /// The runs' f_d(t) and s(t).
    force_reference: LaneSignal<W>,
    motion_reference: LaneSignal<W>,
}

impl<W: Real, R: RobotModel<N>, const N: usize> LaneStages<W, R, N> {
    /// The four runs' stages packed, from their fresh state; `None` if their structures
    /// differ (their stages then run per lane, `step_to_plant`). The lane key
    /// (`AnySimulation::lane_key`) groups runs of one structure; checked again here so that
    /// a caller's group that is not uniform still runs, per lane.
    pub fn pack<const L: usize>(sims: [&Simulation<R, N>; L]) -> Option<Self>
    where
        W: Wide<L>,
    {
        Pipeline::pack(sims.map(|s| s.stages()), R::pack).map(|stages| Self {
            stages,
            force_reference: LaneSignal::pack(sims.map(|s| &s.config().force_reference)),
            motion_reference: LaneSignal::pack(sims.map(|s| &s.config().z_reference)),
        })
    }

    /// Lane `l` takes the fresh run `sim`; false if its structure differs from the
    /// group's (never in `run_lanes`, which packs only groups whose every run fits).
    pub fn put_lane(&mut self, l: usize, sim: &Simulation<R, N>) -> bool {
        let fits = self
            .stages
            .put_lane(l, sim.stages(), |model, arm| R::put_lane(model, l, arm));
        if fits {
            self.force_reference
                .put_lane(l, &sim.config().force_reference);
            self.motion_reference.put_lane(l, &sim.config().z_reference);
        }
        fits
    }

    /// Stages 1–8 for the runs in `slot` (`run`: the run each lane computes; an idle lane
    /// repeats an active one). Each lane's torque to hold, or `None` where the run ended
    /// at this sample; samples are recorded in the lanes' own simulations.
    #[inline(always)]
    pub fn step<const L: usize>(
        &mut self,
        plant: &PackedPlant<W, R::Lanes<W>>,
        start: &LaneStart<W, R, N, L>,
        sims: &mut [Simulation<R, N>],
        slot: &[Option<usize>; L],
        run: &[usize; L],
    ) -> [Option<SVector<f64, N>>; L]
    where
        W: Wide<L>,
    {
        let lanes = run.map(|i| &sims[i]);
        let k = lanes.map(|s| s.sample());
        let t = W::from_lanes(|l| k[l] as f64 * lanes[l].config().period);
        // 1. plant state (the encoders) and the tip's kinematics at it
        let (states, q, qd, at) = (&start.states, &start.q, &start.qd, &start.config);
        let (kin, orientation) = plant.arm.measure(at, qd, self.stages.controller.pose());
        let rotation = self
            .stages
            .sensor
            .needs_rotation()
            .then(|| plant.arm.tip_rotation(at));
        // Each run's noise draws at its own sample, its references at its own t.
        let draws: [[f64; 3]; L] =
            std::array::from_fn(|l| lanes[l].stages().sensor.noise_draws(k[l]));
        let noise: [W; 3] = std::array::from_fn(|a| W::from_lanes(|l| draws[l][a]));
        let f_d = self
            .force_reference
            .at(t, |l| &lanes[l].config().force_reference);
        let s = self
            .motion_reference
            .at(t, |l| &lanes[l].config().z_reference);
        // 2.–7.
        let out = self.stages.step(
            &Inputs {
                first: mask_from::<W>(|l| k[l] == 0),
                q,
                qd,
                kinematics: &kin,
                orientation: orientation.as_ref(),
                rotation: rotation.as_ref(),
                environment: &plant.environment,
                noise,
                force_reference: f_d,
                motion_reference: s,
            },
            at,
        );
        // 8. record sample k, per lane (a lane whose law failed ends its run instead)
        std::array::from_fn(|l| {
            let i = slot[l]?;
            let sim = &mut sims[i];
            let time = lane(t, l);
            if out.singular.extract(l) {
                sim.stop(time, Divergence::SingularJacobian);
                return None;
            }
            if out.non_finite.extract(l) {
                sim.stop(time, Divergence::NonFiniteTorque);
                return None;
            }
            let (p, reference) = (lane_of(&kin.position, l), lane_of(&out.desired.position, l));
            let (tau, command) = (lane_of(&out.tau, l), lane_of(&out.command, l));
            let st = &states[l];
            let more = sim.close_sample(&Row {
                t: time,
                q: st.q.as_slice(),
                qd: st.qd.as_slice(),
                position: [p[0], p[1], p[2]],
                reference: [reference[0], reference[1], reference[2]],
                f: lane(out.force, l),
                f_measured: lane(out.measured, l),
                f_d: lane(f_d.value, l),
                penetration: lane(out.penetration, l),
                x_a: lane(out.x_a.value, l),
                xa_dot: lane(out.x_a.rate, l),
                surface_force: lane_of(&out.surface_force, l).into(),
                f_t: lane(out.f_t, l),
                slip_speed: lane(out.slip_speed, l),
                tau: tau.as_slice(),
                tau_cmd: command.as_slice(),
            });
            more.then_some(tau)
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::robot::ThreeLinkArm;
    use crate::scalar::F64x4;

    type Sim = Simulation<ThreeLinkArm, 3>;
    use crate::control::params::{ControllerParams, TimeDelayParams};
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
            wall: Some(
                WallParams {
                    stiffness: 1e4 * (1.0 + f),
                    ..WallParams::default()
                }
                .into(),
            ),
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
            let alone = crate::sim::dispatch::simulate(cfg).unwrap();
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
        use crate::control::params::{ModelFreeParams, PerJoint, TdcLaw};
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
            let packed = LaneStages::<F64x4, _, 3>::pack([&sims[0], &sims[1], &sims[2], &sims[3]]);
            assert!(packed.is_some_and(|p| p.stages.controller.task_path()));
            for (cfg, r) in c.iter().zip(lanes(&c)) {
                let alone = crate::sim::dispatch::simulate(cfg).unwrap();
                assert_eq!(r.outcome, alone.outcome);
                worst_trace_gap(&alone, &r, 1e-12);
            }
        }
    }
}

/// Every controller kind × outer loop × arm kind runs its stages in lanes (no fallback) and
/// agrees with `simulate`; a caller's mixed group takes the explicit per-lane fallback.
#[cfg(test)]
mod every_kind {
    use super::tests::{varied, worst_trace_gap};
    use crate::control::approach::ApproachParams;
    use crate::control::filter::{AdmittanceParams, ForceControlParams, ImpedanceParams};
    use crate::control::params::{
        ComputedTorqueParams, ControllerParams, ModelFreeParams, PerJoint, TdcLaw, TimeDelayParams,
    };
    use crate::robot::chain::{UrdfArm, UrdfArmParams};
    use crate::robot::{ArmModel, RobotModel, ThreeLinkArm};
    use crate::sim::dispatch::simulate;
    use crate::sim::lanes::tests::with_stack;
    use crate::sim::lanes::{run_lanes_on, StagePath};
    use crate::sim::outcome::Outcome;
    use crate::sim::scenario::RobotConfig;
    use crate::sim::simulation::{ScenarioConfig, Simulation};
    use crate::world::surface::SurfaceParams;

    /// Every controller kind with its structural switches (`joints`: for the per-joint D̄).
    fn controllers(joints: usize) -> Vec<ControllerParams> {
        let per_joint = PerJoint::from_slice(&vec![0.1; joints]);
        let mut out = vec![];
        for contact_compensation in [false, true] {
            out.push(ControllerParams::ComputedTorque(ComputedTorqueParams {
                contact_compensation,
                ..ComputedTorqueParams::default()
            }));
        }
        for joint_inertia in [None, per_joint] {
            out.push(ControllerParams::ModelFree(ModelFreeParams {
                joint_inertia,
                ..ModelFreeParams::default()
            }));
            for law in [TdcLaw::JacobianTranspose, TdcLaw::InverseJacobian] {
                out.push(ControllerParams::TimeDelay(TimeDelayParams {
                    joint_inertia,
                    law,
                    ..TimeDelayParams::default()
                }));
            }
        }
        out
    }

    fn outer_loops() -> [Option<ForceControlParams>; 5] {
        [
            None,
            // The adaptive filter of SPEC §16: its own kind, in lanes.
            Some(ForceControlParams::Admittance(AdmittanceParams::adaptive(
                800.0, 1.0, 0.005,
            ))),
            Some(ForceControlParams::Admittance(AdmittanceParams::scheme1(
                800.0, 400.0, 0.1,
            ))),
            Some(ForceControlParams::Admittance(AdmittanceParams::scheme2(
                800.0, 0.1,
            ))),
            Some(ForceControlParams::Impedance(ImpedanceParams {
                k: 400.0,
                assumed_stiffness: 3e4,
            })),
        ]
    }

    /// Four runs of each controller × outer loop on `robot` through `run_lanes_on`: the
    /// stages ran in lanes, and each run ends as `simulate`'s (a completed run within 1e-9
    /// of it). Returns the number of groups.
    fn check<R: RobotModel<N>, const N: usize>(
        robot: RobotConfig,
        build: impl Fn(&ScenarioConfig) -> Simulation<R, N>,
    ) -> usize {
        let mut groups = 0;
        // Each admittance filter also behind a guarded approach (SPEC §16): the lanes'
        // walls differ, so they switch to force control at different samples.
        let approached = outer_loops()
            .into_iter()
            .filter(|a| matches!(a, Some(ForceControlParams::Admittance(_))))
            .map(|a| (a, true));
        let loops: Vec<_> = outer_loops()
            .into_iter()
            .map(|a| (a, false))
            .chain(approached)
            .collect();
        for controller in controllers(N) {
            for &(admittance, guarded) in &loops {
                let configs: Vec<ScenarioConfig> = (0..4)
                    .map(|i| ScenarioConfig {
                        robot: robot.clone(),
                        admittance,
                        approach: guarded.then(|| ApproachParams {
                            threshold: 0.5 + i as f64,
                            reanchor: i % 2 == 0,
                            ..ApproachParams::default()
                        }),
                        duration: 0.01,
                        ..varied(i, controller)
                    })
                    .map(|mut c| {
                        if let (true, Some(w)) =
                            (guarded, c.wall.as_mut().and_then(SurfaceParams::plane_mut))
                        {
                            // Lane i crosses i·0.1 mm of free space (2 ms at 0.05 m/s each).
                            w.gap = 1e-4 * c.seed.saturating_sub(3) as f64;
                        }
                        c
                    })
                    .collect();
                let mut sims: Vec<_> = configs.iter().map(&build).collect();
                let (runs, path) = run_lanes_on(&mut sims);
                assert_eq!(path, StagePath::Lanes, "{controller:?} {admittance:?}");
                for (c, r) in configs.iter().zip(&runs) {
                    let alone = simulate(c).unwrap();
                    match (r.outcome, alone.outcome) {
                        (Outcome::Completed, Outcome::Completed) => {
                            worst_trace_gap(&alone, r, 1.0);
                        }
                        (Outcome::Diverged { time: a, .. }, Outcome::Diverged { time: b, .. }) => {
                            assert_eq!(a, b)
                        }
                        (a, b) => panic!("lanes {a:?}, simulate {b:?}"),
                    }
                }
                groups += 1;
            }
        }
        groups
    }

    /// Runs `configs` (one lane group on `robot`: the paper's arm, or `arm` for a URDF
    /// config) through `run_lanes_on`, asserts the stages ran in lanes, and compares each
    /// run with `simulate`: a completed run within 1e-9 of it, a diverged one at the same
    /// time. Returns the lane runs that completed.
    fn lanes_match_simulate(
        robot: &RobotConfig,
        arm: &UrdfArm<7>,
        configs: &[ScenarioConfig],
        what: &str,
    ) -> Vec<crate::sim::simulation::RunResult> {
        let runs = match robot {
            RobotConfig::Urdf(_) => {
                let mut sims: Vec<_> = configs
                    .iter()
                    .map(|c| Simulation::with_robot(c, arm.clone()).unwrap())
                    .collect();
                let (runs, path) = run_lanes_on(&mut sims);
                assert_eq!(path, StagePath::Lanes, "{what}");
                runs
            }
            _ => {
                let mut sims: Vec<_> = configs
                    .iter()
                    .map(|c| Simulation::new(c).unwrap())
                    .collect();
                let (runs, path) = run_lanes_on(&mut sims);
                assert_eq!(path, StagePath::Lanes, "{what}");
                runs
            }
        };
        let mut completed = Vec::new();
        for (c, r) in configs.iter().zip(runs) {
            let alone = simulate(c).unwrap();
            match (r.outcome, alone.outcome) {
                (Outcome::Completed, Outcome::Completed) => {
                    worst_trace_gap(&alone, &r, 1.0);
                    completed.push(r);
                }
                // The paper's TDC gains do not suit the Panda: its runs may diverge.
                (Outcome::Diverged { time: a, .. }, Outcome::Diverged { time: b, .. }) => {
                    assert_eq!(a, b, "{what}")
                }
                (a, b) => panic!("{what}: lanes {a:?}, simulate {b:?}"),
            }
        }
        completed
    }

    /// The Panda to `panda_link8` in a posture facing the wall: its parameters and its arm.
    fn panda_at_link8() -> (UrdfArmParams, UrdfArm<7>) {
        let panda = UrdfArmParams {
            q0: Some(vec![0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.785]),
            ..urdf(
                include_str!("../../../../examples/data/panda.urdf"),
                "panda_link8",
            )
        };
        let arm = UrdfArm::<7>::new(&panda).unwrap();
        (panda, arm)
    }

    fn urdf(document: &str, tip: &str) -> UrdfArmParams {
        UrdfArmParams {
            urdf: document.to_owned(),
            tip_link: tip.to_owned(),
            ..UrdfArmParams::default()
        }
    }

    #[test]
    fn every_controller_filter_and_arm_runs_in_lanes() {
        with_stack(every_kind);
    }

    fn every_kind() {
        let paper =
            check::<ThreeLinkArm, 3>(RobotConfig::default(), |c| Simulation::new(c).unwrap());
        let three = urdf(
            include_str!("../../../../examples/data/three_link.urdf"),
            "tip",
        );
        let chain3 = check::<UrdfArm<3>, 3>(RobotConfig::Urdf(three.clone()), |c| {
            Simulation::with_robot(c, UrdfArm::<3>::new(&three).unwrap()).unwrap()
        });
        // 7 joints: pose task (orientation rows) with a null-space posture term.
        let panda = urdf(
            include_str!("../../../../examples/data/panda.urdf"),
            "panda_hand_tcp",
        );
        let arm = UrdfArm::<7>::new(&panda).unwrap();
        let model = arm.model();
        assert!(model
            .orientation(
                &model.configure(&arm.initial_position()),
                &Default::default()
            )
            .is_some());
        let chain7 = check::<UrdfArm<7>, 7>(RobotConfig::Urdf(panda.clone()), |c| {
            Simulation::with_robot(c, arm.clone()).unwrap()
        });
        // 8 controllers × (5 outer loops + 3 filters behind an approach).
        assert_eq!((paper, chain3, chain7), (64, 64, 64));
    }

    /// Every surface kind (SPEC §15), with and without friction and damping, runs in lanes
    /// on the paper's arm and on the Panda, each run within 1e-9 of `simulate`, lanes of
    /// one group differing in radius, friction and stiffness.
    #[test]
    fn every_surface_runs_in_lanes() {
        with_stack(every_surface);
    }

    fn every_surface() {
        use crate::world::height_field::HeightFieldParams;
        use crate::world::round::{CylinderParams, SphereParams};
        // Each lane's grid differs in heights, size and spacing (the lanes read their
        // own grids).
        let bump = |i: usize| -> Vec<Vec<f64>> {
            (0..9 + i)
                .map(|r| {
                    (0..7 + 2 * i)
                        .map(|c| 1e-3 * ((r * 7 + c + i) % 5) as f64 - 4e-3 * r as f64)
                        .collect()
                })
                .collect()
        };
        let surfaces = |i: usize, friction: f64, damping: f64| -> Vec<SurfaceParams> {
            let f = i as f64;
            let (stiffness, friction) = (2e4 * (1.0 + f), friction * (1.0 + 0.5 * f));
            let wall = crate::world::environment::WallParams {
                stiffness,
                damping,
                friction,
                normal: [1.0, 0.0, 0.2],
                ..Default::default()
            };
            let sphere = |inside| SphereParams {
                stiffness,
                damping,
                friction,
                radius: 0.1 + 0.05 * f,
                inside,
                ..Default::default()
            };
            let cylinder = |inside| CylinderParams {
                stiffness,
                damping,
                friction,
                radius: 0.2 + 0.05 * f,
                axis: [0.0, 1.0, 0.3],
                inside,
                ..Default::default()
            };
            vec![
                wall.into(),
                SurfaceParams::Sphere(sphere(false)),
                SurfaceParams::Sphere(sphere(true)),
                SurfaceParams::Cylinder(cylinder(false)),
                SurfaceParams::Cylinder(cylinder(true)),
                SurfaceParams::HeightField(HeightFieldParams {
                    stiffness,
                    damping,
                    friction,
                    heights: bump(i).into(),
                    spacing: [0.01 + 0.002 * f, 0.015],
                    ..Default::default()
                }),
            ]
        };
        let controller = ControllerParams::TimeDelay(TimeDelayParams::default());
        let (panda, arm) = panda_at_link8();
        let (mut groups, mut completed) = (0, 0);
        for (friction, damping) in [(0.0, 0.0), (0.3, 0.0), (0.5, 20.0)] {
            for kind in 0..6 {
                for robot in [RobotConfig::default(), RobotConfig::Urdf(panda.clone())] {
                    let configs: Vec<ScenarioConfig> = (0..4)
                        .map(|i| ScenarioConfig {
                            robot: robot.clone(),
                            wall: Some(surfaces(i, friction, damping).swap_remove(kind)),
                            // The paper's TDC gains do not suit the Panda: within 10 ms
                            // its runs agree; later their growing motion amplifies ulps.
                            duration: if matches!(robot, RobotConfig::Urdf(_)) {
                                0.01
                            } else {
                                0.05
                            },
                            ..varied(i, controller)
                        })
                        .collect();
                    let what = format!("{kind} {friction}");
                    for r in lanes_match_simulate(&robot, &arm, &configs, &what) {
                        if friction > 0.0 {
                            let felt = r.trace.f_t().iter().any(|&f| f > 0.0);
                            assert!(felt, "{kind}: no friction");
                        }
                        completed += 1;
                    }
                    groups += 1;
                }
            }
        }
        assert_eq!(groups, 36);
        // The paper's arm completes every run (the Panda under the paper's TDC gains may not).
        assert!(completed >= 72, "{completed} runs completed");
    }

    /// The 3-axis sensor and a tool (SPEC §15) run in lanes on the paper's arm and on the
    /// Panda: lanes of one group with their own tool masses, estimates, bias vectors and
    /// noise, each run within 1e-9 of `simulate`.
    #[test]
    fn every_sensor_frame_and_tool_runs_in_lanes() {
        with_stack(every_sensor);
    }

    fn every_sensor() {
        use crate::world::environment::WallParams;
        use crate::world::sensor::{Bias, SensorFrame};
        let (panda, arm) = panda_at_link8();
        let mut groups = 0;
        for (frame, tool) in [
            (SensorFrame::Normal, true),
            (SensorFrame::Tip, false),
            (SensorFrame::Tip, true),
        ] {
            for robot in [RobotConfig::default(), RobotConfig::Urdf(panda.clone())] {
                let configs: Vec<ScenarioConfig> = (0..4)
                    .map(|i| {
                        let mut c = ScenarioConfig {
                            robot: robot.clone(),
                            wall: Some(
                                WallParams {
                                    normal: [0.3, 0.0, -1.0],
                                    ..Default::default()
                                }
                                .into(),
                            ),
                            duration: if matches!(robot, RobotConfig::Urdf(_)) {
                                0.01
                            } else {
                                0.05
                            },
                            ..varied(i, ControllerParams::TimeDelay(TimeDelayParams::default()))
                        };
                        let f = i as f64;
                        c.sensor.frame = frame;
                        if frame == SensorFrame::Tip {
                            c.sensor.bias = Bias::Axes([0.1 * f, -0.05, 0.2]);
                        }
                        if tool {
                            c.sensor.tool_mass = 0.5 + 0.25 * f;
                            c.sensor.tool_mass_estimate = (i % 2 == 1).then_some(0.4 * f);
                        }
                        c
                    })
                    .collect();
                lanes_match_simulate(&robot, &arm, &configs, &format!("{frame:?} {tool}"));
                groups += 1;
            }
        }
        assert_eq!(groups, 6);
    }

    /// Runs of different stage structures given to `run_lanes_on` together still run,
    /// each exactly as `simulate` (stages lane by lane, plants in lanes), and say so.
    #[test]
    fn a_mixed_group_takes_the_explicit_fallback() {
        with_stack(mixed);
    }

    fn mixed() {
        let configs: Vec<ScenarioConfig> = controllers(3)
            .into_iter()
            .take(4)
            .enumerate()
            .map(|(i, c)| ScenarioConfig {
                duration: 0.05,
                ..varied(i, c)
            })
            .collect();
        let mut sims: Vec<Simulation<ThreeLinkArm, 3>> = configs
            .iter()
            .map(|c| Simulation::new(c).unwrap())
            .collect();
        let (runs, path) = run_lanes_on(&mut sims);
        assert_eq!(path, StagePath::PerLane);
        for (c, r) in configs.iter().zip(&runs) {
            worst_trace_gap(&simulate(c).unwrap(), r, 1.0);
        }
    }

    /// Plants that cannot share RK4 lanes (a wall and free space) given together run one
    /// by one, each exactly `simulate`'s run (bit for bit), and say so.
    #[test]
    fn mixed_plants_run_one_by_one() {
        let configs: Vec<ScenarioConfig> = (0..3)
            .map(|i| ScenarioConfig {
                duration: 0.05,
                wall: (i != 1).then(SurfaceParams::default),
                admittance: None,
                ..ScenarioConfig::default()
            })
            .collect();
        let mut sims: Vec<Simulation<ThreeLinkArm, 3>> = configs
            .iter()
            .map(|c| Simulation::new(c).unwrap())
            .collect();
        let (runs, path) = run_lanes_on(&mut sims);
        assert_eq!(path, StagePath::PerLane);
        for (c, r) in configs.iter().zip(&runs) {
            // Debug prints each f64 exactly (and NaN, which `==` refuses, as NaN).
            let alone = simulate(c).unwrap().trace;
            assert_eq!(format!("{:?}", r.trace), format!("{alone:?}"));
        }
    }
}
