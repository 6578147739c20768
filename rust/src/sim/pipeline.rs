//! Stages 2–7 of a period (SPEC §10, §14), written once over a scalar `T`: environment force
//! → force sensor → force control (fed by the measured force) → task reference → control
//! law → actuator, with the controller told what was applied. A scalar run
//! (`Simulation::step_to_plant`) is the `f64` case; a lane group (`sim::lanes::stages`) is four
//! runs of one structure packed into [`F64x4`]. The callers only gather what is per run (the
//! plant state and kinematics, each run's noise draw and references at its own t) and record
//! each run's sample; no stage or law is written twice.

use nalgebra::{Matrix3, SVector, Vector3};

use crate::contact::{Contact, KnownTip, Surface, TipMotion};
use crate::control::approach::Approach;
use crate::control::belief::Belief;
use crate::control::controller::{not_finite, Controller, ControllerKey, Measured};
use crate::control::filter::{ForceControl, ForceControlKey};
use crate::control::reference::Sample;
use crate::control::task::{Desired, TaskFrame};
use crate::robot::{ArmModel, Kinematics, Orientation};
use crate::scalar::{every, Real, Wide};
use crate::world::actuator::Actuator;
use crate::world::contact_law::tangential;
use crate::world::sensor::{ForceSensor, Reading, SensorKey};
use crate::world::surface::Environment;

/// The state machines of stages 3–7 and the task frame, over `T`; `M`: computed torque's
/// model (an arm's equations over `T`: one run's, or four in lanes).
#[derive(Debug, Clone)]
pub struct Pipeline<T: Real, M, const N: usize> {
    pub sensor: ForceSensor<T>,
    /// A guarded approach before force control (SPEC §16); `None`: force control from t = 0.
    pub approach: Option<Approach<T>>,
    pub force_control: Option<ForceControl<T>>,
    pub frame: TaskFrame<T>,
    /// A curved estimate of the surface (SPEC §15); `None`: the frame's plane.
    pub belief: Option<Belief>,
    pub controller: Controller<T, M, N>,
    pub actuator: Actuator<N, T>,
}

/// What runs must share for their stages to advance in one lane group, each part given by
/// its stage: the sensor's latency and the actuator's delay (buffer lengths), the outer
/// loop's kind and the controller's structure. Every number (gains, limits, noise,
/// cut-offs, D̄, λ, …) and every on/off limit is per lane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StageKey {
    pub sensor: SensorKey,
    pub actuator_delay: usize,
    /// `None`: position control only.
    pub force_control: Option<ForceControlKey>,
    /// Whether a guarded approach precedes force control.
    pub approach: bool,
    /// Whether the controller believes a curved surface.
    pub curved: bool,
    pub controller: ControllerKey,
}

/// What a period's stages read: the encoders (q, q̇) and the tip kinematics at them, the
/// environment, the sensor's standard normal draw, and the references at t_k.
pub struct Inputs<'a, T: Real, const N: usize> {
    /// The lanes at sample 0.
    pub first: T::SimdBool,
    pub q: &'a SVector<T, N>,
    pub qd: &'a SVector<T, N>,
    pub kinematics: &'a Kinematics<N, T>,
    /// The tip's rotation terms, for a pose task (`Controller::pose`).
    pub orientation: Option<&'a Orientation<N, T>>,
    /// The tip rotation R, for a tip-frame sensor (`ForceSensor::needs_rotation`).
    pub rotation: Option<&'a Matrix3<T>>,
    pub environment: &'a Environment<T>,
    /// The sample's standard normal draws, one per sensor axis.
    pub noise: [T; 3],
    /// f_d(t_k).
    pub force_reference: Sample<T>,
    /// s(t_k), the motion along t̂.
    pub motion_reference: Sample<T>,
}

/// What a period's stages give: the sample's record and the torque to hold.
pub struct Outputs<T: Real, const N: usize> {
    /// The true contact force along n and the penetration (NaN without a wall).
    pub force: T,
    pub penetration: T,
    /// The true force on the surface, f N − F_t (world frame), |F_t| and the slip speed
    /// |v_t| (NaN in free space).
    pub surface_force: Vector3<T>,
    pub f_t: T,
    pub slip_speed: T,
    pub measured: T,
    /// The outer loop's x_a (zero for position control) and the task reference.
    pub x_a: Sample<T>,
    pub desired: Desired<T>,
    pub command: SVector<T, N>,
    /// The applied torque (the command where every lane failed).
    pub tau: SVector<T, N>,
    /// The lanes whose Jacobian failed, and those whose command is not finite: their runs
    /// end at this sample.
    pub singular: T::SimdBool,
    pub non_finite: T::SimdBool,
}

impl<T: Real, M: ArmModel<T, N>, const N: usize> Pipeline<T, M, N> {
    /// Stages 2–7 at t_k, with the arm's configuration values at q (`at`: what computed
    /// torque's model reads). Where every lane failed (always, for a failed scalar run),
    /// the actuator and the controller's memory are left as they were.
    #[inline(always)]
    pub fn step(&mut self, input: &Inputs<T, N>, at: &M::Config) -> Outputs<T, N> {
        let kin = input.kinematics;
        // 2. environment: the contact at the measured tip
        let tip = KnownTip {
            position: &kin.position,
            jacobian: &kin.jacobian,
            qd: input.qd,
        };
        let contact = input.environment.contact(&tip);
        let (force, penetration) = (contact.normal_force, contact.penetration);
        let (surface_force, f_t, slip_speed) = surface_record(&contact, &tip, input.environment);
        // 3. force sensor: the component along n̂ (for a plane × 1 exactly unless the
        // estimated normal is tilted; for a curved estimate n̂ at the tip), read on one axis
        // or on the tip axes, with the tool's weight (SPEC §15)
        let (normal, along) = match &self.belief {
            Some(b) => {
                let n = b.normal_at(&kin.position);
                let along = surface_force.dot(&n);
                (n, along)
            }
            None => (self.frame.normal, force * self.frame.force_projection),
        };
        let measured = self.sensor.sense(&Reading {
            first: input.first,
            along,
            surface_force: &surface_force,
            normal: &normal,
            rotation: input.rotation,
            noise: input.noise,
        });
        // 4.–5. force control, fed by the measured force; then the task reference
        let s = &input.motion_reference;
        let (x_a, desired) = match (&mut self.force_control, &mut self.approach) {
            (Some(fc), Some(approach)) if approach.any_active() => {
                // A guarded approach in some lane: those lanes follow it (x_a recorded as
                // the offset p − x̂_e), the others (and those switching now) the filter.
                let tip = self.frame.normal.dot(&kin.position);
                let g = approach.guard(measured, tip, &mut self.frame, fc);
                let shift = Some(approach.reanchor_shift(&self.frame));
                let held = Sample {
                    value: g.normal.value - self.frame.wall_estimate,
                    rate: g.normal.rate,
                    accel: g.normal.accel,
                };
                let offset = self.frame.approach_offset(&g.normal);
                let guarded = desired(self.belief.as_ref(), &self.frame, &offset, s, shift);
                if T::all(g.approaching) {
                    (held, guarded)
                } else {
                    let x_a = fc.step(&input.force_reference, measured);
                    let force = desired(self.belief.as_ref(), &self.frame, &x_a, s, shift);
                    if T::none(g.approaching) {
                        (x_a, force)
                    } else {
                        (
                            held.select(g.approaching, &x_a),
                            guarded.select(g.approaching, &force),
                        )
                    }
                }
            }
            (Some(fc), approach) => {
                let x_a = fc.step(&input.force_reference, measured);
                let shift = approach.as_ref().map(|a| a.reanchor_shift(&self.frame));
                (
                    x_a,
                    desired(self.belief.as_ref(), &self.frame, &x_a, s, shift),
                )
            }
            (None, _) => (Sample::default(), self.frame.motion_reference(s)),
        };
        // 6. control law
        let measurement = Measured {
            q: input.q,
            qd: input.qd,
            kinematics: kin,
            orientation: input.orientation,
            force: measured,
            normal: &normal,
        };
        let (command, singular) = self.controller.command(&measurement, at, &desired);
        let non_finite = not_finite(&command);
        let mut tau = command;
        if !T::all(singular | non_finite) {
            // 7. actuator; TDC remembers what was applied
            tau = self.actuator.apply_lanes(input.first, &command);
            self.controller.applied(&tau, input.qd);
        }
        Outputs {
            force,
            penetration,
            surface_force,
            f_t,
            slip_speed,
            measured,
            x_a,
            desired,
            command,
            tau,
            singular,
            non_finite,
        }
    }
}

/// The force reference for filter output x_a and motion s: the frame's plane, or the
/// curved belief's surface (SPEC §15).
#[inline(always)]
fn desired<T: Real>(
    belief: Option<&Belief>,
    frame: &TaskFrame<T>,
    x_a: &Sample<T>,
    s: &Sample<T>,
    reanchored: Option<T>,
) -> Desired<T> {
    match (belief, reanchored) {
        // A re-anchored curved estimate is its parallel surface at δ = x̂_e − x̂_e,0 (the
        // approach's `reanchor_shift`): X_d = p(Y) + (δ + x_a) n̂(p(Y)). Only x̂_e + x_a
        // enters, as on a plane, so the switch is bumpless (issue #53, item 1).
        (Some(b), Some(shift)) => b.reference(
            &Sample {
                value: x_a.value + shift,
                ..*x_a
            },
            s,
        ),
        (Some(b), None) => b.reference(x_a, s),
        (None, _) => frame.force_reference(x_a, s),
    }
}

/// What the trace records of a contact (SPEC §15): the force on the surface f N − F_t, |F_t|
/// and the tip's slip speed |v_t| in the contact's tangent plane (NaN in free space).
#[inline(always)]
fn surface_record<T: Real>(
    contact: &Contact<T>,
    tip: &impl TipMotion<T>,
    environment: &Environment<T>,
) -> (Vector3<T>, T, T) {
    let on_surface = contact.normal * contact.normal_force;
    let (on_surface, f_t) = match &contact.friction {
        Some(ft) => (on_surface - ft, ft.norm()),
        None => (on_surface, T::zero()),
    };
    let slip = match environment {
        Environment::Free => T::splat(f64::NAN),
        _ => tangential(&contact.normal, &tip.velocity()).norm(),
    };
    (on_surface, f_t, slip)
}

impl<T: Real, M, const N: usize> Pipeline<T, M, N> {
    /// The stages' structure (see [`StageKey`]).
    pub fn lane_key(&self) -> StageKey {
        StageKey {
            sensor: self.sensor.lane_key(),
            actuator_delay: self.actuator.delay(),
            force_control: self.force_control.as_ref().map(ForceControl::lane_key),
            approach: self.approach.is_some(),
            curved: self.belief.is_some(),
            controller: self.controller.lane_key(),
        }
    }

    /// Every stage back at its initial state.
    pub fn reset(&mut self) {
        self.sensor.reset();
        if let Some(f) = &mut self.force_control {
            f.reset();
        }
        if let Some(a) = &mut self.approach {
            a.reset(&mut self.frame);
        }
        self.controller.reset();
        self.actuator.reset();
    }
}

impl<W: Real, M, const N: usize> Pipeline<W, M, N> {
    /// Four runs' stages of one structure in lanes, from their current state (`None` if
    /// their [`StageKey`]s differ); `models` packs computed torque's four models.
    pub fn pack<R, const L: usize>(
        p: [&Pipeline<f64, R, N>; L],
        models: impl FnOnce([&R; L]) -> M,
    ) -> Option<Self>
    where
        W: Wide<L>,
    {
        if !p.iter().all(|x| x.lane_key() == p[0].lane_key()) {
            return None;
        }
        let force_control = match every(p.map(|x| x.force_control.as_ref())) {
            Some(f) => Some(ForceControl::pack(f)?),
            None => None,
        };
        let approach = every(p.map(|x| x.approach.as_ref())).map(Approach::pack);
        Some(Self {
            sensor: ForceSensor::pack(p.map(|x| &x.sensor)),
            approach,
            force_control,
            frame: TaskFrame::pack(p.map(|x| &x.frame)),
            belief: p[0]
                .belief
                .as_ref()
                .map(|_| Belief::pack(p.iter().filter_map(|x| x.belief.as_ref()))),
            controller: Controller::pack(p.map(|x| &x.controller), models)?,
            actuator: Actuator::pack(p.map(|x| &x.actuator)),
        })
    }

    /// Lane `l` takes the run's stages `p`; false, with nothing changed, if their
    /// [`StageKey`] is not this group's.
    pub fn put_lane<R>(
        &mut self,
        l: usize,
        p: &Pipeline<f64, R, N>,
        model: impl FnOnce(&mut M, &R),
    ) -> bool {
        if p.lane_key() != self.lane_key() {
            return false;
        }
        // One key: the outer loops are of one kind and the controllers of one structure.
        if let (Some(f), Some(g)) = (&mut self.force_control, &p.force_control) {
            f.put_lane(l, g);
        }
        if let (Some(a), Some(b)) = (&mut self.approach, &p.approach) {
            a.put_lane(l, b);
        }
        self.controller.put_lane(l, &p.controller, model);
        self.sensor.put_lane(l, &p.sensor);
        self.frame.put_lane(l, &p.frame);
        if let (Some(b), Some(theirs)) = (&mut self.belief, &p.belief) {
            b.put_lane(l, theirs);
        }
        self.actuator.put_lane(l, &p.actuator);
        true
    }
}
