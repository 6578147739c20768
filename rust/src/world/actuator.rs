//! The actuator stage (SPEC §10): the commanded torque is delayed by whole samples, then
//! rate-limited, then clamped per joint. The result is the torque the plant feels.

use crate::error::{check, Error, Result};
use crate::robot::JointVector;

/// Longest delay accepted, in samples.
pub const MAX_DELAY: usize = 100_000;

/// Actuator parameters. Defaults are the paper's ideal motors (no delay, no limits).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ActuatorParams {
    /// |τ_j| limit per joint [N·m]: one value for every joint, or one per joint; `None`:
    /// unlimited.
    pub torque_limit: Option<Vec<f64>>,
    /// |Δτ_j| per second [N·m/s]: each period the torque moves at most `rate_limit`·T;
    /// `None`: unlimited.
    pub rate_limit: Option<f64>,
    /// Delay of the command in whole controller periods. Default 0.
    pub delay: usize,
}

impl ActuatorParams {
    /// Checks the fields; `joints` is the arm's joint count.
    pub fn validate(&self, joints: usize) -> Result<()> {
        if let Some(limits) = &self.torque_limit {
            if limits.len() != 1 && limits.len() != joints {
                return Err(Error::parameter(
                    "torque_limit",
                    format!("{limits:?}"),
                    &format!("one number, or one per joint ({joints})"),
                ));
            }
            for (i, l) in limits.iter().enumerate() {
                check::positive(&format!("torque_limit[{i}]"), *l)?;
            }
        }
        if let Some(r) = self.rate_limit {
            check::positive("rate_limit", r)?;
        }
        if self.delay > MAX_DELAY {
            return Err(Error::parameter(
                "delay",
                self.delay,
                &format!("an integer from 0 to {MAX_DELAY}"),
            ));
        }
        Ok(())
    }

    pub fn is_ideal(&self) -> bool {
        *self == Self::default()
    }
}

/// The actuator as a state machine: the commands in flight and the last applied torque.
#[derive(Debug, Clone, PartialEq)]
pub struct Actuator<const N: usize> {
    limit: Option<JointVector<N>>,
    /// Largest change per period, rate_limit·T.
    max_step: Option<f64>,
    /// τ_cmd,k−1 … τ_cmd,k−D (most recent first).
    in_flight: Vec<JointVector<N>>,
    /// The torque applied in the previous period.
    applied: JointVector<N>,
}

impl<const N: usize> Actuator<N> {
    /// `p` must be valid for `N` joints.
    pub fn new(p: &ActuatorParams, period: f64) -> Self {
        let limit = p.torque_limit.as_ref().map(|l| {
            if l.len() == 1 {
                JointVector::<N>::repeat(l[0])
            } else {
                JointVector::<N>::from_fn(|i, _| l[i])
            }
        });
        Self {
            limit,
            max_step: p.rate_limit.map(|r| r * period),
            in_flight: vec![JointVector::<N>::zeros(); p.delay],
            applied: JointVector::<N>::zeros(),
        }
    }

    pub fn reset(&mut self) {
        self.in_flight
            .iter_mut()
            .for_each(|v| *v = JointVector::zeros());
        self.applied = JointVector::zeros();
    }

    /// The torque applied at sample `k` for the command `command`.
    #[inline(always)]
    pub fn apply(&mut self, k: usize, command: &JointVector<N>) -> JointVector<N> {
        let delay = self.in_flight.len();
        let mut tau = if delay == 0 {
            *command
        } else {
            if k == 0 {
                // Before the first command arrives the motors hold it.
                self.in_flight.iter_mut().for_each(|v| *v = *command);
            }
            let out = self.in_flight[delay - 1];
            self.in_flight.rotate_right(1);
            self.in_flight[0] = *command;
            out
        };
        if let (Some(step), true) = (self.max_step, k > 0) {
            let prev = self.applied;
            tau = tau.zip_map(&prev, |t, p| t.clamp(p - step, p + step));
        }
        if let Some(limit) = &self.limit {
            tau = tau.zip_map(limit, |t, l| t.clamp(-l, l));
        }
        self.applied = tau;
        tau
    }

    /// Whether any joint of `tau` sits at its torque limit.
    #[inline]
    pub fn saturated(&self, tau: &JointVector<N>) -> bool {
        self.limit
            .as_ref()
            .is_some_and(|l| tau.iter().zip(l.iter()).any(|(t, l)| t.abs() >= *l))
    }

    pub fn state_labels(&self) -> Vec<String> {
        let mut out: Vec<String> = (1..=N).map(|j| format!("actuator.applied{j}")).collect();
        for d in 1..=self.in_flight.len() {
            out.extend((1..=N).map(|j| format!("actuator.in_flight{d}_{j}")));
        }
        out
    }

    pub fn state(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(self.applied.as_slice());
        for v in &self.in_flight {
            out.extend_from_slice(v.as_slice());
        }
    }

    pub fn set_state(&mut self, values: &[f64]) -> usize {
        self.applied = JointVector::<N>::from_column_slice(&values[..N]);
        for (d, v) in self.in_flight.iter_mut().enumerate() {
            *v = JointVector::<N>::from_column_slice(&values[N * (d + 1)..N * (d + 2)]);
        }
        self.state_len()
    }

    pub fn state_len(&self) -> usize {
        N * (1 + self.in_flight.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type V = JointVector<2>;

    #[test]
    fn ideal_actuator_passes_the_command() {
        let mut a = Actuator::<2>::new(&ActuatorParams::default(), 1e-3);
        let c = V::new(-550.0, 3.0);
        assert_eq!(a.apply(0, &c), c);
        assert!(!a.saturated(&c));
    }

    #[test]
    fn delay_then_rate_then_clamp() {
        let p = ActuatorParams {
            torque_limit: Some(vec![10.0, 20.0]),
            rate_limit: Some(1000.0),
            delay: 2,
        };
        let mut a = Actuator::<2>::new(&p, 1e-3);
        let commands = [V::new(5.0, 50.0), V::new(8.0, 0.0), V::new(30.0, -50.0)];
        let mut out = Vec::new();
        for k in 0..6 {
            out.push(a.apply(k, &commands[k.min(2)]));
        }
        // k = 0..2 hold the first command (clamped to 20 on joint 2), then the rate limit
        // (1 N·m per period) walks towards the later commands.
        assert_eq!(out[0], V::new(5.0, 20.0));
        assert_eq!(out[1], V::new(5.0, 20.0));
        assert_eq!(out[2], V::new(5.0, 20.0));
        assert_eq!(out[3], V::new(6.0, 19.0));
        assert_eq!(out[4], V::new(7.0, 18.0));
        assert_eq!(out[5], V::new(8.0, 17.0));
        assert!(a.saturated(&V::new(10.0, 0.0)));
        assert!(!a.saturated(&V::new(9.9, 19.9)));
    }

    #[test]
    fn one_limit_for_every_joint_and_bad_lengths() {
        let p = ActuatorParams {
            torque_limit: Some(vec![1.0]),
            ..ActuatorParams::default()
        };
        assert!(p.validate(3).is_ok());
        let mut a = Actuator::<2>::new(&p, 1e-3);
        assert_eq!(a.apply(0, &V::new(-5.0, 0.5)), V::new(-1.0, 0.5));
        let bad = ActuatorParams {
            torque_limit: Some(vec![1.0, 2.0]),
            ..ActuatorParams::default()
        };
        assert!(bad
            .validate(3)
            .unwrap_err()
            .to_string()
            .starts_with("torque_limit = [1.0, 2.0]"));
    }
}
