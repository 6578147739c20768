//! Per-run metrics (SPEC §7). Step metrics also come in python-control's `step_info`
//! convention (`rise_time_10_90`, `peak_time`; `settling_time` is its 2 % `SettlingTime`).

use crate::control::reference::Signal;
use crate::control::task::TaskFrame;
use crate::robot::TaskVector;
use crate::sim::outcome::Outcome;
use crate::sim::scenario::ScenarioConfig;
use crate::sim::trace::Trace;

/// The steady-state window: the last 2 s.
pub const STEADY_STATE_WINDOW: f64 = 2.0;
/// Transients before this time are left out of `force_rms_error` and `contact_loss`.
pub const TRANSIENT_END: f64 = 1.0;
/// Settling band, as a fraction of f_d.
pub const SETTLING_BAND: f64 = 0.02;
/// A force-controlled run whose `force_oscillation` exceeds this is not stable.
pub const OSCILLATION_LIMIT: f64 = 0.1;
/// A force-controlled run whose `contact_loss` exceeds this is not stable.
pub const CONTACT_LOSS_LIMIT: f64 = 0.05;

/// Metrics of one run. Force metrics are NaN in position-only runs, step metrics NaN when
/// f_d is not a step, and every error metric NaN when the run diverged (`force_peak`
/// still reports the largest force seen).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Metrics {
    /// mean(f_d − f) over the last 2 s [N].
    pub force_ss_error: f64,
    /// RMS of f_d − f for t ≥ 1 s [N].
    pub force_rms_error: f64,
    /// max f [N].
    pub force_peak: f64,
    /// 100 (force_peak − f_d,final) / f_d,final [%]; negative when f never reaches f_d.
    pub overshoot_pct: f64,
    /// First time after which |f − f_d| ≤ 2 % f_d to the end [s].
    pub settling_time: f64,
    /// First time f ≥ 63.2 % f_d [s].
    pub rise_time_63: f64,
    /// step_info RiseTime: from 10 % to 90 % of f_d [s].
    pub rise_time_10_90: f64,
    /// step_info PeakTime: time of the first maximum of |f| [s].
    pub peak_time: f64,
    /// RMS of z_d − z over the whole run [m].
    pub z_rms_error: f64,
    /// RMS of X_d,x − x over the whole run [m].
    pub x_rms_error: f64,
    /// Fraction of samples with f = 0 for t ≥ 1 s.
    pub contact_loss: f64,
    /// std(f − f_d) / mean|f_d| over the last 2 s (t ≥ 1 s); for a constant f_d in that
    /// window this is std(f) / |final f_d|. NaN when the window is empty or f_d ≡ 0 there.
    pub force_oscillation: f64,
    /// Fraction of samples with any joint's applied torque at its limit (0 without limits).
    pub torque_saturation: f64,
    /// Largest excursion of any joint beyond its URDF position limit [rad or m]; 0 if none
    /// (and for arms without limits, such as the three-link arm).
    pub joint_limit_violation: f64,
    /// The run stopped early (non-finite state or the velocity limit).
    pub diverged: bool,
    /// Not diverged and, for force-controlled runs, `force_oscillation` ≤ 0.1 and
    /// `contact_loss` ≤ 0.05 (a criterion whose metric is NaN is not applied).
    pub stable: bool,
}

/// Metric names in the order of `Metrics::values`.
pub const METRIC_NAMES: [&str; 14] = [
    "force_ss_error",
    "force_rms_error",
    "force_peak",
    "overshoot_pct",
    "settling_time",
    "rise_time_63",
    "rise_time_10_90",
    "peak_time",
    "z_rms_error",
    "x_rms_error",
    "contact_loss",
    "force_oscillation",
    "torque_saturation",
    "joint_limit_violation",
];

impl Metrics {
    pub fn values(&self) -> [f64; METRIC_NAMES.len()] {
        [
            self.force_ss_error,
            self.force_rms_error,
            self.force_peak,
            self.overshoot_pct,
            self.settling_time,
            self.rise_time_63,
            self.rise_time_10_90,
            self.peak_time,
            self.z_rms_error,
            self.x_rms_error,
            self.contact_loss,
            self.force_oscillation,
            self.torque_saturation,
            self.joint_limit_violation,
        ]
    }

    /// The metrics of a run from its trace; `frame` gives the directions x (along n) and z
    /// (along t̂) are measured in.
    pub fn compute(
        trace: &Trace,
        config: &ScenarioConfig,
        outcome: &Outcome,
        frame: &TaskFrame,
    ) -> Self {
        let (t, f, f_d) = (&trace.t, &trace.f, &trace.f_d);
        let diverged = outcome.is_diverged();
        let force_control = config.admittance.is_some();
        let nan = f64::NAN;
        let mut m = Metrics {
            force_ss_error: nan,
            force_rms_error: nan,
            force_peak: if force_control { max(f) } else { nan },
            overshoot_pct: nan,
            settling_time: nan,
            rise_time_63: nan,
            rise_time_10_90: nan,
            peak_time: nan,
            z_rms_error: nan,
            x_rms_error: nan,
            contact_loss: nan,
            force_oscillation: nan,
            torque_saturation: torque_saturation(trace, config),
            joint_limit_violation: 0.0,
            diverged,
            stable: !diverged,
        };
        if diverged || trace.is_empty() {
            return m;
        }
        // Tracking errors along n (x for the paper's wall) and along t̂ (z).
        let (along_n, along_t) = task_errors(trace, frame);
        m.x_rms_error = rms(along_n.iter().copied(), along_n.len());
        m.z_rms_error = rms(along_t.iter().copied(), along_t.len());
        if !force_control {
            return m;
        }
        let end = t[t.len() - 1];
        let period = config.period;
        let ss = first_index_at(end - STEADY_STATE_WINDOW, period);
        let late = first_index_at(TRANSIENT_END, period).min(t.len());
        m.force_ss_error = mean_difference(&f_d[ss..], &f[ss..]);
        m.force_rms_error = rms_difference(&f_d[late..], &f[late..]);
        m.contact_loss = if late < f.len() {
            f[late..].iter().filter(|v| **v == 0.0).count() as f64 / (f.len() - late) as f64
        } else {
            nan
        };
        let window = ss.max(late).min(t.len());
        m.force_oscillation = oscillation(&f[window..], &f_d[window..]);
        m.stable = within(m.force_oscillation, OSCILLATION_LIMIT)
            && within(m.contact_loss, CONTACT_LOSS_LIMIT);
        if let Signal::Step { value, .. } = config.force_reference {
            // Relative to f_d: undefined (NaN) for f_d = 0.
            m.overshoot_pct = if value == 0.0 {
                f64::NAN
            } else {
                100.0 * (m.force_peak - value) / value
            };
            m.settling_time = settling_time(t, f, value, SETTLING_BAND);
            m.rise_time_63 = first_crossing(t, f, 0.632 * value, value);
            m.rise_time_10_90 =
                first_crossing(t, f, 0.9 * value, value) - first_crossing(t, f, 0.1 * value, value);
            let peak = f.iter().enumerate().fold(
                0,
                |best, (i, v)| if v.abs() > f[best].abs() { i } else { best },
            );
            m.peak_time = t[peak];
        }
        m
    }
}

/// The largest excursion of the recorded joint positions beyond [lower, upper] (0 if none).
pub fn joint_limit_violation(trace: &Trace, lower: &[f64], upper: &[f64]) -> f64 {
    trace
        .q
        .iter()
        .zip(lower.iter().zip(upper))
        .flat_map(|(q, (lo, hi))| q.iter().map(move |v| (lo - v).max(v - hi).max(0.0)))
        .fold(0.0, f64::max)
}

/// Index of the first sample with time ≥ `time` (sample k is at k·T).
fn first_index_at(time: f64, period: f64) -> usize {
    if time <= 0.0 {
        0
    } else {
        (time / period - 1e-9).ceil() as usize
    }
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
}

fn mean_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x - y).sum::<f64>() / a.len() as f64
}

/// The tracking error X_d − X of every sample, along n and along t̂.
fn task_errors(trace: &Trace, frame: &TaskFrame) -> (Vec<f64>, Vec<f64>) {
    let (n, t) = (&frame.normal, &frame.tangent);
    let errors = trace
        .x_ref
        .iter()
        .zip(&trace.y_ref)
        .zip(&trace.z_ref)
        .zip(trace.x.iter().zip(&trace.y).zip(&trace.z))
        .map(|(((xr, yr), zr), ((x, y), z))| TaskVector::new(xr - x, yr - y, zr - z));
    errors.map(|e| (n.dot(&e), t.dot(&e))).unzip()
}

fn rms(v: impl Iterator<Item = f64> + Clone, n: usize) -> f64 {
    let plain = (v.clone().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
    if plain.is_finite() {
        return plain;
    }
    // The squares overflowed (errors beyond 1e154): scale by the largest, so a huge but
    // finite error reads as itself rather than inf.
    let scale = v.clone().fold(0.0f64, |m, x| m.max(x.abs()));
    if !scale.is_finite() || scale == 0.0 {
        return plain;
    }
    scale * (v.map(|x| (x / scale) * (x / scale)).sum::<f64>() / n as f64).sqrt()
}

/// Fraction of samples where some joint's applied torque sits at its limit.
fn torque_saturation(trace: &Trace, config: &ScenarioConfig) -> f64 {
    let Some(limits) = &config.actuator.torque_limit else {
        return 0.0;
    };
    if trace.is_empty() {
        return f64::NAN;
    }
    let limit = |j: usize| {
        if limits.len() == 1 {
            limits[0]
        } else {
            limits[j]
        }
    };
    let saturated = (0..trace.len())
        .filter(|&i| (0..trace.joints()).any(|j| trace.tau[j][i].abs() >= limit(j)))
        .count();
    saturated as f64 / trace.len() as f64
}

fn rms_difference(a: &[f64], b: &[f64]) -> f64 {
    rms(a.iter().zip(b).map(|(x, y)| x - y), a.len())
}

/// A stability criterion holds: the metric is at most `limit`, or NaN (not judged).
fn within(value: f64, limit: f64) -> bool {
    value.is_nan() || value <= limit
}

/// std(f − f_d) / mean|f_d| (NaN for an empty window or f_d ≡ 0).
fn oscillation(f: &[f64], f_d: &[f64]) -> f64 {
    if f.is_empty() {
        return f64::NAN;
    }
    let n = f.len() as f64;
    let scale = f_d.iter().map(|v| v.abs()).sum::<f64>() / n;
    if scale == 0.0 {
        return f64::NAN;
    }
    let mean = mean_difference(f, f_d);
    let var = f
        .iter()
        .zip(f_d)
        .map(|(a, b)| (a - b - mean) * (a - b - mean))
        .sum::<f64>()
        / n;
    var.sqrt() / scale
}

/// First time the signal reaches `level` on the side of `target`'s sign (NaN if never).
fn first_crossing(t: &[f64], y: &[f64], level: f64, target: f64) -> f64 {
    let sign = target.signum();
    y.iter()
        .position(|v| sign * (v - level) >= 0.0)
        .map_or(f64::NAN, |i| t[i])
}

/// First time after which |y − target| ≤ band·|target| to the end (NaN if the last sample
/// is outside the band).
fn settling_time(t: &[f64], y: &[f64], target: f64, band: f64) -> f64 {
    let tol = band * target.abs();
    match y.iter().rposition(|v| (v - target).abs() > tol) {
        None => t[0],
        Some(i) if i + 1 < t.len() => t[i + 1],
        Some(_) => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_metrics_on_a_known_signal() {
        // f rises linearly from 0 to 11 over 1.1 s, then sits at 10.
        let t: Vec<f64> = (0..=3000).map(|k| k as f64 * 1e-3).collect();
        let f: Vec<f64> = t
            .iter()
            .map(|&t| if t <= 1.1 { 10.0 * t } else { 10.0 })
            .collect();
        assert_eq!(settling_time(&t, &f, 10.0, 0.02), t[1101]);
        assert!((first_crossing(&t, &f, 6.32, 10.0) - 0.632).abs() < 1e-12);
        assert!(
            (first_crossing(&t, &f, 9.0, 10.0) - first_crossing(&t, &f, 1.0, 10.0) - 0.8).abs()
                < 1e-9
        );
        assert!(first_crossing(&t, &f, 20.0, 10.0).is_nan());
        let never: Vec<f64> = t.iter().map(|_| 5.0).collect();
        assert!(settling_time(&t, &never, 10.0, 0.02).is_nan());
    }

    #[test]
    fn oscillation_is_relative_std_about_the_reference() {
        // f alternates 9 / 11 about f_d = 10: std 1, relative 0.1.
        let f: Vec<f64> = (0..1000)
            .map(|k| if k % 2 == 0 { 9.0 } else { 11.0 })
            .collect();
        let f_d = vec![10.0; 1000];
        assert!((oscillation(&f, &f_d) - 0.1).abs() < 1e-12);
        // Tracking a varying reference exactly is no oscillation.
        let ramp: Vec<f64> = (0..1000).map(|k| 5.0 + k as f64 * 1e-2).collect();
        assert_eq!(oscillation(&ramp, &ramp), 0.0);
        assert!(oscillation(&[], &[]).is_nan());
        assert!(oscillation(&[1.0], &[0.0]).is_nan());
    }

    #[test]
    fn windows_by_index() {
        assert_eq!(first_index_at(8.0, 1e-3), 8000);
        assert_eq!(first_index_at(1.0, 1e-3), 1000);
        assert_eq!(first_index_at(-1.0, 1e-3), 0);
        assert!((rms_difference(&[1.0, -1.0], &[0.0, 0.0]) - 1.0).abs() < 1e-15);
        assert_eq!(mean_difference(&[3.0, 5.0], &[1.0, 1.0]), 3.0);
    }

    #[test]
    fn rms_of_huge_errors_does_not_overflow() {
        let v = [1e300, -1e300, 1e300, -1e300];
        assert_eq!(rms(v.iter().copied(), 4), 1e300);
        assert_eq!(rms_difference(&[3.0, 4.0], &[0.0, 0.0]), (12.5f64).sqrt());
    }
}
