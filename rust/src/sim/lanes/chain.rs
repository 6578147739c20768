//! URDF chains in lanes (SPEC §11, §13): four chains of one structure packed for RK4
//! (`ChainLanes`), and what a chain brings to the shared lane stages (`stages::LaneStages`). Its kinematics come from the
//! packed chain at the lanes' q (`SerialChain<F64x4, N>`: frames, the 6×N tip Jacobian and
//! J̇q̇, the tip rotation for a pose task), and computed torque's model is the four
//! controllers' chains (their mass scale) and friction packed.

use nalgebra::SVector;

use crate::contact::Surface;
use crate::control::controller::ControllerModel;
use crate::robot::chain::arm::{accelerate as chain_accelerate, JointFriction};
use crate::robot::chain::{Frames, SerialChain, UrdfArm};
use crate::robot::{Dynamics, Kinematics, Orientation};
use crate::scalar::{F64x4, LANES};
use crate::sim::lanes::stages::{LaneStages, StageArm};
use crate::sim::lanes::{ArmLanes, LaneArm, PackedPlant};
use crate::sim::simulation::Simulation;

/// Four URDF chains of one structure in lanes.
pub struct ChainLanes<const N: usize> {
    pub(crate) chain: SerialChain<F64x4, N>,
    friction: JointFriction<F64x4, N>,
}

impl<const N: usize> LaneArm<N> for UrdfArm<N> {
    type Lanes = ChainLanes<N>;
    type Front = ChainStages<N>;
    const READS_EACH_CONFIG: bool = false;

    fn same_structure(&self, other: &Self) -> bool {
        self.chain.same_structure(&other.chain)
    }

    fn pack(arms: [&Self; LANES]) -> ChainLanes<N> {
        ChainLanes {
            chain: SerialChain::pack(arms.map(|a| &a.chain)),
            friction: JointFriction::pack(arms.map(|a| &a.friction)),
        }
    }

    #[inline(always)]
    fn pack_config(
        lanes: &ChainLanes<N>,
        q: &SVector<F64x4, N>,
        _: [&Frames<f64, N>; LANES],
    ) -> Frames<F64x4, N> {
        // The chain evaluates its frames afresh at every stage anyway.
        lanes.chain.frames(q)
    }
}

impl<const N: usize> ArmLanes<N> for ChainLanes<N> {
    type Config = Frames<F64x4, N>;

    #[inline(always)]
    fn shift(
        &self,
        _: &Frames<F64x4, N>,
        _: &SVector<F64x4, N>,
        shifted: &SVector<F64x4, N>,
        out: &mut Frames<F64x4, N>,
    ) {
        self.chain.frames_into(shifted, out);
    }

    #[inline(always)]
    fn accelerate(
        &self,
        c: &Frames<F64x4, N>,
        qd: &SVector<F64x4, N>,
        tau: &SVector<F64x4, N>,
        surface: &impl Surface<F64x4>,
    ) -> SVector<F64x4, N> {
        chain_accelerate(&self.chain, &self.friction, c, qd, tau, surface).0
    }
}

/// A URDF chain's lane stages.
pub type ChainStages<const N: usize> = LaneStages<UrdfArm<N>, N>;

/// Four controllers' chain models in lanes, with each lane's own (a lane that takes a new
/// run repacks from them).
pub struct ChainModels<const N: usize> {
    chain: SerialChain<F64x4, N>,
    friction: JointFriction<F64x4, N>,
    each: [(SerialChain<f64, N>, JointFriction<f64, N>); LANES],
}

impl<const N: usize> ChainModels<N> {
    fn repack(&mut self) {
        self.chain = SerialChain::pack(self.each.each_ref().map(|e| &e.0));
        self.friction = JointFriction::pack(self.each.each_ref().map(|e| &e.1));
    }
}

impl<const N: usize> StageArm<N> for UrdfArm<N> {
    type Model = ChainModels<N>;
    type At = ();

    fn pack_model(arms: [&Self; LANES]) -> ChainModels<N> {
        ChainModels {
            chain: SerialChain::pack(arms.map(|a| &a.chain)),
            friction: JointFriction::pack(arms.map(|a| &a.friction)),
            each: arms.map(|a| (a.chain, a.friction.clone())),
        }
    }

    fn put_model(model: &mut ChainModels<N>, l: usize, arm: &Self) {
        model.each[l] = (arm.chain, arm.friction.clone());
        model.repack();
    }

    #[inline(always)]
    fn lane_kinematics(
        plant: &PackedPlant<ChainLanes<N>>,
        _: [&Simulation<Self, N>; LANES],
        q: &SVector<F64x4, N>,
        qd: &SVector<F64x4, N>,
        pose: bool,
    ) -> (Kinematics<N, F64x4>, Option<Orientation<N, F64x4>>, ()) {
        // One Jacobian for both the position and the orientation rows (the scalar arm
        // evaluates it twice, to the same bits).
        let frames = plant.arm.chain.frames(q);
        let (j, jdot_qd) = plant.arm.chain.jacobian(&frames, qd);
        let kin = Kinematics {
            position: frames.tip.pos,
            jacobian: j.fixed_rows::<3>(0).into_owned(),
            jdot_qd: jdot_qd.fixed_rows::<3>(0).into_owned(),
        };
        let rotation = pose.then(|| Orientation {
            rotation: frames.tip.rot,
            jacobian: j.fixed_rows::<3>(3).into_owned(),
            jdot_qd: jdot_qd.fixed_rows::<3>(3).into_owned(),
        });
        (kin, rotation, ())
    }
}

impl<const N: usize> ControllerModel<F64x4, N> for ChainModels<N> {
    type At = ();

    #[inline(always)]
    fn terms(
        &self,
        _: &(),
        q: &SVector<F64x4, N>,
        qd: &SVector<F64x4, N>,
    ) -> (Dynamics<N, F64x4>, SVector<F64x4, N>) {
        // The controller's own chain (its mass scale), as `UrdfArm::dynamics`.
        let frames = self.chain.frames(q);
        let (coriolis, gravity) = self.chain.bias(&frames, qd);
        let dynamics = Dynamics {
            inertia: self.chain.crba(&frames),
            coriolis,
            gravity,
        };
        (dynamics, self.friction.torque(qd))
    }
}

#[cfg(test)]
mod tests {
    use crate::control::params::{
        ComputedTorqueParams, ControllerParams, ModelError, ModelFreeParams, PerJoint,
        PositionGains, TimeDelayParams,
    };
    use crate::robot::chain::{UrdfArm, UrdfArmParams};
    use crate::robot::RobotModel;
    use crate::sim::dispatch::simulate;
    use crate::sim::lanes::chain::ChainStages;
    use crate::sim::lanes::stages::tests::{varied, worst_trace_gap};
    use crate::sim::lanes::tests::with_stack;
    use crate::sim::lanes::{run_lanes, Front};
    use crate::sim::outcome::Outcome;
    use crate::sim::scenario::RobotConfig;
    use crate::sim::simulation::{RunResult, ScenarioConfig, Simulation};

    const PANDA: &str = include_str!("../../../../examples/data/panda.urdf");
    const THREE_LINK: &str = include_str!("../../../../examples/data/three_link.urdf");

    fn params(urdf: &str, tip: &str) -> UrdfArmParams {
        UrdfArmParams {
            urdf: urdf.to_owned(),
            tip_link: tip.to_owned(),
            viscous_friction: vec![0.5],
            coulomb_friction: vec![0.2],
            ..UrdfArmParams::default()
        }
    }

    /// Four runs of one controller kind on `arm` (`varied`: each its own wall, sensor
    /// noise and actuator limits).
    fn configs(
        arm: &UrdfArmParams,
        controller: impl Fn(f64) -> ControllerParams,
    ) -> Vec<ScenarioConfig> {
        (0..4)
            .map(|i| ScenarioConfig {
                robot: RobotConfig::Urdf(arm.clone()),
                duration: 0.1,
                ..varied(i, controller(i as f64))
            })
            .collect()
    }

    /// The runs of `configs` advanced by `run_lanes`, after checking that their stages
    /// pack into lanes (else `run_lanes` would step them lane by lane, unseen).
    fn lanes<const N: usize>(arm: &UrdfArmParams, configs: &[ScenarioConfig]) -> Vec<RunResult> {
        let mut sims: Vec<Simulation<UrdfArm<N>, N>> = configs
            .iter()
            .map(|c| Simulation::with_robot(c, UrdfArm::<N>::new(arm).unwrap()).unwrap())
            .collect();
        let four: [&Simulation<UrdfArm<N>, N>; 4] = std::array::from_fn(|l| &sims[l % sims.len()]);
        assert!(<ChainStages<N> as Front<UrdfArm<N>, N>>::pack(four).is_some());
        run_lanes(&mut sims)
    }

    /// Each lane run ends as `simulate`'s does (completed, or diverged at the same sample
    /// for the same cause; a diverging run amplifies the lanes' last-bit `exp`, so its
    /// values are not compared), and a completed run's every trace column is within 1e-9
    /// of `simulate`'s (relative to the column's largest value, at least 1). Returns the worst relative
    /// gap and the number of completed runs.
    fn agree(configs: &[ScenarioConfig], runs: &[RunResult]) -> (f64, usize) {
        let (mut worst_of_all, mut completed) = (0.0_f64, 0);
        for (cfg, r) in configs.iter().zip(runs) {
            let alone = simulate(cfg).unwrap();
            match (r.outcome, alone.outcome) {
                (Outcome::Completed, Outcome::Completed) => completed += 1,
                (
                    Outcome::Diverged { time, cause },
                    Outcome::Diverged {
                        time: expected,
                        cause: expected_cause,
                    },
                ) => {
                    assert_eq!(time, expected);
                    assert_eq!(
                        std::mem::discriminant(&cause),
                        std::mem::discriminant(&expected_cause)
                    );
                    continue;
                }
                (lanes, scalar) => panic!("lanes {lanes:?}, simulate {scalar:?}"),
            }
            // A column that barely moves (a joint the task hardly uses, where the Coulomb
            // tanh's slope f_c/ε amplifies the lanes' last-bit `exp`) is judged against one
            // unit (rad, rad/s, N, N·m), not its own tiny range.
            worst_of_all = worst_of_all.max(worst_trace_gap(&alone, r, 1.0));
        }
        (worst_of_all, completed)
    }

    /// A Panda (7 joints, pose task, posture) in lanes under TDC with a full D̄, model-free
    /// with a per-joint D̄ and computed torque with a model error agrees with `simulate`.
    #[test]
    fn panda_lanes_agree_with_simulate() {
        with_stack(panda_lanes);
    }

    fn panda_lanes() {
        let arm = params(PANDA, "panda_hand_tcp");
        let model = UrdfArm::<7>::new(&arm).unwrap();
        let d0 = model
            .dynamics(
                &model.configure(&model.initial_position()),
                &nalgebra::SVector::zeros(),
            )
            .inertia;
        let gains = |f: f64| PositionGains::new(5.0, 50.0 + f, 600.0);
        let tdc = |f: f64| {
            let dbar = d0 * (0.8 + 0.02 * f);
            let values: Vec<f64> = (0..49).map(|i| dbar[(i / 7, i % 7)]).collect();
            ControllerParams::TimeDelay(TimeDelayParams {
                gains: gains(f),
                joint_inertia: PerJoint::from_slice(&values),
                torque_constant: 50.0,
                ..TimeDelayParams::default()
            })
        };
        let model_free = |f: f64| {
            let values: Vec<f64> = (0..7).map(|j| 0.8 * d0[(j, j)] * (1.0 + 0.1 * f)).collect();
            ControllerParams::ModelFree(ModelFreeParams {
                gains: gains(f),
                joint_inertia: PerJoint::from_slice(&values),
                torque_constant: 50.0,
                ..ModelFreeParams::default()
            })
        };
        let computed = |f: f64| {
            ControllerParams::ComputedTorque(ComputedTorqueParams {
                contact_compensation: true,
                model: ModelError {
                    mass_scale: 1.0 + 0.05 * f,
                    friction_scale: 1.0,
                },
                ..ComputedTorqueParams::default()
            })
        };
        for (name, c) in [
            ("TDC", configs(&arm, tdc)),
            ("model-free", configs(&arm, model_free)),
            ("computed torque", configs(&arm, computed)),
        ] {
            let (worst, completed) = agree(&c, &lanes::<7>(&arm, &c));
            eprintln!("Panda {name}: {completed} of 4 completed, worst relative gap {worst:e}");
            assert!(completed >= 2, "{name}: {completed} completed");
        }
        // Without Coulomb friction no `exp` is left in the loop; the lanes' polynomial
        // sincos of the frames (within 2 ulp of libm's) is the only difference left.
        let smooth = UrdfArmParams {
            coulomb_friction: vec![0.0],
            ..arm.clone()
        };
        let c = configs(&smooth, model_free);
        let (worst, completed) = agree(&c, &lanes::<7>(&smooth, &c));
        assert_eq!(completed, 4);
        assert!(worst < 1e-12, "{worst:e}");
    }

    /// A three-joint URDF position task: the square path (scalar D̄) and the general task
    /// path without posture (a per-joint D̄), both in lanes, agree with `simulate`; and a
    /// run's bits do not depend on its neighbours.
    #[test]
    fn three_joint_chain_takes_either_path_in_lanes() {
        with_stack(three_joint_chain);
    }

    fn three_joint_chain() {
        let arm = params(THREE_LINK, "tip");
        let square = configs(&arm, |f| {
            ControllerParams::TimeDelay(TimeDelayParams {
                inertia: 0.1 + 0.01 * f,
                ..TimeDelayParams::default()
            })
        });
        let runs = lanes::<3>(&arm, &square);
        assert_eq!(agree(&square, &runs).1, 4);
        let other = lanes::<3>(&arm, &[square[1].clone(), square[3].clone()]);
        assert_eq!(other[1].trace, runs[3].trace);
        let task = configs(&arm, |f| {
            ControllerParams::ModelFree(ModelFreeParams {
                joint_inertia: PerJoint::from_slice(&[0.1, 0.1 + 0.01 * f, 0.05]),
                ..ModelFreeParams::default()
            })
        });
        assert_eq!(agree(&task, &lanes::<3>(&arm, &task)).1, 4);
    }
}
