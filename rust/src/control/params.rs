//! The inner position loop's parameters (SPEC §4): the gains of eq. (39), the three
//! controllers' parameter blocks, the model error a controller believes in and the constant
//! inertia D̄ of eqs. (17) and (18). Plain data with `validate()`; the laws are in
//! `control::laws`, the state machine in `control::controller`.

use nalgebra::Vector3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::control::task::Desired;
use crate::error::{check, Error, Result};
use crate::robot::{JointMatrix, JointVector, RobotModel};
use crate::scalar::{Real, Wide};

/// Gains of eq. (39): V = K_A⁻¹ (Ẍ_d + K_D (Ẋ_d − Ẋ) + K_P (X_d − X)), each a scalar times I.
/// Over `f64`, or four runs' gains in lanes (one `scale_feedforward`). Serialised flat into
/// its controller's block; K_A is spelled `command_divisor` (`ka` is its deprecated alias).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PositionGains<T: Real = f64> {
    /// K_A of eq. (39), formerly ``ka``: V = (Ẍ_d + K_D ė + K_P e) / K_A, it divides the
    /// whole Cartesian command, feed-forward included (only the feedback with
    /// ``scale_feedforward=False``) [dimensionless].
    #[serde(rename = "command_divisor", alias = "ka")]
    #[schemars(extend("x-ui" = {"min": 0.01, "max": 100.0, "scale": "log"}))]
    pub ka: T,
    /// K_D of eq. (39) [1/s].
    #[schemars(extend("x-ui" = {"min": 0.1, "max": 1000.0, "scale": "log"}))]
    pub kd: T,
    /// K_P of eq. (39) [1/s²].
    #[schemars(extend("x-ui" = {"min": 1.0, "max": 10000.0, "scale": "log"}))]
    pub kp: T,
    /// ``True`` (SPEC, the paper as written): K_A⁻¹ multiplies Ẍ_d too. ``False``:
    /// V = Ẍ_d + K_A⁻¹(K_D ė + K_P e), a variant reading (see docs/reproduction.md).
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
}

impl<W: Real> PositionGains<W> {
    /// Four runs' gains in lanes (they share `scale_feedforward`: the lane key).
    pub fn pack<const L: usize>(g: [&PositionGains; L]) -> Self
    where
        W: Wide<L>,
    {
        Self {
            ka: W::from_lanes(|i| g[i].ka),
            kd: W::from_lanes(|i| g[i].kd),
            kp: W::from_lanes(|i| g[i].kp),
            scale_feedforward: g[0].scale_feedforward,
        }
    }
}

impl<T: Real> PositionGains<T> {
    /// eq. (39)
    #[inline(always)]
    pub fn command(
        &self,
        desired: &Desired<T>,
        position: &Vector3<T>,
        velocity: &Vector3<T>,
    ) -> Vector3<T> {
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ModelError {
    /// Factor on every link mass (and inertia) in the controller's model [dimensionless].
    #[schemars(extend("x-ui" = {"min": 0.5, "max": 2.0, "scale": "linear"}))]
    pub mass_scale: f64,
    /// Factor on viscous and Coulomb friction in the controller's model [dimensionless].
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 2.0, "scale": "linear"}))]
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

    /// The model a controller believes in: the plant's arm with this error.
    pub(crate) fn arm<R: RobotModel<N>, const N: usize>(&self, robot: &R) -> R::Model {
        robot
            .with_model_error(self.mass_scale, self.friction_scale)
            .model()
            .clone()
    }
}

/// Which TDC law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum TdcLaw {
    /// eq. (18): τ = D̄ K_t Jᵀ V + τ_{k−1} − D̄ q̈_{k−1}.
    JacobianTranspose,
    /// eq. (17): τ = D̄ J⁻¹ (V − J̇q̇) + τ_{k−1} − D̄ q̈_{k−1}.
    InverseJacobian,
}

/// Computed torque, eq. (7) in joint space: τ = D̂ J⁻¹ (V − J̇q̇) + Ĉ + Ĝ + τ̂_f.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ComputedTorqueParams {
    /// Default K_A = 0.1, K_D = 20, K_P = 100.
    #[serde(flatten)]
    pub gains: PositionGains,
    /// Add f J_xᵀ to cancel the measured contact force.
    pub contact_compensation: bool,
    /// The controller's model of the arm.
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

/// The most joints a per-joint parameter can describe.
pub const MAX_JOINTS: usize = 8;

/// A constant inertia D̄ given per joint: n values (D̄ = diag) or n² values (a full
/// symmetric positive definite D̄, row-major), stored inline so parameter blocks stay `Copy`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PerJoint {
    values: [f64; MAX_JOINTS * MAX_JOINTS],
    len: usize,
}

impl PerJoint {
    /// `None` when `values` has more than 64 entries.
    pub fn from_slice(values: &[f64]) -> Option<Self> {
        (values.len() <= MAX_JOINTS * MAX_JOINTS).then(|| {
            let mut v = [0.0; MAX_JOINTS * MAX_JOINTS];
            v[..values.len()].copy_from_slice(values);
            Self {
                values: v,
                len: values.len(),
            }
        })
    }

    pub fn as_slice(&self) -> &[f64] {
        &self.values[..self.len]
    }

    /// Whether it describes an `n`-joint arm (n values or n² values).
    pub fn fits(&self, n: usize) -> bool {
        self.len == n || self.len == n * n
    }

    /// D̄ as a matrix (the caller has checked `fits(N)`).
    pub fn matrix<const N: usize>(&self) -> JointMatrix<N> {
        if self.len == N {
            JointMatrix::<N>::from_diagonal(&JointVector::<N>::from_fn(|i, _| self.values[i]))
        } else {
            JointMatrix::<N>::from_fn(|i, j| self.values[i * N + j])
        }
    }
}

/// D̄ of eqs. 17/18: `inertia`·I, or the per-joint D̄ when given (a URDF arm whose wrist
/// inertias are far below its shoulder's needs one: TDC is stable only while the spectral
/// radius of I − D⁻¹D̄ stays below 1).
pub(crate) fn constant_inertia<const N: usize>(
    inertia: f64,
    joint: &Option<PerJoint>,
) -> JointMatrix<N> {
    joint.map_or_else(
        || JointMatrix::<N>::identity() * inertia,
        |p| p.matrix::<N>(),
    )
}

pub(crate) fn check_joint_inertia(p: &Option<PerJoint>) -> Result<()> {
    if let Some(p) = p {
        for (i, v) in p.as_slice().iter().enumerate() {
            check::finite(&format!("inertia[{i}]"), *v)?;
        }
    }
    Ok(())
}

/// Checks a per-joint D̄ against the arm's joint count: n positive values, or an n×n
/// symmetric positive definite matrix.
pub fn check_inertia_for<const N: usize>(p: &PerJoint) -> Result<()> {
    let shown = || format!("{:?}", p.as_slice());
    if !p.fits(N) {
        return Err(crate::error::Error::parameter(
            "inertia",
            shown(),
            &format!("one number, {N} numbers (diagonal) or {N}x{N} (a matrix)"),
        ));
    }
    let m = p.matrix::<N>();
    if (m - m.transpose()).abs().max() > 1e-12 * m.abs().max() || m.cholesky().is_none() {
        return Err(crate::error::Error::parameter(
            "inertia",
            shown(),
            "positive values, or a symmetric positive definite matrix",
        ));
    }
    Ok(())
}

/// Model-free ("nonmodel") control: eq. (18) without the delay estimate, τ = D̄ K_t Jᵀ V.
/// Crosses serde as `ModelFreeBlock`: one `inertia` field for `inertia` and
/// `joint_inertia`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(try_from = "ModelFreeBlock", into = "ModelFreeBlock")]
pub struct ModelFreeParams {
    /// Default K_A = 5, K_D = 20, K_P = 100.
    pub gains: PositionGains,
    /// Constant inertia D̄ = α I [kg·m²]. Default 0.1.
    pub inertia: f64,
    /// D̄ = diag(values), one per joint, instead of `inertia`·I. Default `None`.
    pub joint_inertia: Option<PerJoint>,
    /// Torque constant K_t. Default 200.
    pub torque_constant: f64,
}

impl Default for ModelFreeParams {
    fn default() -> Self {
        Self {
            gains: PositionGains::new(5.0, 20.0, 100.0),
            inertia: 0.1,
            joint_inertia: None,
            torque_constant: 200.0,
        }
    }
}

/// Time-delayed control, eq. (18) (default) or eq. (17). Crosses serde as
/// `TimeDelayBlock`: one `inertia` field for `inertia` and `joint_inertia`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(try_from = "TimeDelayBlock", into = "TimeDelayBlock")]
pub struct TimeDelayParams {
    /// Default K_A = 5, K_D = 20, K_P = 100.
    pub gains: PositionGains,
    /// Constant inertia D̄ [kg·m²]. Default 0.1.
    pub inertia: f64,
    /// D̄ = diag(values), one per joint, instead of `inertia`·I. Default `None`.
    pub joint_inertia: Option<PerJoint>,
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
            joint_inertia: None,
            torque_constant: mf.torque_constant,
            law: TdcLaw::JacobianTranspose,
            model: ModelError::default(),
        }
    }
}

/// The inner position loop, tagged by `kind` as the Python blocks are.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ControllerParams {
    ComputedTorque(ComputedTorqueParams),
    ModelFree(ModelFreeParams),
    TimeDelay(TimeDelayParams),
}

impl ControllerParams {
    /// D̄ per joint, when given (model-free and TDC).
    pub fn joint_inertia(&self) -> Option<&PerJoint> {
        match self {
            ControllerParams::ComputedTorque(_) => None,
            ControllerParams::ModelFree(p) => p.joint_inertia.as_ref(),
            ControllerParams::TimeDelay(p) => p.joint_inertia.as_ref(),
        }
    }

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
                check_joint_inertia(&p.joint_inertia)?;
                check::positive("torque_constant", p.torque_constant)
            }
            ControllerParams::TimeDelay(p) => {
                gains(&p.gains)?;
                check::positive("inertia", p.inertia)?;
                check_joint_inertia(&p.joint_inertia)?;
                check::positive("torque_constant", p.torque_constant)?;
                p.model.validate().map_err(|e| e.within("model"))
            }
        }
    }
}

/// D̄ of eqs. (17)/(18): one number (D̄ = α I), one per joint (diagonal) or the rows of an
/// n×n symmetric positive definite matrix.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum Inertia {
    One(f64),
    PerJoint(Vec<f64>),
    Rows(Vec<Vec<f64>>),
}

impl Inertia {
    /// (`inertia`, `joint_inertia`) as the controller blocks hold them.
    fn split(self) -> Result<(f64, Option<PerJoint>)> {
        let values = match self {
            Inertia::One(x) => return Ok((x, None)),
            Inertia::PerJoint(v) => v,
            Inertia::Rows(rows)
                if !rows.is_empty() && rows.iter().all(|r| r.len() == rows.len()) =>
            {
                rows.concat()
            }
            Inertia::Rows(rows) => {
                return Err(Error::parameter(
                    "inertia",
                    format!("{rows:?}"),
                    &format!("one number, one per joint or an n×n matrix (n ≤ {MAX_JOINTS})"),
                ))
            }
        };
        match values.as_slice() {
            [one] => Ok((*one, None)),
            many => match PerJoint::from_slice(many) {
                Some(p) if !many.is_empty() => Ok((many[0], Some(p))),
                _ => Err(Error::parameter(
                    "inertia",
                    format!("{many:?}"),
                    &format!("one number, one per joint or an n×n matrix (n ≤ {MAX_JOINTS})"),
                )),
            },
        }
    }

    fn join(inertia: f64, joint: &Option<PerJoint>) -> Self {
        match joint {
            None => Inertia::One(inertia),
            Some(p) => {
                let v = p.as_slice();
                let n = (v.len() as f64).sqrt() as usize;
                if v.len() > 1 && n * n == v.len() && n > 1 {
                    Inertia::Rows(v.chunks(n).map(<[f64]>::to_vec).collect())
                } else {
                    Inertia::PerJoint(v.to_vec())
                }
            }
        }
    }
}

/// `ModelFreeParams` as it crosses serde: the Python `ModelFree` block.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ModelFreeBlock {
    #[serde(flatten)]
    pub gains: PositionGains,
    /// Constant inertia D̄ [kg·m²]: one number (D̄ = α I, the paper's), one per joint
    /// (D̄ = diag(...)) or an n×n symmetric positive definite matrix (rows), for URDF arms
    /// whose inertias differ by orders of magnitude between shoulder and wrist.
    #[serde(default = "default_inertia")]
    #[schemars(extend("x-ui" = {"min": 0.001, "max": 10.0, "scale": "log"}))]
    pub inertia: Inertia,
    /// Torque constant K_t (eq. 18).
    #[serde(default = "default_torque_constant")]
    pub torque_constant: f64,
}

fn default_inertia() -> Inertia {
    Inertia::One(ModelFreeParams::default().inertia)
}

fn default_torque_constant() -> f64 {
    ModelFreeParams::default().torque_constant
}

fn default_law() -> TdcLaw {
    TimeDelayParams::default().law
}

impl TryFrom<ModelFreeBlock> for ModelFreeParams {
    type Error = String;
    fn try_from(b: ModelFreeBlock) -> std::result::Result<Self, String> {
        let (inertia, joint_inertia) = b.inertia.split().map_err(|e| e.to_string())?;
        Ok(Self {
            gains: b.gains,
            inertia,
            joint_inertia,
            torque_constant: b.torque_constant,
        })
    }
}

impl From<ModelFreeParams> for ModelFreeBlock {
    fn from(p: ModelFreeParams) -> Self {
        Self {
            gains: p.gains,
            inertia: Inertia::join(p.inertia, &p.joint_inertia),
            torque_constant: p.torque_constant,
        }
    }
}

/// `TimeDelayParams` as it crosses serde: the Python `TimeDelayControl` block.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TimeDelayBlock {
    #[serde(flatten)]
    pub gains: PositionGains,
    /// Constant inertia D̄ [kg·m²]: one number (D̄ = α I, the paper's), one per joint
    /// (D̄ = diag(...)) or an n×n symmetric positive definite matrix (rows), for URDF arms
    /// whose inertias differ by orders of magnitude between shoulder and wrist.
    #[serde(default = "default_inertia")]
    #[schemars(extend("x-ui" = {"min": 0.001, "max": 10.0, "scale": "log"}))]
    pub inertia: Inertia,
    /// Torque constant K_t (eq. 18).
    #[serde(default = "default_torque_constant")]
    pub torque_constant: f64,
    /// ``"jacobian_transpose"``: eq. (18); ``"inverse_jacobian"``: eq. (17).
    #[serde(default = "default_law")]
    pub law: TdcLaw,
    /// Used only for the initial torque τ_{−1} = Ĝ(q0).
    #[serde(default)]
    pub model: ModelError,
}

impl TryFrom<TimeDelayBlock> for TimeDelayParams {
    type Error = String;
    fn try_from(b: TimeDelayBlock) -> std::result::Result<Self, String> {
        let (inertia, joint_inertia) = b.inertia.split().map_err(|e| e.to_string())?;
        Ok(Self {
            gains: b.gains,
            inertia,
            joint_inertia,
            torque_constant: b.torque_constant,
            law: b.law,
            model: b.model,
        })
    }
}

impl From<TimeDelayParams> for TimeDelayBlock {
    fn from(p: TimeDelayParams) -> Self {
        Self {
            gains: p.gains,
            inertia: Inertia::join(p.inertia, &p.joint_inertia),
            torque_constant: p.torque_constant,
            law: p.law,
            model: p.model,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::three_link::Vec3;

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
}
