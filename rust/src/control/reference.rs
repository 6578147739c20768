//! Reference signals for the desired force and the z position (SPEC §3).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::error::{check, Error, Result};
use crate::scalar::{Real, Wide};

/// A value with its first and second time derivatives: over `f64`, or over lanes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample<T: Real = f64> {
    pub value: T,
    pub rate: T,
    pub accel: T,
}

impl<T: Real> Sample<T> {
    /// `self` in the lanes of `mask`, `other` elsewhere.
    #[inline(always)]
    pub fn select(&self, mask: T::SimdBool, other: &Self) -> Self {
        Self {
            value: self.value.select(mask, other.value),
            rate: self.rate.select(mask, other.rate),
            accel: self.accel.select(mask, other.accel),
        }
    }
}

impl<W: Real> Sample<W> {
    /// Four lanes' samples (each lane's signal evaluated at its own time).
    #[inline]
    pub fn pack<const L: usize>(s: [&Sample; L]) -> Self
    where
        W: Wide<L>,
    {
        Self {
            value: W::from_lanes(|i| s[i].value),
            rate: W::from_lanes(|i| s[i].rate),
            accel: W::from_lanes(|i| s[i].accel),
        }
    }
}

/// A scalar signal of time. Derivatives are analytic where the signal has them; a step
/// contributes no impulse to the derivatives. Tagged by `kind` as the Python blocks are;
/// a field left out takes its default (a 10 N step, a unit sine, one sample at 0).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Signal {
    /// `initial` before `time`, `value` from `time` on.
    Step {
        /// Value from ``time`` on [unit of the signal: N for a force, m for z].
        #[serde(default = "ten")]
        value: f64,
        /// Step time [s].
        #[serde(default)]
        time: f64,
        /// Value before ``time`` [unit of the signal].
        #[serde(default)]
        initial: f64,
    },
    /// `offset + amplitude · sin(omega t + phase)`, omega in rad/s.
    Sine {
        /// Mean value [unit of the signal: N for a force, m for z].
        #[serde(default)]
        offset: f64,
        /// Amplitude [unit of the signal].
        #[serde(default = "one")]
        amplitude: f64,
        /// Angular frequency [rad/s], >= 0 (a negative one is a phase shift: use ``phase``).
        #[serde(default = "one")]
        omega: f64,
        /// Phase at t = 0 [rad].
        #[serde(default)]
        phase: f64,
    },
    /// Linear interpolation through (times, values), held constant outside; the rate is
    /// the segment's slope and the acceleration zero.
    Sampled {
        /// Sample times, increasing [s].
        #[serde(default = "one_sample")]
        times: Vec<f64>,
        /// Sample values, one per time [unit of the signal: N for a force, m for z].
        #[serde(default = "one_sample")]
        values: Vec<f64>,
    },
}

fn ten() -> f64 {
    10.0
}

fn one() -> f64 {
    1.0
}

fn one_sample() -> Vec<f64> {
    vec![0.0]
}

impl Signal {
    pub fn validate(&self) -> Result<()> {
        match self {
            Signal::Step {
                value,
                time,
                initial,
            } => {
                check::finite("value", *value)?;
                check::finite("time", *time)?;
                check::finite("initial", *initial)
            }
            Signal::Sine {
                offset,
                amplitude,
                omega,
                phase,
            } => {
                check::finite("offset", *offset)?;
                check::finite("amplitude", *amplitude)?;
                // A negative frequency is a phase shift of a positive one: say it so.
                check::non_negative("omega", *omega)?;
                check::finite("phase", *phase)
            }
            Signal::Sampled { times, values } => {
                if times.is_empty() || times.len() != values.len() {
                    return Err(Error::parameter(
                        "values",
                        format!("{} samples for {} times", values.len(), times.len()),
                        "one value per time, at least one sample",
                    ));
                }
                for (i, v) in values.iter().enumerate() {
                    check::finite(&format!("values[{i}]"), *v)?;
                }
                for (i, t) in times.iter().enumerate() {
                    check::finite(&format!("times[{i}]"), *t)?;
                    if i > 0 && *t <= times[i - 1] {
                        return Err(Error::parameter(
                            &format!("times[{i}]"),
                            t,
                            "strictly increasing times",
                        ));
                    }
                }
                Ok(())
            }
        }
    }

    #[inline]
    pub fn at(&self, t: f64) -> Sample {
        match self {
            Signal::Step {
                value,
                time,
                initial,
            } => Sample {
                value: if t >= *time { *value } else { *initial },
                ..Sample::default()
            },
            Signal::Sine {
                offset,
                amplitude,
                omega,
                phase,
            } => {
                // libm's sincos, whose bits the lanes reproduce (`LaneSignal`).
                let (s, c) = libm::sincos(omega * t + phase);
                Sample {
                    value: offset + amplitude * s,
                    rate: amplitude * omega * c,
                    accel: -amplitude * omega * omega * s,
                }
            }
            Signal::Sampled { times, values } => sampled_at(times, values, t),
        }
    }

    /// The signal's value if it is constant from `t` on (`None` if it changes after `t`).
    pub fn constant_from(&self, t: f64) -> Option<f64> {
        let now = self.at(t).value;
        let constant = match self {
            Signal::Step {
                value,
                time,
                initial,
            } => *time <= t || value == initial,
            Signal::Sine {
                amplitude, omega, ..
            } => *amplitude == 0.0 || *omega == 0.0,
            Signal::Sampled { times, values } => times
                .iter()
                .zip(values)
                .filter(|(ti, _)| **ti > t)
                .all(|(_, v)| *v == now),
        };
        constant.then_some(now)
    }

    /// How many times the signal turns back or jumps in (t0, t1]: a step's jump, a sine's
    /// extrema, a sampled signal's changes of direction. For the motion these are the
    /// friction reversals the references drive (`sim::held`).
    pub fn reversals(&self, t0: f64, t1: f64) -> usize {
        match self {
            Signal::Step {
                value,
                time,
                initial,
            } => usize::from(value != initial && *time > t0 && *time <= t1),
            Signal::Sine {
                amplitude,
                omega,
                phase,
                ..
            } => {
                if *amplitude == 0.0
                    || *omega == 0.0
                    || t1.partial_cmp(&t0) != Some(std::cmp::Ordering::Greater)
                {
                    return 0;
                }
                // Extrema at ω t + φ = π/2 + k π.
                let k = |t: f64| {
                    ((omega * t + phase - std::f64::consts::FRAC_PI_2) / std::f64::consts::PI)
                        .floor()
                };
                let n = k(t1) - k(t0);
                if n.is_finite() && n > 0.0 {
                    n.min(usize::MAX as f64) as usize
                } else {
                    0
                }
            }
            Signal::Sampled { times, values } => {
                let mut last = 0.0f64;
                let mut turns = 0;
                for (w, v) in times.windows(2).zip(values.windows(2)) {
                    if w[1] <= t0 || w[0] >= t1 {
                        continue;
                    }
                    let slope = (v[1] - v[0]).signum() * f64::from(u8::from(v[1] != v[0]));
                    if slope != 0.0 {
                        turns += usize::from(last != 0.0 && slope != last);
                        last = slope;
                    }
                }
                turns
            }
        }
    }

    /// True for a step: the step-response metrics (rise, settling, overshoot) apply.
    pub fn is_step(&self) -> bool {
        matches!(self, Signal::Step { .. })
    }
}

/// Runs' signals in lanes (SPEC §13): one kind, each lane's own parameters, evaluated in
/// every lane at once with `Signal::at`'s bits (a sine by `scalar::libm_sincos`). Sampled
/// signals, or lanes of different kinds, are evaluated lane by lane.
#[derive(Debug, Clone, PartialEq)]
pub enum LaneSignal<W: Real> {
    Step {
        value: W,
        time: W,
        initial: W,
    },
    Sine {
        offset: W,
        amplitude: W,
        omega: W,
        phase: W,
    },
    PerLane,
}

impl<W: Real> LaneSignal<W> {
    /// `L` runs' signals.
    pub fn pack<const L: usize>(s: [&Signal; L]) -> Self
    where
        W: Wide<L>,
    {
        let mut out = Self::lane_zero(s[0]);
        for (l, signal) in s.iter().enumerate() {
            out.put_lane(l, signal);
        }
        out
    }

    /// Every lane at 0 in `s`'s kind.
    fn lane_zero(s: &Signal) -> Self {
        let z = W::zero();
        match s {
            Signal::Step { .. } => Self::Step {
                value: z,
                time: z,
                initial: z,
            },
            Signal::Sine { .. } => Self::Sine {
                offset: z,
                amplitude: z,
                omega: z,
                phase: z,
            },
            Signal::Sampled { .. } => Self::PerLane,
        }
    }

    /// Lane `l` takes the signal `s` (a new run's). One of another kind makes the group's
    /// signals lane by lane from now on: the same bits, more slowly.
    pub fn put_lane(&mut self, l: usize, s: &Signal) {
        match (self, s) {
            (
                Self::Step {
                    value,
                    time,
                    initial,
                },
                Signal::Step {
                    value: v,
                    time: t,
                    initial: i,
                },
            ) => {
                value.replace(l, *v);
                time.replace(l, *t);
                initial.replace(l, *i);
            }
            (
                Self::Sine {
                    offset,
                    amplitude,
                    omega,
                    phase,
                },
                Signal::Sine {
                    offset: o,
                    amplitude: a,
                    omega: w,
                    phase: p,
                },
            ) => {
                offset.replace(l, *o);
                amplitude.replace(l, *a);
                omega.replace(l, *w);
                phase.replace(l, *p);
            }
            (this, _) => *this = Self::PerLane,
        }
    }

    /// Each lane's signal at its own time `t`; `each(l)`: lane l's signal, for the lanes
    /// evaluated one by one.
    #[inline(always)]
    pub fn at<'a, const L: usize>(&self, t: W, each: impl Fn(usize) -> &'a Signal) -> Sample<W>
    where
        W: Wide<L>,
    {
        match self {
            Self::Step {
                value,
                time,
                initial,
            } => Sample {
                value: value.select(t.simd_ge(*time), *initial),
                ..Sample::default()
            },
            Self::Sine {
                offset,
                amplitude,
                omega,
                phase,
            } => {
                let (s, c) = (*omega * t + *phase).sin_cos_each();
                Sample {
                    value: *offset + *amplitude * s,
                    rate: *amplitude * *omega * c,
                    accel: -*amplitude * *omega * *omega * s,
                }
            }
            Self::PerLane => {
                let each: [Sample; L] = std::array::from_fn(|l| each(l).at(t.extract(l)));
                Sample::pack(each.each_ref())
            }
        }
    }
}

fn sampled_at(times: &[f64], values: &[f64], t: f64) -> Sample {
    let n = times.len();
    // validate() guarantees n ≥ 1; an empty signal would be caught before a run.
    if n == 0 {
        return Sample::default();
    }
    if t <= times[0] {
        return Sample {
            value: values[0],
            ..Sample::default()
        };
    }
    if t >= times[n - 1] {
        return Sample {
            value: values[n - 1],
            ..Sample::default()
        };
    }
    // First index with times[i] > t; t lies in [times[i-1], times[i]).
    let i = times.partition_point(|&ti| ti <= t);
    let (t0, t1, v0, v1) = (times[i - 1], times[i], values[i - 1], values[i]);
    let slope = (v1 - v0) / (t1 - t0);
    Sample {
        value: v0 + slope * (t - t0),
        rate: slope,
        accel: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Turns and jumps counted in (t0, t1]: a step once, a sine at each extremum, a sampled
    /// path at each change of direction (a pause is none).
    #[test]
    fn reversals_count_turns_and_jumps() {
        let step = Signal::Step {
            value: 1.0,
            time: 2.0,
            initial: 0.0,
        };
        assert_eq!(
            (step.reversals(0.0, 10.0), step.reversals(2.0, 10.0)),
            (1, 0)
        );
        let sine = Signal::Sine {
            offset: 0.0,
            amplitude: 0.05,
            omega: 1.0,
            phase: 0.0,
        };
        // Extrema at π/2, 3π/2, 5π/2 = 7.85 s.
        assert_eq!(sine.reversals(0.0, 10.0), 3);
        assert_eq!(sine.reversals(0.0, 1.0), 0);
        let path = Signal::Sampled {
            times: vec![0.0, 1.0, 2.0, 3.0, 4.0],
            values: vec![0.0, 1.0, 1.0, 0.0, 0.5],
        };
        assert_eq!(path.reversals(0.0, 10.0), 2);
        assert_eq!(path.reversals(0.0, 2.5), 1);
    }

    #[test]
    fn step_and_sine() {
        let s = Signal::Step {
            value: 10.0,
            time: 0.0,
            initial: 0.0,
        };
        assert_eq!(s.at(0.0).value, 10.0);
        assert_eq!(s.at(-1e-9).value, 0.0);
        let s = Signal::Sine {
            offset: 10.0,
            amplitude: 5.0,
            omega: 2.0,
            phase: 0.0,
        };
        let x = s.at(0.3);
        assert!((x.value - (10.0 + 5.0 * 0.6f64.sin())).abs() < 1e-15);
        assert!((x.rate - 10.0 * 0.6f64.cos()).abs() < 1e-14);
        assert!((x.accel + 20.0 * 0.6f64.sin()).abs() < 1e-14);
    }

    /// Lanes of one kind, each with its own parameters and time, give `Signal::at`'s bits;
    /// a lane of another kind turns the group lane by lane, with the same bits.
    #[test]
    fn lane_signals_are_each_lane_s_own() {
        use crate::scalar::{lane, F64x4};
        let sine = |i: usize| Signal::Sine {
            offset: 0.1 * i as f64,
            amplitude: 0.05 + 0.01 * i as f64,
            omega: 1.0 + 3.0 * i as f64,
            phase: -0.7 * i as f64,
        };
        let step = |i: usize| Signal::Step {
            value: 10.0 + i as f64,
            time: 0.25 * i as f64,
            initial: -(i as f64),
        };
        let sampled = Signal::Sampled {
            times: vec![0.0, 1.0, 3.0],
            values: vec![0.0, 2.0, 0.0],
        };
        for kind in [sine as fn(usize) -> Signal, step] {
            let mut signals: Vec<Signal> = (0..4).map(kind).collect();
            let mut lanes = LaneSignal::<F64x4>::pack(std::array::from_fn(|i| &signals[i]));
            for round in 0..2 {
                for k in 0..2000 {
                    let t = F64x4::from_lanes(|i| (k + 37 * i) as f64 * 1e-3);
                    let got = lanes.at(t, |l| &signals[l]);
                    for (i, signal) in signals.iter().enumerate() {
                        let want = signal.at(lane(t, i));
                        let bits = |x: Sample<F64x4>| {
                            [x.value, x.rate, x.accel].map(|v| lane(v, i).to_bits())
                        };
                        let want = [want.value, want.rate, want.accel].map(f64::to_bits);
                        assert_eq!(bits(got), want, "{signal:?} at {}", lane(t, i));
                    }
                }
                // Lane 2 takes a run of another kind: lane by lane from then on.
                assert_eq!(round == 0, lanes != LaneSignal::PerLane);
                signals[2] = sampled.clone();
                lanes.put_lane(2, &signals[2]);
                assert_eq!(lanes, LaneSignal::PerLane);
            }
        }
    }

    #[test]
    fn sampled_interpolates_and_holds() {
        let s = Signal::Sampled {
            times: vec![0.0, 1.0, 3.0],
            values: vec![0.0, 2.0, 0.0],
        };
        assert_eq!(s.at(-1.0).value, 0.0);
        assert_eq!(
            s.at(0.5),
            Sample {
                value: 1.0,
                rate: 2.0,
                accel: 0.0
            }
        );
        assert_eq!(
            s.at(2.0),
            Sample {
                value: 1.0,
                rate: -1.0,
                accel: 0.0
            }
        );
        assert_eq!(s.at(5.0).value, 0.0);
        let bad = Signal::Sampled {
            times: vec![0.0, 0.0],
            values: vec![1.0, 2.0],
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("times[1]"));
    }
}
