//! The same run with its drives held (SPEC §23): how a force oscillation or a loss of contact
//! the references drive is told from one the loop sustains by itself.
//!
//! A run that fails a criterion the loop may sustain (force oscillation, loss of contact
//! after touching, bounces) is run again with everything that drives it held: the motion
//! s(t) at s(0), f_d at its value where the last 2 s start (when it varies there) and the
//! sensor's noise off; every other part (the arm, the surface, latency, filter,
//! quantisation, bias, the motors' limits) unchanged. If the held run meets those criteria,
//! the failure was driven: the run is stable and out of tolerance. If it fails them too
//! (or diverges), the loop sustains it: unstable. A run that nothing drives is its own held
//! run, so its failure is self-sustained without a second run. A run without sensor noise
//! that bounces more than `BOUNCES_PER_EVENT` times per reversal of its references is
//! bouncing at the loop's own frequency: self-sustained although its held run is quiet
//! (SPEC §23 names bouncing so).
//!
//! Where the test can be wrong (docs/analysis.md, "Unstable or out of tolerance"):
//! - it probes the loop at the path's start only: a surface that is stiffer further along
//!   the path, or an arm pose there that destabilises the loop, reads as driven;
//! - an oscillation the motion itself creates and the loop then sustains (stick-slip from
//!   friction) stops with the motion: read as driven, unless it bounces more than
//!   `BOUNCES_PER_EVENT` times per reversal;
//! - a self-sustained oscillation whose held amplitude is within the tolerance reads as
//!   driven (the held run meets the criteria the user set).

#[cfg(test)]
use crate::control::reference::Signal;
use crate::error::Result;
use crate::sim::criteria::{Drive, Holds};
use crate::sim::metrics::{Metrics, STEADY_STATE_WINDOW};
use crate::sim::outcome::Outcome;
use crate::sim::scenario::ScenarioConfig;

/// What drives `config`'s run: the motion (s(t) not constant), f_d (varying in the last
/// 2 s) and the sensor noise.
pub fn holds(config: &ScenarioConfig) -> Holds {
    let end = config.samples().saturating_sub(1) as f64 * config.period;
    let window = (end - STEADY_STATE_WINDOW).max(0.0);
    Holds {
        motion: config.z_reference.constant_from(0.0).is_none(),
        force: config.admittance.is_some()
            && config.force_reference.constant_from(window).is_none(),
        noise: config.sensor.noise_std != 0.0,
        events: config.z_reference.reversals(0.0, end) + config.force_reference.reversals(0.0, end),
    }
}

/// `config` with its drives held, and what was held; `None` when nothing drives it.
pub fn held_config(config: &ScenarioConfig) -> Option<(ScenarioConfig, Holds)> {
    let holds = holds(config);
    if !holds.any() {
        return None;
    }
    let mut held = config.clone();
    let constant = |value: f64| crate::control::reference::Signal::Step {
        value,
        time: 0.0,
        initial: value,
    };
    if holds.motion {
        held.z_reference = constant(config.z_reference.at(0.0).value);
    }
    if holds.force {
        let end = config.samples().saturating_sub(1) as f64 * config.period;
        let window = (end - STEADY_STATE_WINDOW).max(0.0);
        held.force_reference = constant(config.force_reference.at(window).value);
    }
    if holds.noise {
        held.sensor.noise_std = 0.0;
    }
    Some((held, holds))
}

/// Judges a finished run of `config` knowing what drives it: when it failed a criterion the
/// loop may sustain, runs the held run with `run` (the caller's way to run a config: alone,
/// or in a batch) and records what it showed. `substeps` is the count the run was
/// integrated with (the held run takes the same, not a new `"auto"` search).
pub fn settle(
    config: &ScenarioConfig,
    metrics: &mut Metrics,
    outcome: &Outcome,
    substeps: Option<usize>,
    run: impl FnOnce(&ScenarioConfig) -> Result<(Metrics, Outcome)>,
) -> Result<()> {
    let Some((held, holds)) = plan(config, metrics, outcome, substeps) else {
        return Ok(());
    };
    let (held_metrics, held_outcome) = run(&held)?;
    attach(metrics, outcome, &held_metrics, &held_outcome, holds);
    Ok(())
}

/// The held run a finished run needs (`None`: none, and `metrics` is judged already).
pub fn plan(
    config: &ScenarioConfig,
    metrics: &mut Metrics,
    outcome: &Outcome,
    substeps: Option<usize>,
) -> Option<(ScenarioConfig, Holds)> {
    if !metrics.needs_held(outcome) || !metrics.criteria.held_run {
        return None;
    }
    match held_config(config) {
        None => {
            metrics.set_drive(Drive::Absent, outcome);
            None
        }
        Some((mut held, holds)) => {
            if let Some(count) = substeps {
                held = held.with_substeps(count);
            }
            Some((held, holds))
        }
    }
}

/// Records what the held run showed and judges the run again.
pub fn attach(
    metrics: &mut Metrics,
    outcome: &Outcome,
    held: &Metrics,
    held_outcome: &Outcome,
    holds: Holds,
) {
    metrics.set_drive(Drive::Held(held.as_held(held_outcome, holds)), outcome);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::sensor::SensorParams;

    /// The paper's default (fig. 14): a sine motion, a step f_d at t = 0, no noise.
    #[test]
    fn the_motion_is_held_at_its_start_and_noise_turned_off() {
        let config = ScenarioConfig {
            sensor: SensorParams {
                noise_std: 0.3,
                ..Default::default()
            },
            z_reference: Signal::Sine {
                offset: 0.01,
                amplitude: 0.05,
                omega: 1.0,
                phase: 0.5,
            },
            ..ScenarioConfig::default()
        };
        let (held, holds) = held_config(&config).expect("driven");
        // The sine's extrema in 10 s: ω t + 0.5 = π/2 + k π at t = 1.07, 4.21, 7.35 s.
        assert_eq!(
            holds,
            Holds {
                motion: true,
                force: false,
                noise: true,
                events: 3,
            }
        );
        let s0 = 0.01 + 0.05 * 0.5f64.sin();
        assert_eq!(held.z_reference.at(0.0).value, s0);
        assert_eq!(held.z_reference.at(7.3).value, s0);
        assert_eq!(held.force_reference, config.force_reference);
        assert_eq!(held.sensor.noise_std, 0.0);
        // Held again, nothing drives it.
        assert_eq!(held_config(&held), None);
    }

    /// f_d is held only when it varies in the last 2 s: a step at 9 s of a 10-s run.
    #[test]
    fn a_force_step_in_the_last_two_seconds_is_held() {
        let late = ScenarioConfig {
            force_reference: Signal::Step {
                value: 12.0,
                time: 9.0,
                initial: 10.0,
            },
            z_reference: Signal::Step {
                value: 0.0,
                time: 0.0,
                initial: 0.0,
            },
            ..ScenarioConfig::default()
        };
        let (held, holds) = held_config(&late).expect("f_d varies late");
        assert!(holds.force && !holds.motion && !holds.noise);
        assert_eq!(held.force_reference.at(0.0).value, 10.0);
        assert_eq!(held.force_reference.at(9.5).value, 10.0);
        let early = ScenarioConfig {
            force_reference: Signal::Step {
                value: 12.0,
                time: 7.9,
                initial: 10.0,
            },
            ..late
        };
        assert_eq!(
            holds_of(&early),
            Holds {
                events: 1,
                ..Holds::default()
            }
        );
    }

    fn holds_of(config: &ScenarioConfig) -> Holds {
        holds(config)
    }
}
