//! The six-axis admittance (SPEC §19): a mass–damper–spring per axis of a frame, driven by
//! the wrench on the tool, with the paper's force laws on the force axis.
//!
//! Per selected axis i (x, y, z, then rotations about x, y, z of the filter's frame):
//!
//! ```text
//!   M_i ẍ_i + D_i ẋ_i + K_i x_i = w_i − w_ref,i        D_i = 2 ζ_i √(M_i K_i) if a ratio is given
//! ```
//!
//! `w` is the wrench the environment applies to the tool (the F/T sensor's convention: a
//! tool pressing along n̂ with force f reads −f along n̂), so `w_ref` is the wrench the
//! environment should apply. Translations step by the exact zero-order hold of each axis
//! (the 1-D filter's [`AdmittanceFilter`] with k_a = 1, so an axis and that filter give the
//! same bits). Rotations live on SO(3): the state is a rotation R_a and an angular velocity
//! ω in the frame's axes; each period, θ = log R_a (the rotation vector) and ω step by the
//! same per-axis hold, and R_a ← R_a·exp([Δθ]×) with Δθ the held step's angle increment,
//! never Euler angles. About one fixed axis this is exact (the angle is the axis's
//! coordinate); about several, the spring acts on log R_a in the tangent space at the
//! current R_a, as a geometric spring does.
//!
//! With `force` set, the force axis (z, along n̂ in the contact frame) runs that law
//! (Scheme 1, Scheme 2, eq. 20, adaptive) on e_f = f_d − f exactly as the 1-D loop does,
//! whatever `selected_axes[2]` says. Any other unselected axis is rigid: its state stays 0.

use nalgebra::{Matrix3, Vector3, Vector6};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::control::filter::{
    AdmittanceFilter, AdmittanceParams, ForceControl, ForceControlParams,
};
use crate::control::reference::Sample;
use crate::error::{Error, Result};
use crate::robot::chain::arm::rotation_vector;
use crate::scalar::Real;

/// The names of the six axes, as errors and labels give them.
pub const AXES: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];

/// The frame whose axes the filter's six values are in (SPEC §19).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum AdmittanceFrame {
    /// (t̂, b̂, n̂) at the estimated surface: z along the normal, x along the motion.
    #[default]
    Contact,
    /// The arm's base frame.
    Base,
    /// The tool's frame (the sensor's), turning with it.
    Tool,
}

/// The six-axis admittance's parameters (SPEC §19).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct WrenchAdmittanceParams {
    /// Mass per axis: [kg] for x, y, z, [kg·m²] for the rotations.
    pub mass: [f64; 6],
    /// Damping per axis [N·s/m, N·m·s/rad]; give this or `damping_ratio`, not both.
    pub damping: Option<[f64; 6]>,
    /// Damping ratio ζ per axis: D = 2 ζ √(M K) (needs K > 0 on a selected axis). Used when
    /// `damping` is not given (1.0 on every axis when neither is).
    pub damping_ratio: Option<[f64; 6]>,
    /// Stiffness per axis [N/m, N·m/rad].
    pub stiffness: [f64; 6],
    /// Which axes comply; an unselected axis is rigid (its state stays 0), except the force
    /// axis when `force` is set.
    pub selected_axes: [bool; 6],
    /// The frame of the six values.
    pub frame: AdmittanceFrame,
    /// The paper's law on the force axis (z of the contact frame), as the 1-D loop runs it.
    pub force: Option<ForceControlParams>,
    /// The wrench the environment should apply to the tool [N, N·m].
    pub wrench_reference: [f64; 6],
}

impl Default for WrenchAdmittanceParams {
    /// Today's loop: the paper's Scheme 2 on the force axis, the other five axes rigid.
    fn default() -> Self {
        Self {
            mass: [1.0, 1.0, 1.0, 0.05, 0.05, 0.05],
            damping: None,
            damping_ratio: None,
            stiffness: [500.0, 500.0, 500.0, 50.0, 50.0, 50.0],
            selected_axes: [false; 6],
            frame: AdmittanceFrame::Contact,
            force: Some(ForceControlParams::Admittance(AdmittanceParams::default())),
            wrench_reference: [0.0; 6],
        }
    }
}

impl WrenchAdmittanceParams {
    /// The damping of every axis: `damping`, else 2 ζ √(M K).
    pub fn resolved_damping(&self) -> [f64; 6] {
        match (self.damping, self.damping_ratio) {
            (Some(d), _) => d,
            (None, ratio) => {
                let zeta = ratio.unwrap_or([1.0; 6]);
                std::array::from_fn(|i| 2.0 * zeta[i] * (self.mass[i] * self.stiffness[i]).sqrt())
            }
        }
    }

    /// The axes that step a mass–damper–spring of their own (the force axis under `force`
    /// runs that law instead).
    fn complies(&self, axis: usize) -> bool {
        self.selected_axes[axis] && !(axis == 2 && self.force.is_some())
    }

    /// One axis as the 1-D filter's parameters (k_a = 1: the input is w − w_ref).
    fn axis(&self, axis: usize) -> AdmittanceParams {
        AdmittanceParams {
            m: self.mass[axis],
            b: self.resolved_damping()[axis],
            k: self.stiffness[axis],
            ka: 1.0,
            sigma: 0.0,
        }
    }

    /// Checks every value, and that each complying axis can be discretised at `period`;
    /// an error names the field and the axis (`damping_ratio[3]`).
    pub fn validate(&self, period: f64) -> Result<()> {
        if self.damping.is_some() && self.damping_ratio.is_some() {
            return Err(Error::parameter(
                "damping_ratio",
                "given with damping",
                "left out when damping is given (one of the two sets D)",
            ));
        }
        let finite = |field: &str, values: &[f64; 6], least: f64, strict: bool| -> Result<()> {
            for (i, &v) in values.iter().enumerate() {
                let ok = v.is_finite() && if strict { v > least } else { v >= least };
                if !ok {
                    let range = if strict {
                        "finite and > 0"
                    } else {
                        "finite and ≥ 0"
                    };
                    return Err(Error::parameter(&format!("{field}[{i}]"), v, range));
                }
            }
            Ok(())
        };
        finite("mass", &self.mass, 0.0, true)?;
        finite("stiffness", &self.stiffness, 0.0, false)?;
        if let Some(d) = &self.damping {
            finite("damping", d, 0.0, false)?;
        }
        if let Some(z) = &self.damping_ratio {
            finite("damping_ratio", z, 0.0, false)?;
        }
        for (i, w) in self.wrench_reference.iter().enumerate() {
            if !w.is_finite() {
                return Err(Error::parameter(
                    &format!("wrench_reference[{i}]"),
                    *w,
                    "a finite number",
                ));
            }
        }
        for axis in (0..6).filter(|&a| self.complies(a)) {
            if self.damping.is_none() && self.stiffness[axis] == 0.0 {
                return Err(Error::parameter(
                    &format!("stiffness[{axis}]"),
                    0.0,
                    &format!(
                        "> 0 on the selected axis {} when the damping is given as a ratio \
                         (2 ζ √(M K) is 0 there: give `damping` instead)",
                        AXES[axis]
                    ),
                ));
            }
            self.axis(axis).validate_for_period(period).map_err(|e| {
                // The 1-D filter names m, b, k: say which axis of which field.
                match e {
                    Error::Parameter {
                        field,
                        value,
                        allowed,
                    } => {
                        let name = match field.as_str() {
                            "m" => "mass",
                            "b" if self.damping.is_some() => "damping",
                            "b" => "damping_ratio",
                            _ => "stiffness",
                        };
                        Error::Parameter {
                            field: format!("{name}[{axis}]"),
                            value,
                            allowed,
                        }
                    }
                }
            })?;
        }
        if let Some(force) = &self.force {
            force.validate(period).map_err(|e| e.within("force"))?;
        }
        Ok(())
    }
}

/// The filter's output at one sample: the pose offset and its rates, in the filter's
/// frame (X_d = (p_ref + R_ref·position, R_ref·rotation), SPEC §19).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdmittanceOffset<T: Real = f64> {
    /// The translation x (with ẋ and the feed-forward ẍ), per axis.
    pub position: [Sample<T>; 3],
    /// R_a.
    pub rotation: Matrix3<T>,
    /// ω, in the frame's axes.
    pub angular_velocity: Vector3<T>,
    /// ω̇ (feed-forward, at the current wrench).
    pub angular_acceleration: Vector3<T>,
}

/// The six-axis admittance as a state machine (SPEC §19; the equations in the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct WrenchAdmittance<T: Real = f64> {
    /// A translation axis's filter (k_a = 1), `None` where rigid or run by `force`.
    linear: [Option<AdmittanceFilter<T>>; 3],
    /// A rotation axis's per-axis hold on (θ_i, ω_i), `None` where rigid.
    angular: [Option<AdmittanceFilter<T>>; 3],
    /// R_a.
    rotation: Matrix3<T>,
    /// ω.
    angular_velocity: Vector3<T>,
    /// The law on the force axis.
    force: Option<ForceControl<T>>,
    reference: Vector6<T>,
    frame: AdmittanceFrame,
}

impl WrenchAdmittance {
    /// The filter of `params` (validated by the caller, `WrenchAdmittanceParams::validate`)
    /// at the sample period `period`.
    pub fn new(params: &WrenchAdmittanceParams, period: f64) -> Self {
        let filter = |axis: usize| {
            params
                .complies(axis)
                .then(|| AdmittanceFilter::new(params.axis(axis), period))
        };
        Self {
            linear: std::array::from_fn(filter),
            angular: std::array::from_fn(|i| filter(3 + i)),
            rotation: Matrix3::identity(),
            angular_velocity: Vector3::zeros(),
            force: params.force.as_ref().map(|f| ForceControl::new(f, period)),
            reference: Vector6::from(params.wrench_reference),
            frame: params.frame,
        }
    }

    pub fn frame(&self) -> AdmittanceFrame {
        self.frame
    }
}

impl<T: Real> WrenchAdmittance<T> {
    pub fn reset(&mut self) {
        for f in self
            .linear
            .iter_mut()
            .chain(self.angular.iter_mut())
            .flatten()
        {
            f.reset();
        }
        self.rotation = Matrix3::identity();
        self.angular_velocity = Vector3::zeros();
        if let Some(f) = &mut self.force {
            f.reset();
        }
    }

    /// The offset at t_k from the wrench on the tool `wrench` (force, then torque about the
    /// control point, in the filter's frame) and, for the force law, the desired force and
    /// the force measured along n̂; then the state advances to t_{k+1}.
    #[inline(always)]
    pub fn step(
        &mut self,
        wrench: &Vector6<T>,
        desired_force: &Sample<T>,
        measured_force: T,
    ) -> AdmittanceOffset<T> {
        let input = wrench - self.reference;
        let rigid = Sample {
            value: T::zero(),
            rate: T::zero(),
            accel: T::zero(),
        };
        let mut position = [rigid; 3];
        for (axis, filter) in self.linear.iter_mut().enumerate() {
            if let Some(f) = filter {
                position[axis] = f.step(input[axis]);
            }
        }
        if let Some(f) = &mut self.force {
            position[2] = f.step(desired_force, measured_force);
        }
        // Rotations: θ = log R_a and ω through each axis's hold, then R_a·exp([Δθ]×).
        let theta = rotation_vector(&self.rotation);
        let mut step = Vector3::zeros();
        let mut angular_acceleration = Vector3::zeros();
        let angular_velocity = self.angular_velocity;
        for (axis, filter) in self.angular.iter_mut().enumerate() {
            if let Some(f) = filter {
                f.set(theta[axis], self.angular_velocity[axis]);
                let out = f.step(input[3 + axis]);
                angular_acceleration[axis] = out.accel;
                let (next, rate) = f.get();
                step[axis] = next - theta[axis];
                self.angular_velocity[axis] = rate;
            }
        }
        let offset = AdmittanceOffset {
            position,
            rotation: self.rotation,
            angular_velocity,
            angular_acceleration,
        };
        self.rotation *= exp_so3(&step);
        offset
    }
}

/// exp([φ]×) by Rodrigues' formula, R = I + (sin θ/θ) [φ]× + ((1 − cos θ)/θ²) [φ]×², with
/// the two ratios' series below θ² = 1e-8 (where the formula's division loses digits; the
/// series' next terms are below 1e-17 there). Over any scalar, with no data-dependent branch.
#[inline(always)]
pub fn exp_so3<T: Real>(phi: &Vector3<T>) -> Matrix3<T> {
    let theta2 = phi.norm_squared();
    let theta = theta2.simd_sqrt();
    let (s, c) = theta.sin_cos_each();
    let small = theta2.simd_lt(T::splat(1e-8));
    // Where small, divide by 1 instead of θ (the series is taken there): no 0/0 in any lane.
    let safe = T::one().select(small, theta);
    let safe2 = T::one().select(small, theta2);
    let a = (T::one() - theta2 / T::splat(6.0)).select(small, s / safe);
    let b = (T::splat(0.5) - theta2 / T::splat(24.0)).select(small, (T::one() - c) / safe2);
    let k = crate::robot::chain::spatial::skew(phi);
    Matrix3::identity() + k * a + (k * k) * b
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    const T: f64 = 1e-3;

    fn sample(value: f64) -> Sample {
        Sample {
            value,
            rate: 0.0,
            accel: 0.0,
        }
    }

    fn all_axes() -> WrenchAdmittanceParams {
        WrenchAdmittanceParams {
            mass: [2.0, 3.0, 4.0, 0.02, 0.03, 0.04],
            damping: Some([80.0, 90.0, 100.0, 0.5, 0.6, 0.7]),
            damping_ratio: None,
            stiffness: [400.0, 500.0, 600.0, 20.0, 30.0, 40.0],
            selected_axes: [true; 6],
            frame: AdmittanceFrame::Base,
            force: None,
            wrench_reference: [1.0, -2.0, 3.0, 0.1, -0.2, 0.3],
        }
    }

    /// A translation axis is the 1-D filter (k_a = 1) fed w − w_ref: the same bits.
    #[test]
    fn a_translation_axis_is_the_one_axis_filter() {
        let p = all_axes();
        let mut six = WrenchAdmittance::new(&p, T);
        let mut one: [AdmittanceFilter; 3] =
            std::array::from_fn(|i| AdmittanceFilter::new(p.axis(i), T));
        for k in 0..500 {
            let w = Vector6::from_fn(|i, _| ((k * (i + 3)) as f64 * 0.37).sin() * 20.0);
            let out = six.step(&w, &sample(0.0), 0.0);
            for (i, f) in one.iter_mut().enumerate() {
                assert_eq!(out.position[i], f.step(w[i] - p.wrench_reference[i]));
            }
        }
    }

    /// With `force`, the force axis runs that law on f_d − f (the 1-D loop's bits) and
    /// ignores the wrench; unselected axes stay at exactly 0 whatever the wrench.
    #[test]
    fn the_force_axis_runs_the_papers_law_and_rigid_axes_stay_still() {
        let p = WrenchAdmittanceParams::default();
        let law = p.force.unwrap();
        let mut six = WrenchAdmittance::new(&p, T);
        let mut one = ForceControl::new(&law, T);
        for k in 0..300 {
            let w = Vector6::from_fn(|i, _| (k as f64 * 0.1 + i as f64).cos() * 50.0);
            let (fd, f) = (sample(10.0), (k as f64 * 0.05).sin() * 12.0);
            let out = six.step(&w, &fd, f);
            assert_eq!(out.position[2], one.step(&fd, f));
            for axis in [0, 1] {
                assert_eq!(out.position[axis], sample(0.0));
            }
            assert_eq!(out.rotation, Matrix3::identity());
            assert_eq!(out.angular_velocity, Vector3::zeros());
        }
    }

    /// A torque step about one axis: the angle follows the exact zero-order-hold response
    /// of M θ̈ + D θ̇ + K θ = τ (closed form, underdamped), to 1e-12 rad, and the rotation
    /// stays about that axis.
    #[test]
    fn a_torque_step_turns_by_the_closed_form() {
        let (m, d, k, tau) = (0.04, 0.7, 40.0, 0.3);
        let mut p = all_axes();
        p.selected_axes = [false, false, false, false, false, true];
        p.mass[5] = m;
        p.damping = Some([0.0, 0.0, 0.0, 0.0, 0.0, d]);
        p.stiffness[5] = k;
        p.wrench_reference = [0.0; 6];
        p.validate(T).unwrap();
        let mut six = WrenchAdmittance::new(&p, T);
        let w = Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, tau);
        // θ(t) = (τ/K)(1 − e^{−ζ ω_n t}(cos ω_d t + ζ ω_n/ω_d sin ω_d t)).
        let wn = (k / m).sqrt();
        let zeta = d / (2.0 * (k * m).sqrt());
        let wd = wn * (1.0 - zeta * zeta).sqrt();
        let mut worst: f64 = 0.0;
        for step in 0..2000 {
            let out = six.step(&w, &sample(0.0), 0.0);
            let t = step as f64 * T;
            let decay = (-zeta * wn * t).exp();
            let exact =
                tau / k * (1.0 - decay * ((wd * t).cos() + zeta * wn / wd * (wd * t).sin()));
            let r = out.rotation;
            worst = worst.max((r[(1, 0)].atan2(r[(0, 0)]) - exact).abs());
            assert_eq!(
                (r[(2, 0)], r[(2, 1)], r[(0, 2)], r[(1, 2)], r[(2, 2)]),
                (0.0, 0.0, 0.0, 0.0, 1.0)
            );
        }
        assert!(worst < 1e-12, "{worst:e}");
    }

    /// Under torques on all three axes for 20 000 periods, R_a stays a rotation
    /// (RᵀR = I to 1e-12, det 1).
    #[test]
    fn the_rotation_stays_on_so3() {
        let mut six = WrenchAdmittance::new(&all_axes(), T);
        let mut out = None;
        for k in 0..20_000 {
            let w = Vector6::from_fn(|i, _| ((k * (i + 1)) as f64 * 0.013).sin() * 0.5);
            out = Some(six.step(&w, &sample(0.0), 0.0));
        }
        let r = out.unwrap().rotation;
        assert!((r.transpose() * r - Matrix3::identity()).abs().max() < 1e-12);
        assert!((r.determinant() - 1.0).abs() < 1e-12);
        assert!(rotation_vector(&r).norm() > 1e-3, "the filter did turn");
    }

    /// The exponential map inverts the log map, at small and large angles.
    #[test]
    fn exp_so3_is_rodrigues() {
        for phi in [
            Vector3::new(1e-9, -2e-9, 3e-10),
            Vector3::new(3e-5, 1e-5, -2e-5),
            Vector3::new(0.3, -1.1, 0.7),
            Vector3::zeros(),
        ] {
            let r = exp_so3(&phi);
            let expected = Rotation3::from_scaled_axis(phi).into_inner();
            assert!((r - expected).abs().max() < 1e-15, "{phi}");
            assert!((rotation_vector(&r) - phi).norm() <= 1e-15 * phi.norm().max(1e-300) + 1e-30);
        }
    }

    /// A damping ratio of 1 is D = 2 √(M K).
    #[test]
    fn a_damping_ratio_sets_the_damping() {
        let mut p = all_axes();
        p.damping = None;
        p.damping_ratio = Some([1.0, 0.5, 0.0, 1.0, 2.0, 0.7]);
        let d = p.resolved_damping();
        assert_eq!(d[0], 2.0 * (2.0f64 * 400.0).sqrt());
        assert_eq!(d[1], (3.0f64 * 500.0).sqrt());
        assert_eq!(d[2], 0.0);
        assert_eq!(d[4], 4.0 * (0.03f64 * 30.0).sqrt());
    }

    /// Each bad value is named with its axis and range.
    #[test]
    fn bad_values_are_named_with_their_axis() {
        let message = |edit: &dyn Fn(&mut WrenchAdmittanceParams)| {
            let mut p = all_axes();
            edit(&mut p);
            p.validate(T).unwrap_err().to_string()
        };
        assert_eq!(
            message(&|p| p.mass[4] = 0.0),
            "mass[4] = 0 is invalid: must be finite and > 0"
        );
        assert_eq!(
            message(&|p| p.stiffness[1] = f64::NAN),
            "stiffness[1] = NaN is invalid: must be finite and ≥ 0"
        );
        assert!(message(&|p| p.damping_ratio = Some([1.0; 6])).starts_with("damping_ratio ="));
        assert!(message(&|p| {
            p.damping = None;
            p.stiffness[3] = 0.0;
        })
        .starts_with("stiffness[3] = 0 is invalid: must be > 0 on the selected axis rx"));
        assert!(message(&|p| p.wrench_reference[5] = f64::INFINITY)
            .starts_with("wrench_reference[5] = inf"));
        // Beyond what a hold represents at 1 ms: the axis's damping is named.
        assert!(
            message(&|p| p.damping = Some([1e300; 6])).starts_with("damping[0] = "),
            "{}",
            message(&|p| p.damping = Some([1e300; 6]))
        );
        let mut p = all_axes();
        p.force = Some(ForceControlParams::Admittance(AdmittanceParams {
            m: -1.0,
            ..AdmittanceParams::default()
        }));
        assert!(p
            .validate(T)
            .unwrap_err()
            .to_string()
            .starts_with("force.m = -1"));
    }
}
