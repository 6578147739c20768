//! Per-run metrics (SPEC §7). Step metrics also come in python-control's `step_info`
//! convention (`rise_time_10_90`, `peak_time`; `settling_time` is its 2 % `SettlingTime`).

use crate::control::reference::Signal;
use crate::control::task::TaskFrame;
use crate::robot::TaskVector;
use crate::sim::criteria::{
    judge, needs_held, CriteriaParams, Drive, Figures, Handover, Held, Judgement,
};
use crate::sim::outcome::Outcome;
use crate::sim::scenario::ScenarioConfig;
use crate::sim::trace::{Row, Trace};

/// The steady-state window: the last 2 s.
pub const STEADY_STATE_WINDOW: f64 = 2.0;
/// Transients before this time after the contact phase starts are left out of
/// `force_rms_error`, `contact_loss` and the steady-state windows (SPEC §16).
pub const TRANSIENT_END: f64 = 1.0;
/// `impact_peak` is the largest force within this time after first contact [s] (SPEC §16).
pub const IMPACT_WINDOW: f64 = 0.5;
/// A run starts touching if its penetration at sample 0 is above −this [m]: the paper's
/// wall passes through X0, and X0 computed by another path (the lanes' kinematics) may put
/// it a few ulp (1e-16 m) away; a real gap is micrometres or more.
pub const TOUCHING_TOLERANCE: f64 = 1e-9;
/// Settling band, as a fraction of f_d.
pub const SETTLING_BAND: f64 = 0.02;

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
    /// step_info PeakTime: time of the whole run's maximum |f| (the first sample that
    /// reaches it) [s]; with motion this can be a bump long after the step.
    pub peak_time: f64,
    /// The step's own overshoot: 100 (p − f_d) / f_d [%] with p the step's first peak, the
    /// first local maximum of f at or after f first reaches f_d; 0 when f never reaches f_d.
    pub step_overshoot_pct: f64,
    /// Time of that first peak [s]; NaN when f never reaches f_d.
    pub step_peak_time: f64,
    /// RMS of z_d − z over the whole run [m].
    pub z_rms_error: f64,
    /// RMS of X_d,x − x over the whole run [m].
    pub x_rms_error: f64,
    /// RMS of the tip's error within the tangent plane (force-controlled runs), or of the
    /// whole error |X_d − X| (position-only runs) over the whole run [m].
    pub path_rms_error: f64,
    /// Fraction of samples with f = 0 for t ≥ 1 s.
    pub contact_loss: f64,
    /// std(f − f_d) / mean|f_d| over the last 2 s (t ≥ 1 s); for a constant f_d in that
    /// window this is std(f) / |final f_d|. NaN when the window is empty or f_d ≡ 0 there.
    pub force_oscillation: f64,
    /// mean |F_t|, the friction force along the surface, over the last 2 s (t ≥ 1 s) [N].
    pub tangential_force_mean: f64,
    /// Fraction of samples with any joint's applied torque at its limit (0 without limits).
    pub torque_saturation: f64,
    /// Largest excursion of any joint beyond its URDF position limit [rad or m]; 0 if none
    /// (and for arms without limits, such as the three-link arm).
    pub joint_limit_violation: f64,
    /// f > 0 → f = 0 transitions after first contact (force-controlled runs).
    pub bounces: f64,
    /// Time of the first sample with f > 0 [s]; NaN if the tool never touches.
    pub first_contact_time: f64,
    /// max f within 0.5 s after first contact [N]; NaN if the tool never touches.
    pub impact_peak: f64,
    /// Span of the window the force criteria judge, from the contact phase's start + 1 s to
    /// the end [s] (NaN for position-only runs).
    pub assessed_time: f64,
    /// Start of the contact phase [s]: 0 for a run that starts touching (or never touches),
    /// else `first_contact_time`. The windows start 1 s after it.
    pub contact_start: f64,
    /// The run stopped early (non-finite state or the velocity limit).
    pub diverged: bool,
    /// The loop's dynamics (SPEC §23, [`judge`]): False when the run diverged or sustains
    /// an oscillation or loss of contact by itself; `None`: not assessed.
    pub stable: Option<bool>,
    /// Every criterion met (SPEC §17); `None`: not assessed.
    pub passed: Option<bool>,
    /// What drives the run, and what the run showed with those drives held
    /// (`sim::held` sets it after the run).
    pub drive: Drive,
    /// The criteria the run was judged by.
    pub criteria: CriteriaParams,
    /// Whether the run has a force loop (what [`judge`] applies).
    pub force_control: bool,
    /// With a guarded approach (SPEC §16): the largest measured force and the threshold
    /// it had to exceed for force control to take over; `None` without one.
    pub handover: Option<Handover>,
}

/// Metric names in the order of `Metrics::values`.
pub const METRIC_NAMES: [&str; 22] = [
    "force_ss_error",
    "force_rms_error",
    "force_peak",
    "overshoot_pct",
    "settling_time",
    "rise_time_63",
    "rise_time_10_90",
    "peak_time",
    "step_overshoot_pct",
    "step_peak_time",
    "z_rms_error",
    "x_rms_error",
    "path_rms_error",
    "contact_loss",
    "force_oscillation",
    "tangential_force_mean",
    "bounces",
    "first_contact_time",
    "impact_peak",
    "assessed_time",
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
            self.step_overshoot_pct,
            self.step_peak_time,
            self.z_rms_error,
            self.x_rms_error,
            self.path_rms_error,
            self.contact_loss,
            self.force_oscillation,
            self.tangential_force_mean,
            self.bounces,
            self.first_contact_time,
            self.impact_peak,
            self.assessed_time,
            self.torque_saturation,
            self.joint_limit_violation,
        ]
    }

    /// `stable`, `passed` and the verdict in words, for a run that ended with `outcome`.
    pub fn judgement(&self, outcome: &Outcome) -> Judgement {
        judge(
            &self.figures(),
            &self.criteria,
            self.force_control,
            outcome,
            &self.drive,
        )
    }

    /// Whether judging this run needs its held run (`sim::held`): it failed a criterion the
    /// loop may sustain by itself and what drives it is not yet known.
    pub fn needs_held(&self, outcome: &Outcome) -> bool {
        self.drive == Drive::Untested
            && needs_held(&self.figures(), &self.criteria, self.force_control, outcome)
    }

    /// Judges the run again, knowing what drives it.
    pub fn set_drive(&mut self, drive: Drive, outcome: &Outcome) {
        self.drive = drive;
        let j = self.judgement(outcome);
        (self.stable, self.passed) = (j.stable, j.passed);
    }

    /// What this run shows as the held run of another (`sim::held`).
    pub fn as_held(&self, outcome: &Outcome, holds: crate::sim::criteria::Holds) -> Held {
        Held {
            holds,
            force_oscillation: self.force_oscillation,
            contact_loss: self.contact_loss,
            bounces: self.bounces,
            first_contact_time: self.first_contact_time,
            diverged_at: match outcome {
                Outcome::Completed => f64::NAN,
                Outcome::Diverged { time, .. } => *time,
            },
        }
    }

    /// What the criteria read.
    fn figures(&self) -> Figures {
        Figures {
            force_peak: self.force_peak,
            contact_loss: self.contact_loss,
            force_oscillation: self.force_oscillation,
            bounces: self.bounces,
            first_contact_time: self.first_contact_time,
            impact_peak: self.impact_peak,
            contact_start: self.contact_start,
            assessed_time: self.assessed_time,
            path_rms_error: self.path_rms_error,
            torque_saturation: self.torque_saturation,
            handover: self.handover,
        }
    }

    /// The metrics of a recorded run, by replaying its trace through [`OnlineMetrics`];
    /// `frame` gives the directions x (along n) and z (along t̂) are measured in.
    pub fn compute(
        trace: &Trace,
        config: &ScenarioConfig,
        outcome: &Outcome,
        frame: &TaskFrame,
    ) -> Self {
        let mut online = OnlineMetrics::new(config, frame);
        online.replay(trace);
        online.finish(outcome)
    }
}

/// Index of the first sample with time ≥ `time` (sample k is at k·T).
fn first_index_at(time: f64, period: f64) -> usize {
    if time <= 0.0 {
        0
    } else {
        (time / period - 1e-9).ceil() as usize
    }
}

/// Σx² of a stream that cannot overflow to inf for finite x: the plain sum (exact
/// sequential order) and, beside it, the sum scaled by a fixed power of two, used only when
/// the plain one overflowed. (A running max|x| scale, as BLAS `nrm2` keeps it, divided at
/// every sample of every run, four sums a sample; and it skipped a NaN sample.)
#[derive(Debug, Clone, Copy)]
struct SumOfSquares {
    plain: f64,
    /// Σ (x·2⁻⁶⁰⁰)²: finite for any finite x (a term is at most 2⁸⁴⁸), and the scaling is
    /// exact, so it gives the RMS where `plain` overflowed (|x| past 1e154) at one product
    /// and one add a sample. Terms with |x| below about 2⁸⁹ go subnormal or vanish in it:
    /// at most 2¹⁷⁸ each, far below its rounding once the sum has passed 2¹⁰²⁴.
    scaled: f64,
    count: usize,
}

/// 2⁻⁶⁰⁰ and 2⁶⁰⁰.
const SHRINK: f64 = 2.409919865102884e-181;
const GROW: f64 = 4.149515568880993e180;

impl SumOfSquares {
    const ZERO: Self = Self {
        plain: 0.0,
        scaled: 0.0,
        count: 0,
    };

    #[inline(always)]
    fn push(&mut self, x: f64) {
        self.plain += x * x;
        self.count += 1;
        let s = x * SHRINK;
        self.scaled += s * s;
    }

    /// √(Σx²/n): NaN for no samples.
    fn rms(&self) -> f64 {
        let n = self.count as f64;
        let plain = (self.plain / n).sqrt();
        if plain.is_finite() || plain.is_nan() {
            return plain;
        }
        (self.scaled / n).sqrt() * GROW
    }
}

/// Running mean and variance of d = f − f_d (Welford's update, stable where the mean is
/// large against the spread), with the mean |f_d| that scales it.
#[derive(Debug, Clone, Copy)]
struct Spread {
    count: usize,
    mean: f64,
    m2: f64,
    reference: f64,
}

impl Spread {
    const ZERO: Self = Self {
        count: 0,
        mean: 0.0,
        m2: 0.0,
        reference: 0.0,
    };

    #[inline(always)]
    fn push(&mut self, f: f64, f_d: f64) {
        self.count += 1;
        let d = f - f_d;
        let delta = d - self.mean;
        self.mean += delta / self.count as f64;
        self.m2 += delta * (d - self.mean);
        self.reference += f_d.abs();
    }

    /// std(f − f_d) / mean|f_d| (NaN for an empty window or f_d ≡ 0).
    fn relative_std(&self) -> f64 {
        if self.count == 0 || self.reference == 0.0 {
            return f64::NAN;
        }
        let n = self.count as f64;
        (self.m2 / n).sqrt() / (self.reference / n)
    }
}

/// Every metric of §7/§10/§16, accumulated one sample at a time while the run advances, so a
/// run needs no trace to be judged. A run that completes ends at t = (N − 1)·T, and a
/// diverged run reports no windowed metric. The windows start 1 s into the contact phase
/// (SPEC §16): at t = 1 s for a run that starts touching (δ ≥ −1 nm at sample 0), else 1 s after
/// first contact. Before first contact f = 0, so a run that starts apart re-anchors its
/// windows at first contact by dropping what they held (samples before it, all outside the
/// new windows); one that never touches keeps today's windows (contact lost throughout).
#[derive(Debug, Clone)]
pub struct OnlineMetrics {
    period: f64,
    force_control: bool,
    /// f_d of a step reference (step metrics are defined only for those).
    step: Option<f64>,
    normal: TaskVector,
    tangent: TaskVector,
    torque_limit: Option<Vec<f64>>,
    /// The arm's joint position limits (lower, upper), when it has them.
    position_limits: Option<(Vec<f64>, Vec<f64>)>,
    /// First sample of the last 2 s of the run, and of the steady-state window (the later of
    /// it and `late_start`, once re-anchored at first contact).
    fixed_steady_start: usize,
    steady_start: usize,
    /// First sample after the transient (1 s into the contact phase).
    late_start: usize,
    /// First sample of the oscillation window: the later of the two.
    window_start: usize,
    /// Samples in 1 s (the transient) and in the impact window.
    transient_samples: usize,
    impact_samples: usize,
    /// The run's first sample: 0, unless a fresh run was set to start later (`start_at`).
    start: usize,
    /// The first sample touched the surface (δ ≥ 0): the contact phase starts with it.
    starts_touching: bool,
    /// The first sample with f > 0, and the largest f within the impact window after it.
    first_contact: Option<usize>,
    impact_peak: f64,
    // Running values.
    samples: usize,
    force_peak: f64,
    /// The largest measured force, and the guarded approach's threshold (if any).
    measured_peak: f64,
    handover_threshold: Option<f64>,
    saturated: usize,
    /// Largest excursion of a joint beyond its limits so far.
    limit_excursion: f64,
    along_n: SumOfSquares,
    along_t: SumOfSquares,
    steady_error_sum: f64,
    /// Σ |F_t| over the steady-state window.
    steady_friction_sum: f64,
    late_error: SumOfSquares,
    contact_lost: usize,
    spread: Spread,
    /// Last sample outside the settling band.
    last_unsettled: Option<usize>,
    /// First samples at 10 %, 63.2 % and 90 % of a step's f_d.
    crossings: [Option<usize>; 3],
    /// First sample of the largest |f|.
    peak: (usize, f64),
    /// The step's first peak: f_d not yet reached, rising (the peak so far) or found.
    lobe: Lobe,
    /// Tangent-plane error (force control) or whole error (position only).
    path: SumOfSquares,
    /// Whether the last sample touched (a bounce is leaving contact).
    touching: bool,
    bounces: usize,
    criteria: CriteriaParams,
}

/// The step response's first peak (`step_overshoot_pct`, `step_peak_time`).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Lobe {
    Before,
    Open { at: usize, peak: f64 },
    Closed { at: usize, peak: f64 },
}

/// The levels of `OnlineMetrics::crossings`, as fractions of f_d.
const CROSSING_LEVELS: [f64; 3] = [0.1, 0.632, 0.9];

impl OnlineMetrics {
    pub fn new(config: &ScenarioConfig, frame: &TaskFrame) -> Self {
        let period = config.period;
        let samples = config.samples();
        let end = samples.saturating_sub(1) as f64 * period;
        let steady_start = first_index_at(end - STEADY_STATE_WINDOW, period);
        let late_start = first_index_at(TRANSIENT_END, period);
        Self {
            transient_samples: late_start,
            impact_samples: first_index_at(IMPACT_WINDOW, period),
            start: 0,
            starts_touching: false,
            first_contact: None,
            impact_peak: f64::NAN,
            period,
            force_control: config.admittance.is_some(),
            step: match config.force_reference {
                Signal::Step { value, .. } => Some(value),
                _ => None,
            },
            normal: frame.normal,
            tangent: frame.tangent,
            torque_limit: config.actuator.torque_limit.clone(),
            position_limits: None,
            fixed_steady_start: steady_start,
            steady_start,
            late_start,
            window_start: steady_start.max(late_start),
            samples: 0,
            force_peak: f64::NEG_INFINITY,
            measured_peak: f64::NEG_INFINITY,
            handover_threshold: config.approach.as_ref().map(|a| a.threshold),
            saturated: 0,
            limit_excursion: 0.0,
            along_n: SumOfSquares::ZERO,
            along_t: SumOfSquares::ZERO,
            steady_error_sum: 0.0,
            steady_friction_sum: 0.0,
            late_error: SumOfSquares::ZERO,
            contact_lost: 0,
            spread: Spread::ZERO,
            last_unsettled: None,
            crossings: [None; 3],
            peak: (0, f64::NEG_INFINITY),
            lobe: Lobe::Before,
            path: SumOfSquares::ZERO,
            touching: false,
            bounces: 0,
            criteria: config.criteria,
        }
    }

    /// Reports `joint_limit_violation` against these joint position limits.
    pub fn set_position_limits(&mut self, lower: &[f64], upper: &[f64]) {
        self.position_limits = Some((lower.to_vec(), upper.to_vec()));
    }

    /// Back to no samples (and the windows anchored at t = 0).
    pub fn reset(&mut self) {
        self.late_start = self.transient_samples;
        self.steady_start = self.fixed_steady_start;
        self.window_start = self.steady_start.max(self.late_start);
        self.start = 0;
        self.starts_touching = false;
        self.first_contact = None;
        self.impact_peak = f64::NAN;
        self.samples = 0;
        self.force_peak = f64::NEG_INFINITY;
        self.measured_peak = f64::NEG_INFINITY;
        self.saturated = 0;
        self.limit_excursion = 0.0;
        self.along_n = SumOfSquares::ZERO;
        self.along_t = SumOfSquares::ZERO;
        self.steady_error_sum = 0.0;
        self.steady_friction_sum = 0.0;
        self.late_error = SumOfSquares::ZERO;
        self.contact_lost = 0;
        self.spread = Spread::ZERO;
        self.last_unsettled = None;
        self.crossings = [None; 3];
        self.peak = (0, f64::NEG_INFINITY);
        self.lobe = Lobe::Before;
        self.path = SumOfSquares::ZERO;
        self.touching = false;
        self.bounces = 0;
    }

    /// The index of the next sample (the samples taken so far, counted from 0 however late
    /// the run started).
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// With no sample taken yet (just built or `reset`): the run starts at sample `first`
    /// (a state set on a fresh run, issue #53 item 3). Times stay the loop's, t_k = k T;
    /// the windows begin no earlier than `first`, and fractions count only samples taken.
    pub fn start_at(&mut self, first: usize) {
        self.start = first;
        self.samples = first;
        self.late_start = self.transient_samples.max(first);
        self.steady_start = self.fixed_steady_start.max(first);
        self.window_start = self.steady_start.max(self.late_start);
    }

    /// Takes sample k (they must come in order, from `start`).
    #[inline(always)]
    pub fn push(&mut self, row: &Row) {
        let k = self.samples;
        self.samples += 1;
        self.saturated += usize::from(self.any_saturated(row.tau));
        if let Some((lower, upper)) = &self.position_limits {
            for ((q, lo), hi) in row.q.iter().zip(lower).zip(upper) {
                let beyond = (lo - q).max(q - hi);
                self.limit_excursion = self.limit_excursion.max(beyond);
            }
        }
        let [xr, yr, zr] = row.reference;
        let [x, y, z] = row.position;
        let e = TaskVector::new(xr - x, yr - y, zr - z);
        let e_n = self.normal.dot(&e);
        self.along_n.push(e_n);
        self.along_t.push(self.tangent.dot(&e));
        if !self.force_control {
            self.path.push(e.norm());
            return;
        }
        // Within the tangent plane: the motion the task asks for (n is unit length).
        self.path.push((e - self.normal * e_n).norm());
        let (f, f_d) = (row.f, row.f_d);
        self.force_peak = self.force_peak.max(f);
        self.measured_peak = self.measured_peak.max(row.f_measured);
        if k == self.start {
            // NaN (no surface) is not touching.
            self.starts_touching = row.penetration >= -TOUCHING_TOLERANCE;
        }
        if f > 0.0 {
            if self.first_contact.is_none() {
                self.first_contact = Some(k);
                self.impact_peak = f;
                if !self.starts_touching {
                    self.anchor_windows(k);
                }
            }
            self.touching = true;
        } else if self.touching {
            self.touching = false;
            self.bounces += 1;
        }
        if let Some(c) = self.first_contact {
            if k - c <= self.impact_samples {
                self.impact_peak = self.impact_peak.max(f);
            }
        }
        if k >= self.steady_start {
            self.steady_error_sum += f_d - f;
            self.steady_friction_sum += row.f_t;
        }
        if k >= self.late_start {
            self.late_error.push(f_d - f);
            self.contact_lost += usize::from(f == 0.0);
        }
        if k >= self.window_start {
            self.spread.push(f, f_d);
        }
        if let Some(target) = self.step {
            if (f - target).abs() > SETTLING_BAND * target.abs() {
                self.last_unsettled = Some(k);
            }
            let sign = target.signum();
            for (first, level) in self.crossings.iter_mut().zip(CROSSING_LEVELS) {
                if first.is_none() && sign * (f - level * target) >= 0.0 {
                    *first = Some(k);
                }
            }
            if f.abs() > self.peak.1 {
                self.peak = (k, f.abs());
            }
            // The first local maximum at or after f first reaches f_d.
            self.lobe = match self.lobe {
                Lobe::Before if sign * (f - target) >= 0.0 => Lobe::Open { at: k, peak: f },
                Lobe::Open { peak, .. } if sign * (f - peak) > 0.0 => Lobe::Open { at: k, peak: f },
                Lobe::Open { at, peak } if sign * (f - peak) < 0.0 => Lobe::Closed { at, peak },
                other => other,
            };
        }
    }

    /// Starts the windows 1 s after first contact at sample `c` (a run that started apart).
    /// What they held came from samples before `c`: dropped.
    #[cold]
    fn anchor_windows(&mut self, c: usize) {
        self.late_start = c + self.transient_samples;
        self.steady_start = self.fixed_steady_start.max(self.late_start);
        self.window_start = self.steady_start;
        self.steady_friction_sum = 0.0;
        self.steady_error_sum = 0.0;
        self.late_error = SumOfSquares::ZERO;
        self.contact_lost = 0;
        self.spread = Spread::ZERO;
    }

    #[inline(always)]
    fn any_saturated(&self, tau: &[f64]) -> bool {
        let Some(limits) = &self.torque_limit else {
            return false;
        };
        let limit = |j: usize| {
            if limits.len() == 1 {
                limits[0]
            } else {
                limits[j]
            }
        };
        tau.iter().enumerate().any(|(j, t)| t.abs() >= limit(j))
    }

    /// Pushes every sample of a recorded trace (started where it starts).
    pub fn replay(&mut self, trace: &Trace) {
        if trace.first() > 0 {
            self.start_at(trace.first());
        }
        trace.for_each_row(|row| self.push(row));
    }

    /// The time of sample k, as the loop computes it.
    fn time(&self, k: usize) -> f64 {
        k as f64 * self.period
    }

    /// The metrics of the samples so far, for a run that ended with `outcome`.
    pub fn finish(&self, outcome: &Outcome) -> Metrics {
        let diverged = outcome.is_diverged();
        let len = self.samples;
        let nan = f64::NAN;
        let mut m = Metrics {
            force_ss_error: nan,
            force_rms_error: nan,
            force_peak: if self.force_control {
                self.force_peak
            } else {
                nan
            },
            overshoot_pct: nan,
            settling_time: nan,
            rise_time_63: nan,
            rise_time_10_90: nan,
            peak_time: nan,
            z_rms_error: nan,
            x_rms_error: nan,
            contact_loss: nan,
            force_oscillation: nan,
            tangential_force_mean: nan,
            torque_saturation: match (&self.torque_limit, len - self.start) {
                (None, _) => 0.0,
                (Some(_), 0) => nan,
                (Some(_), taken) => self.saturated as f64 / taken as f64,
            },
            joint_limit_violation: self.limit_excursion,
            step_overshoot_pct: nan,
            step_peak_time: nan,
            path_rms_error: nan,
            bounces: nan,
            first_contact_time: nan,
            impact_peak: nan,
            assessed_time: nan,
            contact_start: nan,
            diverged,
            stable: None,
            passed: None,
            drive: Drive::Untested,
            criteria: self.criteria,
            force_control: self.force_control,
            handover: match (self.force_control, self.handover_threshold) {
                (true, Some(threshold)) => Some(Handover {
                    measured_peak: self.measured_peak,
                    threshold,
                }),
                _ => None,
            },
        };
        if self.force_control {
            // Facts about what happened, like force_peak: kept for a diverged run too.
            m.first_contact_time = self.first_contact.map_or(nan, |c| self.time(c));
            m.impact_peak = self.impact_peak;
            m.contact_start = match self.first_contact {
                Some(c) if !self.starts_touching => self.time(c),
                _ => self.time(self.start),
            };
        }
        m.set_drive(Drive::Untested, outcome);
        if diverged || len == self.start {
            return m;
        }
        m.x_rms_error = self.along_n.rms();
        m.z_rms_error = self.along_t.rms();
        m.path_rms_error = self.path.rms();
        if !self.force_control {
            m.set_drive(Drive::Untested, outcome);
            return m;
        }
        m.bounces = self.bounces as f64;
        m.assessed_time = if self.late_start < len {
            self.time(len - 1 - self.late_start)
        } else {
            0.0
        };
        let steady = len.saturating_sub(self.steady_start.min(len));
        m.force_ss_error = self.steady_error_sum / steady as f64;
        m.tangential_force_mean = self.steady_friction_sum / steady as f64;
        m.force_rms_error = self.late_error.rms();
        m.contact_loss = if self.late_start < len {
            self.contact_lost as f64 / (len - self.late_start) as f64
        } else {
            nan
        };
        m.force_oscillation = self.spread.relative_std();
        if let Some(value) = self.step {
            // Relative to f_d: undefined (NaN) for f_d = 0.
            m.overshoot_pct = if value == 0.0 {
                nan
            } else {
                100.0 * (m.force_peak - value) / value
            };
            m.settling_time = match self.last_unsettled {
                None => 0.0,
                Some(i) if i + 1 < len => self.time(i + 1),
                Some(_) => nan,
            };
            let at = |c: Option<usize>| c.map_or(nan, |i| self.time(i));
            let [ten, rise, ninety] = self.crossings;
            m.rise_time_63 = at(rise);
            m.rise_time_10_90 = at(ninety) - at(ten);
            m.peak_time = self.time(self.peak.0);
            (m.step_overshoot_pct, m.step_peak_time) = match self.lobe {
                Lobe::Before => (0.0, nan),
                Lobe::Open { at, peak } | Lobe::Closed { at, peak } => (
                    if value == 0.0 {
                        nan
                    } else {
                        100.0 * (peak - value) / value
                    },
                    self.time(at),
                ),
            };
        }
        m.set_drive(Drive::Untested, outcome);
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::filter::{AdmittanceParams, ForceControlParams};

    /// A force-controlled 3-s scenario at T = 1 ms with a 10 N step: 3001 samples.
    fn config() -> ScenarioConfig {
        ScenarioConfig {
            duration: 3.0,
            admittance: Some(ForceControlParams::Admittance(AdmittanceParams::scheme2(
                800.0, 0.1,
            ))),
            ..ScenarioConfig::default()
        }
    }

    fn frame() -> TaskFrame {
        TaskFrame::new(TaskVector::x(), TaskVector::zeros(), 0.0)
    }

    /// Metrics of a force signal f(t), with the tip on its reference, starting touching.
    fn metrics_of(config: &ScenarioConfig, force: impl Fn(usize) -> f64) -> Metrics {
        metrics_from(config, 0.0, force)
    }

    /// Metrics of a force signal f(t) whose sample 0 has penetration `delta0` (negative:
    /// the tool starts apart from the surface).
    fn metrics_from(config: &ScenarioConfig, delta0: f64, force: impl Fn(usize) -> f64) -> Metrics {
        let mut online = OnlineMetrics::new(config, &frame());
        for k in 0..config.samples() {
            online.push(&Row {
                t: k as f64 * config.period,
                q: &[0.0; 3],
                qd: &[0.0; 3],
                position: [0.0; 3],
                reference: [0.0; 3],
                f: force(k),
                f_measured: force(k),
                f_d: 10.0,
                penetration: if k == 0 { delta0 } else { 0.0 },
                x_a: 0.0,
                xa_dot: 0.0,
                surface_force: [0.0; 3],
                f_t: 0.0,
                slip_speed: 0.0,
                tau: &[0.0; 3],
                tau_cmd: &[0.0; 3],
            });
        }
        let mut m = online.finish(&Outcome::Completed);
        // The tip sits on its reference and f_d is constant: nothing drives these signals.
        m.set_drive(Drive::Absent, &Outcome::Completed);
        m
    }

    /// SPEC §16: a run that starts apart is judged from first contact + 1 s; one that
    /// starts touching from t = 1 s (today's windows, unchanged).
    #[test]
    fn windows_start_one_second_after_first_contact() {
        let ten = ScenarioConfig {
            duration: 10.0,
            ..config()
        };
        // Free space for 1.6 s, then 10 N held: no loss of contact in the contact phase.
        let held = |k: usize| if k < 1600 { 0.0 } else { 10.0 };
        let apart = metrics_from(&ten, -0.02, held);
        assert_eq!(apart.first_contact_time, 1600.0 * 1e-3);
        assert_eq!(apart.contact_start, 1600.0 * 1e-3);
        assert_eq!(apart.contact_loss, 0.0);
        assert_eq!(apart.assessed_time, (10_000 - 2600) as f64 * 1e-3);
        assert_eq!((apart.force_rms_error, apart.force_ss_error), (0.0, 0.0));
        assert_eq!(apart.impact_peak, 10.0);
        assert_eq!(apart.bounces, 0.0);
        assert_eq!(apart.stable, Some(true));
        assert_eq!(apart.judgement(&Outcome::Completed).verdict, "stable");
        // The same signal from a run that starts touching: 600 of 9001 samples lost.
        let touching = metrics_from(&ten, 0.0, held);
        assert_eq!(touching.contact_start, 0.0);
        assert_eq!(touching.contact_loss, 600.0 / 9001.0);
        assert_eq!(touching.stable, Some(false));
        assert_eq!(
            touching.judgement(&Outcome::Completed).verdict,
            "unstable: loss of contact: f = 0 in 7 % of samples after t = 1 s, 0 bounces \
             (max_contact_loss 5 %) — self-sustained: nothing drives the run (no motion, f_d \
             constant in the last 2 s, no sensor noise)"
        );
        // Contact at 2.5 s of a 3-s run: 0.5 s of contact phase is too short to assess.
        let late = metrics_from(&config(), -0.02, |k| if k < 2500 { 0.0 } else { 10.0 });
        assert_eq!(late.stable, None);
        assert_eq!(
            late.judgement(&Outcome::Completed).verdict,
            "not assessed: only 0 s of the run after t = 3.5 s (first contact at 2.5 s + 1 s), \
             min_assessed is 1 s"
        );
        // Never touched: today's windows, and the verdict says what happened.
        let never = metrics_from(&ten, -0.02, |_| 0.0);
        assert!(never.first_contact_time.is_nan() && never.impact_peak.is_nan());
        assert_eq!(never.contact_loss, 1.0);
        assert_eq!(
            never.judgement(&Outcome::Completed).verdict,
            "out of tolerance: no contact: f = 0 throughout, the tool never touched the surface \
             (max_contact_loss 5 %)"
        );
    }

    /// impact_peak is the largest force within 0.5 s of first contact; a force_limit it
    /// exceeds is failed and named as the impact.
    #[test]
    fn impact_peak_and_the_force_limit() {
        // Contact at 0.5 s, a 30 N spike at 0.7 s, 10 N after; a 25 N bump at 1.2 s (after
        // the impact window) and one of 40 N at 2 s.
        let signal = |bump: f64| {
            move |k: usize| match k {
                0..=499 => 0.0,
                700 => 30.0,
                1200 => 25.0,
                2000 => bump,
                _ => 10.0,
            }
        };
        let limited = |limit: f64| ScenarioConfig {
            criteria: CriteriaParams {
                force_limit: Some(limit),
                ..CriteriaParams::default()
            },
            ..config()
        };
        let m = metrics_from(&limited(20.0), -0.01, signal(10.0));
        assert_eq!(m.first_contact_time, 0.5);
        assert_eq!(m.impact_peak, 30.0);
        assert_eq!(m.force_peak, 30.0);
        // A force peak is the user's tolerance, not the loop's dynamics (SPEC §23).
        assert_eq!((m.stable, m.passed), (Some(true), Some(false)));
        assert_eq!(
            m.judgement(&Outcome::Completed).verdict,
            "out of tolerance: impact peak 30 N (within 0.5 s of first contact at t = 0.5 s) above \
             force_limit 20 N"
        );
        let m = metrics_from(&limited(20.0), -0.01, signal(40.0));
        assert_eq!(
            m.judgement(&Outcome::Completed).verdict,
            "out of tolerance: impact peak 30 N (within 0.5 s of first contact at t = 0.5 s) above \
             force_limit 20 N (force peak 40 N later)"
        );
        // Only the later bump is above the limit: a force peak, not the impact.
        let m = metrics_from(&limited(35.0), -0.01, signal(40.0));
        assert_eq!(m.impact_peak, 30.0);
        assert_eq!(
            m.judgement(&Outcome::Completed).verdict,
            "out of tolerance: force peak 40 N above force_limit 35 N"
        );
    }

    #[test]
    fn step_metrics_on_a_known_signal() {
        // f rises linearly from 0 to 11 over 0.55 s, then sits at 10.
        let m = metrics_of(&config(), |k| {
            let t = k as f64 * 1e-3;
            if t <= 0.55 {
                20.0 * t
            } else {
                10.0
            }
        });
        assert_eq!(m.settling_time, 551.0 * 1e-3);
        assert!((m.rise_time_63 - 0.316).abs() < 1e-12);
        assert!((m.rise_time_10_90 - 0.4).abs() < 1e-9);
        assert_eq!(m.peak_time, 550.0 * 1e-3);
        assert!((m.overshoot_pct - 10.0).abs() < 1e-9);
        assert!((m.force_peak - 11.0).abs() < 1e-12);
        assert_eq!(
            (m.force_ss_error, m.force_rms_error, m.force_oscillation),
            (0.0, 0.0, 0.0)
        );
        assert_eq!(m.contact_loss, 0.0);
        assert_eq!(m.stable, Some(true));
        // 1 s ≤ t ≤ 1.1 s off by −0.1 N per 10 ms: mean and RMS over the 2001 samples.
        let m = metrics_of(&config(), |k| {
            10.0 + if (1000..=1100).contains(&k) {
                0.01 * (k - 1000) as f64
            } else {
                0.0
            }
        });
        assert!((m.force_ss_error + 0.01 * 5050.0 / 2001.0).abs() < 1e-12);
        let squares: f64 = (0..=100).map(|i| (0.01 * i as f64).powi(2)).sum();
        assert!((m.force_rms_error - (squares / 2001.0).sqrt()).abs() < 1e-12);
        // A signal that never enters the band never settles.
        assert!(metrics_of(&config(), |_| 5.0).settling_time.is_nan());
        assert!(metrics_of(&config(), |_| 5.0).rise_time_63.is_nan());
    }

    #[test]
    fn oscillation_is_relative_std_about_the_reference_in_the_last_2_s() {
        // f alternates 9 / 11 about f_d = 10 (std 1, relative 0.1) in the last 2 s only.
        // 1001 samples at 9 and 1000 at 11: mean error −1/2001.
        let m = metrics_of(&config(), |k| match (k < 1000, k % 2 == 0) {
            (true, _) => 0.0,
            (false, true) => 9.0,
            (false, false) => 11.0,
        });
        let expected = (1.0 - (1.0f64 / 2001.0).powi(2)).sqrt() / 10.0;
        assert!(
            (m.force_oscillation - expected).abs() < 1e-14,
            "{}",
            m.force_oscillation
        );
        assert_eq!(m.stable, Some(true));
        // Large offset, tiny spread: Welford's update keeps it (a one-pass Σd² − n·mean²
        // would lose it in cancellation).
        let m = metrics_of(&config(), |k| 1e6 + if k % 2 == 0 { -1e-6 } else { 1e-6 });
        assert!(
            (m.force_oscillation - 1e-7).abs() < 1e-12,
            "{}",
            m.force_oscillation
        );
        // Contact lost in the last 2 s: 2000 of 2001 samples.
        let m = metrics_of(&config(), |k| if k == 1000 { 10.0 } else { 0.0 });
        assert_eq!(m.contact_loss, 2000.0 / 2001.0);
        assert_eq!(m.stable, Some(false));
    }

    #[test]
    fn windows_by_index() {
        assert_eq!(first_index_at(8.0, 1e-3), 8000);
        assert_eq!(first_index_at(1.0, 1e-3), 1000);
        assert_eq!(first_index_at(-1.0, 1e-3), 0);
        let online = OnlineMetrics::new(&config(), &frame());
        assert_eq!((online.steady_start, online.late_start), (1000, 1000));
        let ten = ScenarioConfig {
            duration: 10.0,
            ..config()
        };
        let online = OnlineMetrics::new(&ten, &frame());
        assert_eq!((online.steady_start, online.window_start), (8000, 8000));
    }

    #[test]
    fn rms_of_huge_errors_does_not_overflow() {
        let mut s = SumOfSquares::ZERO;
        for x in [1e300, -1e300, 1e300, -1e300] {
            s.push(x);
        }
        assert_eq!(s.rms(), 1e300);
        let mut s = SumOfSquares::ZERO;
        for x in [3.0, 4.0] {
            s.push(x);
        }
        assert_eq!(s.rms(), (12.5f64).sqrt());
        let mut s = SumOfSquares::ZERO;
        for x in [0.0, 1e200, 3e200] {
            s.push(x);
        }
        assert!((s.rms() / (1e200 * (10.0f64 / 3.0).sqrt()) - 1.0).abs() < 1e-15);
        // The largest finite values, and small ones beside them (which underflow in the
        // scaled sum, far below its rounding).
        let mut s = SumOfSquares::ZERO;
        for x in [f64::MAX, -f64::MAX, 1e-3, 1.0] {
            s.push(x);
        }
        assert!((s.rms() / (f64::MAX / 2f64.sqrt()) - 1.0).abs() < 1e-15);
        // An infinite sample gives inf, a NaN one NaN (never a finite RMS that skipped it).
        let rms_of = |xs: &[f64]| {
            let mut s = SumOfSquares::ZERO;
            xs.iter().for_each(|&x| s.push(x));
            s.rms()
        };
        assert_eq!(rms_of(&[1.0, f64::INFINITY]), f64::INFINITY);
        assert!(rms_of(&[1e300, f64::NAN, 1e300]).is_nan());
        assert!(rms_of(&[]).is_nan());
    }

    #[test]
    fn saturation_counts_samples_with_any_joint_at_its_limit() {
        let cfg = ScenarioConfig {
            actuator: crate::world::actuator::ActuatorParams {
                torque_limit: Some(vec![1.0, 2.0, 3.0]),
                ..Default::default()
            },
            ..config()
        };
        let mut online = OnlineMetrics::new(&cfg, &frame());
        for tau in [
            [0.5, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, -2.5, 0.0],
            [0.0, 0.0, 2.9],
        ] {
            online.push(&Row {
                t: 0.0,
                q: &[0.0; 3],
                qd: &[0.0; 3],
                position: [0.0; 3],
                reference: [0.0; 3],
                f: 0.0,
                f_measured: 0.0,
                f_d: 10.0,
                penetration: 0.0,
                x_a: 0.0,
                xa_dot: 0.0,
                surface_force: [0.0; 3],
                f_t: 0.0,
                slip_speed: 0.0,
                tau: &tau,
                tau_cmd: &tau,
            });
        }
        let m = online.finish(&Outcome::Completed);
        assert_eq!(m.torque_saturation, 0.5);
    }
}
