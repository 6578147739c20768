//! The closed loop over one controller period as a map x_{k+1} = Φ(x_k, f_d) on the flat
//! state of SPEC §10, its equilibrium and its Jacobians (SPEC §12).
//!
//! Φ is evaluated by the simulator itself: `Simulation::set_state` then one `step`, so every
//! stage (plant, filter, controller memory, sensor, actuator) is covered with no second
//! model to keep in step. The references are frozen (f_d held, the motion at s(0)), the
//! sensor noise and resolution are off (the rounding is not differentiable), and the map
//! is always taken at sample 1 so that no first-sample special case is involved.
//!
//! Derivatives are five-point central differences (fourth order). Every stage is smooth in
//! contact, with the contact clamp (δ = 0) and the exact Coulomb sign (ε ≤ 0) as the only
//! kinks; the step is 1e-5 of the entry's scale (|x_i|, at least 1), cut to an eighth of the
//! penetration so that every evaluation keeps contact. Truncation (h⁴ Φ⁽⁵⁾/30) and round-off
//! (≈ ε_mach |Φ|/h) are both below 1e-9 of the largest entry for the paper's arm; the test
//! `jacobian_is_accurate` checks it against the exact ZOH filter rows and a Richardson
//! comparison.

use nalgebra::{DMatrix, DVector};

use crate::control::filter::ForceControlParams;
use crate::control::reference::{Sample, Signal};
use crate::error::{approx, short, Error};
use crate::robot::{JointVector, RobotModel};
use crate::sim::simulation::{Divergence, Outcome, ScenarioConfig, Simulation};

/// Why an analysis could not be done.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// An invalid scenario (names the field).
    #[error(transparent)]
    Parameter(#[from] Error),
    /// No steady contact to linearise about.
    #[error("no contact equilibrium: {0}")]
    NoEquilibrium(String),
    /// The equilibrium is not isolated: I − A is singular.
    #[error("singular equilibrium: {0}")]
    Singular(String),
    /// A scenario the linearisation does not cover.
    #[error("cannot linearise: {0}")]
    Unsupported(String),
}

pub type AnalysisResult<T> = std::result::Result<T, AnalysisError>;

/// Samples of the settling run that starts the Newton iteration.
pub const SETTLE_SAMPLES: usize = 100;
/// Relative step of the five-point differences.
pub const STEP: f64 = 1e-5;
/// Relative step of the second differences of [`DriveColumns::curvature`].
const CURVATURE_STEP: f64 = 1e-4;
/// Relative step of the central differences inside Newton.
const NEWTON_STEP: f64 = 1e-6;
/// Newton stops when every |Φ(x)_i − x_i| ≤ this × max(|x_i|, 1).
const NEWTON_TOL: f64 = 1e-11;
const NEWTON_MAX: usize = 30;
/// The sample index the map is evaluated at (every first-sample case is behind it).
const SAMPLE: f64 = 1.0;

/// The linearised closed loop about one state.
#[derive(Debug, Clone, PartialEq)]
pub struct Linearization {
    /// δx_{k+1} = A δx_k + B δf_d,k; δy_k = C δx_k + D δf_d,k with y = (f, n·X, t̂·X).
    pub a: DMatrix<f64>,
    pub b: DVector<f64>,
    pub c: DMatrix<f64>,
    pub d: DVector<f64>,
    /// δf̃_k = c_measured δx_k: the force the sensor reports (what the force loop feeds
    /// back; f_d enters only as e_f = f_d − f̃, so the loop cut there is
    /// L(z) = c_measured (zI − A − B c_measured)⁻¹ B).
    pub c_measured: DVector<f64>,
    /// State labels (the flat state of `Simulation::state_labels` without `sample`).
    pub labels: Vec<String>,
    /// The operating point x*.
    pub state: Vec<f64>,
    /// The desired force held there.
    pub force_desired: f64,
    /// y at x*: true force f [N], n·X [m], t̂·X [m].
    pub outputs: [f64; 3],
    /// n·X_d at x* (the reference along n).
    pub reference_normal: f64,
    /// Penetration n·X − x_e at x* [m].
    pub penetration: f64,
    /// Controller period T [s].
    pub period: f64,
    /// Whether x* is a fixed point (false for `at`).
    pub equilibrium: bool,
    /// Newton iterations used (0 for `at`).
    pub iterations: usize,
    /// What the linear model assumes, in words.
    pub caveats: Vec<String>,
    /// The columns of the other inputs, when asked for ([`linearize_driven`]).
    pub drive: Option<DriveColumns>,
}

/// How the motion reference and a joint torque enter the linearised loop (SPEC §23):
/// δx_{k+1} = A δx_k + B δf_d,k + B_u δu_k, δy_k = C δx_k + D δf_d,k + D_u δu_k with
/// u = (s, ṡ, s̈, τ_1 … τ_N): the motion reference along t̂ and its rates, and a torque
/// added to each joint's over the period.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveColumns {
    pub b: DMatrix<f64>,
    /// Rows f, n·X, t̂·X.
    pub d: DMatrix<f64>,
    /// The measured force's row.
    pub c_measured: DVector<f64>,
    /// The inputs' names ([`input_labels`]).
    pub labels: Vec<String>,
    /// Second derivatives of each row of Φ (then of y: f, n·X, t̂·X, f̃) in (x, u): the
    /// quadratic terms (centripetal, the arm's geometry along the path, torque × pose) a
    /// forced response of several centimetres meets.
    pub curvature: Vec<DMatrix<f64>>,
}

/// The scenario with its references frozen for the analysis: f_d held at `force`, the
/// motion held at its value at `time`, no sensor noise or rounding, and room for the
/// settling run. Returns it with f_d.
pub fn frozen(config: &ScenarioConfig, at: Option<f64>) -> AnalysisResult<(ScenarioConfig, f64)> {
    config.validate()?;
    if config.wall.is_none() {
        return Err(AnalysisError::Unsupported(
            "the scenario has no wall (position-only control has no contact loop)".into(),
        ));
    }
    if config.admittance.is_none() {
        return Err(AnalysisError::Unsupported(
            "the scenario has no force loop (admittance is None)".into(),
        ));
    }
    let force = match (at, &config.force_reference) {
        (Some(t), s) => s.at(t).value,
        (None, Signal::Step { value, .. }) => *value,
        (None, Signal::Sine { offset, .. }) => *offset,
        (None, Signal::Sampled { values, .. }) => *values.last().unwrap_or(&0.0),
    };
    let s = config.z_reference.at(at.unwrap_or(0.0)).value;
    let hold = |v: f64| Signal::Step {
        value: v,
        time: 0.0,
        initial: v,
    };
    let mut f = config.clone();
    f.force_reference = hold(force);
    f.z_reference = hold(s);
    f.sensor.noise_std = 0.0;
    f.sensor.resolution = 0.0;
    // The contact phase is linearised: after a guarded approach's switch (SPEC §16), which
    // hands over bumplessly, the loop is the force loop alone.
    f.approach = None;
    f.duration = (SETTLE_SAMPLES + 16) as f64 * config.period;
    if starts_apart(config) {
        // Room to cross the free space first (SPEC §16): the settling run reaches contact.
        f.duration += MAX_APPROACH;
    }
    Ok((f, force))
}

/// Longest approach through free space a settling run waits for [s].
const MAX_APPROACH: f64 = 10.0;

/// Whether the run starts apart from its wall (a gap, or a plane placed beyond X0).
fn starts_apart(config: &ScenarioConfig) -> bool {
    config
        .wall
        .as_ref()
        .is_some_and(|w| w.gap() > 0.0 || w.plane().is_some_and(|p| p.position.is_some()))
}

/// The map Φ of one built simulation.
struct Map<'a, R: RobotModel<N>, const N: usize> {
    sim: &'a mut Simulation<R, N>,
    buf: Vec<f64>,
    /// The inputs besides f_d, at their operating values unless a column perturbs them.
    drive: Drive<N>,
}

/// The map's inputs besides the state and f_d (SPEC §23): the motion reference (s, ṡ, s̈)
/// and a joint torque added to the actuator's.
#[derive(Debug, Clone, Copy)]
struct Drive<const N: usize> {
    motion: Sample,
    torque: JointVector<N>,
}

impl<const N: usize> Drive<N> {
    /// How many inputs there are besides f_d: s, ṡ, s̈ and one torque per joint.
    const COUNT: usize = 3 + N;

    fn get(&self, i: usize) -> f64 {
        match i {
            0 => self.motion.value,
            1 => self.motion.rate,
            2 => self.motion.accel,
            _ => self.torque[i - 3],
        }
    }

    fn set(&mut self, i: usize, v: f64) {
        match i {
            0 => self.motion.value = v,
            1 => self.motion.rate = v,
            2 => self.motion.accel = v,
            _ => self.torque[i - 3] = v,
        }
    }
}

/// Names of the inputs of [`input_columns`], in column order.
pub fn input_labels(joints: usize) -> Vec<String> {
    let mut out = vec!["s".to_owned(), "s_rate".to_owned(), "s_accel".to_owned()];
    out.extend((1..=joints).map(|j| format!("torque{j}")));
    out
}

/// Φ(x) and y(x) at one point.
struct Eval {
    next: Vec<f64>,
    /// f, n·X, t̂·X and the measured force f̃.
    y: [f64; 4],
    reference_normal: f64,
    penetration: f64,
}

impl<R: RobotModel<N>, const N: usize> Map<'_, R, N> {
    fn new(sim: &mut Simulation<R, N>, s0: f64) -> Map<'_, R, N> {
        Map {
            sim,
            buf: Vec::new(),
            drive: Drive {
                motion: Sample {
                    value: s0,
                    ..Sample::default()
                },
                torque: JointVector::zeros(),
            },
        }
    }

    fn eval(&mut self, x: &[f64], force: f64) -> AnalysisResult<Eval> {
        self.buf.clear();
        self.buf.push(SAMPLE);
        self.buf.extend_from_slice(x);
        self.sim.set_state(&self.buf)?;
        let f_d = Sample {
            value: force,
            ..Sample::default()
        };
        let (motion, torque) = (self.drive.motion, self.drive.torque);
        if let Some(Outcome::Diverged { cause, .. }) = self.sim.step_forced((f_d, motion), &torque)
        {
            return Err(match cause {
                Divergence::SingularJacobian => AnalysisError::NoEquilibrium(
                    "the arm reaches a singular Jacobian (stretched out: is the wall within \
                     reach?)"
                        .into(),
                ),
                other => AnalysisError::NoEquilibrium(format!("one period diverges: {other}")),
            });
        }
        let tr = self.sim.trace();
        let last = tr.len() - 1;
        let p = nalgebra::Vector3::new(tr.x()[last], tr.y()[last], tr.z()[last]);
        let r = nalgebra::Vector3::new(tr.x_ref()[last], tr.y_ref()[last], tr.z_ref()[last]);
        let fr = self.sim.frame();
        let y = [
            tr.f()[last],
            fr.normal.dot(&p),
            fr.tangent.dot(&p),
            tr.f_measured()[last],
        ];
        let reference_normal = fr.normal.dot(&r);
        let penetration = tr.penetration()[last];
        let mut next = self.sim.state();
        next.remove(0);
        Ok(Eval {
            next,
            y,
            reference_normal,
            penetration,
        })
    }

    /// (Φ, y) at (x + δx, drive + δu) for δ = (δx, δu) stacked, as one vector.
    fn eval_shifted(&mut self, x: &[f64], force: f64, delta: &[f64]) -> AnalysisResult<Vec<f64>> {
        let n = x.len();
        let shifted: Vec<f64> = x.iter().zip(delta).map(|(x, d)| x + d).collect();
        let saved = self.drive;
        for (j, d) in delta[n..].iter().enumerate() {
            self.drive.set(j, saved.get(j) + d);
        }
        let e = self.eval(&shifted, force);
        self.drive = saved;
        let e = e?;
        Ok(e.next.into_iter().chain(e.y).collect())
    }

    /// The second derivatives of (Φ, y) in (x, u) (u the [`Drive`] inputs): one symmetric
    /// matrix per row of Φ then of y, by central second differences with step `rel` × the
    /// entry's scale (as [`Self::input_columns`]).
    fn curvature(&mut self, x: &[f64], force: f64, rel: f64) -> AnalysisResult<Vec<DMatrix<f64>>> {
        let n = x.len();
        let dim = n + Drive::<N>::COUNT;
        let rows = n + 4;
        let steps: Vec<f64> = (0..dim)
            .map(|i| {
                let v = if i < n { x[i] } else { self.drive.get(i - n) };
                rel * v.abs().max(1.0)
            })
            .collect();
        let mut out = vec![DMatrix::zeros(dim, dim); rows];
        let center = self.eval_shifted(x, force, &vec![0.0; dim])?;
        let mut delta = vec![0.0; dim];
        for i in 0..dim {
            for j in i..dim {
                let mut at = |si: f64, sj: f64, this: &mut Self| {
                    delta.iter_mut().for_each(|d| *d = 0.0);
                    delta[i] += si * steps[i];
                    delta[j] += sj * steps[j];
                    this.eval_shifted(x, force, &delta)
                };
                let second: Vec<f64> = if i == j {
                    let (p, m) = (at(0.5, 0.5, self)?, at(-0.5, -0.5, self)?);
                    let h2 = steps[i] * steps[i];
                    (0..rows)
                        .map(|r| (p[r] - 2.0 * center[r] + m[r]) / h2)
                        .collect()
                } else {
                    let (pp, pm) = (at(1.0, 1.0, self)?, at(1.0, -1.0, self)?);
                    let (mp, mm) = (at(-1.0, 1.0, self)?, at(-1.0, -1.0, self)?);
                    let h2 = 4.0 * steps[i] * steps[j];
                    (0..rows)
                        .map(|r| (pp[r] - pm[r] - mp[r] + mm[r]) / h2)
                        .collect()
                };
                for (r, v) in second.into_iter().enumerate() {
                    out[r][(i, j)] = v;
                    out[r][(j, i)] = v;
                }
            }
        }
        Ok(out)
    }

    /// The columns of Φ and y for the [`Drive`] inputs at (x, f_d): five-point differences
    /// with step `rel` × the input's scale (the motion's: 1 m, 1 m/s, 1 m/s²; a torque's:
    /// 1 N·m).
    fn input_columns(
        &mut self,
        x: &[f64],
        force: f64,
        rel: f64,
    ) -> AnalysisResult<(DMatrix<f64>, DMatrix<f64>)> {
        let n = x.len();
        let m = Drive::<N>::COUNT;
        let mut b = DMatrix::zeros(n, m);
        let mut d = DMatrix::zeros(4, m);
        for j in 0..m {
            let v0 = self.drive.get(j);
            let h = rel * v0.abs().max(1.0);
            let at = |off: f64, this: &mut Self| {
                this.drive.set(j, v0 + off);
                let e = this.eval(x, force);
                this.drive.set(j, v0);
                e
            };
            let (p1, m1) = (at(h, self)?, at(-h, self)?);
            let (p2, m2) = (at(2.0 * h, self)?, at(-2.0 * h, self)?);
            let f = |a: f64, b: f64, c: f64, d: f64| (8.0 * (a - b) - (c - d)) / (12.0 * h);
            for i in 0..n {
                b[(i, j)] = f(p1.next[i], m1.next[i], p2.next[i], m2.next[i]);
            }
            for i in 0..4 {
                d[(i, j)] = f(p1.y[i], m1.y[i], p2.y[i], m2.y[i]);
            }
        }
        Ok((b, d))
    }

    /// Jacobians [A B; C D] at (x, f_d): central (`five = false`) or five-point differences.
    #[allow(clippy::type_complexity)]
    fn jacobian(
        &mut self,
        x: &[f64],
        force: f64,
        rel: f64,
        five: bool,
    ) -> AnalysisResult<(DMatrix<f64>, DVector<f64>, DMatrix<f64>, DVector<f64>)> {
        let n = x.len();
        let mut a = DMatrix::zeros(n, n);
        let mut b = DVector::zeros(n);
        let mut c = DMatrix::zeros(4, n);
        let mut d = DVector::zeros(4);
        let mut xp = x.to_vec();
        for j in 0..=n {
            let (v0, scale) = if j < n {
                (x[j], x[j].abs().max(1.0))
            } else {
                (force, force.abs().max(1.0))
            };
            let h = rel * scale;
            let mut at = |off: f64, this: &mut Self| -> AnalysisResult<Eval> {
                if j < n {
                    xp[j] = v0 + off;
                    let e = this.eval(&xp, force);
                    xp[j] = v0;
                    e
                } else {
                    this.eval(x, v0 + off)
                }
            };
            let (col, ycol): (Vec<f64>, [f64; 4]) = if five {
                let p1 = at(h, self)?;
                let m1 = at(-h, self)?;
                let p2 = at(2.0 * h, self)?;
                let m2 = at(-2.0 * h, self)?;
                let f = |a: f64, b: f64, c: f64, d: f64| (8.0 * (a - b) - (c - d)) / (12.0 * h);
                (
                    (0..n)
                        .map(|i| f(p1.next[i], m1.next[i], p2.next[i], m2.next[i]))
                        .collect(),
                    [0, 1, 2, 3].map(|i| f(p1.y[i], m1.y[i], p2.y[i], m2.y[i])),
                )
            } else {
                let p1 = at(h, self)?;
                let m1 = at(-h, self)?;
                (
                    (0..n)
                        .map(|i| (p1.next[i] - m1.next[i]) / (2.0 * h))
                        .collect(),
                    [0, 1, 2, 3].map(|i| (p1.y[i] - m1.y[i]) / (2.0 * h)),
                )
            };
            if j < n {
                a.set_column(j, &DVector::from_vec(col));
                c.set_column(j, &nalgebra::Vector4::from(ycol));
            } else {
                b = DVector::from_vec(col);
                d = DVector::from_row_slice(&ycol);
            }
        }
        Ok((a, b, c, d))
    }
}

fn residual_norm(r: &[f64], x: &[f64]) -> f64 {
    r.iter()
        .zip(x)
        .map(|(r, x)| r.abs() / x.abs().max(1.0))
        .fold(0.0, f64::max)
}

/// Caveats that hold for every linearisation of `config`, plus those found at x*.
fn caveats(config: &ScenarioConfig, lin: &Linearization) -> Vec<String> {
    let mut out = vec![
        "contact is assumed kept: the clamp of the wall force at zero penetration is not \
         differentiable and is not in the model"
            .to_owned(),
        "smoothed Coulomb friction tanh(q̇/ε) linearises to its slope (coulomb/ε) at q̇ = 0"
            .to_owned(),
        "f_d is held at its final value and the motion reference frozen at s(0)".to_owned(),
    ];
    if config.sensor.noise_std > 0.0 {
        out.push("sensor noise is off in the linear model".to_owned());
    }
    if let Some(a) = &config.approach {
        out.push(format!(
            "the contact phase is linearised: the guarded approach is assumed to have \
             switched to force control (bumplessly, X_d and Ẋ_d continuous){}; the impact \
             itself (approach speed, threshold, sensor lag) is not in the linear model",
            if a.reanchor {
                ", with the estimate re-anchored at the contact point (for Scheme 2 this \
                 moves x_a, not the force loop)"
            } else {
                ""
            }
        ));
    }
    if config.sensor.resolution > 0.0 {
        out.push(
            "sensor resolution is not modelled (rounding is not differentiable; treat it \
             as quantisation noise)"
                .to_owned(),
        );
    }
    if let Some(limit) = &config.actuator.torque_limit {
        let applied: Vec<f64> = lin
            .labels
            .iter()
            .zip(&lin.state)
            .filter(|(l, _)| l.starts_with("actuator.applied"))
            .map(|(_, v)| *v)
            .collect();
        let at_limit = applied.iter().enumerate().any(|(j, t)| {
            let l = if limit.len() == 1 { limit[0] } else { limit[j] };
            t.abs() >= l
        });
        out.push(if at_limit {
            "a joint torque is saturated at the equilibrium: the linear model holds it \
             constant there (zero gain), valid only while it stays saturated"
                .to_owned()
        } else {
            "torque saturation is inactive at the operating point (the limits are not in \
             the linear model)"
                .to_owned()
        });
    }
    if config.actuator.rate_limit.is_some() {
        out.push("the torque rate limit is inactive at the equilibrium (Δτ = 0)".to_owned());
    }
    if matches!(config.admittance, Some(ForceControlParams::Impedance(_))) {
        out.push("the impedance reference (eq. 20) has no filter state".to_owned());
    }
    out
}

/// Newton on Φ(x) = x from `start`, with halved steps when the residual grows. Returns the
/// fixed point and the iterations used.
fn newton<R: RobotModel<N>, const N: usize>(
    map: &mut Map<'_, R, N>,
    start: Vec<f64>,
    force: f64,
) -> AnalysisResult<(Vec<f64>, usize)> {
    let mut x = start;
    let mut iterations = 0;
    let mut e = map.eval(&x, force)?;
    let mut r: Vec<f64> = e.next.iter().zip(&x).map(|(n, x)| n - x).collect();
    let mut norm = residual_norm(&r, &x);
    // Chord iterations: the Jacobian is kept while each step at least halves the residual
    // (the map is nearly linear in contact), and recomputed at the current point otherwise.
    let mut lu: Option<nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>> = None;
    while norm > NEWTON_TOL {
        if iterations == NEWTON_MAX {
            return Err(AnalysisError::NoEquilibrium(format!(
                "Newton did not converge in {NEWTON_MAX} iterations (residual {norm:.3e}, \
                 force {} N, penetration {:.3e} m)",
                approx(e.y[0]),
                e.penetration
            )));
        }
        iterations += 1;
        let n = x.len();
        let fresh = lu.is_none();
        if fresh {
            let (a, ..) = map.jacobian(&x, force, NEWTON_STEP, false)?;
            lu = Some((a - DMatrix::<f64>::identity(n, n)).lu());
        }
        let solved = lu
            .as_ref()
            .and_then(|lu| lu.solve(&DVector::from_iterator(n, r.iter().map(|v| -v))));
        let Some(dx) = solved else {
            return Err(if e.penetration > 0.0 {
                AnalysisError::Singular(
                    "I − A is singular (an integrator without feedback, e.g. \
                     admittance.ka = 0?)"
                        .into(),
                )
            } else {
                AnalysisError::NoEquilibrium(format!(
                    "the tip is off the wall (penetration {:.3e} m): is the wall within \
                     reach and f_d > 0?",
                    e.penetration
                ))
            });
        };
        if !fresh {
            // A chord step that does not halve the residual: retry with a new Jacobian.
            let trial: Vec<f64> = x.iter().zip(dx.iter()).map(|(x, d)| x + d).collect();
            if let Ok(te) = map.eval(&trial, force) {
                let tr: Vec<f64> = te.next.iter().zip(&trial).map(|(n, x)| n - x).collect();
                let tn = residual_norm(&tr, &trial);
                if tn <= 0.5 * norm {
                    x = trial;
                    e = te;
                    r = tr;
                    norm = tn;
                    continue;
                }
            }
            lu = None;
            iterations -= 1;
            continue;
        }
        // Damped step: halve until the residual falls.
        let mut alpha = 1.0;
        loop {
            let trial: Vec<f64> = x
                .iter()
                .zip(dx.iter())
                .map(|(x, d)| x + alpha * d)
                .collect();
            let te = map.eval(&trial, force);
            if let Ok(te) = te {
                let tr: Vec<f64> = te.next.iter().zip(&trial).map(|(n, x)| n - x).collect();
                let tn = residual_norm(&tr, &trial);
                if tn < norm || alpha < 1e-3 {
                    x = trial;
                    e = te;
                    r = tr;
                    norm = tn;
                    break;
                }
            } else if alpha < 1e-3 {
                return Err(te.err().unwrap_or_else(|| {
                    AnalysisError::NoEquilibrium("Newton left the valid region".into())
                }));
            }
            alpha *= 0.5;
        }
    }
    if !(e.y[0] > 0.0 && e.penetration > 0.0) {
        return Err(AnalysisError::NoEquilibrium(format!(
            "the fixed point has no contact (force {} N, penetration {:.3e} m): is \
             the wall within reach and f_d > 0?",
            approx(e.y[0]),
            e.penetration
        )));
    }
    Ok((x, iterations))
}

/// Linearises `config` about its steady contact equilibrium (`at = None`) or about the
/// state of the run at time `at`. `build` makes the pipeline for the scenario's arm.
pub fn linearize<R, const N: usize>(
    config: &ScenarioConfig,
    at: Option<f64>,
    build: impl Fn(&ScenarioConfig) -> crate::error::Result<Simulation<R, N>>,
) -> AnalysisResult<Linearization>
where
    R: RobotModel<N>,
{
    linearize_with(config, at, build, false)
}

/// [`linearize`] with [`Linearization::drive`]: the columns of the motion reference and of
/// a joint torque disturbance, for the forced response (SPEC §23).
pub fn linearize_driven<R, const N: usize>(
    config: &ScenarioConfig,
    at: Option<f64>,
    build: impl Fn(&ScenarioConfig) -> crate::error::Result<Simulation<R, N>>,
) -> AnalysisResult<Linearization>
where
    R: RobotModel<N>,
{
    linearize_with(config, at, build, true)
}

fn linearize_with<R, const N: usize>(
    config: &ScenarioConfig,
    at: Option<f64>,
    build: impl Fn(&ScenarioConfig) -> crate::error::Result<Simulation<R, N>>,
    driven: bool,
) -> AnalysisResult<Linearization>
where
    R: RobotModel<N>,
{
    let (fz, force) = frozen(config, at)?;
    let mut sim = build(&fz)?;
    let labels: Vec<String> = sim.state_labels().into_iter().skip(1).collect();
    let (starts, equilibrium) = match at {
        Some(t) => {
            if !(t.is_finite() && t >= 0.0 && t <= config.duration) {
                return Err(Error::parameter(
                    "at",
                    t,
                    &format!("a time from 0 to the duration {} s", short(config.duration)),
                )
                .into());
            }
            let mut run = build(config)?;
            let k = (t / config.period).round() as usize;
            if let Some(Outcome::Diverged { time, cause }) = run.step(k) {
                return Err(AnalysisError::NoEquilibrium(format!(
                    "the run diverges at t = {time} s ({cause}), before `at`"
                )));
            }
            (vec![run.state()[1..].to_vec()], false)
        }
        None => {
            // Newton from a short settling run, or from the initial state if that fails. A
            // run that starts apart first crosses its free space: the contact phase is what
            // is linearised.
            if starts_apart(config) {
                let most = (MAX_APPROACH / config.period) as usize;
                for _ in 0..most {
                    let touching = sim.trace().f().last().is_some_and(|&f| f > 0.0);
                    if touching || sim.step(1).is_some() {
                        break;
                    }
                }
            }
            sim.step(SETTLE_SAMPLES);
            let settled = sim.state()[1..].to_vec();
            let ok = sim.outcome().is_none() && settled.iter().all(|v| v.is_finite());
            sim.reset();
            let initial = sim.state()[1..].to_vec();
            (
                if ok {
                    vec![settled, initial]
                } else {
                    vec![initial]
                },
                true,
            )
        }
    };
    let s0 = config.z_reference.at(at.unwrap_or(0.0)).value;
    let mut map = Map::new(&mut sim, s0);
    let mut x = Vec::new();
    let mut iterations = 0;
    if equilibrium {
        let mut first = None;
        let mut found = false;
        for start in starts {
            match newton(&mut map, start, force) {
                Ok((xs, it)) => {
                    x = xs;
                    iterations = it;
                    found = true;
                    break;
                }
                // The first start's error is the telling one (the settled state).
                Err(e) => {
                    if first.is_none() {
                        first = Some(e);
                    }
                }
            }
        }
        if !found {
            return Err(
                first.unwrap_or_else(|| AnalysisError::NoEquilibrium("no start for Newton".into()))
            );
        }
    } else {
        x = starts.into_iter().next().unwrap_or_default();
    }
    let e0 = map.eval(&x, force)?;
    // Keep every evaluation in contact: the tip moves about h per unit of q.
    let mut rel = STEP;
    if e0.penetration > 0.0 {
        rel = rel.min(e0.penetration / 8.0);
    }
    let (a, b, c4, d4) = map.jacobian(&x, force, rel, true)?;
    let drive = if driven {
        let (b, d4) = map.input_columns(&x, force, rel)?;
        // Second differences need a larger step than first ones (round-off ε/h²), still
        // within the penetration.
        let curvature = map.curvature(&x, force, CURVATURE_STEP.min(2.0 * rel))?;
        Some(DriveColumns {
            b,
            d: d4.rows(0, 3).into_owned(),
            c_measured: d4.row(3).transpose(),
            labels: input_labels(N),
            curvature,
        })
    } else {
        None
    };
    let c_measured = c4.row(3).transpose();
    let (c, d) = (c4.rows(0, 3).into_owned(), d4.rows(0, 3).into_owned());
    if equilibrium {
        // Scale-free: the pole nearest 1 (rows of A differ by orders of magnitude).
        let gap = a
            .complex_eigenvalues()
            .iter()
            .map(|l| (l - nalgebra::Complex::new(1.0, 0.0)).norm())
            .fold(f64::INFINITY, f64::min);
        if gap < 1e-9 {
            return Err(AnalysisError::Singular(format!(
                "A has a pole at 1 (|λ − 1| = {gap:.1e}): the equilibrium is not isolated, \
                 e.g. a free integrator such as admittance.ka = 0 in Scheme 2"
            )));
        }
    }
    let mut lin = Linearization {
        a,
        b,
        c,
        d,
        c_measured,
        labels,
        state: x,
        force_desired: force,
        outputs: [e0.y[0], e0.y[1], e0.y[2]],
        reference_normal: e0.reference_normal,
        penetration: e0.penetration,
        period: config.period,
        equilibrium,
        iterations,
        caveats: Vec::new(),
        drive,
    };
    lin.caveats = caveats(config, &lin);
    Ok(lin)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::control::filter::AdmittanceParams;
    use crate::sim::simulation::ThreeLinkSimulation;
    use crate::world::environment::WallParams;

    fn fig14() -> ScenarioConfig {
        ScenarioConfig::default()
    }

    fn lin(config: &ScenarioConfig) -> AnalysisResult<Linearization> {
        linearize(config, None, ThreeLinkSimulation::new)
    }

    fn index(l: &Linearization, label: &str) -> usize {
        l.labels.iter().position(|x| x == label).unwrap()
    }

    #[test]
    fn fig14_equilibrium_is_a_fixed_point_in_contact() {
        let l = lin(&fig14()).unwrap();
        assert!(l.equilibrium);
        assert!((l.outputs[0] - 10.0).abs() < 1e-8, "{:?}", l.outputs);
        assert!((l.penetration - 10.0 / 30_000.0).abs() < 1e-10);
        assert_eq!(l.a.nrows(), l.labels.len());
        assert!(l.labels[0] == "plant.q1" && l.labels.iter().all(|s| s != "sample"));
        // Velocities vanish at rest.
        for j in 1..=3 {
            assert!(l.state[index(&l, &format!("plant.qd{j}"))].abs() < 1e-9);
        }
    }

    /// The filter rows of A and B are the exact ZOH pair: Φ is linear in them, so the
    /// differences must reproduce `discretize` to round-off (≤ 1e-9 relative); and the
    /// whole Jacobian agrees with itself at half the step (Richardson) to ≤ 1e-7 of its
    /// largest entry.
    #[test]
    fn jacobian_is_accurate() {
        let cfg = fig14();
        let l = lin(&cfg).unwrap();
        let Some(ForceControlParams::Admittance(p)) = &cfg.admittance else {
            unreachable!()
        };
        let (ad, bd) = p.discretize(cfg.period);
        let (i, j) = (index(&l, "filter.x_a"), index(&l, "filter.xa_dot"));
        for (r, row) in [i, j].into_iter().enumerate() {
            for (c, col) in [i, j].into_iter().enumerate() {
                let err = (l.a[(row, col)] - ad[(r, c)]).abs();
                assert!(err <= 1e-9 * ad.abs().max(), "A[{r},{c}] off by {err}");
            }
            assert!((l.b[row] - bd[r]).abs() <= 1e-9 * bd.abs().max());
        }
        // The measured force enters the filter with −B_d: ∂x_a'/∂(sensor) through f.
        let mut sim = ThreeLinkSimulation::new(&frozen(&cfg, None).unwrap().0).unwrap();
        let mut map = Map::new(&mut sim, 0.0);
        let (a2, b2, c2, _) = map.jacobian(&l.state, 10.0, STEP / 2.0, true).unwrap();
        let scale = l.a.abs().max();
        let diff = (&a2 - &l.a).abs().max();
        assert!(diff <= 1e-7 * scale, "Richardson: {diff:e} of {scale:e}");
        assert!((&b2 - &l.b).abs().max() <= 1e-7 * l.b.abs().max());
        assert!((c2.rows(0, 3) - &l.c).abs().max() <= 1e-7 * l.c.abs().max());
        // Without a sensor model the measured force is the true one.
        assert!((c2.row(3) - l.c.row(0)).abs().max() <= 1e-7 * l.c.abs().max());
    }

    /// A torque δτ held over one period moves q̇ by T M(q*)⁻¹ δτ and q by T²/2 M⁻¹ δτ (up
    /// to the contact's and viscous friction's action within the period: under 1 % here,
    /// without Coulomb friction, whose slope at rest c/ε would act too); the true force at
    /// a sample depends on the state only, not on the inputs of its period.
    #[test]
    fn torque_columns_are_the_inverse_inertia() {
        use crate::robot::ThreeLinkArm;
        let mut cfg = fig14();
        let crate::sim::scenario::RobotConfig::ThreeLink(p) = &mut cfg.robot else {
            unreachable!()
        };
        p.coulomb_friction = [0.0; 3];
        let params = p.clone();
        let l = linearize_driven(&cfg, None, ThreeLinkSimulation::new).unwrap();
        let drive = l.drive.as_ref().unwrap();
        assert_eq!(
            drive.labels,
            ["s", "s_rate", "s_accel", "torque1", "torque2", "torque3"]
        );
        let q = nalgebra::Vector3::from_fn(|i, _| l.state[index(&l, &format!("plant.q{}", i + 1))]);
        let (_, dynamics) = ThreeLinkArm::new(&params).evaluate(&q, &nalgebra::Vector3::zeros());
        let m_inv = dynamics.inertia.try_inverse().unwrap();
        let t = cfg.period;
        for i in 0..3 {
            let (qi, qdi) = (
                index(&l, &format!("plant.q{}", i + 1)),
                index(&l, &format!("plant.qd{}", i + 1)),
            );
            for j in 0..3 {
                let (speed, angle) = (drive.b[(qdi, 3 + j)], drive.b[(qi, 3 + j)]);
                let scale = m_inv.abs().max();
                assert!(
                    (speed - t * m_inv[(i, j)]).abs() <= 0.01 * t * scale,
                    "q̇{i} per τ{j}: {speed:e}, T M⁻¹ = {:e}",
                    t * m_inv[(i, j)]
                );
                assert!((angle - 0.5 * t * t * m_inv[(i, j)]).abs() <= 0.01 * t * t * scale);
            }
        }
        for j in 0..6 {
            assert!(drive.d[(0, j)].abs() < 1e-9, "f depends on input {j}");
        }
        // The motion reference moves the arm through the controller: the next q̇ answers.
        let qd2 = index(&l, "plant.qd2");
        assert!(drive.b[(qd2, 0)].abs() > 1e-3, "{}", drive.b[(qd2, 0)]);
    }

    /// Eqs. (26), (28) with k_a: f(∞) = f_d k_a k_e / (k + k_a k_e), penetration f/k_e.
    #[test]
    fn scheme1_ideal_steady_state() {
        let l = lin(&ScenarioConfig::ideal_inner_loop(
            AdmittanceParams::scheme1(800.0, 400.0, 0.1),
        ))
        .unwrap();
        let r = 0.1 * 30_000.0 / 400.0;
        let f = 10.0 * r / (1.0 + r);
        assert!((l.outputs[0] - f).abs() < 1e-6 * f, "{}", l.outputs[0]);
        assert!((l.penetration - f / 30_000.0).abs() < 1e-9);
    }

    #[test]
    fn bad_scenarios_are_clear_errors() {
        // The wall out of reach.
        let far = ScenarioConfig {
            wall: Some(
                WallParams {
                    position: Some(2.0),
                    ..Default::default()
                }
                .into(),
            ),
            ..fig14()
        };
        let e = lin(&far).unwrap_err();
        assert!(matches!(e, AnalysisError::NoEquilibrium(_)), "{e}");
        // k_a = 0: x_a is a free integrator.
        // (pressing through a wall estimate 1 mm deep, so that there is contact).
        let e = lin(&ScenarioConfig {
            wall: Some(
                WallParams {
                    position_error: 1e-3,
                    ..Default::default()
                }
                .into(),
            ),
            ..ScenarioConfig::ideal_inner_loop(AdmittanceParams::scheme2(800.0, 0.0))
        })
        .unwrap_err();
        assert!(matches!(e, AnalysisError::Singular(_)), "{e}");
        // No wall.
        let e = lin(&ScenarioConfig {
            wall: None,
            ..fig14()
        })
        .unwrap_err();
        assert!(e.to_string().contains("no wall"), "{e}");
    }

    /// A run that starts 3 mm apart (SPEC §16) is linearised in its contact phase: the
    /// fixed point presses the shifted wall with f_d, 3 mm further along n (3e4 N/m: the
    /// same 0.33 mm penetration), and a guarded approach changes nothing there.
    #[test]
    fn a_gap_and_an_approach_linearise_the_contact_phase() {
        use crate::control::approach::ApproachParams;
        let apart = ScenarioConfig {
            wall: Some(
                WallParams {
                    gap: 0.003,
                    ..WallParams::default()
                }
                .into(),
            ),
            ..fig14()
        };
        let l = lin(&apart).unwrap();
        let touching = lin(&fig14()).unwrap();
        assert!((l.outputs[0] - 10.0).abs() < 1e-6, "{:?}", l.outputs);
        assert!(
            (l.penetration - 10.0 / 3e4).abs() < 1e-8,
            "{}",
            l.penetration
        );
        assert!((l.outputs[1] - touching.outputs[1] - 0.003).abs() < 1e-8);
        let guarded = lin(&ScenarioConfig {
            approach: Some(ApproachParams::default()),
            ..apart.clone()
        })
        .unwrap();
        assert_eq!(guarded.a, l.a);
        assert!(guarded
            .caveats
            .iter()
            .any(|c| c.contains("guarded approach")));
    }

    #[test]
    fn at_a_time_linearises_the_running_state() {
        let l = linearize(&fig14(), Some(0.5), ThreeLinkSimulation::new).unwrap();
        assert!(!l.equilibrium && l.iterations == 0);
        assert!(l.outputs[0] > 0.0);
    }
}
