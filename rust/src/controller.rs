//! The inner position loop: computed torque (eq. 7), model-free control (eq. 18 without the
//! delay estimate) and time-delayed control (eqs. 17 and 18), all driven by the Cartesian
//! command V of eq. (39). Each is a state machine with `reset()` and `step()`.

use crate::error::{check, Result};
use crate::robot::{Kinematics, Mat3, RobotModel, RobotParams, ThreeLinkArm, Vec3};

/// Gains of eq. (39): V = K_A⁻¹ (Ẍ_d + K_D (Ẋ_d − Ẋ) + K_P (X_d − X)), each a scalar times I.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionGains {
    pub ka: f64,
    pub kd: f64,
    pub kp: f64,
    /// `true` (SPEC §4, the paper as written): K_A⁻¹ multiplies the feed-forward Ẍ_d too.
    /// `false`: V = Ẍ_d + K_A⁻¹ (K_D ė + K_P e), a reading under which computed torque
    /// tracks X_d exactly; offered as a labelled variant, never the default.
    pub scale_feedforward: bool,
}

impl PositionGains {
    pub const fn new(ka: f64, kd: f64, kp: f64) -> Self {
        Self {
            ka,
            kd,
            kp,
            scale_feedforward: true,
        }
    }
}

impl PositionGains {
    pub fn validate(&self) -> Result<()> {
        check::positive("ka", self.ka)?;
        check::non_negative("kd", self.kd)?;
        check::non_negative("kp", self.kp)
    }

    /// eq. (39)
    #[inline]
    pub fn command(&self, desired: &Desired, position: &Vec3, velocity: &Vec3) -> Vec3 {
        let feedback =
            (desired.velocity - velocity) * self.kd + (desired.position - position) * self.kp;
        if self.scale_feedforward {
            (desired.acceleration + feedback) / self.ka
        } else {
            desired.acceleration + feedback / self.ka
        }
    }
}

/// The controller's belief about the arm, relative to the plant (SPEC §4, for sweeps).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelError {
    /// Factor on every link mass (and so every inertia). Default 1.
    pub mass_scale: f64,
    /// Factor on viscous and Coulomb friction. Default 1.
    pub friction_scale: f64,
}

impl Default for ModelError {
    fn default() -> Self {
        Self {
            mass_scale: 1.0,
            friction_scale: 1.0,
        }
    }
}

impl ModelError {
    pub fn validate(&self) -> Result<()> {
        check::positive("mass_scale", self.mass_scale)?;
        check::non_negative("friction_scale", self.friction_scale)
    }

    fn arm(&self, robot: &RobotParams) -> ThreeLinkArm {
        ThreeLinkArm::new(&robot.with_model_error(self.mass_scale, self.friction_scale))
    }
}

/// Which TDC law.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TdcLaw {
    /// eq. (18): τ = D̄ K_t Jᵀ V + τ_{k−1} − D̄ q̈_{k−1}.
    JacobianTranspose,
    /// eq. (17): τ = D̄ J⁻¹ (V − J̇q̇) + τ_{k−1} − D̄ q̈_{k−1}.
    InverseJacobian,
}

/// Computed torque, eq. (7) in joint space: τ = D̂ J⁻¹ (V − J̇q̇) + Ĉ + Ĝ + τ̂_f.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComputedTorqueParams {
    /// Default K_A = 0.1, K_D = 20, K_P = 100.
    pub gains: PositionGains,
    /// Add f J_xᵀ to cancel the measured contact force. Default false.
    pub contact_compensation: bool,
    pub model: ModelError,
}

impl Default for ComputedTorqueParams {
    fn default() -> Self {
        Self {
            gains: PositionGains::new(0.1, 20.0, 100.0),
            contact_compensation: false,
            model: ModelError::default(),
        }
    }
}

/// Model-free ("nonmodel") control: eq. (18) without the delay estimate, τ = D̄ K_t Jᵀ V.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelFreeParams {
    /// Default K_A = 5, K_D = 20, K_P = 100.
    pub gains: PositionGains,
    /// Constant inertia D̄ = α I [kg·m²]. Default 0.1.
    pub inertia: f64,
    /// Torque constant K_t. Default 200.
    pub torque_constant: f64,
}

impl Default for ModelFreeParams {
    fn default() -> Self {
        Self {
            gains: PositionGains::new(5.0, 20.0, 100.0),
            inertia: 0.1,
            torque_constant: 200.0,
        }
    }
}

/// Time-delayed control, eq. (18) (default) or eq. (17).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeDelayParams {
    /// Default K_A = 5, K_D = 20, K_P = 100.
    pub gains: PositionGains,
    /// Constant inertia D̄ [kg·m²]. Default 0.1.
    pub inertia: f64,
    /// Torque constant K_t (eq. 18 only). Default 200.
    pub torque_constant: f64,
    pub law: TdcLaw,
    /// Used only for the initial torque τ_{−1} = Ĝ(q0).
    pub model: ModelError,
}

impl Default for TimeDelayParams {
    fn default() -> Self {
        let mf = ModelFreeParams::default();
        Self {
            gains: mf.gains,
            inertia: mf.inertia,
            torque_constant: mf.torque_constant,
            law: TdcLaw::JacobianTranspose,
            model: ModelError::default(),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ControllerParams {
    ComputedTorque(ComputedTorqueParams),
    ModelFree(ModelFreeParams),
    TimeDelay(TimeDelayParams),
}

impl ControllerParams {
    pub fn validate(&self) -> Result<()> {
        let gains = |g: &PositionGains| g.validate();
        match self {
            ControllerParams::ComputedTorque(p) => {
                gains(&p.gains)?;
                p.model.validate().map_err(|e| e.within("model"))
            }
            ControllerParams::ModelFree(p) => {
                gains(&p.gains)?;
                check::positive("inertia", p.inertia)?;
                check::positive("torque_constant", p.torque_constant)
            }
            ControllerParams::TimeDelay(p) => {
                gains(&p.gains)?;
                check::positive("inertia", p.inertia)?;
                check::positive("torque_constant", p.torque_constant)?;
                p.model.validate().map_err(|e| e.within("model"))
            }
        }
    }
}

/// Desired tip position, velocity and acceleration at one sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Desired {
    pub position: Vec3,
    pub velocity: Vec3,
    pub acceleration: Vec3,
}

/// What the controller measures at t_k. The kinematics are evaluated once by the
/// simulation: the controller's model shares the plant's geometry.
#[derive(Debug, Clone, Copy)]
pub struct Measurement<'a> {
    pub q: &'a Vec3,
    pub qd: &'a Vec3,
    pub kinematics: &'a Kinematics,
    /// Contact force along x [N].
    pub force: f64,
}

/// Why a control law could not produce a torque.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlFailure {
    SingularJacobian,
}

/// det J relative to its Hadamard bound (the product of the column norms) below which the
/// Jacobian counts as singular: J⁻¹ would amplify rounding beyond any use.
const SINGULAR_RATIO: f64 = 1e-9;

#[inline]
fn solve_jacobian(j: &Mat3, rhs: &Vec3) -> std::result::Result<Vec3, ControlFailure> {
    let bound = j.column(0).norm() * j.column(1).norm() * j.column(2).norm();
    let det = j.determinant().abs();
    if det.is_nan() || det <= SINGULAR_RATIO * bound {
        return Err(ControlFailure::SingularJacobian);
    }
    j.try_inverse()
        .map(|inv| inv * rhs)
        .ok_or(ControlFailure::SingularJacobian)
}

/// A position controller as a state machine.
#[derive(Debug, Clone, PartialEq)]
pub enum Controller {
    ComputedTorque {
        params: ComputedTorqueParams,
        model: ThreeLinkArm,
    },
    ModelFree(ModelFreeParams),
    TimeDelay {
        params: TimeDelayParams,
        period: f64,
        initial_torque: Vec3,
        tau_prev: Vec3,
        qd_prev: Option<Vec3>,
    },
}

impl Controller {
    pub fn new(params: &ControllerParams, robot: &RobotParams, period: f64) -> Self {
        match params {
            ControllerParams::ComputedTorque(p) => Controller::ComputedTorque {
                params: *p,
                model: p.model.arm(robot),
            },
            ControllerParams::ModelFree(p) => Controller::ModelFree(*p),
            ControllerParams::TimeDelay(p) => {
                let q0 = Vec3::from(robot.q0);
                let g0 = p.model.arm(robot).dynamics(&q0, &Vec3::zeros()).gravity;
                Controller::TimeDelay {
                    params: *p,
                    period,
                    initial_torque: g0,
                    tau_prev: g0,
                    qd_prev: None,
                }
            }
        }
    }

    pub fn gains(&self) -> &PositionGains {
        match self {
            Controller::ComputedTorque { params, .. } => &params.gains,
            Controller::ModelFree(p) => &p.gains,
            Controller::TimeDelay { params, .. } => &params.gains,
        }
    }

    pub fn reset(&mut self) {
        if let Controller::TimeDelay {
            initial_torque,
            tau_prev,
            qd_prev,
            ..
        } = self
        {
            *tau_prev = *initial_torque;
            *qd_prev = None;
        }
    }

    /// The joint torque τ_k for the measurement at t_k.
    #[inline]
    pub fn step(
        &mut self,
        m: &Measurement,
        desired: &Desired,
    ) -> std::result::Result<Vec3, ControlFailure> {
        let k = m.kinematics;
        let velocity = k.jacobian * m.qd;
        let v = self.gains().command(desired, &k.position, &velocity);
        match self {
            Controller::ComputedTorque { params, model } => {
                // eq. (7) mapped to joint space with eq. (4).
                let qdd = solve_jacobian(&k.jacobian, &(v - k.jdot_qd))?;
                let d = model.dynamics(m.q, m.qd);
                let mut tau = d.inertia * qdd + d.coriolis + d.gravity + model.friction(m.qd);
                if params.contact_compensation {
                    // The plant feels Jᵀ[−f, 0, 0]; add it back.
                    tau += k.jacobian.row(0).transpose() * m.force;
                }
                Ok(tau)
            }
            Controller::ModelFree(p) => {
                Ok(k.jacobian.transpose() * v * (p.inertia * p.torque_constant))
            }
            Controller::TimeDelay {
                params,
                period,
                tau_prev,
                qd_prev,
                ..
            } => {
                // eq. (14): ĥ ≈ τ_{k−1} − D̄ q̈_{k−1}, with q̈_{k−1} = (q̇_k − q̇_{k−1})/T, q̈_{−1} = 0.
                let qdd_prev = qd_prev.map_or_else(Vec3::zeros, |p| (m.qd - p) / *period);
                let h_hat = *tau_prev - qdd_prev * params.inertia;
                let u = match params.law {
                    TdcLaw::JacobianTranspose => {
                        k.jacobian.transpose() * v * (params.inertia * params.torque_constant)
                    }
                    TdcLaw::InverseJacobian => {
                        solve_jacobian(&k.jacobian, &(v - k.jdot_qd))? * params.inertia
                    }
                };
                let tau = u + h_hat;
                *tau_prev = tau;
                *qd_prev = Some(*m.qd);
                Ok(tau)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::RobotModel;

    fn at_q0() -> (RobotParams, Vec3, Kinematics) {
        let r = RobotParams::default();
        let q = Vec3::from(r.q0);
        let k = ThreeLinkArm::new(&r).kinematics(&q, &Vec3::zeros());
        (r, q, k)
    }

    #[test]
    fn command_is_eq39() {
        let g = PositionGains::new(5.0, 20.0, 100.0);
        let d = Desired {
            position: Vec3::new(1.0, 0.0, 0.0),
            velocity: Vec3::new(0.0, 1.0, 0.0),
            acceleration: Vec3::new(0.0, 0.0, 5.0),
        };
        let v = g.command(&d, &Vec3::zeros(), &Vec3::zeros());
        assert_eq!(v, Vec3::new(20.0, 4.0, 1.0));
        let unscaled = PositionGains {
            scale_feedforward: false,
            ..g
        };
        let v = unscaled.command(&d, &Vec3::zeros(), &Vec3::zeros());
        assert_eq!(v, Vec3::new(20.0, 4.0, 5.0));
    }

    #[test]
    fn computed_torque_holds_still_with_gravity_compensation() {
        let (r, q, k) = at_q0();
        let mut c = Controller::new(
            &ControllerParams::ComputedTorque(ComputedTorqueParams::default()),
            &r,
            1e-3,
        );
        let m = Measurement {
            q: &q,
            qd: &Vec3::zeros(),
            kinematics: &k,
            force: 0.0,
        };
        let d = Desired {
            position: k.position,
            ..Desired::default()
        };
        let tau = c.step(&m, &d).unwrap();
        let g = ThreeLinkArm::new(&r).dynamics(&q, &Vec3::zeros()).gravity;
        assert!((tau - g).abs().max() < 1e-12);
    }

    #[test]
    fn tdc_first_step_is_gravity_plus_transpose_term() {
        let (r, q, k) = at_q0();
        let mut c = Controller::new(
            &ControllerParams::TimeDelay(TimeDelayParams::default()),
            &r,
            1e-3,
        );
        let d = Desired {
            position: k.position + Vec3::new(0.01, 0.0, 0.0),
            ..Desired::default()
        };
        let qd = Vec3::zeros();
        let m = Measurement {
            q: &q,
            qd: &qd,
            kinematics: &k,
            force: 0.0,
        };
        let tau0 = c.step(&m, &d).unwrap();
        let g = ThreeLinkArm::new(&r).dynamics(&q, &qd).gravity;
        // V = 100·0.01/5 = 0.2 along x; D̄ K_t = 20.
        let expected = g + k.jacobian.transpose() * Vec3::new(0.2, 0.0, 0.0) * 20.0;
        assert!((tau0 - expected).abs().max() < 1e-12);
        // Next step: q̇ changed by 0.001 rad/s on joint 2 ⇒ q̈_{k−1} = 1 rad/s².
        let qd1 = Vec3::new(0.0, 0.001, 0.0);
        let m1 = Measurement { qd: &qd1, ..m };
        let tau1 = c.step(&m1, &d).unwrap();
        let v1 = k.jacobian.transpose() * (Vec3::new(0.2, 0.0, 0.0) - k.jacobian * qd1 * 4.0);
        let expected1 = tau0 + v1 * 20.0 - Vec3::new(0.0, 0.1, 0.0);
        assert!((tau1 - expected1).abs().max() < 1e-12);
        c.reset();
        assert!((c.step(&m, &d).unwrap() - tau0).abs().max() < 1e-15);
    }

    #[test]
    fn singular_jacobian_is_reported() {
        let r = RobotParams::default();
        let q = Vec3::new(0.0, 0.3, 0.0);
        let k = ThreeLinkArm::new(&r).kinematics(&q, &Vec3::zeros());
        let mut c = Controller::new(
            &ControllerParams::ComputedTorque(ComputedTorqueParams::default()),
            &r,
            1e-3,
        );
        let m = Measurement {
            q: &q,
            qd: &Vec3::zeros(),
            kinematics: &k,
            force: 0.0,
        };
        assert_eq!(
            c.step(&m, &Desired::default()),
            Err(ControlFailure::SingularJacobian)
        );
    }
}
