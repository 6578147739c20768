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
//! | `plant/control_period` | one 1-ms period: measure, references, filter, TDC, 10 substeps |
//! | `run/fig14_10s`        | `Simulation::run` of fig. 14 (10 001 samples, trace, metrics)  |
//! | `batch/fig14_64x10s`   | 64 fig. 14 runs (k_e 1e4 … 1e5), rayon `par_iter_mut`          |
//!
//! The batch uses rayon's global pool: `RAYON_NUM_THREADS=1 cargo bench -- batch` for one thread.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use rayon::prelude::*;

use admit_rs::controller::{Controller, Desired, Measurement};
use admit_rs::environment::{Wall, WallParams};
use admit_rs::filter::{AdmittanceFilter, AdmittanceParams, ForceControlParams};
use admit_rs::integrator::{Plant, PlantState};
use admit_rs::reference::Signal;
use admit_rs::robot::{RobotModel, ThreeLinkArm, Vec3};
use admit_rs::simulation::col;
use admit_rs::{simulate, ScenarioConfig, Simulation};

/// Every sample (q, q̇, τ_k) of the fig. 14 run, replayed in a cycle so that a per-call
/// benchmark averages over the states the run goes through. The cost depends on the state:
/// glibc's tanh(q̇/ε) takes a fast path once |q̇/ε| > 22, i.e. |q̇| > 0.22 rad/s.
struct Replay {
    states: Vec<(PlantState, Vec3)>,
    next: usize,
}

impl Replay {
    fn new(cfg: &ScenarioConfig) -> Self {
        let r = simulate(cfg).expect("fig14 config is valid");
        let c = &r.trace.columns;
        let v = |i: usize, k: usize| Vec3::new(c[i][k], c[i + 1][k], c[i + 2][k]);
        let states = (0..r.trace.len())
            .map(|k| {
                let s = PlantState {
                    q: v(col::Q, k),
                    qd: v(col::QD, k),
                };
                (s, v(col::TAU, k))
            })
            .collect();
        Self { states, next: 0 }
    }

    #[inline]
    fn next(&mut self) -> &(PlantState, Vec3) {
        let i = self.next;
        self.next = if i + 1 == self.states.len() { 0 } else { i + 1 };
        &self.states[i]
    }
}

fn arm_and_wall(cfg: &ScenarioConfig) -> (ThreeLinkArm, Wall, Vec3) {
    let arm = ThreeLinkArm::new(&cfg.robot);
    let x0 = arm.forward_kinematics(&Vec3::from(cfg.robot.q0));
    let wall = Wall::new(cfg.wall.as_ref().expect("fig14 has a wall"), x0[0]);
    (arm, wall, x0)
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
    let (arm, wall, _) = arm_and_wall(&cfg);
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
            arm.accelerate(black_box(&s.q), black_box(&s.qd), black_box(tau), |x| {
                wall.force(x)
            })
        })
    });
    g.finish();
}

/// One control period of `Simulation::run` without the trace: measure, references, the
/// admittance filter, time-delayed control and the plant's 10 RK4 substeps. It walks through
/// the fig. 14 run and starts over after 10 s, so the average covers the whole run.
struct ControlLoop {
    plant: Plant,
    controller: Controller,
    filter: AdmittanceFilter,
    force_reference: Signal,
    z_reference: Signal,
    x0: Vec3,
    wall_estimate: f64,
    period: f64,
    k: usize,
    periods: usize,
}

impl ControlLoop {
    fn new(cfg: &ScenarioConfig) -> Self {
        let (arm, wall, x0) = arm_and_wall(cfg);
        let initial = PlantState {
            q: Vec3::from(cfg.robot.q0),
            qd: Vec3::zeros(),
        };
        let filter = match cfg.admittance {
            Some(ForceControlParams::Admittance(p)) => AdmittanceFilter::new(p, cfg.period),
            _ => AdmittanceFilter::new(AdmittanceParams::default(), cfg.period),
        };
        Self {
            plant: Plant::new(arm, Some(wall), initial, cfg.period, cfg.substeps),
            controller: Controller::new(&cfg.controller, &cfg.robot, cfg.period),
            filter,
            force_reference: cfg.force_reference.clone(),
            z_reference: cfg.z_reference.clone(),
            x0,
            wall_estimate: wall.estimated_position(),
            period: cfg.period,
            k: 0,
            periods: cfg.samples() - 1,
        }
    }

    #[inline]
    fn step(&mut self) -> Vec3 {
        if self.k == self.periods {
            self.k = 0;
            self.plant.reset();
            self.controller.reset();
            self.filter.reset();
        }
        let t = self.k as f64 * self.period;
        let PlantState { q, qd } = *self.plant.state();
        let kin = self.plant.kinematics();
        let force = self.plant.force_at(kin.position[0]);
        let f_d = self.force_reference.at(t);
        let z = self.z_reference.at(t);
        let x_a = self.filter.step(f_d.value - force);
        let desired = Desired {
            position: Vec3::new(
                self.wall_estimate + x_a.value,
                self.x0[1],
                self.x0[2] + z.value,
            ),
            velocity: Vec3::new(x_a.rate, 0.0, z.rate),
            acceleration: Vec3::new(x_a.accel, 0.0, z.accel),
        };
        let m = Measurement {
            q: &q,
            qd: &qd,
            kinematics: &kin,
            force,
        };
        let tau = self
            .controller
            .step(&m, &desired)
            .expect("fig14 stays regular");
        self.plant.advance(&tau);
        self.k += 1;
        tau
    }
}

fn plant(c: &mut Criterion) {
    let cfg = ScenarioConfig::default();
    let replay = Replay::new(&cfg);
    let (arm, wall, _) = arm_and_wall(&cfg);
    let mut g = c.benchmark_group("plant");
    // One 0.1-ms substep, as the run takes it: a plant with the run's period and 10 substeps
    // replays the run's torques (so it retraces the run's states exactly, starting over
    // after 10 s), and the time per period is divided by the substeps. This includes each
    // period's share of its one fresh sin/cos evaluation, as in the run.
    let taus: Vec<Vec3> = replay.states.iter().map(|(_, tau)| *tau).collect();
    let mut whole = Plant::new(
        arm,
        Some(wall),
        replay.states[0].0,
        cfg.period,
        cfg.substeps,
    );
    let mut k = 0;
    let substeps = cfg.substeps as u64;
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
    let mut lp = ControlLoop::new(&cfg);
    g.bench_function("control_period", |b| b.iter(|| lp.step()));
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
            wall: Some(WallParams {
                stiffness: 1e4 + 9e4 * i as f64 / 63.0,
                ..WallParams::default()
            }),
            ..ScenarioConfig::default()
        })
        .collect();
    let mut sims: Vec<Simulation> = black_box(&configs)
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
    g.finish();
}

criterion_group!(benches, libm, dynamics, plant, run, batch);
criterion_main!(benches);
