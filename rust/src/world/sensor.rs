//! The force sensor stage (SPEC §10, §15): bias, seeded Gaussian noise, resolution, a
//! first-order low-pass and a latency of whole samples, in that order, on one axis along the
//! estimated normal n̂ (a load cell, `frame = "normal"`) or on the three axes of the tip
//! frame (an F/T sensor, `frame = "tip"`). An optional tool of mass m_t between the sensor
//! and the tip adds its weight to the reading; the controller subtracts its estimated weight.
//!
//! The noise of sample k is drawn from a generator seeded by (seed, k) alone, so a run can
//! be stopped, its state set and resumed, and a sweep split anyhow, with the same noise.

use nalgebra::{Matrix3, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64Mcg;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::error::{check, Error, Result};
use crate::scalar::{choose, mask_from, mat_t_vec, put, put_vector, Real, Wide};
use simba::simd::SimdValue;

/// Longest latency accepted, in samples.
pub const MAX_LATENCY: usize = 100_000;
/// Heaviest tool accepted [kg] (as a link's mass).
pub const MAX_TOOL_MASS: f64 = 1e9;

/// Where the sensor's axes are (SPEC §15).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema, Hash)]
#[serde(rename_all = "snake_case")]
pub enum SensorFrame {
    /// One axis along the estimated normal n̂: a load cell aligned with the force direction.
    #[default]
    Normal,
    /// Three axes in the tip frame: a 3-axis F/T sensor.
    Tip,
}

/// A constant offset: one number along n̂, or one per axis of the tip frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum Bias {
    Along(f64),
    Axes([f64; 3]),
}

impl Default for Bias {
    fn default() -> Self {
        Bias::Along(0.0)
    }
}

/// Sensor parameters. Defaults are the ideal sensor of the paper (it reads f exactly).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct SensorParams {
    /// Constant offset added to the reading [N]: one number (along n̂), or one per axis of the tip frame (``frame="tip"``).
    #[schemars(extend("x-ui" = {"min": -5.0, "max": 5.0, "scale": "linear"}))]
    pub bias: Bias,
    /// Standard deviation of white Gaussian noise [N], on each axis.
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 5.0, "scale": "linear"}))]
    pub noise_std: f64,
    /// Quantisation step [N] of each axis; 0: none.
    pub resolution: f64,
    /// First-order low-pass cut-off f_c [Hz] of each axis, at most the Nyquist frequency 1/(2·period)
    /// (a scenario with a higher one is rejected); ``None``: no filter.
    #[schemars(extend("x-ui" = {"min": 1.0, "max": 500.0, "scale": "log"}))]
    pub cutoff: Option<f64>,
    /// Delay of the output in whole controller periods (0 to 100 000).
    #[serde(deserialize_with = "latency")]
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 50.0, "scale": "linear", "unit": "periods"}))]
    pub latency: usize,
    /// ``"normal"``: one axis along the estimated normal n̂ (a load cell); ``"tip"``: three axes in the tip frame (an F/T sensor; the three-link arm's link 3 frame, x along the link, y along the pitch axes; a URDF arm's tip link frame), rotated to the world with the current tip rotation, the component along n̂ fed to the filter.
    pub frame: SensorFrame,
    /// Mass of a tool between the sensor and the tip [kg]: its weight adds to the reading and its mass to the arm's tip.
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 5.0, "scale": "linear", "unit": "kg"}))]
    pub tool_mass: f64,
    /// The tool mass the controller believes [kg]: it subtracts this weight from the reading and its computed-torque model carries this mass; ``None``: ``tool_mass``.
    pub tool_mass_estimate: Option<f64>,
}

impl SensorParams {
    pub fn validate(&self) -> Result<()> {
        match self.bias {
            Bias::Along(b) => check::finite("bias", b)?,
            Bias::Axes(b) => {
                for (i, v) in b.iter().enumerate() {
                    check::finite(&format!("bias[{i}]"), *v)?;
                }
                if self.frame != SensorFrame::Tip {
                    return Err(Error::parameter(
                        "bias",
                        format!("{b:?}"),
                        "a number with frame='normal' (a 3-vector is a bias per axis of \
                         the tip frame: frame='tip')",
                    ));
                }
            }
        }
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
        tool("tool_mass", self.tool_mass)?;
        if let Some(m) = self.tool_mass_estimate {
            tool("tool_mass_estimate", m)?;
        }
        Ok(())
    }

    /// The tool mass the controller believes [kg].
    pub fn believed_tool_mass(&self) -> f64 {
        self.tool_mass_estimate.unwrap_or(self.tool_mass)
    }
}

fn tool(field: &str, m: f64) -> Result<()> {
    if !(0.0..=MAX_TOOL_MASS).contains(&m) {
        return Err(Error::parameter(
            field,
            m,
            &format!("a mass from 0 to {MAX_TOOL_MASS:e} kg"),
        ));
    }
    Ok(())
}

/// What the sensor reads at one sample, world frame: the force the tool pushes on the
/// surface F_s = f N − F_t, and for a tip-frame sensor the tip rotation R (tip axes in the
/// world); n̂ is the estimated normal the filter's component is taken along.
pub struct Reading<'a, T: Real> {
    /// The lanes at sample 0.
    pub first: T::SimdBool,
    /// n̂·F_s, as the one-axis sensor reads it (computed by the caller in its exact form).
    pub along: T,
    pub surface_force: &'a Vector3<T>,
    pub normal: &'a Vector3<T>,
    /// R; read only by a tip-frame sensor.
    pub rotation: Option<&'a Matrix3<T>>,
    /// The sample's standard normal draws, one per axis (a one-axis sensor reads the first).
    pub noise: [T; 3],
}

/// The sensor as a state machine: the low-pass output and the samples in flight. Over
/// `f64` for one run, or four runs' sensors (their own parameters, one latency, one frame)
/// in lanes.
#[derive(Debug, Clone, PartialEq)]
pub struct ForceSensor<T: Real = f64> {
    /// β along n̂ (a number) and β per tip axis (a 3-vector; zero otherwise).
    bias: T,
    bias_tip: Vector3<T>,
    noise_std: T,
    resolution: T,
    /// Lanes with a low-pass (a cut-off).
    filtering: T::SimdBool,
    /// The noise generator's seed (one run's; lanes are handed each run's own draws).
    seed: u64,
    /// α = 1 − exp(−2π f_c T); 1 without a low-pass.
    alpha: T,
    /// The one axis along n̂: y_{k−1} and y_{k−1}, …, y_{k−L} (most recent first).
    filtered: T,
    in_flight: Vec<T>,
    /// The three tip axes (`frame = "tip"`): the same, per axis.
    tip: Option<TipAxes<T>>,
    /// The tool's weight (true, believed) [N], world frame; `None` without a tool, so a
    /// tool-free run does no arithmetic for it and keeps its bits.
    weight: Option<Weight<T>>,
}

#[derive(Debug, Clone, PartialEq)]
struct TipAxes<T: Real> {
    filtered: Vector3<T>,
    in_flight: Vec<Vector3<T>>,
}

/// m_t g e_z and m̂_t g e_z: what the tool adds to the reading and what the controller
/// takes off (gravity along −z; the arm holds the tool up, so the sensor reads +z).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Weight<T: Real> {
    actual: Vector3<T>,
    believed: Vector3<T>,
}

/// What runs must share for their sensors to advance in lanes: the buffers' shape and
/// whether a tool's weight enters the reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SensorKey {
    pub latency: usize,
    pub frame: SensorFrame,
    pub tool: bool,
}

impl ForceSensor {
    /// The sensor of `params` on an arm whose gravity is `gravity` [m/s²] along −z.
    pub fn new(params: &SensorParams, period: f64, seed: u64, gravity: f64) -> Self {
        let alpha = params.cutoff.map_or(1.0, |fc| {
            1.0 - (-2.0 * std::f64::consts::PI * fc * period).exp()
        });
        let (bias, bias_tip) = match params.bias {
            Bias::Along(b) => (b, Vector3::zeros()),
            Bias::Axes(b) => (0.0, Vector3::from(b)),
        };
        let tip = params.frame == SensorFrame::Tip;
        let believed = params.believed_tool_mass();
        let weight = (params.tool_mass > 0.0 || believed > 0.0).then(|| Weight {
            actual: Vector3::new(0.0, 0.0, params.tool_mass * gravity),
            believed: Vector3::new(0.0, 0.0, believed * gravity),
        });
        Self {
            bias,
            bias_tip,
            noise_std: params.noise_std,
            resolution: params.resolution,
            filtering: params.cutoff.is_some(),
            seed,
            alpha,
            filtered: 0.0,
            in_flight: vec![0.0; if tip { 0 } else { params.latency }],
            tip: tip.then(|| TipAxes {
                filtered: Vector3::zeros(),
                in_flight: vec![Vector3::zeros(); params.latency],
            }),
            weight,
        }
    }

    /// The low-pass coefficient α.
    pub fn alpha(&self) -> f64 {
        self.alpha
    }

    /// The standard normal draw of sample `k` (before scaling by `noise_std`).
    pub fn noise(&self, k: usize) -> f64 {
        StandardNormal.sample(&mut self.generator(k))
    }

    /// One small generator per sample, seeded from (seed, k) by a SplitMix-style mix so
    /// that neighbouring seeds and samples give unrelated streams.
    fn generator(&self, k: usize) -> Pcg64Mcg {
        Pcg64Mcg::seed_from_u64(mix(self.seed, k as u64))
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

    /// The draws of sample `k`, one per axis: the one-axis sensor's is the first (the
    /// same draw as [`Self::noise_draw`]); the tip axes take the generator's next two.
    #[inline(always)]
    pub fn noise_draws(&self, k: usize) -> [f64; 3] {
        if self.noise_std <= 0.0 {
            return [0.0; 3];
        }
        let mut rng = self.generator(k);
        let first = StandardNormal.sample(&mut rng);
        if self.tip.is_none() {
            return [first, 0.0, 0.0];
        }
        [
            first,
            StandardNormal.sample(&mut rng),
            StandardNormal.sample(&mut rng),
        ]
    }

    /// The reading at sample `k` of the true force `force` [N] on the one axis.
    #[inline(always)]
    pub fn measure(&mut self, k: usize, force: f64) -> f64 {
        let noise = self.noise_draw(k);
        self.read(k == 0, force, noise)
    }
}

impl<W: Real> ForceSensor<W> {
    /// Sensors of one [`SensorKey`] in lanes.
    pub fn pack<const L: usize>(s: [&ForceSensor; L]) -> Self
    where
        W: Wide<L>,
    {
        debug_assert!(s.iter().all(|x| x.lane_key() == s[0].lane_key()));
        let vector =
            |f: &dyn Fn(usize) -> Vector3<f64>| Vector3::from_fn(|r, _| W::from_lanes(|i| f(i)[r]));
        Self {
            bias: W::from_lanes(|i| s[i].bias),
            bias_tip: vector(&|i| s[i].bias_tip),
            noise_std: W::from_lanes(|i| s[i].noise_std),
            resolution: W::from_lanes(|i| s[i].resolution),
            filtering: mask_from::<W>(|i| s[i].filtering),
            seed: s[0].seed,
            alpha: W::from_lanes(|i| s[i].alpha),
            filtered: W::from_lanes(|i| s[i].filtered),
            in_flight: (0..s[0].in_flight.len())
                .map(|d| W::from_lanes(|i| s[i].in_flight[d]))
                .collect(),
            tip: s[0].tip.as_ref().map(|t0| {
                let axes = |i: usize| s[i].tip.as_ref().unwrap_or(t0);
                TipAxes {
                    filtered: vector(&|i| axes(i).filtered),
                    in_flight: (0..t0.in_flight.len())
                        .map(|d| vector(&|i| axes(i).in_flight[d]))
                        .collect(),
                }
            }),
            weight: s[0].weight.map(|w0| {
                let w = |i: usize| s[i].weight.unwrap_or(w0);
                Weight {
                    actual: vector(&|i| w(i).actual),
                    believed: vector(&|i| w(i).believed),
                }
            }),
        }
    }

    /// Lane `l` takes the sensor `s` (parameters and state; of this group's key).
    pub fn put_lane(&mut self, l: usize, s: &ForceSensor) {
        put(&mut self.bias, l, s.bias);
        put_vector(&mut self.bias_tip, l, &s.bias_tip);
        put(&mut self.noise_std, l, s.noise_std);
        put(&mut self.resolution, l, s.resolution);
        self.filtering.replace(l, s.filtering);
        put(&mut self.alpha, l, s.alpha);
        put(&mut self.filtered, l, s.filtered);
        for (v, x) in self.in_flight.iter_mut().zip(&s.in_flight) {
            put(v, l, *x);
        }
        if let (Some(t), Some(theirs)) = (&mut self.tip, &s.tip) {
            put_vector(&mut t.filtered, l, &theirs.filtered);
            for (v, x) in t.in_flight.iter_mut().zip(&theirs.in_flight) {
                put_vector(v, l, x);
            }
        }
        if let (Some(w), Some(theirs)) = (&mut self.weight, &s.weight) {
            put_vector(&mut w.actual, l, &theirs.actual);
            put_vector(&mut w.believed, l, &theirs.believed);
        }
    }
}

impl<T: Real> ForceSensor<T> {
    /// Samples of latency.
    pub fn latency(&self) -> usize {
        match &self.tip {
            Some(t) => t.in_flight.len(),
            None => self.in_flight.len(),
        }
    }

    /// Whether the reading needs the tip rotation (a tip-frame sensor).
    pub fn needs_rotation(&self) -> bool {
        self.tip.is_some()
    }

    /// The sensor's structure (see [`SensorKey`]).
    pub fn lane_key(&self) -> SensorKey {
        SensorKey {
            latency: self.latency(),
            frame: if self.tip.is_some() {
                SensorFrame::Tip
            } else {
                SensorFrame::Normal
            },
            tool: self.weight.is_some(),
        }
    }

    pub fn reset(&mut self) {
        self.filtered = T::zero();
        self.in_flight.iter_mut().for_each(|v| *v = T::zero());
        if let Some(t) = &mut self.tip {
            t.filtered = Vector3::zeros();
            t.in_flight.iter_mut().for_each(|v| *v = Vector3::zeros());
        }
    }

    /// The measured force along n̂ that the filter is fed (SPEC §15): the reading of the
    /// force on the surface plus the tool's weight, on one axis along n̂ or on the tip
    /// axes rotated back to the world with the current R, less the believed weight.
    #[inline(always)]
    pub fn sense(&mut self, r: &Reading<T>) -> T {
        let weight = self.weight;
        match (self.tip.is_some(), r.rotation) {
            (true, Some(rotation)) => {
                // β along n̂ is a world vector; the tip axes add their own β.
                let mut world = *r.surface_force + r.normal * self.bias;
                if let Some(w) = &weight {
                    world += w.actual;
                }
                // Rᵀ w and R y written out (nalgebra's sums, so its bits): its generic
                // product stayed out of line in the AVX-512 lane build.
                let y = self.read_tip(r.first, &mat_t_vec(rotation, &world), &r.noise);
                let mut back = T::mat3_vec(rotation, &y);
                if let Some(w) = &weight {
                    back -= w.believed;
                }
                r.normal.dot(&back)
            }
            _ => {
                // The one axis (a tip-frame sensor is always handed R: `needs_rotation`).
                let along = match &weight {
                    Some(w) => r.along + r.normal.dot(&w.actual),
                    None => r.along,
                };
                let y = self.read(r.first, along, r.noise[0]);
                match &weight {
                    Some(w) => y - r.normal.dot(&w.believed),
                    None => y,
                }
            }
        }
    }

    /// u + σ n rounded to the resolution (SPEC §10), on one axis.
    #[inline(always)]
    fn condition(&self, u: T, noise: T) -> T {
        let zero = T::zero();
        let (std, res) = (self.noise_std, self.resolution);
        let u = choose(std.simd_gt(zero), || u + std * noise, || u);
        choose(res.simd_gt(zero), || (u / res).simd_round() * res, || u)
    }

    /// y_0 = u_0, y_k = y_{k−1} + α (u_k − y_{k−1}), on one axis.
    #[inline(always)]
    fn low_pass(&self, first: T::SimdBool, u: T, filtered: T) -> T {
        let alpha = self.alpha;
        choose(
            first | !self.filtering,
            || u,
            || filtered + alpha * (u - filtered),
        )
    }

    /// The reading of the true force `force` [N] given the standard normal draw `noise`
    /// of this sample; `first`: the lanes at sample 0. SPEC §10: u = f + β + σ n, rounded
    /// to the resolution; y_0 = u_0, y_k = y_{k−1} + α (u_k − y_{k−1}); then the latency.
    #[inline(always)]
    pub fn read(&mut self, first: T::SimdBool, force: T, noise: T) -> T {
        let u = self.condition(force + self.bias, noise);
        let y = self.low_pass(first, u, self.filtered);
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

    /// The three tip axes' reading of `force` (tip frame, the weight included): per axis
    /// β, noise, resolution and low-pass as [`Self::read`], then one latency.
    #[inline(always)]
    fn read_tip(&mut self, first: T::SimdBool, force: &Vector3<T>, noise: &[T; 3]) -> Vector3<T> {
        // The tip state is taken out while the conditioning borrows the rest of the sensor.
        let Some(mut tip) = self.tip.take() else {
            return *force; // a one-axis sensor has no tip state (its caller reads along n̂)
        };
        let y = Vector3::from_fn(|a, _| {
            let u = self.condition(force[a] + self.bias_tip[a], noise[a]);
            self.low_pass(first, u, tip.filtered[a])
        });
        tip.filtered = y;
        let latency = tip.in_flight.len();
        let out = if latency == 0 {
            y
        } else {
            if !T::none(first) {
                tip.in_flight.iter_mut().for_each(|v| {
                    *v = Vector3::from_fn(|a, _| choose(first, || y[a], || v[a]));
                });
            }
            let out = tip.in_flight[latency - 1];
            tip.in_flight.rotate_right(1);
            tip.in_flight[0] = y;
            out
        };
        self.tip = Some(tip);
        out
    }
}

impl ForceSensor {
    /// Labels of the sensor's state, in the order of `state`.
    pub fn state_labels(&self) -> Vec<String> {
        match &self.tip {
            None => {
                let mut out = vec!["sensor.filtered".to_owned()];
                out.extend((1..=self.in_flight.len()).map(|i| format!("sensor.in_flight{i}")));
                out
            }
            Some(t) => {
                let axes = |name: String| ["x", "y", "z"].map(|a| format!("{name}_{a}"));
                let mut out = axes("sensor.filtered".to_owned()).to_vec();
                for i in 1..=t.in_flight.len() {
                    out.extend(axes(format!("sensor.in_flight{i}")));
                }
                out
            }
        }
    }

    pub fn state(&self, out: &mut Vec<f64>) {
        match &self.tip {
            None => {
                out.push(self.filtered);
                out.extend_from_slice(&self.in_flight);
            }
            Some(t) => {
                out.extend_from_slice(t.filtered.as_slice());
                t.in_flight
                    .iter()
                    .for_each(|v| out.extend_from_slice(v.as_slice()));
            }
        }
    }

    /// Reads the state written by `state`; returns the number of values used.
    pub fn set_state(&mut self, values: &[f64]) -> usize {
        match &mut self.tip {
            None => {
                self.filtered = values[0];
                let n = self.in_flight.len();
                self.in_flight.copy_from_slice(&values[1..=n]);
                n + 1
            }
            Some(t) => {
                t.filtered = Vector3::from_column_slice(&values[0..3]);
                for (i, v) in t.in_flight.iter_mut().enumerate() {
                    *v = Vector3::from_column_slice(&values[3 + 3 * i..6 + 3 * i]);
                }
                3 * (1 + t.in_flight.len())
            }
        }
    }

    pub fn state_len(&self) -> usize {
        match &self.tip {
            None => 1 + self.in_flight.len(),
            Some(t) => 3 * (1 + t.in_flight.len()),
        }
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
        ForceSensor::new(&p, 1e-3, 7, 9.81)
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
            bias: Bias::Along(0.3),
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
        let mut other = ForceSensor::new(&p, 1e-3, 8, 9.81);
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
                bias: Bias::Along(0.3),
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
            .map(|i| ForceSensor::new(&params[i], 1e-3, 11 + i as u64, 9.81))
            .collect();
        let mut lanes =
            ForceSensor::<F64x4>::pack([&scalar[0], &scalar[1], &scalar[2], &scalar[3]]);
        let mut k = [0usize; 4];
        for step in 0..40 {
            if step == 17 {
                scalar[3] = ForceSensor::new(&params[3], 1e-3, 99, 9.81);
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

    /// Tip-frame sensors with tools, four in lanes, read what four scalar ones read, bit
    /// for bit; their state round-trips.
    #[test]
    fn tip_axes_in_lanes_and_state() {
        use crate::scalar::{lane, F64x4};
        let params: [SensorParams; 4] = std::array::from_fn(|i| SensorParams {
            frame: SensorFrame::Tip,
            bias: Bias::Axes([0.1 * i as f64, -0.2, 0.05]),
            noise_std: 0.1 * i as f64,
            resolution: if i == 2 { 0.05 } else { 0.0 },
            cutoff: (i % 2 == 0).then_some(60.0),
            latency: 2,
            tool_mass: 0.5 + 0.5 * i as f64,
            tool_mass_estimate: (i == 3).then_some(1.0),
        });
        let mut scalar: Vec<ForceSensor> = (0..4)
            .map(|i| ForceSensor::new(&params[i], 1e-3, 5 + i as u64, 9.81))
            .collect();
        let refs: [&ForceSensor; 4] = std::array::from_fn(|i| &scalar[i]);
        let mut lanes = ForceSensor::<F64x4>::pack(refs);
        assert_eq!(lanes.lane_key(), scalar[0].lane_key());
        let rotation = |k: usize| {
            nalgebra::Rotation3::from_euler_angles(0.1 * k as f64, 0.3, -0.2).into_inner()
        };
        let normal = Vector3::new(0.6, 0.0, -0.8);
        for k in 0..30 {
            let r = rotation(k);
            let force = |i: usize| normal * (10.0 + (k + i) as f64) + Vector3::new(0.0, 1.0, 0.0);
            let draws: [[f64; 3]; 4] = std::array::from_fn(|i| scalar[i].noise_draws(k));
            let wide = |f: &dyn Fn(usize) -> Vector3<f64>| {
                Vector3::from_fn(|a, _| F64x4::from_lanes(|i| f(i)[a]))
            };
            let (fw, nw, rw) = (
                wide(&force),
                wide(&|_| normal),
                nalgebra::Matrix3::from_fn(|a, b| F64x4::splat(r[(a, b)])),
            );
            let out = lanes.sense(&Reading {
                first: mask_from::<F64x4>(|_| k == 0),
                along: F64x4::from_lanes(|i| force(i).dot(&normal)),
                surface_force: &fw,
                normal: &nw,
                rotation: Some(&rw),
                noise: std::array::from_fn(|a| F64x4::from_lanes(|i| draws[i][a])),
            });
            for i in 0..4 {
                let expected = scalar[i].sense(&Reading {
                    first: k == 0,
                    along: force(i).dot(&normal),
                    surface_force: &force(i),
                    normal: &normal,
                    rotation: Some(&r),
                    noise: draws[i],
                });
                assert_eq!(lane(out, i).to_bits(), expected.to_bits(), "k {k} lane {i}");
            }
        }
        // State: 3 axes × (filtered + 2 in flight), and it round-trips.
        let mut st = Vec::new();
        scalar[1].state(&mut st);
        assert_eq!((st.len(), scalar[1].state_len()), (9, 9));
        assert_eq!(scalar[1].state_labels()[0], "sensor.filtered_x");
        let mut copy = ForceSensor::new(&params[1], 1e-3, 6, 9.81);
        assert_eq!(copy.set_state(&st), 9);
        assert_eq!(copy, scalar[1]);
    }

    /// A tool's weight in the one-axis reading is taken off again: a known tool reads
    /// the contact force; an estimate off by Δm reads Δm g n̂·e_z off.
    #[test]
    fn tool_weight_on_one_axis() {
        let n = Vector3::new(0.0, 0.0, -1.0);
        let read = |estimate: Option<f64>| {
            let mut s = ForceSensor::new(
                &SensorParams {
                    tool_mass: 1.0,
                    tool_mass_estimate: estimate,
                    ..SensorParams::default()
                },
                1e-3,
                0,
                9.81,
            );
            let f = n * 10.0;
            s.sense(&Reading {
                first: true,
                along: 10.0,
                surface_force: &f,
                normal: &n,
                rotation: None,
                noise: [0.0; 3],
            })
        };
        assert_eq!(read(None), 10.0);
        assert!((read(Some(1.2)) - (10.0 + 0.2 * 9.81)).abs() < 1e-12);
    }
}
