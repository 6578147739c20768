//! URDF chains in lanes (SPEC §11, §13), tested against `simulate`: a chain brings nothing
//! to the lanes but its `ArmModel<F64x4, N>` (`robot::chain::Chain`), so these tests run
//! its runs through the shared lane stages and compare.

use crate::control::params::{
    ComputedTorqueParams, ControllerParams, ModelError, ModelFreeParams, PerJoint, PositionGains,
    TimeDelayParams,
};
use crate::robot::chain::{UrdfArm, UrdfArmParams};
use crate::robot::{ArmModel, RobotModel};
use crate::scalar::F64x4;
use crate::sim::dispatch::simulate;
use crate::sim::lanes::run_lanes;
use crate::sim::lanes::stages::tests::{varied, worst_trace_gap};
use crate::sim::lanes::stages::LaneStages;
use crate::sim::lanes::tests::with_stack;
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
        .map(|c| {
            Simulation::with_robot(c, UrdfArm::<N>::new(arm).expect("a valid test scenario"))
                .expect("a valid test scenario")
        })
        .collect();
    let four: [&Simulation<UrdfArm<N>, N>; 4] = std::array::from_fn(|l| &sims[l % sims.len()]);
    assert!(LaneStages::<F64x4, _, N>::pack(four).is_some());
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
        let alone = simulate(cfg).expect("a valid test scenario");
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
    let robot = UrdfArm::<7>::new(&arm).expect("a valid test scenario");
    let model = robot.model();
    let d0 = model
        .dynamics(
            &model.configure(&robot.initial_position()),
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
