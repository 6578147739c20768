//! The force sensor stage (SPEC §10): bias, seeded Gaussian noise, resolution, a first-order
//! low-pass and a latency of whole samples, in that order.
//!
//! The noise of sample k is drawn from a generator seeded by (seed, k) alone, so a run can
//! be stopped, its state set and resumed, and a sweep split anyhow, with the same noise.

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64Mcg;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::error::{check, Error, Result};
use crate::scalar::{choose, mask_from, put, Real, Wide};
use simba::simd::SimdValue;

/// Longest latency accepted, in samples.
pub const MAX_LATENCY: usize = 100_000;

/// Sensor parameters. Defaults are the ideal sensor of the paper (it reads f exactly).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct SensorParams {
    /// Constant offset added to the reading [N].
    #[schemars(extend("x-ui" = {"min": -5.0, "max": 5.0, "scale": "linear"}))]
    pub bias: f64,
    /// Standard deviation of white Gaussian noise [N].
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 5.0, "scale": "linear"}))]
    pub noise_std: f64,
    /// Quantisation step [N]; 0: none.
    pub resolution: f64,
    /// First-order low-pass cut-off f_c [Hz], at most the Nyquist frequency 1/(2·period)
    /// (a scenario with a higher one is rejected); ``None``: no filter.
    #[schemars(extend("x-ui" = {"min": 1.0, "max": 500.0, "scale": "log"}))]
    pub cutoff: Option<f64>,
    /// Delay of the output in whole controller periods (0 to 100 000).
    #[serde(deserialize_with = "latency")]
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 50.0, "scale": "linear", "unit": "periods"}))]
    pub latency: usize,
}

impl SensorParams {
    pub fn validate(&self) -> Result<()> {
        check::finite("bias", self.bias)?;
        check::non_negative("noise_std", self.noise_std)?;
        check::non_negative("resolution", self.resolution)?;
        if let Some(fc) = self.cutoff {
            check::positive("cutoff", fc)?;
        }
        if self.latency > MAX_LATENCY {
            return Err(Error::parameter(
                "latency",
                self.latency,
                &format!("an integer from 0 to {MAX_LATENCY}"),
            ));
        }
        Ok(())
    }

    /// Whether the sensor reads the force exactly (the paper's sensor).
    pub fn is_ideal(&self) -> bool {
        *self == Self::default()
    }
}

/// The sensor as a state machine: the low-pass output and the samples in flight. Over
/// `f64` for one run, or four runs' sensors (their own parameters, one latency) in lanes.
#[derive(Debug, Clone, PartialEq)]
pub struct ForceSensor<T: Real = f64> {
    bias: T,
    noise_std: T,
    resolution: T,
    /// Lanes with a low-pass (a cut-off).
    filtering: T::SimdBool,
    /// The noise generator's seed (one run's; lanes are handed each run's own draws).
    seed: u64,
    /// α = 1 − exp(−2π f_c T); 1 without a low-pass.
    alpha: T,
    /// y_{k−1}, the low-pass output of the previous sample.
    filtered: T,
    /// y_{k−1}, …, y_{k−L} (most recent first): the outputs still in flight.
    in_flight: Vec<T>,
}

impl ForceSensor {
    pub fn new(params: &SensorParams, period: f64, seed: u64) -> Self {
        let alpha = params.cutoff.map_or(1.0, |fc| {
            1.0 - (-2.0 * std::f64::consts::PI * fc * period).exp()
        });
        Self {
            bias: params.bias,
            noise_std: params.noise_std,
            resolution: params.resolution,
            filtering: params.cutoff.is_some(),
            seed,
            alpha,
            filtered: 0.0,
            in_flight: vec![0.0; params.latency],
        }
    }

    /// The low-pass coefficient α.
    pub fn alpha(&self) -> f64 {
        self.alpha
    }

    /// The standard normal draw of sample `k` (before scaling by `noise_std`).
    pub fn noise(&self, k: usize) -> f64 {
        // One small generator per sample, seeded from (seed, k) by a SplitMix-style mix so
        // that neighbouring seeds and samples give unrelated streams.
        let mut rng = Pcg64Mcg::seed_from_u64(mix(self.seed, k as u64));
        StandardNormal.sample(&mut rng)
    }

    /// The draw sample `k` adds (0 for a noiseless sensor, which draws nothing).
    #[inline(always)]
    pub fn noise_draw(&self, k: usize) -> f64 {
        if self.noise_std > 0.0 {
            self.noise(k)
        } else {
            0.0
        }
    }

    /// The reading at sample `k` of the true force `force` [N].
    #[inline(always)]
    pub fn measure(&mut self, k: usize, force: f64) -> f64 {
        let noise = self.noise_draw(k);
        self.read(k == 0, force, noise)
    }
}

impl<W: Real> ForceSensor<W> {
    /// Four sensors of one latency in lanes.
    pub fn pack<const L: usize>(s: [&ForceSensor; L]) -> Self
    where
        W: Wide<L>,
    {
        debug_assert!(s.iter().all(|x| x.in_flight.len() == s[0].in_flight.len()));
        Self {
            bias: W::from_lanes(|i| s[i].bias),
            noise_std: W::from_lanes(|i| s[i].noise_std),
            resolution: W::from_lanes(|i| s[i].resolution),
            filtering: mask_from::<W>(|i| s[i].filtering),
            seed: s[0].seed,
            alpha: W::from_lanes(|i| s[i].alpha),
            filtered: W::from_lanes(|i| s[i].filtered),
            in_flight: (0..s[0].in_flight.len())
                .map(|d| W::from_lanes(|i| s[i].in_flight[d]))
                .collect(),
        }
    }

    /// Lane `l` takes the sensor `s` (parameters and state; the same latency).
    pub fn put_lane(&mut self, l: usize, s: &ForceSensor) {
        put(&mut self.bias, l, s.bias);
        put(&mut self.noise_std, l, s.noise_std);
        put(&mut self.resolution, l, s.resolution);
        self.filtering.replace(l, s.filtering);
        put(&mut self.alpha, l, s.alpha);
        put(&mut self.filtered, l, s.filtered);
        for (v, x) in self.in_flight.iter_mut().zip(&s.in_flight) {
            put(v, l, *x);
        }
    }
}

impl<T: Real> ForceSensor<T> {
    /// Samples of latency.
    pub fn latency(&self) -> usize {
        self.in_flight.len()
    }

    pub fn reset(&mut self) {
        self.filtered = T::zero();
        self.in_flight.iter_mut().for_each(|v| *v = T::zero());
    }

    /// The reading of the true force `force` [N] given the standard normal draw `noise`
    /// of this sample; `first`: the lanes at sample 0. SPEC §10: u = f + β + σ n, rounded
    /// to the resolution; y_0 = u_0, y_k = y_{k−1} + α (u_k − y_{k−1}); then the latency.
    #[inline(always)]
    pub fn read(&mut self, first: T::SimdBool, force: T, noise: T) -> T {
        let zero = T::zero();
        let mut u = force + self.bias;
        let (std, res) = (self.noise_std, self.resolution);
        u = choose(std.simd_gt(zero), || u + std * noise, || u);
        u = choose(res.simd_gt(zero), || (u / res).simd_round() * res, || u);
        let (filtered, alpha) = (self.filtered, self.alpha);
        let y = choose(
            first | !self.filtering,
            || u,
            || filtered + alpha * (u - filtered),
        );
        self.filtered = y;
        let latency = self.in_flight.len();
        if latency == 0 {
            return y;
        }
        // Before the first reading arrives the output holds y_0.
        if !T::none(first) {
            self.in_flight
                .iter_mut()
                .for_each(|v| *v = choose(first, || y, || *v));
        }
        let out = self.in_flight[latency - 1];
        self.in_flight.rotate_right(1);
        self.in_flight[0] = y;
        out
    }
}

impl ForceSensor {
    /// Labels of the sensor's state, in the order of `state`.
    pub fn state_labels(&self) -> Vec<String> {
        let mut out = vec!["sensor.filtered".to_owned()];
        out.extend((1..=self.in_flight.len()).map(|i| format!("sensor.in_flight{i}")));
        out
    }

    pub fn state(&self, out: &mut Vec<f64>) {
        out.push(self.filtered);
        out.extend_from_slice(&self.in_flight);
    }

    /// Reads the state written by `state`; returns the number of values used.
    pub fn set_state(&mut self, values: &[f64]) -> usize {
        self.filtered = values[0];
        let n = self.in_flight.len();
        self.in_flight.copy_from_slice(&values[1..=n]);
        n + 1
    }

    pub fn state_len(&self) -> usize {
        1 + self.in_flight.len()
    }
}

/// SplitMix64's finaliser over (seed, k): a bijective scramble of the pair.
fn mix(seed: u64, k: u64) -> u64 {
    let mut z = seed ^ k.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// `ForceSensor.latency` from serde: a whole number of samples from 0 to `MAX_LATENCY`.
fn latency<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<usize, D::Error> {
    let max = MAX_LATENCY;
    crate::schema::fields::whole(d, 0, max as u64, &format!("an integer from 0 to {max}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sensor(p: SensorParams) -> ForceSensor {
        ForceSensor::new(&p, 1e-3, 7)
    }

    #[test]
    fn ideal_sensor_reads_exactly() {
        let mut s = sensor(SensorParams::default());
        for (k, f) in [0.0, 3.5, -2.0, 1e5].iter().enumerate() {
            assert_eq!(s.measure(k, *f), *f);
        }
    }

    /// y_k = 1 − (1 − α)^k for a unit step that starts after sample 0.
    #[test]
    fn low_pass_step_response() {
        let mut s = sensor(SensorParams {
            cutoff: Some(30.0),
            ..SensorParams::default()
        });
        let alpha = 1.0 - (-2.0 * std::f64::consts::PI * 30.0 * 1e-3f64).exp();
        assert_eq!(s.alpha(), alpha);
        assert_eq!(s.measure(0, 0.0), 0.0);
        for k in 1..200 {
            let y = s.measure(k, 1.0);
            let exact = 1.0 - (1.0 - alpha).powi(k as i32);
            assert!((y - exact).abs() < 1e-12, "k = {k}: {y} vs {exact}");
        }
    }

    #[test]
    fn latency_delays_whole_samples_and_holds_the_first() {
        let mut s = sensor(SensorParams {
            latency: 3,
            ..SensorParams::default()
        });
        let out: Vec<f64> = (0..8).map(|k| s.measure(k, 10.0 + k as f64)).collect();
        assert_eq!(out, [10.0, 10.0, 10.0, 10.0, 11.0, 12.0, 13.0, 14.0]);
    }

    #[test]
    fn bias_and_resolution() {
        let mut s = sensor(SensorParams {
            bias: 0.3,
            resolution: 0.25,
            ..SensorParams::default()
        });
        assert_eq!(s.measure(0, 1.0), 1.25);
        assert_eq!(s.measure(1, 1.1), 1.5);
    }

    #[test]
    fn noise_statistics_and_seeding() {
        let p = SensorParams {
            noise_std: 0.5,
            ..SensorParams::default()
        };
        let mut s = sensor(p);
        let x: Vec<f64> = (0..10_000).map(|k| s.measure(k, 0.0)).collect();
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        let std = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
        assert!((std - 0.5).abs() < 0.025, "std {std}");
        assert!(mean.abs() < 0.02, "mean {mean}");
        // The same (seed, k) gives the same draw, out of order too; another seed differs.
        assert_eq!(sensor(p).measure(1234, 0.0), x[1234]);
        let mut other = ForceSensor::new(&p, 1e-3, 8);
        assert_ne!(other.measure(1234, 0.0), x[1234]);
    }

    #[test]
    fn state_round_trip() {
        let p = SensorParams {
            cutoff: Some(30.0),
            latency: 2,
            noise_std: 0.1,
            ..SensorParams::default()
        };
        let mut a = sensor(p);
        for k in 0..10 {
            a.measure(k, k as f64);
        }
        let mut st = Vec::new();
        a.state(&mut st);
        assert_eq!(st.len(), a.state_len());
        let mut b = sensor(p);
        assert_eq!(b.set_state(&st), 3);
        for k in 10..20 {
            assert_eq!(a.measure(k, 1.0), b.measure(k, 1.0));
        }
    }

    #[test]
    fn invalid_parameters() {
        let e = SensorParams {
            cutoff: Some(0.0),
            ..SensorParams::default()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().starts_with("cutoff = 0"), "{e}");
    }

    /// Four sensors with their own parameters in lanes read what four scalar sensors read,
    /// bit for bit, with lanes at different samples (lane 3 takes a new run midway).
    #[test]
    fn lanes_read_as_four_scalar_sensors() {
        use crate::scalar::{lane, F64x4};
        let params = [
            SensorParams {
                latency: 2,
                ..SensorParams::default()
            },
            SensorParams {
                bias: 0.3,
                noise_std: 0.5,
                cutoff: Some(30.0),
                latency: 2,
                ..SensorParams::default()
            },
            SensorParams {
                resolution: 0.25,
                cutoff: Some(80.0),
                latency: 2,
                ..SensorParams::default()
            },
            SensorParams {
                noise_std: 0.2,
                resolution: 0.1,
                latency: 2,
                ..SensorParams::default()
            },
        ];
        let mut scalar: Vec<ForceSensor> = (0..4)
            .map(|i| ForceSensor::new(&params[i], 1e-3, 11 + i as u64))
            .collect();
        let mut lanes =
            ForceSensor::<F64x4>::pack([&scalar[0], &scalar[1], &scalar[2], &scalar[3]]);
        let mut k = [0usize; 4];
        for step in 0..40 {
            if step == 17 {
                scalar[3] = ForceSensor::new(&params[3], 1e-3, 99);
                lanes.put_lane(3, &scalar[3]);
                k[3] = 0;
            }
            let force: [f64; 4] =
                std::array::from_fn(|i| (step as f64 * 0.37 + i as f64).sin() * 20.0);
            let noise = F64x4::from_lanes(|i| scalar[i].noise_draw(k[i]));
            let first = mask_from::<F64x4>(|i| k[i] == 0);
            let out = lanes.read(first, F64x4::from_lanes(|i| force[i]), noise);
            for i in 0..4 {
                let expected = scalar[i].measure(k[i], force[i]);
                assert_eq!(
                    lane(out, i).to_bits(),
                    expected.to_bits(),
                    "step {step} lane {i}"
                );
                k[i] += 1;
            }
        }
    }
}
