//! The plant: the arm against the wall, integrated by fixed-step RK4 with substeps while the
//! control torque is held (zero-order hold, SPEC §6).

use crate::environment::Wall;
use crate::robot::{ThreeLinkArm, Vec3};

/// Joint positions and velocities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantState {
    pub q: Vec3,
    pub qd: Vec3,
}

/// The true arm and environment. Owns the state; `advance` moves it one control period.
#[derive(Debug, Clone, PartialEq)]
pub struct Plant {
    arm: ThreeLinkArm,
    wall: Option<Wall>,
    substeps: usize,
    substep: f64,
    initial: PlantState,
    pub state: PlantState,
}

impl Plant {
    pub fn new(
        arm: ThreeLinkArm,
        wall: Option<Wall>,
        initial: PlantState,
        period: f64,
        substeps: usize,
    ) -> Self {
        Self {
            arm,
            wall,
            substeps,
            substep: period / substeps as f64,
            initial,
            state: initial,
        }
    }

    pub fn reset(&mut self) {
        self.state = self.initial;
    }

    #[inline]
    fn contact(&self, x: f64) -> f64 {
        self.wall.as_ref().map_or(0.0, |w| w.force(x))
    }

    #[inline(always)]
    fn acceleration(&self, q: &Vec3, qd: &Vec3, tau: &Vec3) -> Vec3 {
        self.arm.accelerate(q, qd, tau, |x| self.contact(x)).0
    }

    /// The contact force the (ideal) sensor reads at tip x position `x`.
    #[inline]
    pub fn force_at(&self, x: f64) -> f64 {
        self.contact(x)
    }

    /// One control period: `substeps` classical RK4 steps with τ held.
    #[inline]
    pub fn advance(&mut self, tau: &Vec3) {
        let h = self.substep;
        let PlantState { mut q, mut qd } = self.state;
        for _ in 0..self.substeps {
            let a1 = self.acceleration(&q, &qd, tau);
            let (q2, qd2) = (q + qd * (h / 2.0), qd + a1 * (h / 2.0));
            let a2 = self.acceleration(&q2, &qd2, tau);
            let (q3, qd3) = (q + qd2 * (h / 2.0), qd + a2 * (h / 2.0));
            let a3 = self.acceleration(&q3, &qd3, tau);
            let (q4, qd4) = (q + qd3 * h, qd + a3 * h);
            let a4 = self.acceleration(&q4, &qd4, tau);
            q += (qd + (qd2 + qd3) * 2.0 + qd4) * (h / 6.0);
            qd += (a1 + (a2 + a3) * 2.0 + a4) * (h / 6.0);
        }
        self.state = PlantState { q, qd };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::{RobotModel, RobotParams};

    /// RK4 is fourth order: halving the step cuts the error ~16×.
    #[test]
    fn fourth_order_convergence() {
        // Smooth dynamics: tanh(q̇/0.01) friction is stiff enough to hide the order.
        let p = RobotParams {
            coulomb_friction: [0.0; 3],
            ..RobotParams::default()
        };
        let start = PlantState {
            q: Vec3::from(p.q0),
            qd: Vec3::new(0.5, -0.3, 0.2),
        };
        let run = |substeps: usize| {
            let mut plant = Plant::new(ThreeLinkArm::new(&p), None, start, 0.01, substeps);
            for _ in 0..20 {
                plant.advance(&Vec3::new(1.0, 40.0, 8.0));
            }
            plant.state.q
        };
        let reference = run(256);
        let e1 = (run(4) - reference).norm();
        let e2 = (run(8) - reference).norm();
        let ratio = e1 / e2;
        assert!(ratio > 13.0 && ratio < 19.0, "ratio {ratio}");
    }

    /// Holding exactly the gravity torque keeps the arm at rest (friction is zero at q̇ = 0).
    #[test]
    fn gravity_torque_holds_still() {
        let p = RobotParams::default();
        let arm = ThreeLinkArm::new(&p);
        let q0 = Vec3::from(p.q0);
        let g = arm.dynamics(&q0, &Vec3::zeros()).gravity;
        let start = PlantState {
            q: q0,
            qd: Vec3::zeros(),
        };
        let mut plant = Plant::new(arm, None, start, 1e-3, 10);
        for _ in 0..1000 {
            plant.advance(&g);
        }
        assert!((plant.state.q - q0).abs().max() < 1e-12);
    }
}
