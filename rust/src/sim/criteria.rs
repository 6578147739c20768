//! Verdicts a user can set (SPEC §17, §23): the criteria a run is judged by, and the
//! judgement in words. One place decides `stable` (the loop's dynamics) and `passed` (the
//! criteria) and writes the verdict, so `Result.metrics`, `Result.verdict`, sweep tables and
//! the command line cannot disagree.

use crate::error::{check, Error, Result};
use crate::sim::outcome::Outcome;

/// What a run must meet to pass. Limits left at ``None`` are not judged.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(default, deny_unknown_fields)]
pub struct CriteriaParams {
    /// Largest force_oscillation (std(f − f_d) over the last 2 s of the contact phase / mean |f_d|) of a force-controlled run that passes [fraction of f_d].
    pub max_force_oscillation: f64,
    /// Largest contact_loss (fraction of samples with f = 0 from first contact + 1 s; t ≥ 1 s for a run that starts touching) of a force-controlled run that passes [fraction].
    pub max_contact_loss: f64,
    /// Largest contact force anywhere in the run (force_peak, the impact peak included) [N]; ``None``: not judged.
    pub force_limit: Option<f64>,
    /// Largest number of bounces (contact lost after first contact) [count]; ``None``: not judged.
    pub max_bounces: Option<f64>,
    /// Largest path_rms_error [m]; ``None``: not judged.
    pub max_path_error: Option<f64>,
    /// Largest torque_saturation (fraction of samples with a joint at its torque limit) [fraction]; ``None``: not judged.
    pub max_torque_saturation: Option<f64>,
    /// Shortest assessed window (assessed_time, from first contact + 1 s to the end) a force-controlled run needs for a verdict [s]; shorter runs are "not assessed".
    pub min_assessed: f64,
    /// Run a run that fails max_force_oscillation, max_contact_loss or max_bounces again with its drives held (the motion at s(0), f_d held, no sensor noise) to tell a ripple the motion drives (stable, out of tolerance) from one the loop sustains (unstable), SPEC §23; false: no second run, such runs are "stable" None (``passed`` is judged either way).
    pub held_run: bool,
}

impl Default for CriteriaParams {
    fn default() -> Self {
        Self {
            max_force_oscillation: 0.1,
            max_contact_loss: 0.05,
            force_limit: None,
            max_bounces: None,
            max_path_error: None,
            max_torque_saturation: None,
            min_assessed: 1.0,
            held_run: true,
        }
    }
}

impl CriteriaParams {
    pub fn validate(&self) -> Result<()> {
        check::non_negative("max_force_oscillation", self.max_force_oscillation)?;
        check::non_negative("max_contact_loss", self.max_contact_loss)?;
        check::non_negative("min_assessed", self.min_assessed)?;
        for (name, v) in [
            ("force_limit", self.force_limit),
            ("max_path_error", self.max_path_error),
            ("max_torque_saturation", self.max_torque_saturation),
        ] {
            if let Some(v) = v {
                check::non_negative(name, v)?;
            }
        }
        if let Some(b) = self.max_bounces {
            if !(b.is_finite() && b >= 0.0 && b == b.round()) {
                return Err(Error::parameter(
                    "max_bounces",
                    b,
                    "a whole number >= 0 or None",
                ));
            }
        }
        Ok(())
    }
}

/// The figures of a run that the criteria read. `Metrics::figures` gives them; the
/// criteria take them by value so that this file stays below the metrics (no cycle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figures {
    pub force_peak: f64,
    pub contact_loss: f64,
    pub force_oscillation: f64,
    pub bounces: f64,
    pub first_contact_time: f64,
    pub impact_peak: f64,
    /// When the contact phase starts (0: the run starts touching or never touches).
    pub contact_start: f64,
    pub assessed_time: f64,
    pub path_rms_error: f64,
    pub torque_saturation: f64,
    /// A guarded approach's handover, if the run has one.
    pub handover: Option<Handover>,
}

/// Whether a guarded approach handed over to force control: it does at the first sample
/// whose measured force exceeds its threshold (`control::approach`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Handover {
    pub measured_peak: f64,
    pub threshold: f64,
}

impl Handover {
    /// Force control took over at some sample.
    pub fn happened(&self) -> bool {
        self.measured_peak > self.threshold
    }
}

impl Figures {
    /// "force control never took over (…)" when a guarded approach never handed over: the
    /// force loop never ran, so neither its dynamics nor its criteria can be judged.
    fn never_handed_over(&self) -> Option<String> {
        let h = self.handover.filter(|h| !h.happened())?;
        let peak = if h.measured_peak.is_finite() {
            format!("{} N", short(h.measured_peak))
        } else {
            "nothing".to_owned()
        };
        Some(format!(
            "force control never took over: the measured force peaked at {peak}, never above \
             the guarded approach's threshold {} N, so the approach pushed on to the end",
            short(h.threshold)
        ))
    }
}

/// What drives a run besides its own loop, and what the run showed with those drives held
/// (SPEC §23): how an oscillation the references drive is told from one the loop sustains.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Drive {
    /// Nothing drives the assessed window (no motion, f_d constant in it, no sensor
    /// noise): an oscillation there is the loop's own.
    Absent,
    /// Something drives the run and the held run has not been run.
    Untested,
    /// The same run with its drives held (`sim/held.rs`): what it showed.
    Held(Held),
}

/// Which drives a held run held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Holds {
    /// The motion s(t), held at s(0).
    pub motion: bool,
    /// f_d, held at its value where the last 2 s start.
    pub force: bool,
    /// The sensor's noise, off.
    pub noise: bool,
    /// Times the references turn back or jump in the run (`Signal::reversals`): the
    /// events a driven loss of contact can follow.
    pub events: usize,
}

impl Holds {
    pub fn any(&self) -> bool {
        self.motion || self.force || self.noise
    }

    /// "the motion held and the sensor noise off".
    fn words(&self) -> String {
        let mut parts = Vec::new();
        if self.motion {
            parts.push("the motion held");
        }
        if self.force {
            parts.push("f_d held");
        }
        if self.noise {
            parts.push("the sensor noise off");
        }
        match parts.as_slice() {
            [] => "nothing held".into(),
            [one] => (*one).into(),
            [init @ .., last] => format!("{} and {last}", init.join(", ")),
        }
    }
}

/// A loss of contact the references drive leaves the surface a few times per event (a
/// friction reversal, a step of f_d); more bounces than this per event (plus one) is the
/// loop bouncing at its own frequency, whatever the held run shows.
pub const BOUNCES_PER_EVENT: f64 = 3.0;

/// The figures of the held run that tell driven from self-sustained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Held {
    pub holds: Holds,
    pub force_oscillation: f64,
    pub contact_loss: f64,
    pub bounces: f64,
    /// When the held run touched the surface first (NaN: never).
    pub first_contact_time: f64,
    /// When the held run diverged (NaN: it completed).
    pub diverged_at: f64,
}

/// The judgement of one run (SPEC §23): `stable` is the loop's dynamics (diverged, or an
/// oscillation or loss of contact the loop sustains by itself), `passed` the criteria;
/// ``None``: not assessed. The verdict says which, in words.
#[derive(Debug, Clone, PartialEq)]
pub struct Judgement {
    pub stable: Option<bool>,
    pub passed: Option<bool>,
    pub verdict: String,
}

/// A criterion a run failed, in words; `dynamic` when the loop may sustain it by itself
/// (force oscillation, loss of contact after touching, bounces), which the held run tells.
struct Failure {
    words: String,
    dynamic: bool,
}

/// A short number: 4 significant digits, trailing zeros dropped (1e-4 ≤ |x| < 1e6), else
/// scientific.
pub fn short(x: f64) -> String {
    significant(x, 4)
}

/// `x` to `digits` significant digits, trailing zeros dropped (1e-4 ≤ |x| < 1e6), else
/// scientific.
fn significant(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".into();
    }
    let a = x.abs();
    if (1e-4..1e6).contains(&a) {
        let decimals = (digits as i32 - 1 - a.log10().floor() as i32).clamp(0, 16) as usize;
        let s = format!("{x:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            s
        }
    } else {
        format!("{x:.prec$e}", prec = digits.saturating_sub(1))
    }
}

/// A fraction as a percentage: whole per cent from 1 %, two significant digits below
/// ("0.12 %", "5.5e-5 %").
fn pct(v: f64) -> String {
    let p = 100.0 * v;
    if v >= 0.01 {
        format!("{p:.0} %")
    } else if p != 0.0 && p.abs() < 1e-4 {
        format!("{p:.1e} %")
    } else {
        format!("{} %", short(float_2g(p)))
    }
}

/// A value and the limit it failed, written so that they read apart: a value just over its
/// limit gets the digits that show it ("4.04 % (max 4 %)", not "4 % (max 4 %)").
fn apart(value: f64, limit: f64, percent: bool) -> (String, String) {
    let first = if percent {
        (pct(value), pct(limit))
    } else {
        (short(value), short(limit))
    };
    if first.0 != first.1 || value == limit || !(value.is_finite() && limit.is_finite()) {
        return first;
    }
    // More significant digits than `pct` and `short` give, until the two differ.
    let (scale, unit, from) = if percent {
        (100.0, " %", 2)
    } else {
        (1.0, "", 5)
    };
    for digits in from..=17 {
        let (v, l) = (
            significant(scale * value, digits),
            significant(scale * limit, digits),
        );
        if v != l {
            return (format!("{v}{unit}"), format!("{l}{unit}"));
        }
    }
    first
}

/// "1 bounce", "198 bounces".
fn bounces(n: f64) -> String {
    if n == 1.0 {
        "1 bounce".into()
    } else {
        format!("{} bounces", short(n))
    }
}

fn float_2g(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let scale = 10f64.powi(1 - x.abs().log10().floor() as i32);
    (x * scale).round() / scale
}

/// The criteria a run failed, and why the rest could not be judged (a short window).
fn failures(
    m: &Figures,
    criteria: &CriteriaParams,
    force_control: bool,
) -> (Vec<Failure>, Vec<String>) {
    let mut failed: Vec<Failure> = Vec::new();
    let mut unjudged: Vec<String> = Vec::new();
    let mut fail = |words: String, dynamic: bool| failed.push(Failure { words, dynamic });
    let exceeds = |v: f64, limit: f64| v.is_finite() && v > limit;
    if force_control {
        let (loss, osc) = (m.contact_loss, m.force_oscillation);
        // The windows start 1 s into the contact phase (SPEC §16).
        let after = if m.contact_start > 0.0 {
            format!(
                "after t = {} s (first contact at {} s + 1 s)",
                short(m.contact_start + 1.0),
                short(m.contact_start)
            )
        } else {
            "after t = 1 s".to_owned()
        };
        if exceeds(loss, criteria.max_contact_loss) {
            if m.first_contact_time.is_nan() {
                // Not the loop's dynamics: the tool never reached the surface.
                fail(
                    format!(
                        "no contact: f = 0 throughout, the tool never touched the surface \
                         (max_contact_loss {})",
                        pct(criteria.max_contact_loss)
                    ),
                    false,
                );
            } else {
                let (value, limit) = apart(loss, criteria.max_contact_loss, true);
                fail(
                    format!(
                        "loss of contact: f = 0 in {value} of samples {after}, {} \
                         (max_contact_loss {limit})",
                        bounces(m.bounces),
                    ),
                    true,
                );
            }
        }
        if exceeds(osc, criteria.max_force_oscillation) {
            // Ripple in contact (friction, motion) reads differently from bouncing.
            let kind = if loss == 0.0 {
                "force oscillation, contact kept"
            } else {
                "force oscillation with loss of contact"
            };
            let (value, limit) = apart(osc, criteria.max_force_oscillation, true);
            fail(
                format!(
                    "{kind}: std(f − f_d) over the last 2 s is {value} of f_d \
                     (max_force_oscillation {limit})"
                ),
                true,
            );
        }
        if let Some(limit) = criteria.force_limit {
            // The impact (0.5 s from first contact) is named: it is what a guarded
            // approach or a slower one changes, unlike a later peak.
            let (impact_peak, impact_limit) = apart(m.impact_peak, limit, false);
            let (force_peak, force_limit) = apart(m.force_peak, limit, false);
            let impact = format!(
                "impact peak {impact_peak} N (within 0.5 s of first contact at t = {} s)",
                short(m.first_contact_time)
            );
            match (exceeds(m.impact_peak, limit), exceeds(m.force_peak, limit)) {
                (true, _) if m.force_peak > m.impact_peak => fail(
                    format!(
                        "{impact} above force_limit {impact_limit} N (force peak \
                         {force_peak} N later)"
                    ),
                    false,
                ),
                (true, _) => fail(
                    format!("{impact} above force_limit {impact_limit} N"),
                    false,
                ),
                (false, true) => fail(
                    format!("force peak {force_peak} N above force_limit {force_limit} N"),
                    false,
                ),
                (false, false) => {}
            }
        }
        if let Some(limit) = criteria.max_bounces {
            if exceeds(m.bounces, limit) {
                fail(
                    format!("{} above max_bounces {}", bounces(m.bounces), short(limit)),
                    true,
                );
            }
        }
        if !(m.assessed_time >= criteria.min_assessed && m.assessed_time > 0.0) {
            unjudged.push(format!(
                "only {} s of the run {after}, min_assessed is {} s",
                short(m.assessed_time.max(0.0)),
                short(criteria.min_assessed)
            ));
        } else if osc.is_nan() || loss.is_nan() {
            unjudged.push("f_d is 0 in the last 2 s, so force_oscillation is undefined".into());
        }
    }
    if let Some(limit) = criteria.max_path_error {
        if exceeds(m.path_rms_error, limit) {
            let (value, limit) = apart(m.path_rms_error, limit, false);
            fail(
                format!("path error {value} m RMS above max_path_error {limit} m"),
                false,
            );
        }
    }
    if let Some(limit) = criteria.max_torque_saturation {
        if exceeds(m.torque_saturation, limit) {
            let (value, limit) = apart(m.torque_saturation, limit, true);
            fail(
                format!("torque saturated in {value} of samples (max_torque_saturation {limit})"),
                false,
            );
        }
    }
    (failed, unjudged)
}

/// Whether a run needs its held run to be judged: it completed and failed a criterion the
/// loop may sustain by itself (force oscillation, loss of contact after touching, bounces).
pub fn needs_held(
    m: &Figures,
    criteria: &CriteriaParams,
    force_control: bool,
    outcome: &Outcome,
) -> bool {
    !outcome.is_diverged()
        && m.never_handed_over().is_none()
        && failures(m, criteria, force_control)
            .0
            .iter()
            .any(|f| f.dynamic)
}

/// What the held run says of the dynamic failures: `Some(true)` self-sustained (the held
/// run fails a dynamic criterion too, or diverged), `Some(false)` driven, `None` untold.
fn sustained(held: &Held, criteria: &CriteriaParams) -> Option<bool> {
    if held.diverged_at.is_finite() {
        return Some(true);
    }
    if held.first_contact_time.is_nan() {
        // Held, the tool never reached the surface: the test says nothing.
        return None;
    }
    let exceeds = |v: f64, limit: f64| v.is_finite() && v > limit;
    Some(
        exceeds(held.contact_loss, criteria.max_contact_loss)
            || exceeds(held.force_oscillation, criteria.max_force_oscillation)
            || criteria
                .max_bounces
                .is_some_and(|limit| exceeds(held.bounces, limit)),
    )
}

/// "std(f − f_d) 0.52 % of f_d, contact lost in 0 % of samples": the held run's figures.
/// With `max_bounces` set, the held run's bounces too.
fn held_figures(held: &Held, criteria: &CriteriaParams) -> String {
    if held.diverged_at.is_finite() {
        return format!("it diverged at t = {} s", short(held.diverged_at));
    }
    let (osc, loss) = (pct(held.force_oscillation), pct(held.contact_loss));
    match criteria.max_bounces {
        None => format!("std(f − f_d) is {osc} of f_d and f = 0 in {loss} of samples"),
        Some(_) => format!(
            "std(f − f_d) is {osc} of f_d, f = 0 in {loss} of samples and {}",
            bounces(held.bounces)
        ),
    }
}

/// Judges a run (SPEC §17, §23). Diverged: unstable. A failed criterion the loop may sustain
/// by itself (force oscillation, loss of contact, bounces) makes it unstable when the same
/// run with its drives held ([`Drive`]) fails it too, or nothing drives the run; else the
/// run is stable and out of tolerance, like any other failed criterion, each named with its
/// value and limit. A force-controlled run whose assessed window is shorter than
/// `min_assessed` (or empty) and failed nothing is not assessed (`None`); position-only runs
/// are judged on divergence and, if set, the path error and torque saturation.
pub fn judge(
    m: &Figures,
    criteria: &CriteriaParams,
    force_control: bool,
    outcome: &Outcome,
    drive: &Drive,
) -> Judgement {
    if let Outcome::Diverged { time, cause } = outcome {
        return Judgement {
            stable: Some(false),
            passed: Some(false),
            verdict: format!("unstable: diverged at t = {} s ({cause})", short(*time)),
        };
    }
    if let Some(why) = m.never_handed_over() {
        // Not the force loop's dynamics (it never ran): not assessed, and failed.
        return Judgement {
            stable: None,
            passed: Some(false),
            verdict: format!("not assessed: {why}"),
        };
    }
    let (failed, unjudged) = failures(m, criteria, force_control);
    let words = |dynamic: bool| -> Vec<String> {
        failed
            .iter()
            .filter(|f| f.dynamic == dynamic)
            .map(|f| f.words.clone())
            .collect()
    };
    let (dynamic, tolerance) = (words(true), words(false));
    let not_assessed = format!("not assessed: {}", unjudged.join("; "));
    if !dynamic.is_empty() {
        let (sustained, why) = match drive {
            Drive::Absent => (
                Some(true),
                "self-sustained: nothing drives the run (no motion, f_d constant in the \
                 last 2 s, no sensor noise)"
                    .to_owned(),
            ),
            Drive::Untested => (
                None,
                if criteria.held_run {
                    "driven or self-sustained: the run with its references held was not run"
                        .to_owned()
                } else {
                    "driven or self-sustained: not told (criteria.held_run is false)".to_owned()
                },
            ),
            Drive::Held(held) => {
                let with = held.holds.words();
                match sustained(held, criteria) {
                    Some(true) => (
                        Some(true),
                        format!(
                            "self-sustained: with {with}, {}",
                            held_figures(held, criteria)
                        ),
                    ),
                    // Quiet when held, yet bouncing far more often than the references
                    // turn: the loop's own frequency (not with noise, whose events are
                    // not counted).
                    Some(false)
                        if !held.holds.noise
                            && m.bounces > BOUNCES_PER_EVENT * (held.holds.events as f64 + 1.0) =>
                    {
                        (
                            Some(true),
                            format!(
                                "self-sustained: {}, more than {} per reversal of the \
                                 references ({} in the run): the loop bouncing at its own \
                                 frequency",
                                bounces(m.bounces),
                                short(BOUNCES_PER_EVENT),
                                held.holds.events
                            ),
                        )
                    }
                    Some(false) => (
                        Some(false),
                        format!("driven: with {with}, {}", held_figures(held, criteria)),
                    ),
                    None => (
                        None,
                        format!(
                            "driven or self-sustained: with {with} the tool never touched \
                             the surface"
                        ),
                    ),
                }
            }
        };
        let dynamic = format!("{} — {why}", dynamic.join("; "));
        let also = if tolerance.is_empty() {
            String::new()
        } else {
            format!("; out of tolerance: {}", tolerance.join("; "))
        };
        let verdict = match sustained {
            Some(true) => format!("unstable: {dynamic}{also}"),
            Some(false) => {
                let all: Vec<String> = std::iter::once(dynamic).chain(tolerance).collect();
                format!("out of tolerance: {}", all.join("; "))
            }
            None => format!("out of tolerance: {dynamic}{also}; stability not assessed"),
        };
        return Judgement {
            stable: sustained.map(|s| !s),
            passed: Some(false),
            verdict,
        };
    }
    if !tolerance.is_empty() {
        let (stable, short_window) = if unjudged.is_empty() {
            (Some(true), String::new())
        } else {
            (None, format!("; stability {not_assessed}"))
        };
        return Judgement {
            stable,
            passed: Some(false),
            verdict: format!("out of tolerance: {}{short_window}", tolerance.join("; ")),
        };
    }
    if !unjudged.is_empty() {
        return Judgement {
            stable: None,
            passed: None,
            verdict: not_assessed,
        };
    }
    let mut notes: Vec<String> = Vec::new();
    if !force_control {
        notes.push(match criteria.max_path_error {
            Some(_) => "position-only run: judged on divergence and path error".into(),
            None => "position-only run: judged on divergence only (set max_path_error)".into(),
        });
    }
    if criteria.max_torque_saturation.is_none() && m.torque_saturation > 0.0 {
        notes.push(format!(
            "torque saturated in {} of samples, not judged (set max_torque_saturation)",
            pct(m.torque_saturation)
        ));
    }
    Judgement {
        stable: Some(true),
        passed: Some(true),
        verdict: if notes.is_empty() {
            "stable".into()
        } else {
            format!("stable ({})", notes.join("; "))
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_numbers() {
        assert_eq!(short(38.8123), "38.81");
        assert_eq!(short(0.321), "0.321");
        assert_eq!(short(10.0), "10");
        assert_eq!(short(1e300), "1.000e300");
        assert_eq!(short(-2.5e-7), "-2.500e-7");
        assert_eq!(pct(0.78), "78 %");
        assert_eq!(pct(0.00123), "0.12 %");
        assert_eq!(pct(5.5e-7), "5.5e-5 %");
        assert_eq!(pct(0.0), "0 %");
    }

    /// Issue #53, item 18: a value just over its limit read as equal to it.
    #[test]
    fn a_value_and_its_limit_read_apart() {
        assert_eq!(apart(0.0404, 0.04, true), ("4.04 %".into(), "4 %".into()));
        assert_eq!(apart(0.12, 0.04, true), ("12 %".into(), "4 %".into()));
        assert_eq!(
            apart(12.5812, 12.58, false),
            ("12.581".into(), "12.58".into())
        );
        assert_eq!(apart(12.58 + 1e-12, 12.58, false).0, "12.580000000001");
        assert_eq!(apart(3.0, 3.0, false), ("3".into(), "3".into()));
        assert_eq!(
            (bounces(1.0), bounces(198.0)),
            ("1 bounce".into(), "198 bounces".into())
        );
    }

    /// A run in contact throughout whose force ripples at 14 % of f_d (the issue #54 cell).
    fn rippling() -> Figures {
        Figures {
            force_peak: 12.0,
            contact_loss: 0.0,
            force_oscillation: 0.14,
            bounces: 0.0,
            first_contact_time: 0.001,
            impact_peak: 11.0,
            contact_start: 0.0,
            assessed_time: 9.0,
            path_rms_error: 1e-4,
            torque_saturation: 0.0,
            handover: None,
        }
    }

    /// Issue #53 item 7: a guarded approach whose threshold is never reached pushes on
    /// (709 N); the verdict said "force oscillation, contact kept: 1219 %".
    #[test]
    fn an_approach_that_never_hands_over_is_said() {
        let pushing = Figures {
            force_peak: 709.0,
            force_oscillation: 12.19,
            handover: Some(Handover {
                measured_peak: 709.2,
                threshold: 1e4,
            }),
            ..rippling()
        };
        let criteria = CriteriaParams::default();
        let j = judge(
            &pushing,
            &criteria,
            true,
            &Outcome::Completed,
            &Drive::Untested,
        );
        assert_eq!(
            j.verdict,
            "not assessed: force control never took over: the measured force peaked at 709.2 \
             N, never above the guarded approach's threshold 10000 N, so the approach pushed \
             on to the end"
        );
        assert_eq!((j.stable, j.passed), (None, Some(false)));
        assert!(!needs_held(&pushing, &criteria, true, &Outcome::Completed));
        // Handed over: judged as usual.
        let handed = Figures {
            handover: Some(Handover {
                measured_peak: 10.5,
                threshold: 1.0,
            }),
            ..rippling()
        };
        assert!(needs_held(&handed, &criteria, true, &Outcome::Completed));
    }

    fn held(force_oscillation: f64, contact_loss: f64) -> Drive {
        Drive::Held(Held {
            holds: Holds {
                motion: true,
                force: false,
                noise: true,
                events: 3,
            },
            force_oscillation,
            contact_loss,
            bounces: 0.0,
            first_contact_time: 0.001,
            diverged_at: f64::NAN,
        })
    }

    /// SPEC §23: the ripple is the motion's when the held run is quiet, the loop's when the
    /// held run ripples too, or when nothing drives the run; untold before the held run.
    #[test]
    fn driven_ripple_is_out_of_tolerance_and_sustained_ripple_unstable() {
        let c = CriteriaParams::default();
        let done = Outcome::Completed;
        let ripple = "force oscillation, contact kept: std(f − f_d) over the last 2 s is 14 % \
                      of f_d (max_force_oscillation 10 %)";
        let j = judge(&rippling(), &c, true, &done, &held(0.004, 0.0));
        assert_eq!((j.stable, j.passed), (Some(true), Some(false)));
        assert_eq!(
            j.verdict,
            format!(
                "out of tolerance: {ripple} — driven: with the motion held and the sensor \
                 noise off, std(f − f_d) is 0.4 % of f_d and f = 0 in 0 % of samples"
            )
        );
        let j = judge(&rippling(), &c, true, &done, &held(0.13, 0.0));
        assert_eq!((j.stable, j.passed), (Some(false), Some(false)));
        assert_eq!(
            j.verdict,
            format!(
                "unstable: {ripple} — self-sustained: with the motion held and the sensor \
                 noise off, std(f − f_d) is 13 % of f_d and f = 0 in 0 % of samples"
            )
        );
        // Held, the tool leaves the surface: bouncing is the loop's.
        let j = judge(&rippling(), &c, true, &done, &held(0.05, 0.2));
        assert_eq!(j.stable, Some(false));
        let j = judge(&rippling(), &c, true, &done, &Drive::Absent);
        assert_eq!(j.stable, Some(false));
        assert!(j.verdict.ends_with(
            "self-sustained: nothing drives the run (no motion, f_d \
             constant in the last 2 s, no sensor noise)"
        ));
        let j = judge(&rippling(), &c, true, &done, &Drive::Untested);
        assert_eq!((j.stable, j.passed), (None, Some(false)));
        // A path error beside a sustained ripple: unstable, and the tolerance named after.
        let strict = CriteriaParams {
            max_path_error: Some(1e-5),
            ..c
        };
        let j = judge(&rippling(), &strict, true, &done, &Drive::Absent);
        assert!(
            j.verdict.starts_with("unstable: force oscillation")
                && j.verdict.ends_with(
                    "no sensor noise); out of tolerance: path error 0.0001 m RMS above \
                     max_path_error 1.000e-5 m"
                ),
            "{}",
            j.verdict
        );
        // Bouncing with the motion only, 154 times against 3 reversals: the loop's own
        // frequency, whatever the held run shows (SPEC §23 names bouncing self-sustained).
        let chatter = Figures {
            contact_loss: 0.33,
            bounces: 154.0,
            ..rippling()
        };
        let quiet = |d: Drive| match d {
            Drive::Held(h) => Drive::Held(Held {
                holds: Holds {
                    noise: false,
                    ..h.holds
                },
                ..h
            }),
            other => other,
        };
        let j = judge(&chatter, &c, true, &done, &quiet(held(0.004, 0.0)));
        assert_eq!((j.stable, j.passed), (Some(false), Some(false)));
        assert!(
            j.verdict.ends_with(
                "— self-sustained: 154 bounces, more than 3 per reversal of the references \
                 (3 in the run): the loop bouncing at its own frequency"
            ),
            "{}",
            j.verdict
        );
        // One lift-off per reversal is what a driven loss of contact looks like.
        let lifted = Figures {
            bounces: 12.0,
            ..chatter
        };
        assert_eq!(
            judge(&lifted, &c, true, &done, &quiet(held(0.004, 0.0))).stable,
            Some(true)
        );
        // With noise the bounces are not counted against the references' events: the held
        // run (noise off) decides.
        assert_eq!(
            judge(&chatter, &c, true, &done, &held(0.004, 0.0)).stable,
            Some(true)
        );
        // A held run that diverged: unstable.
        let mut d = held(0.0, 0.0);
        if let Drive::Held(h) = &mut d {
            h.diverged_at = 3.25;
        }
        let j = judge(&rippling(), &c, true, &done, &d);
        assert_eq!(j.stable, Some(false));
        assert!(
            j.verdict.contains("it diverged at t = 3.25 s"),
            "{}",
            j.verdict
        );
        // Diverged itself: unstable, and failed.
        let diverged = Outcome::Diverged {
            time: 1.5,
            cause: crate::sim::outcome::Divergence::NonFiniteState,
        };
        let j = judge(&rippling(), &c, true, &diverged, &Drive::Untested);
        assert_eq!((j.stable, j.passed), (Some(false), Some(false)));
        assert!(!needs_held(&rippling(), &c, true, &diverged));
        assert!(needs_held(&rippling(), &c, true, &done));
        // Within tolerance: no held run needed, stable and passed.
        let calm = Figures {
            force_oscillation: 0.05,
            ..rippling()
        };
        assert!(!needs_held(&calm, &c, true, &done));
        let j = judge(&calm, &c, true, &done, &Drive::Untested);
        assert_eq!(
            (j.stable, j.passed, j.verdict.as_str()),
            (Some(true), Some(true), "stable")
        );
    }

    #[test]
    fn bounces_must_be_whole() {
        let c = CriteriaParams {
            max_bounces: Some(1.5),
            ..Default::default()
        };
        assert!(c.validate().is_err());
        assert!(CriteriaParams::default().validate().is_ok());
    }
}
