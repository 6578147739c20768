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
    let eig = a.complex_eigenvalues();
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

/// Solves (zI − H) x = r for an upper Hessenberg H, by Gaussian elimination with pivoting
/// between neighbouring rows: O(n²).
fn hessenberg_solve(h: &DMatrix<f64>, z: Complex<f64>, r: &[Complex<f64>]) -> Vec<Complex<f64>> {
    let n = r.len();
    let mut m: Vec<Complex<f64>> = (0..n * n)
        .map(|k| {
            let (i, j) = (k / n, k % n);
            let v = Complex::new(-h[(i, j)], 0.0);
            if i == j {
                v + z
            } else {
                v
            }
        })
        .collect();
    let mut x = r.to_vec();
    for k in 0..n.saturating_sub(1) {
        if m[(k + 1) * n + k].norm() > m[k * n + k].norm() {
            for j in k..n {
                m.swap(k * n + j, (k + 1) * n + j);
            }
            x.swap(k, k + 1);
        }
        let pivot = m[k * n + k];
        if pivot.norm() == 0.0 {
            continue;
        }
        let l = m[(k + 1) * n + k] / pivot;
        for j in k..n {
            let v = m[k * n + j];
            m[(k + 1) * n + j] -= l * v;
        }
        let v = x[k];
        x[k + 1] -= l * v;
    }
    for i in (0..n).rev() {
        let mut acc = x[i];
        for j in i + 1..n {
            acc -= m[i * n + j] * x[j];
        }
        x[i] = acc / m[i * n + i];
    }
    x
}

/// The force loop cut where the measured force enters the filter (f_d enters only as
/// e_f = f_d − f̃): L(z) = c̃ (zI − A₀)⁻¹ B with A₀ = A + B c̃, so that the closed loop is
/// A = A₀ − B c̃ (negative feedback, python-control's convention). Evaluated on a
/// logarithmic grid of θ = ωT in (0, π] refined around every pole of the open and the
/// closed loop, crossings located by bisection.
pub fn loop_margins(lin: &Linearization) -> LoopMargins {
    let c = &lin.c_measured;
    let a0 = &lin.a + &lin.b * c.transpose();
    let (q, h) = a0.clone().hessenberg().unpack();
    let qb: Vec<Complex<f64>> = (q.transpose() * &lin.b)
        .iter()
        .map(|v| Complex::new(*v, 0.0))
        .collect();
    let cq: DVector<f64> = q.transpose() * c;
    let l_at = |theta: f64| -> Complex<f64> {
        let x = hessenberg_solve(&h, Complex::from_polar(1.0, theta), &qb);
        cq.iter().zip(&x).map(|(c, x)| x * *c).sum()
    };
    let pi = std::f64::consts::PI;
    let mut grid: Vec<f64> = (0..=600)
        .map(|i| 1e-5 * (pi / 1e-5).powf(i as f64 / 600.0))
        .collect();
    for l in a0
        .complex_eigenvalues()
        .iter()
        .chain(lin.a.complex_eigenvalues().iter())
    {
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
    let values: Vec<Complex<f64>> = grid.iter().map(|&t| l_at(t)).collect();
    // Bisection on a sign change of g between grid points a and b.
    let bisect = |mut a: f64, mut b: f64, g: &dyn Fn(Complex<f64>) -> f64| -> f64 {
        let mut ga = g(l_at(a));
        for _ in 0..40 {
            let m = 0.5 * (a + b);
            let gm = g(l_at(m));
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
            let t = bisect(grid[i - 1], grid[i], &magnitude);
            let arg = l_at(t).arg() + pi;
            // Wrapped to (−180°, 180°].
            let pm = if arg > pi { arg - 2.0 * pi } else { arg };
            phase = phase.min(pm.to_degrees());
            delay = delay.min(if pm > 0.0 { pm / t } else { 0.0 });
        }
        if (l0.im > 0.0) != (l1.im > 0.0) && (l0.re < 0.0 || l1.re < 0.0) {
            let l = l_at(bisect(grid[i - 1], grid[i], &imaginary));
            if l.re < 0.0 {
                gain = gain.min(1.0 / l.norm());
            }
        }
    }
    // At the Nyquist frequency L is real: a crossing of the negative axis if Re L < 0.
    let nyquist = l_at(pi);
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
    // Row-major A for a cache-friendly matrix-vector product.
    let a: Vec<f64> = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| lin.a[(i, j)])
        .collect();
    let c: Vec<f64> = (0..n).map(|j| lin.c[(output, j)]).collect();
    let b: Vec<f64> = lin.b.iter().copied().collect();
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
        for (i, nx) in next.iter_mut().enumerate() {
            let row = &a[i * n..(i + 1) * n];
            *nx = row.iter().zip(&x).map(|(a, x)| a * x).sum::<f64>() + b[i];
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

/// Predicted metrics from a linearisation about the equilibrium; `horizon` caps the step
/// response [samples] (the run's length, like the simulated metrics).
pub fn predict_from(lin: &Linearization, horizon: usize) -> Prediction {
    let (rho, freq, damping) = dominant_pole(&lin.a, lin.period);
    let stable = rho < 1.0;
    let margins = loop_margins(lin);
    let watch: Vec<usize> = lin
        .labels
        .iter()
        .enumerate()
        .filter(|(_, l)| l.starts_with("plant.qd"))
        .map(|(i, _)| i)
        .collect();
    let window = (PEAK_WINDOW / lin.period).round() as usize;
    // Long enough for the slowest mode to decay to 1e-4 of its start.
    let samples = if stable {
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
    let (overshoot, rise, settling) = if stable {
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
    let lin = linearize(config, None, build)?;
    Ok(predict_from(&lin, config.samples()))
}

/// `predict` for every scenario on all cores (or `threads`), in order. One cell's error
/// does not stop the others.
pub fn predict_batch<R, const N: usize, F>(
    configs: &[ScenarioConfig],
    threads: Option<usize>,
    build: F,
) -> Vec<AnalysisResult<Prediction>>
where
    R: RobotModel<N>,
    F: Fn(&ScenarioConfig) -> crate::error::Result<Simulation<R, N>> + Sync,
{
    let work = || {
        configs
            .par_iter()
            .map(|c| predict(c, &build))
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
            ThreeLinkSimulation::new,
        );
        assert_eq!(out[0].as_ref().unwrap(), &one);
        assert!(matches!(out[1], Err(AnalysisError::NoEquilibrium(_))));
        assert_eq!(out[2].as_ref().unwrap(), &one);
    }
}
