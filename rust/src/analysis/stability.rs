//! What the linear model predicts (SPEC §12): poles, steady state and the step response's
//! metrics in the definitions of SPEC §7, and many predictions in parallel for maps.

use nalgebra::{Complex, DMatrix, DVector};
use rayon::prelude::*;

use crate::analysis::linearize::{linearize, AnalysisError, AnalysisResult, Linearization};
use crate::robot::RobotModel;
use crate::sim::simulation::{ScenarioConfig, Simulation};

/// Predicted behaviour of one scenario.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// f_d − f at the equilibrium [N].
    pub force_ss_error: f64,
    /// n·X_d − n·X at the equilibrium [m] (what `x_rms_error` measures, in steady state).
    pub x_ss_error: f64,
    /// From the linear step response f = f_d s(t) (SPEC §7 definitions); NaN if unstable.
    pub overshoot_pct: f64,
    pub rise_time_63: f64,
    pub settling_time: f64,
    /// max |eig(A)|.
    pub spectral_radius: f64,
    /// |arg λ| / (2π T) of the pole of largest modulus [Hz].
    pub dominant_frequency: f64,
    /// ζ = −Re(s)/|s|, s = ln(λ)/T, of that pole.
    pub dominant_damping: f64,
    /// ρ < 1.
    pub stable: bool,
    /// Largest |q̇_j| of the linear response to the whole step 0 → f_d in its first
    /// `PEAK_WINDOW` [rad/s] (the amplitude for a describing-function friction gain).
    pub peak_joint_speed: f64,
    /// Margins of the force loop ([`loop_margins`]).
    pub gain_margin: f64,
    /// [deg].
    pub phase_margin: f64,
    /// [samples].
    pub delay_margin: f64,
}

/// Window of `peak_joint_speed` [s]: the transient of a step, not a slow divergence.
pub const PEAK_WINDOW: f64 = 0.5;

/// Field names of `Prediction`, in the order of `values`.
pub const PREDICTION_NAMES: [&str; 13] = [
    "force_ss_error",
    "x_ss_error",
    "overshoot_pct",
    "rise_time_63",
    "settling_time",
    "spectral_radius",
    "dominant_frequency",
    "dominant_damping",
    "stable",
    "peak_joint_speed",
    "gain_margin",
    "phase_margin",
    "delay_margin",
];

impl Prediction {
    /// The fields as numbers (`stable` as 0/1), in `PREDICTION_NAMES` order.
    pub fn values(&self) -> [f64; 13] {
        [
            self.force_ss_error,
            self.x_ss_error,
            self.overshoot_pct,
            self.rise_time_63,
            self.settling_time,
            self.spectral_radius,
            self.dominant_frequency,
            self.dominant_damping,
            if self.stable { 1.0 } else { 0.0 },
            self.peak_joint_speed,
            self.gain_margin,
            self.phase_margin,
            self.delay_margin,
        ]
    }

    /// A cell with no prediction (no equilibrium): NaN everywhere, not stable.
    pub fn missing() -> Self {
        Self {
            force_ss_error: f64::NAN,
            x_ss_error: f64::NAN,
            overshoot_pct: f64::NAN,
            rise_time_63: f64::NAN,
            settling_time: f64::NAN,
            spectral_radius: f64::NAN,
            dominant_frequency: f64::NAN,
            dominant_damping: f64::NAN,
            stable: false,
            peak_joint_speed: f64::NAN,
            gain_margin: f64::NAN,
            phase_margin: f64::NAN,
            delay_margin: f64::NAN,
        }
    }
}

/// The pole of largest modulus: (ρ, frequency [Hz], damping ratio).
pub fn dominant_pole(a: &DMatrix<f64>, period: f64) -> (f64, f64, f64) {
    dominant_of(a.complex_eigenvalues().as_slice(), period)
}

/// [`dominant_pole`] of eigenvalues already computed.
fn dominant_of(eig: &[Complex<f64>], period: f64) -> (f64, f64, f64) {
    let Some(l) = eig
        .iter()
        .copied()
        .max_by(|x, y| x.norm().total_cmp(&y.norm()))
    else {
        return (0.0, 0.0, 1.0);
    };
    let rho = l.norm();
    let s = l.ln() / period;
    let freq = s.im.abs() / (2.0 * std::f64::consts::PI);
    let damping = if s.norm() > 0.0 {
        -s.re / s.norm()
    } else {
        1.0
    };
    (rho, freq, damping)
}

/// Stability margins of the force loop, in python-control's `stability_margins`
/// conventions (frequencies as θ = ωT in rad per sample).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopMargins {
    /// 1/|L| where L crosses the negative real axis (the smallest; inf if it never does).
    pub gain: f64,
    /// 180° + arg L at the gain crossovers |L| = 1, the smallest, wrapped to (−180°, 180°]
    /// (inf without a crossover) [deg].
    pub phase: f64,
    /// The smallest phase margin / θ over the crossovers: the extra loop delay that
    /// destabilises [samples] (0 when a phase margin is ≤ 0).
    pub delay: f64,
}

/// The open loop L(z) = cᵀ (zI − A₀)⁻¹ b in an orthogonal basis Q where A₀ = Q M Qᵀ and M
/// is quasi upper triangular (the real Schur form: 1×1 and 2×2 blocks on the diagonal), or
/// only upper Hessenberg where the Schur iteration does not converge. Each L(z) is then
/// one back substitution, O(n²/2) real-by-complex products and no pivoting, instead of an
/// elimination; a map evaluates it about a thousand times per cell.
struct OpenLoop {
    n: usize,
    /// M row by row.
    m: Vec<f64>,
    /// Qᵀb and Qᵀc.
    b: Vec<f64>,
    c: Vec<f64>,
    /// The diagonal blocks' first rows and sizes (1 or 2); empty: M is only Hessenberg.
    blocks: Vec<(usize, usize)>,
    /// Scratch for the solution and, on the Hessenberg path, the eliminated matrix.
    x: Vec<Complex<f64>>,
    work: Vec<Complex<f64>>,
}

impl OpenLoop {
    /// L for `a0`, `b`, `c`; also the eigenvalues of `a0`. `schur`: false takes the
    /// Hessenberg path even where the Schur form exists.
    fn new(
        a0: DMatrix<f64>,
        b: &DVector<f64>,
        c: &DVector<f64>,
        schur: bool,
    ) -> (Self, Vec<Complex<f64>>) {
        let n = a0.nrows();
        let form = if schur {
            a0.clone().try_schur(f64::EPSILON, 30 * n.max(10))
        } else {
            None
        };
        let (q, m, blocks, eig) = match form {
            Some(schur) => {
                let eig = schur.complex_eigenvalues().iter().copied().collect();
                let (q, t) = schur.unpack();
                let blocks = diagonal_blocks(&t);
                (q, t, blocks, eig)
            }
            None => {
                let eig = a0.complex_eigenvalues().iter().copied().collect();
                let (q, h) = a0.hessenberg().unpack();
                (q, h, Vec::new(), eig)
            }
        };
        let row_major = (0..n * n).map(|k| m[(k / n, k % n)]).collect();
        let loop_ = Self {
            n,
            m: row_major,
            b: (q.transpose() * b).iter().copied().collect(),
            c: (q.transpose() * c).iter().copied().collect(),
            blocks,
            x: vec![Complex::new(0.0, 0.0); n],
            work: Vec::new(),
        };
        (loop_, eig)
    }

    /// L(e^{iθ}).
    fn at(&mut self, theta: f64) -> Complex<f64> {
        let z = Complex::from_polar(1.0, theta);
        if self.blocks.is_empty() {
            self.hessenberg_solve(z);
        } else {
            self.schur_solve(z);
        }
        self.c.iter().zip(&self.x).map(|(c, x)| x * *c).sum()
    }

    /// (zI − M) x = Qᵀb by back substitution over the diagonal blocks, bottom up.
    fn schur_solve(&mut self, z: Complex<f64>) {
        let n = self.n;
        let m = &self.m;
        for &(i, size) in self.blocks.iter().rev() {
            let tail = i + size;
            let rhs = |r: usize, x: &[Complex<f64>]| -> Complex<f64> {
                let row = &m[r * n + tail..(r + 1) * n];
                row.iter()
                    .zip(&x[tail..])
                    .fold(Complex::new(self.b[r], 0.0), |acc, (t, x)| acc + x * *t)
            };
            if size == 1 {
                let r = rhs(i, &self.x);
                self.x[i] = r / (z - m[i * n + i]);
            } else {
                // [[z − p, −q], [−s, z − u]] (x_i, x_i+1) = (r1, r2), by Cramer's rule.
                let (r1, r2) = (rhs(i, &self.x), rhs(i + 1, &self.x));
                let (p, q) = (m[i * n + i], m[i * n + i + 1]);
                let (s, u) = (m[(i + 1) * n + i], m[(i + 1) * n + i + 1]);
                let det = (z - p) * (z - u) - q * s;
                self.x[i] = ((z - u) * r1 + r2 * q) / det;
                self.x[i + 1] = (r1 * s + (z - p) * r2) / det;
            }
        }
    }

    /// (zI − H) x = Qᵀb for an upper Hessenberg H, by Gaussian elimination with pivoting
    /// between neighbouring rows: O(n²).
    fn hessenberg_solve(&mut self, z: Complex<f64>) {
        let n = self.n;
        let w = &mut self.work;
        w.clear();
        w.extend(self.m.iter().enumerate().map(|(k, h)| {
            let v = Complex::new(-h, 0.0);
            if k / n == k % n {
                v + z
            } else {
                v
            }
        }));
        let x = &mut self.x;
        for (xi, b) in x.iter_mut().zip(&self.b) {
            *xi = Complex::new(*b, 0.0);
        }
        for k in 0..n.saturating_sub(1) {
            if w[(k + 1) * n + k].norm() > w[k * n + k].norm() {
                for j in k..n {
                    w.swap(k * n + j, (k + 1) * n + j);
                }
                x.swap(k, k + 1);
            }
            let pivot = w[k * n + k];
            if pivot.norm() == 0.0 {
                continue;
            }
            let l = w[(k + 1) * n + k] / pivot;
            for j in k..n {
                let v = w[k * n + j];
                w[(k + 1) * n + j] -= l * v;
            }
            let v = x[k];
            x[k + 1] -= l * v;
        }
        for i in (0..n).rev() {
            let mut acc = x[i];
            for j in i + 1..n {
                acc -= w[i * n + j] * x[j];
            }
            x[i] = acc / w[i * n + i];
        }
    }
}

/// The diagonal blocks of a real Schur form `t`: (first row, 1 or 2); empty if two
/// subdiagonal entries in a row are nonzero (then `t` is not quasi-triangular).
fn diagonal_blocks(t: &DMatrix<f64>) -> Vec<(usize, usize)> {
    let n = t.nrows();
    let mut blocks = Vec::with_capacity(n);
    let mut i = 0;
    while i < n {
        if i + 1 < n && t[(i + 1, i)] != 0.0 {
            if i + 2 < n && t[(i + 2, i + 1)] != 0.0 {
                return Vec::new();
            }
            blocks.push((i, 2));
            i += 2;
        } else {
            blocks.push((i, 1));
            i += 1;
        }
    }
    blocks
}

/// The force loop cut where the measured force enters the filter (f_d enters only as
/// e_f = f_d − f̃): L(z) = c̃ (zI − A₀)⁻¹ B with A₀ = A + B c̃, so that the closed loop is
/// A = A₀ − B c̃ (negative feedback, python-control's convention). Evaluated on a
/// logarithmic grid of θ = ωT in (0, π] refined around every pole of the open and the
/// closed loop, crossings located by bisection.
pub fn loop_margins(lin: &Linearization) -> LoopMargins {
    loop_margins_with(lin, lin.a.complex_eigenvalues().as_slice())
}

/// [`loop_margins`] with the closed loop's eigenvalues already computed.
fn loop_margins_with(lin: &Linearization, closed: &[Complex<f64>]) -> LoopMargins {
    let c = &lin.c_measured;
    let a0 = &lin.a + &lin.b * c.transpose();
    let (mut open, open_poles) = OpenLoop::new(a0, &lin.b, c, true);
    let pi = std::f64::consts::PI;
    let mut grid: Vec<f64> = (0..=600)
        .map(|i| 1e-5 * (pi / 1e-5).powf(i as f64 / 600.0))
        .collect();
    for l in open_poles.iter().chain(closed) {
        let (r, th) = (l.norm(), l.arg().abs());
        if r > 0.2 && th > 0.0 {
            let w = (1.0 - r).abs().max(1e-7);
            for k in [-8.0, -4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 4.0, 8.0] {
                let t = th + k * w;
                if t > 1e-5 && t < pi {
                    grid.push(t);
                }
            }
        }
    }
    grid.sort_by(f64::total_cmp);
    grid.dedup();
    let values: Vec<Complex<f64>> = grid.iter().map(|&t| open.at(t)).collect();
    // Bisection on a sign change of g between grid points a and b.
    let bisect =
        |open: &mut OpenLoop, mut a: f64, mut b: f64, g: &dyn Fn(Complex<f64>) -> f64| -> f64 {
            let mut ga = g(open.at(a));
            for _ in 0..40 {
                let m = 0.5 * (a + b);
                let gm = g(open.at(m));
                if (gm > 0.0) == (ga > 0.0) {
                    a = m;
                    ga = gm;
                } else {
                    b = m;
                }
            }
            0.5 * (a + b)
        };
    let magnitude = |l: Complex<f64>| l.norm().ln();
    let imaginary = |l: Complex<f64>| l.im;
    let (mut gain, mut phase, mut delay) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    for i in 1..grid.len() {
        let (l0, l1) = (values[i - 1], values[i]);
        if !(l0.norm().is_finite() && l1.norm().is_finite()) {
            continue;
        }
        if (magnitude(l0) > 0.0) != (magnitude(l1) > 0.0) {
            let t = bisect(&mut open, grid[i - 1], grid[i], &magnitude);
            let arg = open.at(t).arg() + pi;
            // Wrapped to (−180°, 180°].
            let pm = if arg > pi { arg - 2.0 * pi } else { arg };
            phase = phase.min(pm.to_degrees());
            delay = delay.min(if pm > 0.0 { pm / t } else { 0.0 });
        }
        if (l0.im > 0.0) != (l1.im > 0.0) && (l0.re < 0.0 || l1.re < 0.0) {
            let t = bisect(&mut open, grid[i - 1], grid[i], &imaginary);
            let l = open.at(t);
            if l.re < 0.0 {
                gain = gain.min(1.0 / l.norm());
            }
        }
    }
    // At the Nyquist frequency L is real: a crossing of the negative axis if Re L < 0.
    let nyquist = open.at(pi);
    if nyquist.re < 0.0 {
        gain = gain.min(1.0 / nyquist.norm());
    }
    LoopMargins { gain, phase, delay }
}

/// Response of output `output` (0: f, 1: n·X, 2: t̂·X) to a unit step of δf_d from rest,
/// over `samples` samples (sample 0 is the state before the step acts).
pub fn step_response(lin: &Linearization, output: usize, samples: usize) -> Vec<f64> {
    step_response_with_peak(lin, output, samples, &[], 0).0
}

/// `step_response`, and the largest |x_i| over states `watch` in the first `peak_samples`.
pub fn step_response_with_peak(
    lin: &Linearization,
    output: usize,
    samples: usize,
    watch: &[usize],
    peak_samples: usize,
) -> (Vec<f64>, f64) {
    let n = lin.state.len();
    // A is column-major: next = A x + b accumulates column by column, an axpy down
    // contiguous memory that vectorises over the rows while adding each row's products in
    // the order of a row-by-row dot product (the same bits, a few times faster).
    let a = lin.a.as_slice();
    let c: Vec<f64> = (0..n).map(|j| lin.c[(output, j)]).collect();
    let b = lin.b.as_slice();
    let d = lin.d[output];
    let mut x = vec![0.0; n];
    let mut next = vec![0.0; n];
    let mut out = Vec::with_capacity(samples);
    let mut peak: f64 = 0.0;
    for k in 0..samples.max(peak_samples) {
        if k < samples {
            out.push(c.iter().zip(&x).map(|(c, x)| c * x).sum::<f64>() + d);
        }
        if k < peak_samples {
            peak = watch.iter().fold(peak, |p, &i| p.max(x[i].abs()));
        }
        next.fill(-0.0);
        for (column, xj) in a.chunks_exact(n.max(1)).zip(&x) {
            for (nx, aij) in next.iter_mut().zip(column) {
                *nx += aij * xj;
            }
        }
        for (nx, bi) in next.iter_mut().zip(b) {
            *nx += bi;
        }
        std::mem::swap(&mut x, &mut next);
    }
    (out, peak)
}

/// Step metrics of f = f_d s in SPEC §7's definitions, normalised by f_d:
/// (overshoot %, rise 63 %, 2 % settling) with the time of sample k = k T.
pub fn step_metrics(s: &[f64], period: f64) -> (f64, f64, f64) {
    let peak = s.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let overshoot = 100.0 * (peak - 1.0);
    let rise = s
        .iter()
        .position(|v| *v >= 0.632)
        .map_or(f64::NAN, |k| k as f64 * period);
    let settling = match s.iter().rposition(|v| (v - 1.0).abs() > 0.02) {
        None => 0.0,
        Some(k) if k + 1 < s.len() => (k + 1) as f64 * period,
        Some(_) => f64::NAN,
    };
    (overshoot, rise, settling)
}

/// What a prediction computes: everything, or only what the describing-function friction
/// iteration of a stability map reads between its steps (the poles and the peak joint
/// speed; the margins and the step metrics are NaN), a fraction of the cost.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Extent {
    Full,
    Transient,
}

/// Predicted metrics from a linearisation about the equilibrium; `horizon` caps the step
/// response [samples] (the run's length, like the simulated metrics).
pub fn predict_from(lin: &Linearization, horizon: usize) -> Prediction {
    predict_extent(lin, horizon, Extent::Full)
}

/// [`predict_from`] to the given extent.
pub fn predict_extent(lin: &Linearization, horizon: usize, extent: Extent) -> Prediction {
    let closed = lin.a.complex_eigenvalues();
    let (rho, freq, damping) = dominant_of(closed.as_slice(), lin.period);
    let stable = rho < 1.0;
    let margins = match extent {
        Extent::Full => loop_margins_with(lin, closed.as_slice()),
        Extent::Transient => LoopMargins {
            gain: f64::NAN,
            phase: f64::NAN,
            delay: f64::NAN,
        },
    };
    let watch: Vec<usize> = lin
        .labels
        .iter()
        .enumerate()
        .filter(|(_, l)| l.starts_with("plant.qd"))
        .map(|(i, _)| i)
        .collect();
    let window = (PEAK_WINDOW / lin.period).round() as usize;
    // Long enough for the slowest mode to decay to 1e-4 of its start.
    let samples = if stable && extent == Extent::Full {
        let decay = if rho > 0.0 {
            (1e-4f64.ln() / rho.ln()).ceil()
        } else {
            1.0
        };
        (decay.max(200.0) as usize).min(horizon.max(2))
    } else {
        0
    };
    let (s, peak) = step_response_with_peak(lin, 0, samples, &watch, window);
    let (overshoot, rise, settling) = if stable && extent == Extent::Full {
        step_metrics(&s, lin.period)
    } else {
        (f64::NAN, f64::NAN, f64::NAN)
    };
    Prediction {
        force_ss_error: lin.force_desired - lin.outputs[0],
        x_ss_error: lin.reference_normal - lin.outputs[1],
        overshoot_pct: overshoot,
        rise_time_63: rise,
        settling_time: settling,
        spectral_radius: rho,
        dominant_frequency: freq,
        dominant_damping: damping,
        stable,
        peak_joint_speed: peak * lin.force_desired.abs(),
        gain_margin: margins.gain,
        phase_margin: margins.phase,
        delay_margin: margins.delay,
    }
}

/// Linearises `config` about its equilibrium and predicts.
pub fn predict<R, const N: usize>(
    config: &ScenarioConfig,
    build: impl Fn(&ScenarioConfig) -> crate::error::Result<Simulation<R, N>>,
) -> AnalysisResult<Prediction>
where
    R: RobotModel<N>,
{
    predict_to(config, Extent::Full, build)
}

/// [`predict`] to the given extent.
pub fn predict_to<R, const N: usize>(
    config: &ScenarioConfig,
    extent: Extent,
    build: impl Fn(&ScenarioConfig) -> crate::error::Result<Simulation<R, N>>,
) -> AnalysisResult<Prediction>
where
    R: RobotModel<N>,
{
    let lin = linearize(config, None, build)?;
    Ok(predict_extent(&lin, config.samples(), extent))
}

/// `predict` for every scenario on all cores (or `threads`), in order. One cell's error
/// does not stop the others.
pub fn predict_batch<R, const N: usize, F>(
    configs: &[ScenarioConfig],
    threads: Option<usize>,
    extent: Extent,
    build: F,
) -> Vec<AnalysisResult<Prediction>>
where
    R: RobotModel<N>,
    F: Fn(&ScenarioConfig) -> crate::error::Result<Simulation<R, N>> + Sync,
{
    let work = || {
        configs
            .par_iter()
            .map(|c| predict_to(c, extent, &build))
            .collect::<Vec<_>>()
    };
    match threads {
        Some(t) => match rayon::ThreadPoolBuilder::new().num_threads(t).build() {
            Ok(pool) => pool.install(work),
            Err(e) => vec![Err(AnalysisError::Unsupported(e.to_string())); configs.len()],
        },
        None => work(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::simulation::ThreeLinkSimulation;
    use crate::world::surface::SurfaceParams;

    /// SPEC §7's definitions on a known response: 1 − e^{−k/τ} with one overshoot.
    #[test]
    fn step_metrics_follow_the_definitions() {
        let s: Vec<f64> = (0..1000)
            .map(|k| 1.0 - (-(k as f64) / 100.0).exp())
            .collect();
        let (overshoot, rise, settling) = step_metrics(&s, 1e-3);
        assert!(overshoot < 0.0);
        // 63.2 % at k ≥ 100 τ ln(1/0.368) ≈ 100.
        assert!((rise - 0.1).abs() <= 1e-3, "{rise}");
        // |s − 1| ≤ 2 % from k = ceil(100 ln 50) = 392 on.
        assert!((settling - 0.392).abs() <= 1e-3, "{settling}");
        let never = vec![0.5; 10];
        assert!(step_metrics(&never, 1e-3).2.is_nan());
    }

    /// A 2×2 rotation scaled by r: ρ = r, frequency θ/(2πT), ζ from ln(λ)/T.
    #[test]
    fn dominant_pole_of_a_known_matrix() {
        let (r, th, t) = (0.99f64, 0.05f64, 1e-3);
        let a = DMatrix::from_row_slice(
            2,
            2,
            &[r * th.cos(), -r * th.sin(), r * th.sin(), r * th.cos()],
        );
        let (rho, f, zeta) = dominant_pole(&a, t);
        assert!((rho - r).abs() < 1e-12);
        assert!((f - th / (2.0 * std::f64::consts::PI * t)).abs() < 1e-9);
        let (re, im) = (r.ln() / t, th / t);
        assert!((zeta + re / (re * re + im * im).sqrt()).abs() < 1e-9);
    }

    /// L(z) = k/(z − 1), an integrator: |L| = 1 at θ_c = 2 asin(k/2), arg L = −(π + θ)/2,
    /// so PM = (π − θ_c)/2, the delay margin PM/θ_c and GM = 2/k (at the Nyquist frequency).
    #[test]
    fn margins_of_a_discrete_integrator() {
        let k = 0.3;
        let lin = Linearization {
            a: DMatrix::from_element(1, 1, 1.0 - k),
            b: DVector::from_element(1, 1.0),
            c: DMatrix::from_element(3, 1, 0.0),
            d: DVector::zeros(3),
            c_measured: DVector::from_element(1, k),
            labels: vec!["x".into()],
            state: vec![0.0],
            force_desired: 1.0,
            outputs: [0.0; 3],
            reference_normal: 0.0,
            penetration: 0.0,
            period: 1e-3,
            equilibrium: true,
            iterations: 0,
            caveats: vec![],
            drive: None,
        };
        let m = loop_margins(&lin);
        let pi = std::f64::consts::PI;
        let theta = 2.0 * (k / 2.0f64).asin();
        let pm = (pi - theta) / 2.0;
        assert!((m.phase - pm.to_degrees()).abs() < 1e-9, "{m:?}");
        assert!((m.delay - pm / theta).abs() < 1e-9, "{m:?}");
        assert!((m.gain - 2.0 / k).abs() < 1e-9, "{m:?}");
    }

    /// L(e^{iθ}) through the real Schur form and through the Hessenberg elimination equal a
    /// dense complex LU's on fig. 14's loop (18 states, complex pole pairs) within its
    /// conditioning, and both give the same eigenvalues.
    #[test]
    fn open_loop_schur_equals_hessenberg() {
        let config = ScenarioConfig::default();
        let lin = linearize(&config, None, ThreeLinkSimulation::new).unwrap();
        let a0 = &lin.a + &lin.b * lin.c_measured.transpose();
        let (mut schur, eig) = OpenLoop::new(a0.clone(), &lin.b, &lin.c_measured, true);
        let (mut hess, eig_h) = OpenLoop::new(a0.clone(), &lin.b, &lin.c_measured, false);
        let n = a0.nrows();
        assert!(schur.blocks.iter().any(|b| b.1 == 2), "{:?}", schur.blocks);
        assert!(hess.blocks.is_empty());
        assert_eq!(eig, eig_h);
        for theta in [1e-5, 1e-3, 0.05, 0.3, 1.0, 2.5, std::f64::consts::PI] {
            let (ls, lh) = (schur.at(theta), hess.at(theta));
            // The reference: a dense complex LU of zI − A₀ in the original basis.
            let z = Complex::from_polar(1.0, theta);
            let m = a0.map(|v| Complex::new(-v, 0.0)) + DMatrix::identity(n, n) * z;
            let x = m.lu().solve(&lin.b.map(|v| Complex::new(v, 0.0))).unwrap();
            let lf: Complex<f64> = lin
                .c_measured
                .iter()
                .zip(x.iter())
                .map(|(c, x)| x * c)
                .sum();
            // zI − A₀ nears singular as θ → 0 (the filter's integrator): cond ~ 1/θ.
            let tol = 1e-9 + 2e-11 / theta;
            for (path, l) in [("schur", ls), ("hessenberg", lh)] {
                let rel = (l - lf).norm() / lf.norm();
                assert!(
                    rel <= tol,
                    "θ = {theta}, {path}: {l} vs {lf} ({rel:e} > {tol:e})"
                );
            }
        }
    }

    /// A transient-only prediction has the full one's poles and peak joint speed, and NaN
    /// margins and step metrics.
    #[test]
    fn transient_extent_keeps_poles_and_peak() {
        let config = ScenarioConfig::default();
        let full = predict_to(&config, Extent::Full, ThreeLinkSimulation::new).unwrap();
        let part = predict_to(&config, Extent::Transient, ThreeLinkSimulation::new).unwrap();
        assert!(full.peak_joint_speed > 0.0 && full.gain_margin.is_finite());
        assert_eq!(part.spectral_radius, full.spectral_radius);
        assert_eq!(part.stable, full.stable);
        assert_eq!(part.peak_joint_speed, full.peak_joint_speed);
        assert_eq!(part.dominant_frequency, full.dominant_frequency);
        assert!(part.gain_margin.is_nan() && part.overshoot_pct.is_nan());
    }

    /// The fig. 14 prediction and a batch of it agree, in order; a bad cell is its error.
    #[test]
    fn batch_equals_single_and_keeps_errors() {
        let good = ScenarioConfig::default();
        let mut far = ScenarioConfig::default();
        if let Some(w) = far.wall.as_mut().and_then(SurfaceParams::plane_mut) {
            w.position = Some(3.0);
        }
        let one = predict(&good, ThreeLinkSimulation::new).unwrap();
        assert!(one.stable && one.spectral_radius < 1.0 && one.force_ss_error.abs() < 1e-8);
        let out = predict_batch(
            &[good.clone(), far, good],
            Some(2),
            Extent::Full,
            ThreeLinkSimulation::new,
        );
        assert_eq!(out[0].as_ref().unwrap(), &one);
        assert!(matches!(out[1], Err(AnalysisError::NoEquilibrium(_))));
        assert_eq!(out[2].as_ref().unwrap(), &one);
    }
}
