//! The guarded approach (SPEC §16): position control along the estimated normal n̂ from the
//! start toward the estimated surface, slowing to `contact_speed` within
//! `slowdown_distance` of it, until the **measured** normal force exceeds `threshold`; then
//! force control takes over bumplessly, optionally re-anchoring the estimated surface at the
//! point where contact was detected.
//!
//! Discrete form, per sample k while approaching (p_0 = n̂·X0, v_0 = 0, x̂_e the estimate):
//!
//! ```text
//!   w_k = speed          if p_k < x̂_e − slowdown_distance
//!         contact_speed  otherwise (within the slowdown distance, and beyond the surface)
//!   acceleration = None (velocity steps): v_k = w_k,  a_k = 0
//!   acceleration = A:   v_k as carried,   a_k = clamp((w_k − v_k) / T, −A, A)
//!   X_d = X0 + (p_k − n̂·X0) n̂ + s(t_k) t̂,  Ẋ_d = v_k n̂ + ṡ t̂,  Ẍ_d = a_k n̂ + s̈ t̂
//!   p_{k+1} = p_k + v_k T + a_k T² / 2,  v_{k+1} = v_k + a_k T  (w_k exactly once reached)
//! ```
//!
//! Why a bounded acceleration: a velocity step carries no acceleration feedforward, so the
//! inner loop lags the ramp by its transient (v t e^{−ωt} for a critically damped loop); at
//! the switch that lead X_d − X is pressed into the surface, since X_d is kept continuous.
//! A ramp at A with Ẍ_d = A n̂ fed forward is tracked closely, as a robot's motion generator
//! would command it (docs/first_contact.md §3).
//!
//! At the first sample k_s with f̃_k > threshold (the sensor's output: noise, low-pass and
//! latency delay the switch as on a robot): with `reanchor`, x̂_e ← n̂·X_{k_s} (the tip's
//! measured position); then the admittance state is set to x_a = p_{k_s} − x̂_e,
//! ẋ_a = v_{k_s} (and ψ = 0), and the filter runs from this sample on. The force reference
//! X_d = X0 + (x̂_e + x_a − n̂·X0) n̂ + s t̂ therefore equals the approach's at k_s (to
//! rounding) and Ẋ_d = ẋ_a n̂ + ṡ t̂ continues v_{k_s}; from there ẋ_a follows the filter, whose
//! change over one period is ẍ_a T to first order (the "loop's discretisation").
//!
//! A curved estimate (SPEC §15: X_d = p(Y) + x_a n̂(p(Y))) is re-anchored the same way: it
//! moves along its own normal by δ = x̂_e − x̂_e,0 (its parallel surface: a sphere's or a
//! cylinder's radius changes by δ), X_d = p(Y) + (δ + x_a) n̂(p(Y)), so only x̂_e + x_a enters
//! and the switch is bumpless on any shape.
//!
//! With Scheme 2 (k = 0) the force loop does not depend on where x̂_e is (only x̂_e + x_a
//! enters X_d, and the filter has no stiffness term), so re-anchoring moves x_a's zero, not
//! the force; it changes the run of Scheme 1 (k > 0), whose spring pulls toward x̂_e.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::control::filter::ForceControl;
use crate::control::reference::Sample;
use crate::control::task::{Desired, TaskFrame};
use crate::error::{check, Result};
use crate::scalar::{put, Real, Wide};

/// `Scenario.approach`: a guarded approach through free space before force control.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ApproachParams {
    /// Approach speed along the estimated normal n̂ in free space [m/s].
    pub speed: f64,
    /// Speed within slowdown_distance of the estimated surface, and beyond it [m/s].
    pub contact_speed: f64,
    /// Distance before the estimated surface at which the approach slows to contact_speed [m].
    pub slowdown_distance: f64,
    /// Measured normal force above which contact is detected and force control takes over [N].
    pub threshold: f64,
    /// Move the estimated surface to the tip's measured position along n̂ where contact was detected.
    pub reanchor: bool,
    /// Largest |dv/dt| of the approach along n̂ [m/s²], fed forward as Ẍ_d; ``None``: velocity steps.
    pub acceleration: Option<f64>,
}

impl Default for ApproachParams {
    fn default() -> Self {
        Self {
            speed: 0.05,
            contact_speed: 0.01,
            slowdown_distance: 0.005,
            threshold: 1.0,
            reanchor: true,
            acceleration: Some(1.0),
        }
    }
}

impl ApproachParams {
    pub fn validate(&self) -> Result<()> {
        check::positive("speed", self.speed)?;
        check::positive("contact_speed", self.contact_speed)?;
        check::non_negative("slowdown_distance", self.slowdown_distance)?;
        check::non_negative("threshold", self.threshold)?;
        if let Some(a) = self.acceleration {
            check::positive("acceleration", a)?;
        }
        Ok(())
    }
}

/// The approach's state machine, over `f64` or four runs in lanes (each lane switches at
/// its own sample: the phase is a per-lane number, its branches selects).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Approach<T: Real = f64> {
    speed: T,
    contact_speed: T,
    slowdown_distance: T,
    threshold: T,
    /// 1 where the estimate is re-anchored at the switch, else 0.
    reanchor: T,
    /// The bound A on the approach's acceleration (∞: velocity steps, no feedforward).
    acceleration: T,
    period: T,
    /// p_0 = n̂·X0 and the estimate x̂_e before any re-anchoring: what `reset` restores.
    start: T,
    estimate: T,
    /// 1 while approaching (position control), 0 once force control has taken over.
    active: T,
    /// p_k, the reference's coordinate along n̂ at the current sample [m].
    position: T,
    /// v_k, its rate, carried between samples when the acceleration is bounded [m/s].
    velocity: T,
}

/// What the approach gives the task reference at one sample.
pub struct Guard<T: Real> {
    /// The lanes still under position control at this sample.
    pub approaching: T::SimdBool,
    /// The approach's reference along n̂: (p_k, v_k, 0).
    pub normal: Sample<T>,
}

impl Approach {
    /// The approach of a run whose task frame is `frame`, sampled at `period`.
    pub fn new(p: &ApproachParams, frame: &TaskFrame, period: f64) -> Self {
        let start = frame.along_normal(&frame.start);
        Self {
            speed: p.speed,
            contact_speed: p.contact_speed,
            slowdown_distance: p.slowdown_distance,
            threshold: p.threshold,
            reanchor: if p.reanchor { 1.0 } else { 0.0 },
            acceleration: p.acceleration.unwrap_or(f64::INFINITY),
            period,
            start,
            estimate: frame.wall_estimate,
            active: 1.0,
            position: start,
            velocity: 0.0,
        }
    }

    pub const STATE_LABELS: [&'static str; 4] = [
        "approach.active",
        "approach.position",
        "approach.velocity",
        "approach.estimate",
    ];

    /// (active, p_k, v_k, the estimate x̂_e in use) as `Simulation::state` lays them out.
    pub fn state(&self, frame: &TaskFrame, out: &mut Vec<f64>) {
        out.extend_from_slice(&[
            self.active,
            self.position,
            self.velocity,
            frame.wall_estimate,
        ]);
    }

    /// Reads `state`'s values (any non-zero `active` is approaching); returns the count.
    pub fn set_state(&mut self, frame: &mut TaskFrame, values: &[f64]) -> usize {
        self.active = if values[0] != 0.0 { 1.0 } else { 0.0 };
        self.position = values[1];
        self.velocity = values[2];
        frame.wall_estimate = values[3];
        4
    }
}

impl<W: Real> Approach<W> {
    pub fn pack<const L: usize>(a: [&Approach; L]) -> Self
    where
        W: Wide<L>,
    {
        let p = |f: fn(&Approach) -> f64| W::from_lanes(|i| f(a[i]));
        Self {
            speed: p(|a| a.speed),
            contact_speed: p(|a| a.contact_speed),
            slowdown_distance: p(|a| a.slowdown_distance),
            threshold: p(|a| a.threshold),
            reanchor: p(|a| a.reanchor),
            acceleration: p(|a| a.acceleration),
            period: p(|a| a.period),
            start: p(|a| a.start),
            estimate: p(|a| a.estimate),
            active: p(|a| a.active),
            position: p(|a| a.position),
            velocity: p(|a| a.velocity),
        }
    }

    pub fn put_lane(&mut self, l: usize, a: &Approach) {
        put(&mut self.speed, l, a.speed);
        put(&mut self.contact_speed, l, a.contact_speed);
        put(&mut self.slowdown_distance, l, a.slowdown_distance);
        put(&mut self.threshold, l, a.threshold);
        put(&mut self.reanchor, l, a.reanchor);
        put(&mut self.acceleration, l, a.acceleration);
        put(&mut self.period, l, a.period);
        put(&mut self.start, l, a.start);
        put(&mut self.estimate, l, a.estimate);
        put(&mut self.active, l, a.active);
        put(&mut self.position, l, a.position);
        put(&mut self.velocity, l, a.velocity);
    }
}

impl<T: Real> Approach<T> {
    /// Back to the start: approaching from p_0, the estimate as it was.
    pub fn reset(&mut self, frame: &mut TaskFrame<T>) {
        self.active = T::one();
        self.position = self.start;
        self.velocity = T::zero();
        frame.wall_estimate = self.estimate;
    }

    /// δ = x̂_e − x̂_e,0: how far re-anchoring moved the estimate along n̂ (0 before the
    /// switch and without `reanchor`). A curved estimate is moved by it along its own normal
    /// (`pipeline::desired`), as a plane's x̂_e is.
    #[inline(always)]
    pub fn reanchor_shift(&self, frame: &TaskFrame<T>) -> T {
        frame.wall_estimate - self.estimate
    }

    /// Whether any lane is still approaching.
    #[inline(always)]
    pub fn any_active(&self) -> bool {
        !T::none(self.active.simd_gt(T::zero()))
    }

    /// At t_k, before the filter: lanes whose measured force `measured` exceeds the
    /// threshold switch to force control here (re-anchoring x̂_e at the tip's `tip_along` =
    /// n̂·X_k and starting the filter bumplessly); the others follow the approach, which then
    /// advances to p_{k+1}.
    #[inline(always)]
    pub fn guard(
        &mut self,
        measured: T,
        tip_along: T,
        frame: &mut TaskFrame<T>,
        force_control: &mut ForceControl<T>,
    ) -> Guard<T> {
        let zero = T::zero();
        let active = self.active.simd_gt(zero);
        let far = self
            .position
            .simd_lt(frame.wall_estimate - self.slowdown_distance);
        let wanted = self.speed.select(far, self.contact_speed);
        // Velocity steps where unbounded; else a ramp at ±A toward the wanted speed, landing
        // on it exactly (so a cruise is the step case's arithmetic).
        let steps = self.acceleration.simd_eq(T::splat(f64::INFINITY));
        let change = wanted - self.velocity;
        let reached = change.simd_abs().simd_le(self.acceleration * self.period);
        let ramp = self
            .acceleration
            .select(change.simd_gt(zero), -self.acceleration);
        let v = wanted.select(steps, self.velocity);
        let dv = zero.select(steps, change.select(reached, ramp * self.period));
        let accel = zero.select(steps, (change / self.period).select(reached, ramp));
        let normal = Sample {
            value: self.position,
            rate: v,
            accel,
        };
        let switching = active & measured.simd_gt(self.threshold);
        if !T::none(switching) {
            let moved = switching & self.reanchor.simd_gt(zero);
            frame.wall_estimate = tip_along.select(moved, frame.wall_estimate);
            // Bumpless: x̂_e + x_a = p_k and ẋ_a = v_k.
            force_control.start(switching, self.position - frame.wall_estimate, v);
            self.active = zero.select(switching, self.active);
        }
        let approaching = active & !switching;
        let next = v * self.period + accel * (self.period * self.period * T::splat(0.5));
        self.position = (self.position + next).select(approaching, self.position);
        let next_v = wanted.select(steps | reached, v + dv);
        self.velocity = next_v.select(approaching, self.velocity);
        Guard {
            approaching,
            normal,
        }
    }
}

impl<T: Real> TaskFrame<T> {
    /// The approach's reference: X_d = X0 + (p − n̂·X0) n̂ + s t̂ from the approach's
    /// coordinate p along n̂ (with its rate) and the motion s(t).
    #[inline(always)]
    pub fn approach_reference(&self, p: &Sample<T>, s: &Sample<T>) -> Desired<T> {
        // The force reference with x̂_e + x_a = p: one formula for both phases.
        self.force_reference(&self.approach_offset(p), s)
    }

    /// The x_a that puts the force reference at coordinate p along n̂: p − x̂_e.
    #[inline(always)]
    pub fn approach_offset(&self, p: &Sample<T>) -> Sample<T> {
        Sample {
            value: p.value - self.wall_estimate,
            ..*p
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::filter::{AdmittanceParams, ForceControlParams};
    use crate::robot::TaskVector;

    fn frame() -> TaskFrame {
        TaskFrame::new(TaskVector::x(), TaskVector::new(0.7, 0.0, 0.9), 0.71)
    }

    /// The approach runs at `speed` until within the slowdown distance, then at
    /// `contact_speed`; at the switch X_d and Ẋ_d continue and x̂_e moves to the tip.
    #[test]
    fn speeds_switch_and_reanchor() {
        let p = ApproachParams {
            speed: 0.05,
            contact_speed: 0.01,
            slowdown_distance: 0.00476,
            threshold: 1.0,
            reanchor: true,
            acceleration: None,
        };
        let mut frame = frame();
        let mut a = Approach::new(&p, &frame, 1e-3);
        let mut fc = ForceControl::new(
            &ForceControlParams::Admittance(AdmittanceParams::scheme2(800.0, 1.0)),
            1e-3,
        );
        let s = Sample::default();
        // Slow from 0.70524 m on: 105 samples at full speed (p_104 = 0.7052), then 0.01 m/s.
        for k in 0..105 {
            let g = a.guard(0.0, 0.7, &mut frame, &mut fc);
            assert!(g.approaching);
            assert_eq!(g.normal.rate, 0.05, "{k}");
        }
        assert!((a.position - 0.70525).abs() < 1e-12);
        let g = a.guard(0.5, 0.7, &mut frame, &mut fc);
        assert_eq!(g.normal.rate, 0.01);
        let before = frame.approach_reference(&g.normal, &s);
        // Contact detected at the tip's 0.7042: the estimate moves there.
        let g = a.guard(1.5, 0.7042, &mut frame, &mut fc);
        assert!(!g.approaching);
        assert_eq!(frame.wall_estimate, 0.7042);
        let x_a = fc.step(
            &Sample {
                value: 10.0,
                ..Sample::default()
            },
            1.5,
        );
        let after = frame.force_reference(&x_a, &s);
        let predicted = before.position[0] + 1e-3 * before.velocity[0];
        assert!((after.position[0] - predicted).abs() < 1e-15);
        assert_eq!(after.velocity[0], 0.01);
        assert!(!a.any_active());
        a.reset(&mut frame);
        assert!(a.any_active() && frame.wall_estimate == 0.71 && a.position == 0.7);
    }

    /// With a bounded acceleration A the reference ramps from rest to `speed` at A (Ẍ_d = A
    /// fed forward), cruises, and ramps down to `contact_speed` once within the slowdown
    /// distance: p, v and a are the exact piecewise-constant-acceleration motion.
    #[test]
    fn a_bounded_acceleration_ramps_the_reference() {
        let (accel, t) = (2.0, 1e-3);
        let p = ApproachParams {
            slowdown_distance: 0.005,
            acceleration: Some(accel),
            ..Default::default()
        };
        let mut frame = frame();
        let mut a = Approach::new(&p, &frame, t);
        let mut fc = ForceControl::new(
            &ForceControlParams::Admittance(AdmittanceParams::scheme2(800.0, 1.0)),
            t,
        );
        let mut samples = Vec::new();
        for _ in 0..300 {
            let g = a.guard(0.0, 0.7, &mut frame, &mut fc);
            assert!(g.approaching);
            samples.push(g.normal);
        }
        // Up to 0.05 m/s in 25 samples at 2 m/s²: v_k = A k T, p_k = p_0 + A (kT)² / 2.
        for (k, s) in samples.iter().enumerate().take(25) {
            let tk = k as f64 * t;
            assert!((s.rate - accel * tk).abs() < 1e-15, "{k}");
            assert!(
                (s.value - (0.7 + accel * tk * tk / 2.0)).abs() < 1e-15,
                "{k}"
            );
            assert!((s.accel - accel).abs() < 1e-10, "{k}");
        }
        assert_eq!((samples[25].rate, samples[25].accel), (0.05, 0.0));
        // Every step is the exact motion under the sample's constant acceleration.
        for w in samples.windows(2) {
            let (s, n) = (&w[0], &w[1]);
            assert!((n.rate - (s.rate + s.accel * t)).abs() < 1e-15);
            assert!((n.value - (s.value + s.rate * t + s.accel * t * t / 2.0)).abs() < 1e-15);
            assert!(s.accel.abs() <= accel);
        }
        // Slowing from the first sample within 5 mm of x̂_e = 0.71, down to 0.01 m/s in 20.
        let slow = samples.iter().position(|s| s.value >= 0.705).unwrap();
        assert!((samples[slow].accel + accel).abs() < 1e-10);
        assert!(samples[slow - 1].rate == 0.05 && samples[slow - 1].accel == 0.0);
        assert_eq!(samples[slow + 20].rate, 0.01);
        assert!(samples[slow + 20..]
            .iter()
            .all(|s| s.rate == 0.01 && s.accel == 0.0));
        // Reset: from rest again.
        a.reset(&mut frame);
        assert_eq!(a.guard(0.0, 0.7, &mut frame, &mut fc).normal.rate, 0.0);
    }

    #[test]
    fn invalid_approaches_name_the_field() {
        let bad = |p: ApproachParams| p.validate().unwrap_err().to_string();
        assert!(bad(ApproachParams {
            speed: 0.0,
            ..Default::default()
        })
        .starts_with("speed = 0"));
        assert!(bad(ApproachParams {
            threshold: f64::NAN,
            ..Default::default()
        })
        .starts_with("threshold = NaN"));
    }
}
