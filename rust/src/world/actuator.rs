//! The actuator stage (SPEC §10): the commanded torque is delayed by whole samples, then
//! rate-limited, then clamped per joint. The result is the torque the plant feels.

use crate::error::{check, Error, Result};
use nalgebra::SVector;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use simba::simd::SimdValue;

use crate::robot::JointVector;
use crate::scalar::{choose_vector, mask_from, pack_vector, put, put_vector, Real, Wide};

/// Longest delay accepted, in samples.
pub const MAX_DELAY: usize = 100_000;

/// Actuator parameters. Defaults are the paper's ideal motors (no delay, no limits).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ActuatorParams {
    /// |τ_j| limit [N·m]: one number for every joint or one per joint; ``None``: unlimited.
    #[serde(with = "crate::schema::fields::optional_numbers")]
    #[schemars(with = "Option<crate::schema::fields::Numbers>")]
    #[schemars(extend("x-ui" = {"min": 1.0, "max": 1000.0, "scale": "log"}))]
    pub torque_limit: Option<Vec<f64>>,
    /// Largest |dτ/dt| [N·m/s]: the torque moves at most ``rate_limit``·T per period.
    #[schemars(extend("x-ui" = {"min": 10.0, "max": 1000000.0, "scale": "log"}))]
    pub rate_limit: Option<f64>,
    /// Delay of the command in whole controller periods (0 to 100 000).
    #[serde(deserialize_with = "delay")]
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 50.0, "scale": "linear", "unit": "periods"}))]
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
}

/// The actuator as a state machine: the commands in flight and the last applied torque.
/// Over `f64` for one run, or four runs' actuators (their own limits, one delay) in lanes.
#[derive(Debug, Clone, PartialEq)]
pub struct Actuator<const N: usize, T: Real = f64> {
    /// Lanes with a torque limit, and the limit per joint (∞ where there is none).
    limited: T::SimdBool,
    limit: SVector<T, N>,
    /// Lanes with a rate limit, and their largest change per period, rate_limit·T.
    rate_limited: T::SimdBool,
    max_step: T,
    /// τ_cmd,k−1 … τ_cmd,k−D (most recent first).
    in_flight: Vec<SVector<T, N>>,
    /// The torque applied in the previous period.
    applied: SVector<T, N>,
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
            limited: limit.is_some(),
            limit: limit.unwrap_or_else(|| JointVector::repeat(f64::INFINITY)),
            rate_limited: p.rate_limit.is_some(),
            max_step: p.rate_limit.map_or(f64::INFINITY, |r| r * period),
            in_flight: vec![JointVector::<N>::zeros(); p.delay],
            applied: JointVector::<N>::zeros(),
        }
    }

    /// The torque applied at sample `k` for the command `command`.
    #[inline(always)]
    pub fn apply(&mut self, k: usize, command: &JointVector<N>) -> JointVector<N> {
        self.apply_lanes(k == 0, command)
    }
}

impl<W: Real, const N: usize> Actuator<N, W> {
    /// Four actuators of one delay in lanes.
    pub fn pack<const L: usize>(a: [&Actuator<N>; L]) -> Self
    where
        W: Wide<L>,
    {
        debug_assert!(a.iter().all(|x| x.in_flight.len() == a[0].in_flight.len()));
        Self {
            limited: mask_from::<W>(|i| a[i].limited),
            limit: pack_vector(a.map(|a| &a.limit)),
            rate_limited: mask_from::<W>(|i| a[i].rate_limited),
            max_step: W::from_lanes(|i| a[i].max_step),
            in_flight: (0..a[0].in_flight.len())
                .map(|d| pack_vector(a.map(|a| &a.in_flight[d])))
                .collect(),
            applied: pack_vector(a.map(|a| &a.applied)),
        }
    }

    /// Lane `l` takes the actuator `a` (limits and state; the same delay).
    pub fn put_lane(&mut self, l: usize, a: &Actuator<N>) {
        self.limited.replace(l, a.limited);
        put_vector(&mut self.limit, l, &a.limit);
        self.rate_limited.replace(l, a.rate_limited);
        put(&mut self.max_step, l, a.max_step);
        for (v, x) in self.in_flight.iter_mut().zip(&a.in_flight) {
            put_vector(v, l, x);
        }
        put_vector(&mut self.applied, l, &a.applied);
    }
}

impl<const N: usize, T: Real> Actuator<N, T> {
    /// Samples of delay.
    pub fn delay(&self) -> usize {
        self.in_flight.len()
    }

    pub fn reset(&mut self) {
        self.in_flight
            .iter_mut()
            .for_each(|v| *v = SVector::zeros());
        self.applied = SVector::zeros();
    }

    /// The torque applied for the command `command`; `first`: the lanes at sample 0.
    /// SPEC §10: delayed by whole samples, then |Δτ| ≤ rate_limit·T, then |τ_j| ≤ limit_j.
    #[inline(always)]
    pub fn apply_lanes(&mut self, first: T::SimdBool, command: &SVector<T, N>) -> SVector<T, N> {
        let delay = self.in_flight.len();
        let mut tau = if delay == 0 {
            *command
        } else {
            // Before the first command arrives the motors hold it.
            if !T::none(first) {
                self.in_flight
                    .iter_mut()
                    .for_each(|v| *v = choose_vector(first, || *command, || *v));
            }
            let out = self.in_flight[delay - 1];
            self.in_flight.rotate_right(1);
            self.in_flight[0] = *command;
            out
        };
        let (prev, step) = (self.applied, self.max_step);
        tau = choose_vector(
            self.rate_limited & !first,
            || tau.zip_map(&prev, |t, p| t.simd_clamp(p - step, p + step)),
            || tau,
        );
        let limit = self.limit;
        tau = choose_vector(
            self.limited,
            || tau.zip_map(&limit, |t, l| t.simd_clamp(-l, l)),
            || tau,
        );
        self.applied = tau;
        tau
    }

    /// The lanes where any joint of `tau` sits at its torque limit.
    #[inline]
    pub fn saturated(&self, tau: &SVector<T, N>) -> T::SimdBool {
        let mut at = tau[0].simd_abs().simd_ge(self.limit[0]);
        for j in 1..N {
            at = at | tau[j].simd_abs().simd_ge(self.limit[j]);
        }
        at & self.limited
    }
}

impl<const N: usize> Actuator<N> {
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

/// `Actuator.delay` from serde: a whole number of samples from 0 to `MAX_DELAY`.
fn delay<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<usize, D::Error> {
    let max = MAX_DELAY;
    crate::schema::fields::whole(d, 0, max as u64, &format!("an integer from 0 to {max}"))
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

    /// Four actuators (their own limits, some unlimited; one delay) in lanes apply what
    /// four scalar actuators apply, bit for bit, lane 2 restarting midway.
    #[test]
    fn lanes_apply_as_four_scalar_actuators() {
        use crate::scalar::{lane_of, mask_from, F64x4};
        let params = [
            ActuatorParams {
                delay: 1,
                ..ActuatorParams::default()
            },
            ActuatorParams {
                torque_limit: Some(vec![10.0, 20.0]),
                rate_limit: Some(1000.0),
                delay: 1,
            },
            ActuatorParams {
                torque_limit: Some(vec![4.0]),
                delay: 1,
                ..ActuatorParams::default()
            },
            ActuatorParams {
                rate_limit: Some(3000.0),
                delay: 1,
                ..ActuatorParams::default()
            },
        ];
        let mut scalar: Vec<Actuator<2>> = params.iter().map(|p| Actuator::new(p, 1e-3)).collect();
        let mut lanes =
            Actuator::<2, F64x4>::pack([&scalar[0], &scalar[1], &scalar[2], &scalar[3]]);
        let mut k = [0usize; 4];
        for step in 0..30 {
            if step == 11 {
                scalar[2] = Actuator::new(&params[2], 1e-3);
                lanes.put_lane(2, &scalar[2]);
                k[2] = 0;
            }
            let c: [V; 4] = std::array::from_fn(|i| {
                V::new(
                    (step as f64 + i as f64).sin() * 30.0,
                    (step as f64 * 0.5).cos() * 25.0,
                )
            });
            let first = mask_from::<F64x4>(|i| k[i] == 0);
            let out = lanes.apply_lanes(first, &pack_vector([&c[0], &c[1], &c[2], &c[3]]));
            let saturated = lanes.saturated(&out);
            for i in 0..4 {
                let e = scalar[i].apply(k[i], &c[i]);
                assert_eq!(lane_of(&out, i), e, "step {step} lane {i}");
                assert_eq!(saturated.extract(i), scalar[i].saturated(&e));
                k[i] += 1;
            }
        }
    }
}
