//! Criterion benchmarks of the URDF chain algorithms (SPEC §11) and a full Panda run.
//! `cargo bench --bench chain` (a minute or two) or `cargo bench --bench chain -- aba`.
//!
//! | bench                    | one iteration                                              |
//! |--------------------------|------------------------------------------------------------|
//! | `chain_rnea/<arm>`       | RNEA: C q̇ + G (inverse dynamics at q̈ = 0, gravity on)     |
//! | `chain_crba/<arm>`       | CRBA: D(q)                                                 |
//! | `chain_aba/<arm>`        | ABA: q̈ with a tip force (friction-free τ)                 |
//! | `chain_jacobian/<arm>`   | frames (FK) + 6×n tip Jacobian + J̇q̇                       |
//! | `chain_eval/<arm>_scalar4` | one RK4 stage's work four times (frames + contact + friction + ABA), scalar, AVX2 |
//! | `chain_eval/<arm>_lanes4`  | the same four evaluations at once in SIMD lanes ([`F64x4`]), AVX2 |
//! | `chain_run/panda_10s`    | a 10-s TDC + Scheme 2 run of the Panda: 10 001 samples, 100 000 RK4 substeps |
//! | `chain_sweep/panda_lanes_16x2s` | 16 two-second Panda runs (wall stiffness 1e4 … 1e5) as a sweep in SIMD lanes, 1 thread |
//! | `chain_sweep/panda_scalar_16x2s` | … and on the scalar path (issue #12's target: lanes ≥ 2.5× scalar) |
//!
//! `<arm>` is `three_link3`, `ur5_6` or `panda7` (the files in `examples/data`). The per-call
//! benches cycle through 1024 pseudo-random states drawn once outside the timing, so no
//! single state flatters them; the kinematics (`frames`) are computed per call where the
//! algorithm needs them, except for ABA/RNEA/CRBA, which take precomputed frames as in
//! the plant (one `configure` per RK4 stage is the `chain_jacobian` figure).

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};

use admit_rs::control::params::{ControllerParams, PerJoint, PositionGains, TimeDelayParams};
use admit_rs::robot::chain::{Chain, Frames, UrdfArm, UrdfArmParams};
use admit_rs::robot::{ArmModel, JointVector, RobotModel};
use admit_rs::scalar::{F64x4, Real};
use admit_rs::sim::scenario::RobotConfig;
use admit_rs::sim::sweep::run_batch_with;
use admit_rs::world::contact_law::ContactLaw;
use admit_rs::world::environment::WallParams;
use admit_rs::world::environment::{ContactModel, Wall};
use admit_rs::{ScenarioConfig, Simulation};
use nalgebra::{SVector, Vector3};

const THREE: &str = include_str!("../examples/data/three_link.urdf");
const UR5: &str = include_str!("../examples/data/ur5.urdf");
const PANDA: &str = include_str!("../examples/data/panda.urdf");

fn params(urdf: &str, tip: &str) -> UrdfArmParams {
    UrdfArmParams {
        urdf: urdf.to_owned(),
        tip_link: tip.to_owned(),
        ..UrdfArmParams::default()
    }
}

/// 1024 deterministic pseudo-random states (q, q̇, τ) in [−2, 2].
fn states<const N: usize>() -> Vec<(JointVector<N>, JointVector<N>, JointVector<N>)> {
    let mut s = 0x9e3779b97f4a7c15u64;
    let mut r = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((s >> 11) as f64 / (1u64 << 53) as f64) * 4.0 - 2.0
    };
    (0..1024)
        .map(|_| {
            (
                JointVector::<N>::from_fn(|_, _| r()),
                JointVector::<N>::from_fn(|_, _| r()),
                JointVector::<N>::from_fn(|_, _| 5.0 * r()),
            )
        })
        .collect()
}

fn bench_arm<const N: usize>(c: &mut Criterion, name: &str, urdf: &str, tip: &str) {
    let arm = UrdfArm::<N>::new(&params(urdf, tip)).expect("valid URDF");
    let chain = arm.model.chain;
    let states = states::<N>();
    let frames: Vec<Frames<f64, N>> = states.iter().map(|(q, _, _)| chain.frames(q)).collect();
    let force = nalgebra::Vector3::new(-10.0, 0.5, 1.0);
    let mut i = 0usize;
    let mut next = move || {
        i = (i + 1) & 1023;
        i
    };
    c.benchmark_group("chain_rnea").bench_function(name, |b| {
        b.iter(|| {
            let k = next();
            black_box(chain.bias(&frames[k], &states[k].1))
        })
    });
    c.benchmark_group("chain_crba")
        .bench_function(name, |b| b.iter(|| black_box(chain.crba(&frames[next()]))));
    c.benchmark_group("chain_aba").bench_function(name, |b| {
        b.iter(|| {
            let k = next();
            let w = chain.tip_wrench(&frames[k], &force);
            black_box(chain.aba(&frames[k], &states[k].1, &states[k].2, &w))
        })
    });
    c.benchmark_group("chain_jacobian")
        .bench_function(name, |b| {
            b.iter(|| {
                let k = next();
                let f = chain.frames(&states[k].0);
                black_box(chain.jacobian(&f, &states[k].1))
            })
        });
}

/// One RK4 stage's plant evaluation: frames at q, then q̈ with the wall's force at the tip
/// (a penalty wall along x at 0.3 m; the chain's own friction). Generic over the scalar,
/// as the plant runs it.
#[inline(always)]
fn evaluate<T: Real, const N: usize>(
    model: &Chain<T, N>,
    q: &SVector<T, N>,
    qd: &SVector<T, N>,
    tau: &SVector<T, N>,
) -> SVector<T, N> {
    let f = model.configure(q);
    let normal = Vector3::new(T::one(), T::zero(), T::zero());
    let wall = Wall {
        law: ContactLaw {
            stiffness: T::splat(3e4),
            damping: T::zero(),
            model: ContactModel::KelvinVoigt,
            exponent: T::one(),
            friction: T::zero(),
            stiction_velocity: T::splat(1e-3),
        },
        normal,
        position: T::splat(0.3),
        position_error: T::zero(),
    };
    model.accelerate(&f, qd, tau, &wall).0
}

/// Four evaluations one after the other, in the dispatched AVX2 + FMA code the lanes run in.
#[target_feature(enable = "avx2,fma")]
unsafe fn scalar4_avx2<const N: usize>(
    model: &Chain<f64, N>,
    x: &[(JointVector<N>, JointVector<N>, JointVector<N>); 4],
) -> [JointVector<N>; 4] {
    std::array::from_fn(|l| evaluate(model, &x[l].0, &x[l].1, &x[l].2))
}

/// The same four evaluations in lanes.
#[target_feature(enable = "avx2,fma")]
unsafe fn lanes4_avx2<const N: usize>(
    model: &Chain<F64x4, N>,
    x: &(SVector<F64x4, N>, SVector<F64x4, N>, SVector<F64x4, N>),
) -> SVector<F64x4, N> {
    evaluate(model, &x.0, &x.1, &x.2)
}

fn bench_eval<const N: usize>(c: &mut Criterion, name: &str, urdf: &str, tip: &str) {
    if !is_x86_feature_detected!("avx2") || !is_x86_feature_detected!("fma") {
        return;
    }
    let arm = UrdfArm::<N>::new(&params(urdf, tip)).expect("valid URDF");
    let states = states::<N>();
    let quads: Vec<[(JointVector<N>, JointVector<N>, JointVector<N>); 4]> = states
        .chunks_exact(4)
        .map(|q| [q[0], q[1], q[2], q[3]])
        .collect();
    let pack = |v: [&JointVector<N>; 4]| {
        SVector::<F64x4, N>::from_fn(|j, _| F64x4::from_lanes(|l| v[l][j]))
    };
    let packed: Vec<_> = quads
        .iter()
        .map(|q| {
            (
                pack([&q[0].0, &q[1].0, &q[2].0, &q[3].0]),
                pack([&q[0].1, &q[1].1, &q[2].1, &q[3].1]),
                pack([&q[0].2, &q[1].2, &q[2].2, &q[3].2]),
            )
        })
        .collect();
    let lanes = Chain::pack([&arm.model; 4]);
    let mut i = 0usize;
    let mut next = move || {
        i = (i + 1) & 255;
        i
    };
    let mut g = c.benchmark_group("chain_eval");
    // SAFETY (both): AVX2 and FMA were detected above.
    g.bench_function(format!("{name}_scalar4"), |b| {
        b.iter(|| unsafe { black_box(scalar4_avx2(&arm.model, &quads[next()])) })
    });
    g.bench_function(format!("{name}_lanes4"), |b| {
        b.iter(|| unsafe { black_box(lanes4_avx2(&lanes, &packed[next()])) })
    });
    g.finish();
}

fn evals(c: &mut Criterion) {
    bench_eval::<6>(c, "ur5_6", UR5, "tool0");
    bench_eval::<7>(c, "panda7", PANDA, "panda_hand_tcp");
}

fn arms(c: &mut Criterion) {
    bench_arm::<3>(c, "three_link3", THREE, "tip");
    bench_arm::<6>(c, "ur5_6", UR5, "tool0");
    bench_arm::<7>(c, "panda7", PANDA, "panda_hand_tcp");
}

/// The Panda of `examples/arms.py`: TDC (eq. 18) + Scheme 2 with the arm preset of
/// `TimeDelayControl.for_arm` (D̄ = 0.8 D(q0), K_t = 50, K_P = 600, K_D = 50).
pub fn panda_config() -> ScenarioConfig {
    let p = UrdfArmParams {
        q0: Some(vec![0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]),
        ..params(PANDA, "panda_hand_tcp")
    };
    let arm = UrdfArm::<7>::new(&p).expect("valid");
    let q0 = arm.initial_position();
    let d = arm
        .model
        .dynamics(&arm.model.configure(&q0), &JointVector::zeros())
        .inertia
        * 0.8;
    let rows: Vec<f64> = d.transpose().as_slice().to_vec();
    ScenarioConfig {
        robot: RobotConfig::Urdf(p),
        controller: ControllerParams::TimeDelay(TimeDelayParams {
            gains: PositionGains::new(5.0, 50.0, 600.0),
            torque_constant: 50.0,
            joint_inertia: PerJoint::from_slice(&rows),
            ..TimeDelayParams::default()
        }),
        ..ScenarioConfig::default()
    }
}

fn run(c: &mut Criterion) {
    let cfg = panda_config();
    let p = match &cfg.robot {
        RobotConfig::Urdf(p) => p.clone(),
        RobotConfig::ThreeLink(_) => unreachable!(),
    };
    let mut sim =
        Simulation::with_robot(&cfg, UrdfArm::<7>::new(&p).expect("valid")).expect("valid");
    assert!(
        sim.run().metrics.stable == Some(true),
        "the benchmarked run is the stable one"
    );
    let mut g = c.benchmark_group("chain_run");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    g.bench_function("panda_10s", |b| b.iter(|| black_box(sim.run())));
    g.finish();
}

/// The 7-DOF sweep of issue #12: 16 Panda runs in lanes against the scalar path, on one
/// thread.
fn sweep(c: &mut Criterion) {
    let configs: Vec<ScenarioConfig> = (0..16)
        .map(|i| {
            let base = panda_config();
            ScenarioConfig {
                wall: Some(
                    WallParams {
                        stiffness: 1e4 + 6e3 * i as f64,
                        ..base
                            .wall
                            .as_ref()
                            .and_then(|w| w.plane().cloned())
                            .unwrap_or_default()
                    }
                    .into(),
                ),
                duration: 2.0,
                ..base
            }
        })
        .collect();
    let mut g = c.benchmark_group("chain_sweep");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for (name, lanes) in [("panda_lanes_16x2s", true), ("panda_scalar_16x2s", false)] {
        g.bench_function(name, |b| {
            b.iter(|| run_batch_with(black_box(&configs), Some(1), false, lanes).expect("valid"))
        });
    }
    g.finish();
}

criterion_group!(benches, arms, evals, run, sweep);
criterion_main!(benches);
