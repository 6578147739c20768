//! Criterion benchmarks of the admit_rs core, from one dynamics evaluation up to a batch of
//! 64 ten-second runs. `cargo bench` (all, a few minutes) or `cargo bench -- NAME` (one group).
//!
//! The per-call benchmarks replay the states of the fig. 14 run (all 10 001 samples in turn),
//! never one fixed state or rest: glibc's tanh and sin/cos cost depends on the argument, so a
//! single state would flatter (at rest) or penalise (slow motion) the numbers.
//!
//! | bench                  | one iteration                                                  |
//! |------------------------|----------------------------------------------------------------|
//! | `libm/*`               | std `sin_cos`, `tanh` (reference points; the core calls neither) |
//! | `dynamics/evaluate`    | `ThreeLinkArm::evaluate`: tip position, J, J̇q̇, D, C, G         |
//! | `dynamics/accelerate`  | `ThreeLinkArm::accelerate`: q̈ with the contact force          |
//! | `plant/rk4_substep`    | one RK4 step of 0.1 ms (a 10-substep period ÷ 10)              |
//! | `plant/control_period` | `Simulation::step` once: every stage of one 1-ms period, 10 substeps |
//! | `run/fig14_10s`        | `Simulation::run` of fig. 14 (10 001 samples, trace, metrics)  |
//! | `batch/fig14_64x10s`   | 64 fig. 14 runs (k_e 1e4 … 1e5), rayon `par_iter_mut`          |
//! | `batch/sweep_lanes_64x10s` | the same 64 runs as a sweep (metrics only) in SIMD lanes   |
//! | `batch/sweep_scalar_64x10s` | … and on the scalar path (`lanes=False`)                  |
//!
//! The batch uses rayon's global pool: `RAYON_NUM_THREADS=1 cargo bench -- batch` for one thread.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use rayon::prelude::*;

use admit_rs::robot::three_link::{Trig, Vec3};
use admit_rs::robot::{ArmModel, RobotModel, ThreeLinkArm};
use admit_rs::sim::plant::{Plant, PlantState};
use admit_rs::sim::simulation::ThreeLinkSimulation;
use admit_rs::sim::sweep::run_batch_with;
use admit_rs::world::environment::{Wall, WallParams};
use admit_rs::world::surface::Environment;
use admit_rs::{simulate, ScenarioConfig, Simulation};

/// Every sample (q, q̇, τ_k) of the fig. 14 run, replayed in a cycle so that a per-call
/// benchmark averages over the states the run goes through. The cost depends on the state:
/// glibc's tanh(q̇/ε) takes a fast path once |q̇/ε| > 22, i.e. |q̇| > 0.22 rad/s.
struct Replay {
    states: Vec<(PlantState<3>, Vec3)>,
    next: usize,
}

impl Replay {
    fn new(cfg: &ScenarioConfig) -> Self {
        let r = simulate(cfg).expect("fig14 config is valid");
        let v = |c: &[f64]| Vec3::new(c[0], c[1], c[2]);
        let mut states = Vec::with_capacity(r.trace.len());
        r.trace.for_each_row(|row| {
            let s = PlantState {
                q: v(row.q),
                qd: v(row.qd),
            };
            states.push((s, v(row.tau)));
        });
        Self { states, next: 0 }
    }

    #[inline]
    fn next(&mut self) -> &(PlantState<3>, Vec3) {
        let i = self.next;
        self.next = if i + 1 == self.states.len() { 0 } else { i + 1 };
        &self.states[i]
    }
}

fn arm_and_wall(cfg: &ScenarioConfig) -> (ThreeLinkArm, Wall) {
    let arm = ThreeLinkArm::new(cfg.robot.three_link().expect("the paper's arm"));
    let x0 = arm.forward_kinematics(&arm.initial_position());
    let wall = Wall::new(
        cfg.wall
            .as_ref()
            .and_then(|w| w.plane())
            .expect("fig14 has a wall"),
        &x0,
    )
    .expect("valid");
    (arm, wall)
}

fn libm(c: &mut Criterion) {
    let mut g = c.benchmark_group("libm");
    // A typical joint angle (q2 stays near π/4).
    g.bench_function("sin_cos", |b| b.iter(|| black_box(0.7f64).sin_cos()));
    // Friction's tanh(q̇/ε): q̇ = 0.031 rad/s (full evaluation) and 0.3 rad/s (saturated).
    g.bench_function("tanh", |b| b.iter(|| black_box(3.1f64).tanh()));
    g.bench_function("tanh_saturated", |b| b.iter(|| black_box(30.0f64).tanh()));
    g.finish();
}

fn dynamics(c: &mut Criterion) {
    let cfg = ScenarioConfig::default();
    let mut replay = Replay::new(&cfg);
    let (arm, wall) = arm_and_wall(&cfg);
    let mut g = c.benchmark_group("dynamics");
    g.bench_function("evaluate", |b| {
        b.iter(|| {
            let (s, _) = replay.next();
            arm.evaluate(black_box(&s.q), black_box(&s.qd))
        })
    });
    g.bench_function("accelerate", |b| {
        b.iter(|| {
            let (s, tau) = replay.next();
            arm.model().accelerate(
                &Trig::new(black_box(&s.q)),
                black_box(&s.qd),
                black_box(tau),
                &wall,
            )
        })
    });
    g.finish();
}

fn plant(c: &mut Criterion) {
    let cfg = ScenarioConfig::default();
    let replay = Replay::new(&cfg);
    let (arm, wall) = arm_and_wall(&cfg);
    let mut g = c.benchmark_group("plant");
    // One 0.1-ms substep, as the run takes it: a plant with the run's period and 10 substeps
    // replays the run's torques (so it retraces the run's states exactly, starting over
    // after 10 s), and the time per period is divided by the substeps. This includes each
    // period's share of its one fresh sin/cos evaluation, as in the run.
    let taus: Vec<Vec3> = replay.states.iter().map(|(_, tau)| *tau).collect();
    let substeps = cfg.substeps.count().unwrap_or(10);
    let mut whole = Plant::new(
        arm,
        Environment::Plane(wall),
        replay.states[0].0,
        cfg.period,
        substeps,
    );
    let mut k = 0;
    let substeps = substeps as u64;
    g.bench_function("rk4_substep", |b| {
        b.iter_custom(|iters| {
            let periods = iters.div_ceil(substeps);
            let start = Instant::now();
            for _ in 0..periods {
                if k + 1 == taus.len() {
                    whole.reset();
                    k = 0;
                }
                whole.advance(black_box(&taus[k]));
                k += 1;
            }
            black_box(whole.state());
            start
                .elapsed()
                .mul_f64(iters as f64 / (periods * substeps) as f64)
        })
    });
    // One period of the stage pipeline, the code `run()` and sweeps call: the simulation
    // walks through the fig. 14 run and starts over at its end (the reset, its share of
    // one period in 10 000, is inside the timing).
    let mut sim = Simulation::new(&cfg).expect("fig14 config is valid");
    g.bench_function("control_period", |b| {
        b.iter(|| {
            if sim.step(1).is_some() {
                sim.reset();
            }
        })
    });
    g.finish();
}

fn run(c: &mut Criterion) {
    let cfg = ScenarioConfig::default();
    let mut sim = Simulation::new(black_box(&cfg)).expect("valid");
    let mut g = c.benchmark_group("run");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    g.bench_function("fig14_10s", |b| b.iter(|| sim.run()));
    g.finish();
}

fn batch(c: &mut Criterion) {
    let configs: Vec<ScenarioConfig> = (0..64)
        .map(|i| ScenarioConfig {
            wall: Some(
                WallParams {
                    stiffness: 1e4 + 9e4 * i as f64 / 63.0,
                    ..WallParams::default()
                }
                .into(),
            ),
            ..ScenarioConfig::default()
        })
        .collect();
    let mut sims: Vec<ThreeLinkSimulation> = black_box(&configs)
        .iter()
        .map(|c| Simulation::new(c).expect("valid"))
        .collect();
    let mut g = c.benchmark_group("batch");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(20));
    g.bench_function("fig14_64x10s", |b| {
        b.iter(|| {
            sims.par_iter_mut()
                .map(|s| s.run().metrics.force_rms_error)
                .collect::<Vec<f64>>()
        })
    });
    // The sweep path (`ar.sweep`): metrics only, no trace; four runs per SIMD lane group
    // (issue #12), and the scalar path for reference.
    for (name, lanes) in [("sweep_lanes_64x10s", true), ("sweep_scalar_64x10s", false)] {
        g.bench_function(name, |b| {
            b.iter(|| run_batch_with(black_box(&configs), None, false, lanes).expect("valid"))
        });
    }
    g.finish();
}

criterion_group!(benches, libm, dynamics, plant, run, batch);
criterion_main!(benches);
