//! The outer force loop: admittance filters (eqs. 30 and 38), the adaptive admittance of
//! Jung, Hsia & Bonitz (2004) (SPEC §16) and the impedance reference of eq. (20) as a
//! baseline (SPEC §5). Each turns the force error (or the desired force) into the position
//! modification x_a with its rate and acceleration for feed-forward.
//!
//! **Adaptive admittance** (`sigma` > 0). Jung, Hsia & Bonitz write Scheme 2 with an
//! adaptive velocity offset Φ, m ë + b (ė + Φ) = e_f, Φ(t) = Φ(t − T) + σ e_f(t − T) / b
//! (T the sample time; Duan et al. 2018 use the same update). With this library's gain k_a
//! and signs (x_a grows with e_f = f_d − f) the same law, written with ψ = b Φ / k_a in
//! newtons (no division by b), is
//!
//! ```text
//!   m ẍ_a + b ẋ_a + k x_a = k_a (e_f + ψ)          (ψ held over the period)
//!   [x_a, ẋ_a]_{k+1} = Ad [x_a, ẋ_a]_k + Bd (e_f,k + ψ_k)   (the same exact ZOH pair)
//!   ψ_{k+1} = ψ_k + σ e_f,k                          (ψ_0 = 0)
//!   ẍ_a,k = (k_a (e_f,k + ψ_k) − b ẋ_a,k − k x_a,k) / m   (feed-forward, current sample)
//! ```
//!
//! ψ is a discrete integral of the force error: at a steady state e_f = 0 and
//! b ẋ_a + k x_a = k_a ψ, so a surface receding at a constant rate v (ẋ_a = v, k = 0) is
//! tracked with zero force error (ψ → b v / k_a), where Scheme 2 keeps e_f = b v / k_a.
//! With an ideal inner loop and k = 0 the force loop's characteristic polynomial is
//! s² + (k_a k_e / b) s + σ k_a k_e / (b T) (m and the sampling neglected): critically
//! damped at σ_c = k_a k_e T / (4 b) (0.0094 for k_a = 1, k_e = 3e4, b = 800, T = 1 ms),
//! oscillatory above.

use nalgebra::{Matrix2, Matrix3, Vector2};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::error::{check, Error, Result};
use crate::scalar::{every, pack_vector, put, put_vector, Real, Wide};

/// Largest b·T/m, k·T²/m or k_a·T/m accepted (see `AdmittanceParams::validate_for_period`).
pub const MAX_DISCRETE_RATE: f64 = 1e6;
use crate::control::reference::Sample;

/// `m ẍ_a + b ẋ_a + k x_a = k_a e_f`, e_f = f_d − f.
/// Scheme 1 (eq. 30) has k > 0; Scheme 2 (eq. 38) has k = 0.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct AdmittanceParams {
    /// Mass [kg].
    #[schemars(extend("x-ui" = {"min": 0.01, "max": 100.0, "scale": "log"}))]
    pub m: f64,
    /// Damping [N·s/m].
    #[schemars(extend("x-ui" = {"min": 10.0, "max": 10000.0, "scale": "log"}))]
    pub b: f64,
    /// Stiffness [N/m]; 0 is Scheme 2.
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 2000.0, "scale": "linear"}))]
    pub k: f64,
    /// Filter gain k_a of eqs. (30)/(38): the filter input is k_a e_f [dimensionless].
    #[schemars(extend("x-ui" = {"min": 0.01, "max": 10.0, "scale": "log"}))]
    pub ka: f64,
    /// Adaptation gain σ of the adaptive force-error term (Jung, Hsia & Bonitz 2004): ψ_{k+1} = ψ_k + σ e_f,k is added to e_f [per sample]; 0 is the plain filter.
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 0.05, "scale": "linear"}))]
    pub sigma: f64,
}

impl Default for AdmittanceParams {
    fn default() -> Self {
        Self::scheme2(800.0, 1.0)
    }
}

impl AdmittanceParams {
    /// Scheme 1, eq. (30): force tracking impedance with stiffness; keeps an offset.
    pub fn scheme1(b: f64, k: f64, ka: f64) -> Self {
        Self {
            m: 1.0,
            b,
            k,
            ka,
            sigma: 0.0,
        }
    }

    /// Scheme 2, eq. (38): k = 0, infinite compliance; no steady-state force error.
    pub fn scheme2(b: f64, ka: f64) -> Self {
        Self {
            m: 1.0,
            b,
            k: 0.0,
            ka,
            sigma: 0.0,
        }
    }

    /// Scheme 2 with the adaptive force-error term (SPEC §16; see the module docs).
    pub fn adaptive(b: f64, ka: f64, sigma: f64) -> Self {
        Self {
            sigma,
            ..Self::scheme2(b, ka)
        }
    }

    pub fn validate(&self) -> Result<()> {
        check::positive("m", self.m)?;
        check::non_negative("b", self.b)?;
        check::non_negative("k", self.k)?;
        check::non_negative("ka", self.ka)?;
        // σ is a per-sample integral gain on a force: beyond 1 it adds more than the
        // error itself every sample, which no sample rate makes a filter.
        if !(self.sigma.is_finite() && (0.0..=1.0).contains(&self.sigma)) {
            return Err(Error::parameter("sigma", self.sigma, "from 0 to 1"));
        }
        Ok(())
    }

    /// Checks that the filter can be discretised at `period`: the rates b/m, k/m and k_a/m
    /// times T (and T²) must stay within `MAX_DISCRETE_RATE`, beyond which the matrix
    /// exponential of the zero-order hold overflows (a pole at −b/m = −1e100 rad/s is not a
    /// filter a controller can run at any sample rate).
    pub fn validate_for_period(&self, period: f64) -> Result<()> {
        self.validate()?;
        // (field, its value, the rate it drives with m = 1, the rate with the true m)
        let rates = [
            ("b", self.b, self.b * period),
            ("k", self.k, self.k * period * period),
            ("ka", self.ka, self.ka * period),
        ];
        for (field, value, unit_mass_rate) in rates {
            let rate = unit_mass_rate / self.m;
            if rate.is_finite() && rate <= MAX_DISCRETE_RATE {
                continue;
            }
            // Blame m when the field alone would be fine with a unit mass.
            let (field, value) = if unit_mass_rate <= MAX_DISCRETE_RATE {
                ("m", self.m)
            } else {
                (field, value)
            };
            return Err(Error::parameter(
                field,
                value,
                &format!(
                    "such that b·T/m, k·T²/m and ka·T/m are at most {MAX_DISCRETE_RATE:e} \
                     (T = {period} s, m = {}, b = {}, k = {}, ka = {}): the filter's \
                     zero-order hold is not representable beyond that",
                    self.m, self.b, self.k, self.ka
                ),
            ));
        }
        let (ad, bd) = self.discretize(period);
        if !(ad.iter().chain(bd.iter()).all(|v| v.is_finite())) {
            return Err(Error::parameter(
                "b",
                self.b,
                "values whose zero-order-hold discretisation is finite",
            ));
        }
        Ok(())
    }

    /// Exact zero-order-hold discretisation: expm([[A, B], [0, 0]] T) = [[Ad, Bd], [0, 1]]
    /// for the state [x_a, ẋ_a].
    pub fn discretize(&self, period: f64) -> (Matrix2<f64>, Vector2<f64>) {
        let (m, b, k, ka) = (self.m, self.b, self.k, self.ka);
        #[rustfmt::skip]
        let augmented = Matrix3::new(
            0.0,    1.0,    0.0,
            -k / m, -b / m, ka / m,
            0.0,    0.0,    0.0,
        ) * period;
        let e = augmented.exp();
        (
            Matrix2::new(e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]),
            Vector2::new(e[(0, 2)], e[(1, 2)]),
        )
    }
}

/// A discretised admittance filter (eqs. 30 and 38 by zero-order hold): a small state
/// machine over `f64`, or four filters with their own parameters in lanes.
#[derive(Debug, Clone, PartialEq)]
pub struct AdmittanceFilter<T: Real = f64> {
    m: T,
    b: T,
    k: T,
    ka: T,
    ad: Matrix2<T>,
    bd: Vector2<T>,
    state: Vector2<T>,
}

impl AdmittanceFilter {
    pub fn new(params: AdmittanceParams, period: f64) -> Self {
        let (ad, bd) = params.discretize(period);
        Self {
            m: params.m,
            b: params.b,
            k: params.k,
            ka: params.ka,
            ad,
            bd,
            state: Vector2::zeros(),
        }
    }
}

impl<W: Real> AdmittanceFilter<W> {
    /// Four filters in lanes.
    pub fn pack<const L: usize>(f: [&AdmittanceFilter; L]) -> Self
    where
        W: Wide<L>,
    {
        Self {
            m: W::from_lanes(|i| f[i].m),
            b: W::from_lanes(|i| f[i].b),
            k: W::from_lanes(|i| f[i].k),
            ka: W::from_lanes(|i| f[i].ka),
            ad: pack_vector(f.map(|f| &f.ad)),
            bd: pack_vector(f.map(|f| &f.bd)),
            state: pack_vector(f.map(|f| &f.state)),
        }
    }

    /// Lane `l` takes the filter `f` (parameters and state).
    pub fn put_lane(&mut self, l: usize, f: &AdmittanceFilter) {
        put(&mut self.m, l, f.m);
        put(&mut self.b, l, f.b);
        put(&mut self.k, l, f.k);
        put(&mut self.ka, l, f.ka);
        put_vector(&mut self.ad, l, &f.ad);
        put_vector(&mut self.bd, l, &f.bd);
        put_vector(&mut self.state, l, &f.state);
    }
}

impl<T: Real> AdmittanceFilter<T> {
    pub fn reset(&mut self) {
        self.state = Vector2::zeros();
    }

    /// The state (x_a, ẋ_a).
    pub(crate) fn get(&self) -> (T, T) {
        (self.state[0], self.state[1])
    }

    /// Sets the state (x_a, ẋ_a): the six-axis filter holds a rotation axis's (θ, ω) in its
    /// rotation and sets them here each period.
    pub(crate) fn set(&mut self, x_a: T, xa_dot: T) {
        self.state = Vector2::new(x_a, xa_dot);
    }

    /// Lanes in `mask` take the state (x_a, ẋ_a).
    #[inline(always)]
    fn start(&mut self, mask: T::SimdBool, x_a: T, xa_dot: T) {
        self.state = Vector2::new(
            x_a.select(mask, self.state[0]),
            xa_dot.select(mask, self.state[1]),
        );
    }

    /// Output at t_k, then advance to t_{k+1}. The filter is strictly proper: x_a,k and
    /// ẋ_a,k depend on e_f up to k−1; the feed-forward ẍ_a,k uses the current sample.
    #[inline(always)]
    pub fn step(&mut self, force_error: T) -> Sample<T> {
        let (xa, xa_dot) = (self.state[0], self.state[1]);
        let out = Sample {
            value: xa,
            rate: xa_dot,
            // ẍ_a from eq. (30) (eq. 38: k = 0) at the current error.
            accel: (self.ka * force_error - self.b * xa_dot - self.k * xa) / self.m,
        };
        // [x_a, ẋ_a]_{k+1} = Ad [x_a, ẋ_a]_k + Bd e_f,k
        // Written out (nalgebra's order: Ad's columns, then Bd e_f): its generic product
        // stayed out of line in the lane builds.
        let (ad, bd, x) = (&self.ad, &self.bd, self.state);
        self.state = Vector2::new(
            (ad[(0, 0)] * x[0] + ad[(0, 1)] * x[1]) + bd[0] * force_error,
            (ad[(1, 0)] * x[0] + ad[(1, 1)] * x[1]) + bd[1] * force_error,
        );
        out
    }
}

/// The adaptive admittance filter (SPEC §16; equations in the module docs): the plain
/// filter fed e_f + ψ, with ψ the discrete integral of e_f at gain σ.
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveFilter<T: Real = f64> {
    filter: AdmittanceFilter<T>,
    sigma: T,
    /// ψ [N].
    psi: T,
}

impl AdaptiveFilter {
    pub fn new(params: AdmittanceParams, period: f64) -> Self {
        Self {
            filter: AdmittanceFilter::new(params, period),
            sigma: params.sigma,
            psi: 0.0,
        }
    }
}

impl<W: Real> AdaptiveFilter<W> {
    pub fn pack<const L: usize>(f: [&AdaptiveFilter; L]) -> Self
    where
        W: Wide<L>,
    {
        Self {
            filter: AdmittanceFilter::pack(f.map(|f| &f.filter)),
            sigma: W::from_lanes(|i| f[i].sigma),
            psi: W::from_lanes(|i| f[i].psi),
        }
    }

    pub fn put_lane(&mut self, l: usize, f: &AdaptiveFilter) {
        self.filter.put_lane(l, &f.filter);
        put(&mut self.sigma, l, f.sigma);
        put(&mut self.psi, l, f.psi);
    }
}

impl<T: Real> AdaptiveFilter<T> {
    pub fn reset(&mut self) {
        self.filter.reset();
        self.psi = T::zero();
    }

    /// Output at t_k, then advance: the filter fed e_f,k + ψ_k, then ψ_{k+1} = ψ_k + σ e_f,k.
    #[inline(always)]
    pub fn step(&mut self, force_error: T) -> Sample<T> {
        let out = self.filter.step(force_error + self.psi);
        self.psi += self.sigma * force_error;
        out
    }
}

/// Eq. (20): x_d = x̂_e + f_d / k_eff with k_eff = k k̂_e / (k + k̂_e), an assumed wall
/// stiffness and no force feedback. The baseline the admittance schemes improve on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ImpedanceParams {
    /// Impedance stiffness [N/m].
    pub k: f64,
    /// The wall stiffness the designer assumes, k̂_e [N/m].
    pub assumed_stiffness: f64,
}

impl Default for ImpedanceParams {
    fn default() -> Self {
        Self {
            k: 10_000.0,
            assumed_stiffness: 30_000.0,
        }
    }
}

impl ImpedanceParams {
    pub fn validate(&self) -> Result<()> {
        check::positive("k", self.k)?;
        check::positive("assumed_stiffness", self.assumed_stiffness)
    }

    pub fn effective_stiffness(&self) -> f64 {
        self.k * self.assumed_stiffness / (self.k + self.assumed_stiffness)
    }
}

/// Which outer loop shapes the x reference, tagged by `kind` as the Python blocks are.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ForceControlParams {
    Admittance(AdmittanceParams),
    Impedance(ImpedanceParams),
}

impl ForceControlParams {
    /// Checks the fields, and that an admittance filter can be discretised at `period`.
    pub fn validate(&self, period: f64) -> Result<()> {
        match self {
            ForceControlParams::Admittance(p) => p.validate_for_period(period),
            ForceControlParams::Impedance(p) => p.validate(),
        }
    }
}

/// The outer force loop as a state machine (over `f64`, or lanes of one kind).
#[derive(Debug, Clone, PartialEq)]
pub enum ForceControl<T: Real = f64> {
    Admittance(AdmittanceFilter<T>),
    /// An admittance filter with σ > 0.
    Adaptive(AdaptiveFilter<T>),
    Impedance {
        effective_stiffness: T,
    },
}

/// The outer loop's kind: what runs must share for their outer loops to advance in one lane
/// group (every coefficient is a number a lane carries).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ForceControlKey {
    /// Eqs. (21)–(38), any scheme.
    Admittance,
    /// The same with the adaptive force-error term (one more state, ψ).
    Adaptive,
    /// Eq. (20).
    Impedance,
}

impl<T: Real> ForceControl<T> {
    pub fn lane_key(&self) -> ForceControlKey {
        match self {
            ForceControl::Admittance(_) => ForceControlKey::Admittance,
            ForceControl::Adaptive(_) => ForceControlKey::Adaptive,
            ForceControl::Impedance { .. } => ForceControlKey::Impedance,
        }
    }
}

impl<W: Real> ForceControl<W> {
    /// `L` outer loops of one kind in lanes; `None` if the kinds differ.
    pub fn pack<const L: usize>(f: [&ForceControl; L]) -> Option<Self>
    where
        W: Wide<L>,
    {
        let admittance = f.map(|x| match x {
            ForceControl::Admittance(a) => Some(a),
            _ => None,
        });
        let adaptive = f.map(|x| match x {
            ForceControl::Adaptive(a) => Some(a),
            _ => None,
        });
        let impedance = f.map(|x| match x {
            ForceControl::Impedance {
                effective_stiffness,
            } => Some(*effective_stiffness),
            _ => None,
        });
        if let Some(a) = every(admittance) {
            Some(ForceControl::Admittance(AdmittanceFilter::pack(a)))
        } else if let Some(a) = every(adaptive) {
            Some(ForceControl::Adaptive(AdaptiveFilter::pack(a)))
        } else {
            every(impedance).map(|k| ForceControl::Impedance {
                effective_stiffness: W::from_lanes(|i| k[i]),
            })
        }
    }

    /// Lane `l` takes `f` (of this kind: the lane key guarantees it); false if the kinds
    /// differ.
    pub fn put_lane(&mut self, l: usize, f: &ForceControl) -> bool {
        match (self, f) {
            (ForceControl::Admittance(a), ForceControl::Admittance(b)) => a.put_lane(l, b),
            (ForceControl::Adaptive(a), ForceControl::Adaptive(b)) => a.put_lane(l, b),
            (
                ForceControl::Impedance {
                    effective_stiffness: a,
                },
                ForceControl::Impedance {
                    effective_stiffness: b,
                },
            ) => put(a, l, *b),
            _ => return false,
        }
        true
    }
}

impl ForceControl {
    pub fn new(p: &ForceControlParams, period: f64) -> Self {
        match p {
            // σ = 0 keeps the plain filter's code, and its bits.
            ForceControlParams::Admittance(a) if a.sigma > 0.0 => {
                ForceControl::Adaptive(AdaptiveFilter::new(*a, period))
            }
            ForceControlParams::Admittance(a) => {
                ForceControl::Admittance(AdmittanceFilter::new(*a, period))
            }
            ForceControlParams::Impedance(i) => ForceControl::Impedance {
                effective_stiffness: i.effective_stiffness(),
            },
        }
    }

    /// Labels of the filter state (x_a, ẋ_a of an admittance filter; none for eq. 20).
    pub fn state_labels(&self) -> &'static [&'static str] {
        match self {
            ForceControl::Admittance(_) => &["x_a", "xa_dot"],
            ForceControl::Adaptive(_) => &["x_a", "xa_dot", "psi"],
            ForceControl::Impedance { .. } => &[],
        }
    }

    pub fn state(&self, out: &mut Vec<f64>) {
        match self {
            ForceControl::Admittance(f) => out.extend_from_slice(f.state.as_slice()),
            ForceControl::Adaptive(a) => {
                out.extend_from_slice(a.filter.state.as_slice());
                out.push(a.psi);
            }
            ForceControl::Impedance { .. } => {}
        }
    }

    /// Reads the state written by `state`; returns the number of values used.
    pub fn set_state(&mut self, values: &[f64]) -> usize {
        match self {
            ForceControl::Admittance(f) => {
                f.state = Vector2::new(values[0], values[1]);
                2
            }
            ForceControl::Adaptive(a) => {
                a.filter.state = Vector2::new(values[0], values[1]);
                a.psi = values[2];
                3
            }
            ForceControl::Impedance { .. } => 0,
        }
    }
}

impl<T: Real> ForceControl<T> {
    /// Lanes in `mask` start from x_a, ẋ_a (and ψ = 0): the bumpless switch of a guarded
    /// approach (`control::approach`). The eq. 20 reference has no state to start
    /// (`ScenarioConfig::validate` refuses an approach with it).
    #[inline(always)]
    pub fn start(&mut self, mask: T::SimdBool, x_a: T, xa_dot: T) {
        match self {
            ForceControl::Admittance(f) => f.start(mask, x_a, xa_dot),
            ForceControl::Adaptive(a) => {
                a.filter.start(mask, x_a, xa_dot);
                a.psi = T::zero().select(mask, a.psi);
            }
            ForceControl::Impedance { .. } => {}
        }
    }

    pub fn reset(&mut self) {
        match self {
            ForceControl::Admittance(f) => f.reset(),
            ForceControl::Adaptive(a) => a.reset(),
            ForceControl::Impedance { .. } => {}
        }
    }

    /// x_a (with rate and acceleration) from the desired force and the measured force:
    /// the admittance filter fed by e_f = f_d − f̃, or eq. (20)'s x_a = f_d / k_eff.
    #[inline(always)]
    pub fn step(&mut self, desired: &Sample<T>, measured: T) -> Sample<T> {
        match self {
            ForceControl::Admittance(f) => f.step(desired.value - measured),
            ForceControl::Adaptive(a) => a.step(desired.value - measured),
            ForceControl::Impedance {
                effective_stiffness: k,
            } => Sample {
                value: desired.value / *k,
                rate: desired.rate / *k,
                accel: desired.accel / *k,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scheme2_zoh_closed_form() {
        let (b, ka, t) = (800.0, 0.1, 1e-3);
        let (ad, bd) = AdmittanceParams::scheme2(b, ka).discretize(t);
        let e = (-b * t).exp();
        let g = (1.0 - e) / b;
        assert!((ad - Matrix2::new(1.0, g, 0.0, e)).abs().max() < 1e-14);
        assert!((bd - Vector2::new(ka * (t - g) / b, ka * g)).abs().max() < 1e-15);
    }

    /// With a constant input the ZOH model is exact at the samples: compare with the
    /// analytic step response of k_a / (m s² + b s + k).
    #[test]
    fn step_response_is_exact_at_samples() {
        let (m, b, k, ka, ef) = (1.0, 800.0, 400.0, 0.1, 10.0);
        let mut f: AdmittanceFilter = AdmittanceFilter::new(
            AdmittanceParams {
                m,
                b,
                k,
                ka,
                sigma: 0.0,
            },
            1e-3,
        );
        let disc = (b * b - 4.0 * m * k).sqrt();
        let (p1, p2) = ((-b + disc) / (2.0 * m), (-b - disc) / (2.0 * m));
        let fin = ka * ef / k;
        for n in 0..3000 {
            let t = n as f64 * 1e-3;
            let exact = fin * (1.0 + (p2 * (p1 * t).exp() - p1 * (p2 * t).exp()) / (p1 - p2));
            let out = f.step(ef);
            assert!((out.value - exact).abs() < 1e-12 * fin.max(1.0), "n={n}");
        }
    }

    #[test]
    fn feed_forward_uses_current_error() {
        let mut f = AdmittanceFilter::new(AdmittanceParams::scheme2(800.0, 1.0), 1e-3);
        let first = f.step(10.0);
        assert_eq!(first.value, 0.0);
        assert_eq!(first.rate, 0.0);
        assert_eq!(first.accel, 10.0);
        f.reset();
        assert_eq!(f.step(0.0), Sample::default());
    }

    #[test]
    fn impedance_reference_eq20() {
        let p = ImpedanceParams {
            k: 1e4,
            assumed_stiffness: 3e4,
        };
        assert!((p.effective_stiffness() - 7500.0).abs() < 1e-9);
        let mut fc = ForceControl::new(&ForceControlParams::Impedance(p), 1e-3);
        let fd = Sample {
            value: 15.0,
            rate: 3.0,
            accel: 0.0,
        };
        let xa = fc.step(&fd, 123.0);
        assert!((xa.value - 0.002).abs() < 1e-15);
        assert!((xa.rate - 0.0004).abs() < 1e-15);
    }

    #[test]
    fn negative_damping_rejected() {
        let p = AdmittanceParams::scheme2(-1.0, 1.0);
        assert!(p.validate().unwrap_err().to_string().starts_with("b = -1"));
    }

    /// Gains the zero-order hold cannot represent are errors naming the culprit, at once
    /// (they used to hang the matrix exponential); the largest accepted rate discretises.
    #[test]
    fn unrepresentable_filters_are_rejected_quickly() {
        let t = 1e-3;
        for (p, field) in [
            (
                AdmittanceParams {
                    k: 1e100,
                    ..AdmittanceParams::default()
                },
                "k = ",
            ),
            (
                AdmittanceParams {
                    b: 1e100,
                    ..AdmittanceParams::default()
                },
                "b = ",
            ),
            (
                AdmittanceParams {
                    k: 1e300,
                    ..AdmittanceParams::default()
                },
                "k = ",
            ),
            (
                AdmittanceParams {
                    m: 1e-300,
                    ..AdmittanceParams::default()
                },
                "m = ",
            ),
        ] {
            let e = p.validate_for_period(t).unwrap_err().to_string();
            assert!(e.starts_with(field), "{e}");
        }
        let edge = AdmittanceParams {
            b: MAX_DISCRETE_RATE / t,
            k: MAX_DISCRETE_RATE / (t * t),
            ..AdmittanceParams::default()
        };
        edge.validate_for_period(t).unwrap();
        let (ad, bd) = edge.discretize(t);
        assert!(ad.iter().chain(bd.iter()).all(|v| v.is_finite()));
    }

    /// Four filters with their own parameters in lanes step as four scalar filters, bit
    /// for bit (the ZOH matrices are each run's own, discretised once in f64).
    #[test]
    fn lanes_step_as_four_scalar_filters() {
        use crate::scalar::F64x4;
        let params = [
            AdmittanceParams::scheme2(800.0, 0.1),
            AdmittanceParams::scheme1(800.0, 400.0, 0.1),
            AdmittanceParams {
                m: 2.0,
                b: 300.0,
                k: 50.0,
                ka: 1.5,
                sigma: 0.0,
            },
            AdmittanceParams::scheme2(1500.0, 0.02),
        ];
        check_lanes(params);
        // The adaptive kind (σ > 0), four of them with their own gains.
        check_lanes(std::array::from_fn(|i| AdmittanceParams {
            sigma: 0.002 * (1 + i) as f64,
            ..params[i]
        }));
        // Kinds do not mix in one pack.
        let scalar: Vec<ForceControl> = params
            .iter()
            .map(|p| ForceControl::new(&ForceControlParams::Admittance(*p), 1e-3))
            .collect();
        let adaptive = ForceControl::new(
            &ForceControlParams::Admittance(AdmittanceParams::adaptive(800.0, 1.0, 0.01)),
            1e-3,
        );
        assert_eq!(adaptive.lane_key(), ForceControlKey::Adaptive);
        assert!(
            ForceControl::<F64x4>::pack([&scalar[0], &adaptive, &scalar[2], &scalar[3]]).is_none()
        );
        let imp = ForceControl::new(
            &ForceControlParams::Impedance(ImpedanceParams {
                k: 1e4,
                assumed_stiffness: 3e4,
            }),
            1e-3,
        );
        assert!(ForceControl::<F64x4>::pack([&scalar[0], &imp, &scalar[2], &scalar[3]]).is_none());
    }

    fn check_lanes(params: [AdmittanceParams; 4]) {
        use crate::scalar::{lane, F64x4};
        let mut scalar: Vec<ForceControl> = params
            .iter()
            .map(|p| ForceControl::new(&ForceControlParams::Admittance(*p), 1e-3))
            .collect();
        let mut lanes =
            ForceControl::<F64x4>::pack([&scalar[0], &scalar[1], &scalar[2], &scalar[3]]).unwrap();
        for n in 0..200 {
            let fd: [Sample; 4] = std::array::from_fn(|i| Sample {
                value: 10.0 + i as f64,
                ..Sample::default()
            });
            let f: [f64; 4] = std::array::from_fn(|i| (n as f64 * 0.1 + i as f64).cos() * 12.0);
            let out = lanes.step(&Sample::pack(fd.each_ref()), F64x4::from_lanes(|i| f[i]));
            for i in 0..4 {
                let e = scalar[i].step(&fd[i], f[i]);
                assert_eq!(lane(out.value, i).to_bits(), e.value.to_bits());
                assert_eq!(lane(out.rate, i).to_bits(), e.rate.to_bits());
                assert_eq!(lane(out.accel, i).to_bits(), e.accel.to_bits());
            }
        }
    }

    /// The adaptive term is the discrete integral ψ_{k+1} = ψ_k + σ e_f,k added to the
    /// filter's input: a constant error e gives the plain filter's response to e (1 + σ k)
    /// at sample k (ψ_k = σ k e), and the feed-forward reads e_f,k + ψ_k.
    #[test]
    fn adaptive_term_integrates_the_error() {
        let (b, ka, sigma, e) = (800.0, 1.0, 0.01, 2.0);
        let mut adaptive = ForceControl::new(
            &ForceControlParams::Admittance(AdmittanceParams::adaptive(b, ka, sigma)),
            1e-3,
        );
        let mut plain = AdmittanceFilter::new(AdmittanceParams::scheme2(b, ka), 1e-3);
        let fd = |v: f64| Sample {
            value: v,
            ..Sample::default()
        };
        for k in 0..50 {
            let a = adaptive.step(&fd(e), 0.0);
            let p = plain.step(e * (1.0 + sigma * k as f64));
            assert!((a.value - p.value).abs() < 1e-18, "{k}");
            assert!((a.rate - p.rate).abs() < 1e-15, "{k}");
            assert!((a.accel - p.accel).abs() < 1e-12, "{k}");
        }
        let mut state = vec![];
        adaptive.state(&mut state);
        assert!((state[2] - 50.0 * sigma * e).abs() < 1e-12);
        assert_eq!(adaptive.state_labels(), &["x_a", "xa_dot", "psi"]);
        let bad = AdmittanceParams::adaptive(b, ka, -0.1)
            .validate()
            .unwrap_err();
        assert!(bad.to_string().starts_with("sigma = -0.1"), "{bad}");
    }
}
