//! The simulation loop (SPEC §6) as a pipeline: measure → references → outer force loop →
//! control law → record → plant integration, once per controller period.

use crate::controller::{ControlFailure, Controller, ControllerParams, Desired, Measurement};
use crate::environment::{Wall, WallParams};
use crate::error::{check, Error, Result};
use crate::filter::{ForceControl, ForceControlParams};
use crate::integrator::{Plant, PlantState};
use crate::metrics::Metrics;
use crate::reference::{Sample, Signal};
use crate::robot::{RobotModel, RobotParams, ThreeLinkArm, Vec3};

/// Largest run accepted, in samples: a trace this long already takes ~1.5 GB.
pub const MAX_SAMPLES: usize = 10_000_000;
/// Largest number of RK4 substeps per control period.
pub const MAX_SUBSTEPS: usize = 10_000;

/// Everything that defines one run. Defaults are the paper preset of fig. 14.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioConfig {
    pub robot: RobotParams,
    /// `None`: free space.
    pub wall: Option<WallParams>,
    pub controller: ControllerParams,
    /// The outer force loop; `None` is position-only control (X_d,x = X0 x).
    pub admittance: Option<ForceControlParams>,
    /// Desired contact force f_d(t) [N].
    pub force_reference: Signal,
    /// Desired z relative to the start: z_d = z0 + signal(t) [m].
    pub z_reference: Signal,
    /// Controller period T [s]. Default 1 ms.
    pub period: f64,
    /// RK4 substeps per period. Default 10.
    pub substeps: usize,
    /// Run length [s]; a multiple of `period`. Default 10.
    pub duration: f64,
    /// |q̇| at or above this [rad/s] stops the run as unstable. Default 100.
    pub velocity_limit: f64,
}

impl Default for ScenarioConfig {
    fn default() -> Self {
        Self {
            robot: RobotParams::default(),
            wall: Some(WallParams::default()),
            controller: ControllerParams::TimeDelay(Default::default()),
            admittance: Some(ForceControlParams::Admittance(Default::default())),
            force_reference: Signal::Step {
                value: 10.0,
                time: 0.0,
                initial: 0.0,
            },
            z_reference: Signal::Sine {
                offset: 0.0,
                amplitude: 0.05,
                omega: 1.0,
                phase: 0.0,
            },
            period: 1e-3,
            substeps: 10,
            duration: 10.0,
            velocity_limit: 100.0,
        }
    }
}

impl ScenarioConfig {
    /// Checks every field; errors name the field by its dotted path.
    pub fn validate(&self) -> Result<()> {
        self.robot.validate().map_err(|e| e.within("robot"))?;
        if let Some(w) = &self.wall {
            w.validate().map_err(|e| e.within("wall"))?;
        }
        self.controller
            .validate()
            .map_err(|e| e.within("controller"))?;
        if let Some(a) = &self.admittance {
            a.validate().map_err(|e| e.within("admittance"))?;
        }
        self.force_reference
            .validate()
            .map_err(|e| e.within("force_reference"))?;
        self.z_reference
            .validate()
            .map_err(|e| e.within("z_reference"))?;
        check::positive("period", self.period)?;
        check::positive("duration", self.duration)?;
        check::positive("velocity_limit", self.velocity_limit)?;
        if self.substeps == 0 || self.substeps > MAX_SUBSTEPS {
            return Err(Error::parameter(
                "substeps",
                self.substeps,
                &format!("an integer from 1 to {MAX_SUBSTEPS}"),
            ));
        }
        let periods = self.duration / self.period;
        if (periods - periods.round()).abs() > 1e-6 * periods.max(1.0) {
            return Err(Error::parameter(
                "duration",
                self.duration,
                &format!("a whole multiple of period = {}", self.period),
            ));
        }
        if periods.round() + 1.0 > MAX_SAMPLES as f64 {
            return Err(Error::parameter(
                "duration",
                self.duration,
                &format!("at most {} periods of {} s", MAX_SAMPLES - 1, self.period),
            ));
        }
        Ok(())
    }

    /// N = D/T + 1 samples.
    pub fn samples(&self) -> usize {
        (self.duration / self.period).round() as usize + 1
    }
}

/// Why a run stopped early.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Divergence {
    /// A joint position or velocity became NaN or infinite.
    NonFiniteState,
    /// The control law produced a NaN or infinite torque.
    NonFiniteTorque,
    /// |q̇_joint| reached the velocity limit.
    VelocityLimit { joint: usize, velocity: f64 },
    /// The Jacobian became singular, so the control law has no answer.
    SingularJacobian,
}

impl std::fmt::Display for Divergence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Divergence::NonFiniteState => write!(f, "joint state became non-finite"),
            Divergence::NonFiniteTorque => write!(f, "control torque became non-finite"),
            Divergence::VelocityLimit { joint, velocity } => write!(
                f,
                "joint {} velocity {velocity:.2} rad/s reached the velocity limit",
                joint + 1
            ),
            Divergence::SingularJacobian => {
                write!(
                    f,
                    "the Jacobian became singular (arm at a kinematic singularity)"
                )
            }
        }
    }
}

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    Completed,
    /// Stopped at `time` [s]; the trace holds every sample before it.
    Diverged {
        time: f64,
        cause: Divergence,
    },
}

impl Outcome {
    pub fn is_stable(&self) -> bool {
        matches!(self, Outcome::Completed)
    }
}

/// Column names of a trace, in order (SPEC §8 plus joint velocities).
pub const TRACE_COLUMNS: [&str; 20] = [
    "t", "q1", "q2", "q3", "qd1", "qd2", "qd3", "x", "y", "z", "x_ref", "y_ref", "z_ref", "f",
    "f_d", "x_a", "tau1", "tau2", "tau3", "xa_dot",
];

/// The recorded run, one Vec per column (structure of arrays).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trace {
    pub columns: [Vec<f64>; TRACE_COLUMNS.len()],
}

/// Column indices into `Trace::columns`.
pub mod col {
    pub const T: usize = 0;
    pub const Q: usize = 1;
    pub const QD: usize = 4;
    pub const X: usize = 7;
    pub const Y: usize = 8;
    pub const Z: usize = 9;
    pub const X_REF: usize = 10;
    pub const Z_REF: usize = 12;
    pub const F: usize = 13;
    pub const F_D: usize = 14;
    pub const X_A: usize = 15;
    pub const TAU: usize = 16;
}

impl Trace {
    fn with_capacity(n: usize) -> Self {
        Self {
            columns: std::array::from_fn(|_| Vec::with_capacity(n)),
        }
    }

    pub fn len(&self) -> usize {
        self.columns[0].len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn column(&self, name: &str) -> Option<&[f64]> {
        TRACE_COLUMNS
            .iter()
            .position(|c| *c == name)
            .map(|i| self.columns[i].as_slice())
    }

    #[inline]
    fn push(&mut self, row: &[f64; TRACE_COLUMNS.len()]) {
        for (c, v) in self.columns.iter_mut().zip(row) {
            c.push(*v);
        }
    }
}

/// A finished run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    pub trace: Trace,
    pub outcome: Outcome,
    pub metrics: Metrics,
}

/// One run's pipeline: owns every state machine and resets them together.
#[derive(Debug, Clone)]
pub struct Simulation {
    config: ScenarioConfig,
    plant: Plant,
    controller: Controller,
    force_control: Option<ForceControl>,
    start_position: Vec3,
    wall_estimate: f64,
}

impl Simulation {
    /// Validates `config` and builds the pipeline.
    pub fn new(config: &ScenarioConfig) -> Result<Self> {
        config.validate()?;
        let robot = &config.robot;
        let arm = ThreeLinkArm::new(robot);
        let q0 = Vec3::from(robot.q0);
        let start_position = arm.forward_kinematics(&q0);
        let wall = config
            .wall
            .as_ref()
            .map(|w| Wall::new(w, start_position[0]));
        let wall_estimate = wall.map_or(start_position[0], |w| w.estimated_position());
        let plant = Plant::new(
            arm.clone(),
            wall,
            PlantState {
                q: q0,
                qd: Vec3::zeros(),
            },
            config.period,
            config.substeps,
        );
        Ok(Self {
            controller: Controller::new(&config.controller, robot, config.period),
            force_control: config
                .admittance
                .as_ref()
                .map(|a| ForceControl::new(a, config.period)),
            config: config.clone(),
            plant,
            start_position,
            wall_estimate,
        })
    }

    pub fn config(&self) -> &ScenarioConfig {
        &self.config
    }

    pub fn reset(&mut self) {
        self.plant.reset();
        self.controller.reset();
        if let Some(f) = &mut self.force_control {
            f.reset();
        }
    }

    /// Runs from the initial state to the end (or to divergence) and computes the metrics.
    pub fn run(&mut self) -> RunResult {
        self.reset();
        let n = self.config.samples();
        let mut trace = Trace::with_capacity(n);
        let outcome = self.run_into(&mut trace, n);
        let metrics = Metrics::compute(&trace, &self.config, &outcome);
        RunResult {
            trace,
            outcome,
            metrics,
        }
    }

    /// The step loop, compiled twice: for x86-64 with AVX2 and FMA when the CPU has them
    /// (three-operand VEX code, about 8 % faster), and for the baseline ISA otherwise. The
    /// two give bit-identical results: Rust never fuses a multiply and an add on its own, so
    /// enabling FMA changes the encoding, not the arithmetic (tested).
    fn run_into(&mut self, trace: &mut Trace, n: usize) -> Outcome {
        #[cfg(target_arch = "x86_64")]
        if crate::integrator::has_avx2_fma() {
            // SAFETY: the features `run_into_avx2` is compiled for were detected just above.
            return unsafe { self.run_into_avx2(trace, n) };
        }
        self.run_into_baseline(trace, n)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn run_into_avx2(&mut self, trace: &mut Trace, n: usize) -> Outcome {
        self.run_into_baseline(trace, n)
    }

    #[inline(always)]
    fn run_into_baseline(&mut self, trace: &mut Trace, n: usize) -> Outcome {
        let period = self.config.period;
        let x0 = self.start_position;
        for k in 0..n {
            let t = k as f64 * period;
            // 1. measure
            let PlantState { q, qd } = *self.plant.state();
            let kin = self.plant.kinematics();
            let force = self.plant.force_at(kin.position[0]);
            // 2. references
            let f_d = self.config.force_reference.at(t);
            let z = self.config.z_reference.at(t);
            // 3. outer force loop (its state advances with e_f,k after its output)
            let x_a = match &mut self.force_control {
                Some(fc) => fc.step(&f_d, force),
                None => Sample::default(),
            };
            let x_ref = if self.force_control.is_some() {
                self.wall_estimate + x_a.value
            } else {
                x0[0]
            };
            let desired = Desired {
                position: Vec3::new(x_ref, x0[1], x0[2] + z.value),
                velocity: Vec3::new(x_a.rate, 0.0, z.rate),
                acceleration: Vec3::new(x_a.accel, 0.0, z.accel),
            };
            // 4. control law
            let measurement = Measurement {
                q: &q,
                qd: &qd,
                kinematics: &kin,
                force,
            };
            let tau = match self.controller.step(&measurement, &desired) {
                Ok(tau) if tau.iter().all(|v| v.is_finite()) => tau,
                Ok(_) => return diverged(t, Divergence::NonFiniteTorque),
                Err(ControlFailure::SingularJacobian) => {
                    return diverged(t, Divergence::SingularJacobian)
                }
            };
            // 5. record sample k
            let p = kin.position;
            trace.push(&[
                t,
                q[0],
                q[1],
                q[2],
                qd[0],
                qd[1],
                qd[2],
                p[0],
                p[1],
                p[2],
                x_ref,
                desired.position[1],
                desired.position[2],
                force,
                f_d.value,
                x_a.value,
                tau[0],
                tau[1],
                tau[2],
                x_a.rate,
            ]);
            // 6. integrate the plant over [t_k, t_{k+1}] with τ_k held
            if k + 1 < n {
                self.plant.advance_inlined(&tau);
                if let Some(cause) = self.check_state() {
                    return diverged((k + 1) as f64 * period, cause);
                }
            }
        }
        Outcome::Completed
    }

    fn check_state(&self) -> Option<Divergence> {
        let s = self.plant.state();
        if !(s.q.iter().chain(s.qd.iter()).all(|v| v.is_finite())) {
            return Some(Divergence::NonFiniteState);
        }
        s.qd.iter()
            .position(|v| v.abs() >= self.config.velocity_limit)
            .map(|joint| Divergence::VelocityLimit {
                joint,
                velocity: s.qd[joint],
            })
    }
}

fn diverged(time: f64, cause: Divergence) -> Outcome {
    Outcome::Diverged { time, cause }
}

/// Validates, builds and runs one scenario.
pub fn simulate(config: &ScenarioConfig) -> Result<RunResult> {
    Ok(Simulation::new(config)?.run())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::{ComputedTorqueParams, ModelFreeParams, PositionGains};
    use crate::filter::AdmittanceParams;

    fn ideal_inner_loop(admittance: AdmittanceParams) -> ScenarioConfig {
        ScenarioConfig {
            controller: ControllerParams::ComputedTorque(ComputedTorqueParams {
                gains: PositionGains::new(1.0, 200.0, 1e4),
                contact_compensation: true,
                ..Default::default()
            }),
            admittance: Some(ForceControlParams::Admittance(admittance)),
            z_reference: Signal::Step {
                value: 0.0,
                time: 0.0,
                initial: 0.0,
            },
            ..ScenarioConfig::default()
        }
    }

    fn final_force(r: &RunResult) -> f64 {
        *r.trace.columns[col::F].last().unwrap()
    }

    /// eq. (26) with the admittance gain: f(∞) = f_d · r / (1 + r), r = k_a k_e / k.
    #[test]
    fn scheme1_steady_state_offset() {
        let cfg = ideal_inner_loop(AdmittanceParams::scheme1(800.0, 400.0, 0.1));
        let r = simulate(&cfg).unwrap();
        assert!(r.outcome.is_stable());
        let ratio = 0.1 * 30_000.0 / 400.0;
        let expected: f64 = 10.0 * ratio / (1.0 + ratio);
        assert!((expected - 8.823529).abs() < 1e-6);
        assert!(
            (final_force(&r) - expected).abs() < 1e-3 * expected,
            "{}",
            final_force(&r)
        );
    }

    /// eq. (35): Scheme 2 has no steady-state force error.
    #[test]
    fn scheme2_zero_error() {
        let cfg = ideal_inner_loop(AdmittanceParams::scheme2(800.0, 0.1));
        let r = simulate(&cfg).unwrap();
        assert!((final_force(&r) - 10.0).abs() < 1e-6, "{}", final_force(&r));
    }

    #[test]
    fn trace_has_n_samples_and_exact_times() {
        let cfg = ScenarioConfig {
            duration: 0.05,
            ..ScenarioConfig::default()
        };
        let r = simulate(&cfg).unwrap();
        assert_eq!(r.trace.len(), 51);
        assert_eq!(r.trace.columns[col::T][50], 50.0 * 1e-3);
        // Sample 0 is the initial state: touching the wall with zero force.
        assert_eq!(r.trace.columns[col::F][0], 0.0);
        assert_eq!(r.trace.columns[col::F_D][0], 10.0);
    }

    #[test]
    fn deterministic() {
        let cfg = ScenarioConfig {
            duration: 0.5,
            ..ScenarioConfig::default()
        };
        let a = simulate(&cfg).unwrap();
        let b = simulate(&cfg).unwrap();
        assert_eq!(a.trace, b.trace);
    }

    /// The AVX2 + FMA build of the step loop (taken on this machine when the CPU has them)
    /// and the baseline build give the same bits.
    #[test]
    fn instruction_sets_agree_bit_for_bit() {
        let cfg = ScenarioConfig {
            duration: 1.0,
            ..ScenarioConfig::default()
        };
        let mut sim = Simulation::new(&cfg).unwrap();
        let dispatched = sim.run().trace;
        sim.reset();
        let n = cfg.samples();
        let mut baseline = Trace::with_capacity(n);
        assert_eq!(sim.run_into_baseline(&mut baseline, n), Outcome::Completed);
        assert_eq!(dispatched, baseline);
    }

    #[test]
    fn model_free_with_small_ka_diverges_and_says_when() {
        let cfg = ScenarioConfig {
            controller: ControllerParams::ModelFree(ModelFreeParams {
                gains: PositionGains::new(0.1, 20.0, 100.0),
                ..Default::default()
            }),
            ..ScenarioConfig::default()
        };
        let r = simulate(&cfg).unwrap();
        match r.outcome {
            Outcome::Diverged { time, cause } => {
                assert!(time > 0.0 && time < 10.0);
                assert_eq!(r.trace.len(), (time / 1e-3).round() as usize);
                assert!(matches!(
                    cause,
                    Divergence::VelocityLimit { .. } | Divergence::NonFiniteState
                ));
            }
            Outcome::Completed => panic!("expected divergence"),
        }
        assert!(!r.metrics.stable && r.metrics.diverged);
    }

    #[test]
    fn duration_must_be_a_multiple_of_period() {
        let cfg = ScenarioConfig {
            duration: 0.0105,
            ..ScenarioConfig::default()
        };
        let e = Simulation::new(&cfg).unwrap_err().to_string();
        assert!(e.starts_with("duration = 0.0105"), "{e}");
    }
}
