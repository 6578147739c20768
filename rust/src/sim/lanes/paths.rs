//! Every build of the lane loop gives the same bits (issue #25): the portable 4-wide loop,
//! the 8-wide loop compiled portably (which any CPU runs, so the 8-wide grouping is tested
//! everywhere), and each dispatched build this CPU has (AVX2 4-wide, AVX-512 8-wide; one
//! the CPU lacks is skipped with a message). Groups are ragged (11 and 13 runs: neither a
//! multiple of 4 nor of 8) and hold diverging runs, so leftover lanes and runs that end
//! early are covered.

use crate::control::params::{ControllerParams, ModelFreeParams, PositionGains, TimeDelayParams};
use crate::robot::chain::{UrdfArm, UrdfArmParams};
use crate::robot::{RobotModel, ThreeLinkArm};
use crate::scalar::{F64x4, F64x8, Wide};
use crate::sim::lanes::stages::tests::varied;
use crate::sim::lanes::tests::{bits, with_stack};
use crate::sim::lanes::{lanes_loop, run_lanes_via, LanePath, StagePath};
use crate::sim::outcome::Outcome;
use crate::sim::scenario::RobotConfig;
use crate::sim::simulation::{RunResult, ScenarioConfig, Simulation};
use crate::world::environment::WallParams;

/// `sims` through the generic loop at width `L`, compiled without target features.
fn portable<W: Wide<L>, const L: usize, R: RobotModel<N>, const N: usize>(
    mut sims: Vec<Simulation<R, N>>,
) -> Vec<RunResult> {
    sims.iter_mut().for_each(|s| s.reset());
    assert_eq!(lanes_loop::<W, L, R, N>(&mut sims), StagePath::Lanes);
    sims.iter_mut().map(|s| s.take_result()).collect()
}

/// Runs `make()`'s group on every path and asserts one set of bits; returns the results
/// and how many dispatched builds ran.
fn every_path<R: RobotModel<N>, const N: usize>(
    make: impl Fn() -> Vec<Simulation<R, N>>,
) -> (Vec<RunResult>, usize) {
    let reference = portable::<F64x4, 4, R, N>(make());
    let expected = bits(&reference);
    assert_eq!(
        bits(&portable::<F64x8, 8, R, N>(make())),
        expected,
        "8-wide portable"
    );
    let mut ran = 0;
    for path in LanePath::ALL {
        if !path.available() {
            eprintln!("skipped: this CPU cannot run the {} build", path.name());
            continue;
        }
        let (runs, stages) = run_lanes_via(&mut make(), path);
        assert_eq!(stages, StagePath::Lanes, "{}", path.name());
        assert_eq!(bits(&runs), expected, "{}", path.name());
        ran += 1;
    }
    (reference, ran)
}

/// Fig. 19-like runs (TDC and Scheme 2 against walls of 1e4 to 1e7 N/m, each with its own
/// sensor and actuator options), the stiffest diverging.
fn fig19(i: usize) -> ScenarioConfig {
    let mut c = ScenarioConfig {
        duration: 0.25,
        ..varied(
            i % 5,
            ControllerParams::TimeDelay(TimeDelayParams {
                inertia: 0.1 + 0.005 * i as f64,
                ..TimeDelayParams::default()
            }),
        )
    };
    c.seed = 11 + i as u64;
    c.wall = Some(
        WallParams {
            stiffness: 1e4 * 10f64.powf(3.0 * i as f64 / 12.0),
            position_error: 1e-3 * i as f64,
            ..WallParams::default()
        }
        .into(),
    );
    c
}

#[test]
fn three_link_runs_take_the_same_bits_on_every_path() {
    with_stack(three_link);
}

/// Fig. 12-like runs (model-free, K_A from 0.05 to 5): every fourth has K_A = 0.05 and
/// diverges within milliseconds, so its lane takes the next run mid-group.
fn fig12(i: usize) -> ScenarioConfig {
    ScenarioConfig {
        duration: 0.1,
        ..varied(
            i % 5,
            ControllerParams::ModelFree(ModelFreeParams {
                gains: PositionGains::new(
                    if i.is_multiple_of(4) {
                        0.05
                    } else {
                        0.05 * 100f64.powf(i as f64 / 10.0)
                    },
                    20.0,
                    100.0,
                ),
                ..ModelFreeParams::default()
            }),
        )
    }
}

fn three_link() {
    let mut diverged = 0;
    for (name, configs) in [
        ("fig. 19", (0..13).map(fig19).collect::<Vec<_>>()),
        ("fig. 12", (0..11).map(fig12).collect()),
    ] {
        let make = || -> Vec<Simulation<ThreeLinkArm, 3>> {
            configs
                .iter()
                .map(|c| Simulation::new(c).expect("a valid test scenario"))
                .collect()
        };
        let (runs, ran) = every_path(make);
        eprintln!("three-link {name}: {ran} dispatched builds ran");
        let ended = runs
            .iter()
            .filter(|r| matches!(r.outcome, Outcome::Diverged { .. }))
            .count();
        assert!(ended < runs.len(), "{name}: every run diverged");
        diverged += ended;
    }
    // Runs ending early leave their lanes to the next run (or idle) mid-group.
    assert!(diverged >= 2, "{diverged} diverged");
}

/// A URDF arm's `L` runs of one controller: Panda (7 joints, pose task, Coulomb friction's
/// `exp`, the frames' sincos) and the three-link URDF (the position task).
fn urdf_every_path<const N: usize>(document: &str, tip: &str, runs: usize) {
    let arm = UrdfArmParams {
        urdf: document.to_owned(),
        tip_link: tip.to_owned(),
        viscous_friction: vec![0.5],
        coulomb_friction: vec![0.2],
        ..UrdfArmParams::default()
    };
    let configs: Vec<ScenarioConfig> = (0..runs)
        .map(|i| ScenarioConfig {
            robot: RobotConfig::Urdf(arm.clone()),
            duration: 0.05,
            ..varied(
                i % 5,
                ControllerParams::ModelFree(ModelFreeParams {
                    torque_constant: 50.0 + i as f64,
                    ..ModelFreeParams::default()
                }),
            )
        })
        .collect();
    let robot = UrdfArm::<N>::new(&arm).expect("a valid test scenario");
    let make = || -> Vec<Simulation<UrdfArm<N>, N>> {
        configs
            .iter()
            .map(|c| Simulation::with_robot(c, robot.clone()).expect("a valid test scenario"))
            .collect()
    };
    let (_, ran) = every_path(make);
    eprintln!("{tip}: {ran} dispatched builds ran");
}

#[test]
fn panda_runs_take_the_same_bits_on_every_path() {
    with_stack(|| {
        urdf_every_path::<7>(
            include_str!("../../../../examples/data/panda.urdf"),
            "panda_hand_tcp",
            11,
        )
    });
}

#[test]
fn three_joint_urdf_runs_take_the_same_bits_on_every_path() {
    with_stack(|| {
        urdf_every_path::<3>(
            include_str!("../../../../examples/data/three_link.urdf"),
            "tip",
            9,
        )
    });
}

/// The forced path is the one `lane_path` reports; one this CPU lacks is refused.
#[test]
fn a_path_is_forced_only_where_the_cpu_runs_it() {
    use crate::sim::lanes::{lane_path, set_lane_path};
    let before = lane_path();
    assert!(set_lane_path(Some(LanePath::Portable)));
    assert_eq!(lane_path(), LanePath::Portable);
    for p in LanePath::ALL {
        assert_eq!(set_lane_path(Some(p)), p.available(), "{}", p.name());
    }
    assert!(set_lane_path(None));
    assert_eq!(lane_path(), LanePath::fastest());
    assert!(before.available());
    assert_eq!(LanePath::parse("avx512"), Some(LanePath::Avx512));
    assert_eq!(LanePath::parse("sse"), None);
}
