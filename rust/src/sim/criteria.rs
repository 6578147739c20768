//! Verdicts a user can set (SPEC §17): the criteria a run is judged by, and the judgement
//! in words. One place decides `stable` and writes the verdict, so `Result.metrics`,
//! `Result.verdict`, sweep tables and the command line cannot disagree.

use crate::error::{check, Error, Result};
use crate::sim::outcome::Outcome;

/// What a run must meet to be called stable. Limits left at ``None`` are not judged.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(default, deny_unknown_fields)]
pub struct CriteriaParams {
    /// Largest force_oscillation (std(f − f_d) over the last 2 s of the contact phase / mean |f_d|) of a stable force-controlled run [fraction of f_d].
    pub max_force_oscillation: f64,
    /// Largest contact_loss (fraction of samples with f = 0 from first contact + 1 s; t ≥ 1 s for a run that starts touching) of a stable force-controlled run [fraction].
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
}

/// The judgement of one run: `stable` (``None``: not assessed) and why, in words.
#[derive(Debug, Clone, PartialEq)]
pub struct Judgement {
    pub stable: Option<bool>,
    pub verdict: String,
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

/// A fraction as a percentage: whole per cent from 1 %, two significant digits below.
fn pct(v: f64) -> String {
    if v >= 0.01 {
        format!("{:.0} %", 100.0 * v)
    } else {
        format!("{} %", short(float_2g(100.0 * v)))
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

/// Judges a run (SPEC §17). Diverged: unstable. Any criterion that fails: unstable, each
/// named with its value and limit. Otherwise a force-controlled run whose assessed window
/// is shorter than `min_assessed` (or empty) is not assessed (`stable` = None); position-only
/// runs are judged on divergence and, if set, the path error and torque saturation.
pub fn judge(
    m: &Figures,
    criteria: &CriteriaParams,
    force_control: bool,
    outcome: &Outcome,
) -> Judgement {
    if let Outcome::Diverged { time, cause } = outcome {
        return Judgement {
            stable: Some(false),
            verdict: format!("unstable: diverged at t = {} s ({cause})", short(*time)),
        };
    }
    let mut failed: Vec<String> = Vec::new();
    let mut unjudged: Vec<String> = Vec::new();
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
                failed.push(format!(
                    "no contact: f = 0 throughout, the tool never touched the surface \
                     (max_contact_loss {})",
                    pct(criteria.max_contact_loss)
                ));
            } else {
                let (value, limit) = apart(loss, criteria.max_contact_loss, true);
                failed.push(format!(
                    "loss of contact: f = 0 in {value} of samples {after}, {} \
                     (max_contact_loss {limit})",
                    bounces(m.bounces),
                ));
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
            failed.push(format!(
                "{kind}: std(f − f_d) over the last 2 s is {value} of f_d \
                 (max_force_oscillation {limit})"
            ));
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
                (true, _) if m.force_peak > m.impact_peak => failed.push(format!(
                    "{impact} above force_limit {impact_limit} N (force peak {force_peak} N \
                     later)"
                )),
                (true, _) => failed.push(format!("{impact} above force_limit {impact_limit} N")),
                (false, true) => failed.push(format!(
                    "force peak {force_peak} N above force_limit {force_limit} N"
                )),
                (false, false) => {}
            }
        }
        if let Some(limit) = criteria.max_bounces {
            if exceeds(m.bounces, limit) {
                failed.push(format!(
                    "{} above max_bounces {}",
                    bounces(m.bounces),
                    short(limit)
                ));
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
            failed.push(format!(
                "path error {value} m RMS above max_path_error {limit} m"
            ));
        }
    }
    if let Some(limit) = criteria.max_torque_saturation {
        if exceeds(m.torque_saturation, limit) {
            let (value, limit) = apart(m.torque_saturation, limit, true);
            failed.push(format!(
                "torque saturated in {value} of samples (max_torque_saturation {limit})"
            ));
        }
    }
    if !failed.is_empty() {
        return Judgement {
            stable: Some(false),
            verdict: format!("unstable: {}", failed.join("; ")),
        };
    }
    if !unjudged.is_empty() {
        return Judgement {
            stable: None,
            verdict: format!("not assessed: {}", unjudged.join("; ")),
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
