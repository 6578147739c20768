//! The three-link arm of SPEC §1 in lanes: four closed forms packed for RK4
//! ([`ArmLanes`]), its lane kinematics from each run's fresh trig and computed torque's
//! model ([`StageArm`], [`ControllerModel`]).

use nalgebra::Vector3;

use crate::contact::Surface;
use crate::control::controller::ControllerModel;
use crate::robot::three_link::{ClosedForm, Trig};
use crate::robot::{Dynamics, Kinematics, Orientation, ThreeLinkArm};
use crate::scalar::{F64x4, LANES};
use crate::sim::lanes::stages::{LaneStages, StageArm};
use crate::sim::lanes::{ArmLanes, LaneArm, PackedPlant};
use crate::sim::simulation::Simulation;

/// The three-link arm's lane stages.
pub type ThreeLinkStages = LaneStages<ThreeLinkArm, 3>;

impl ControllerModel<F64x4, 3> for ClosedForm<F64x4> {
    type At = Trig<F64x4>;

    #[inline(always)]
    fn terms(
        &self,
        trig: &Trig<F64x4>,
        _: &Vector3<F64x4>,
        qd: &Vector3<F64x4>,
    ) -> (Dynamics<3, F64x4>, Vector3<F64x4>) {
        (self.dynamics(trig, qd), self.friction(qd))
    }
}

impl StageArm<3> for ThreeLinkArm {
    type Model = ClosedForm<F64x4>;
    type At = Trig<F64x4>;

    fn pack_model(arms: [&Self; LANES]) -> ClosedForm<F64x4> {
        ClosedForm::pack(arms.map(|a| a.closed_form()))
    }

    fn put_model(model: &mut ClosedForm<F64x4>, l: usize, arm: &Self) {
        model.put_lane(l, arm.closed_form());
    }

    #[inline(always)]
    fn lane_kinematics(
        plant: &PackedPlant<ClosedForm<F64x4>>,
        lanes: [&Simulation<Self, 3>; LANES],
        _: &Vector3<F64x4>,
        qd: &Vector3<F64x4>,
        _: bool,
    ) -> (
        Kinematics<3, F64x4>,
        Option<Orientation<3, F64x4>>,
        Trig<F64x4>,
    ) {
        // Each lane's fresh trig of q, as the scalar plant holds it.
        let trig = Trig::pack(lanes.map(|s| s.plant().config()));
        (plant.arm.kinematics(&trig, qd), None, trig)
    }
}

impl LaneArm<3> for ThreeLinkArm {
    type Lanes = ClosedForm<F64x4>;
    type Front = ThreeLinkStages;
    const READS_EACH_CONFIG: bool = true;

    fn same_structure(&self, _: &Self) -> bool {
        true
    }

    fn pack(arms: [&Self; LANES]) -> ClosedForm<F64x4> {
        ClosedForm::pack(arms.map(|a| a.closed_form()))
    }

    #[inline(always)]
    fn pack_config(
        _: &ClosedForm<F64x4>,
        _: &Vector3<F64x4>,
        configs: [&Trig; LANES],
    ) -> Trig<F64x4> {
        // Each lane's own fresh evaluation (libm's sincos), as the scalar plant starts from.
        Trig::pack(configs)
    }
}

impl ArmLanes<3> for ClosedForm<F64x4> {
    type Config = Trig<F64x4>;

    #[inline(always)]
    fn shift(
        &self,
        c: &Trig<F64x4>,
        delta: &Vector3<F64x4>,
        shifted: &Vector3<F64x4>,
        out: &mut Trig<F64x4>,
    ) {
        *out = c.shifted(delta, shifted);
    }

    #[inline(always)]
    fn accelerate(
        &self,
        c: &Trig<F64x4>,
        qd: &Vector3<F64x4>,
        tau: &Vector3<F64x4>,
        surface: &impl Surface<F64x4>,
    ) -> Vector3<F64x4> {
        ClosedForm::accelerate(self, c, qd, tau, surface).0
    }
}
