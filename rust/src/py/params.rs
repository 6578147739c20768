//! Parameter blocks in: the dicts made by `admit_rs.config` read into the core's structs,
//! every error naming its dotted field; and the blocks' declaration out (`defaults`,
//! `schema`).

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::errors::{parameter_error, to_py_err};
use crate::control::filter::{AdmittanceParams, ForceControlParams, ImpedanceParams};
use crate::control::params::{
    ComputedTorqueParams, ControllerParams, ModelError, ModelFreeParams, PerJoint, PositionGains,
    TdcLaw, TimeDelayParams,
};
use crate::control::reference::Signal;
use crate::robot::chain::urdf::MAX_JOINTS;
use crate::robot::chain::{TaskKind, UrdfArmParams};
use crate::robot::{MassModel, RobotParams};
use crate::sim::scenario::RobotConfig;
use crate::sim::simulation::{ScenarioConfig, MAX_SUBSTEPS};
use crate::world::actuator::ActuatorParams;
use crate::world::environment::{ContactModel, WallParams};
use crate::world::sensor::SensorParams;

/// Reads typed fields out of one config dict, naming the dotted path in every error.
struct Block<'py> {
    dict: Bound<'py, PyDict>,
    path: String,
}

impl<'py> Block<'py> {
    fn new(obj: &Bound<'py, PyAny>, path: &str) -> PyResult<Self> {
        let dict = obj.cast::<PyDict>().map_err(|_| {
            PyTypeError::new_err(format!(
                "{}: expected a dict, got {}",
                display_path(path),
                type_name(obj)
            ))
        })?;
        Ok(Self {
            dict: dict.clone(),
            path: path.to_owned(),
        })
    }

    fn field_path(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.to_owned()
        } else {
            format!("{}.{key}", self.path)
        }
    }

    fn item(&self, key: &str) -> PyResult<Bound<'py, PyAny>> {
        self.dict
            .get_item(key)?
            .ok_or_else(|| PyTypeError::new_err(format!("missing field {}", self.field_path(key))))
    }

    fn typed<T: for<'a> FromPyObjectOwned<'a>>(&self, key: &str, what: &str) -> PyResult<T> {
        let v = self.item(key)?;
        v.extract::<T>().map_err(|_| {
            PyTypeError::new_err(format!(
                "{} must be {what}, got {}",
                self.field_path(key),
                type_name(&v)
            ))
        })
    }

    fn f64(&self, key: &str) -> PyResult<f64> {
        self.typed(key, "a number")
    }

    fn opt_f64(&self, key: &str) -> PyResult<Option<f64>> {
        self.typed(key, "a number or None")
    }

    fn bool(&self, key: &str) -> PyResult<bool> {
        self.typed(key, "a bool")
    }

    fn vec3(&self, key: &str) -> PyResult<[f64; 3]> {
        self.typed(key, "a sequence of 3 numbers")
    }

    fn vec(&self, key: &str) -> PyResult<Vec<f64>> {
        self.typed(key, "a sequence of numbers")
    }

    /// A whole number from 0 to `max`, given as an int or an integral float; anything else
    /// is a `ParameterError` naming the field.
    fn count(&self, key: &str, max: usize) -> PyResult<usize> {
        let v = self.f64(key)?;
        if v.fract() == 0.0 && v >= 0.0 && v <= max as f64 {
            Ok(v as usize)
        } else {
            Err(parameter_error(
                self.dict.py(),
                &self.field_path(key),
                &v.to_string(),
                &format!("an integer from 0 to {max}"),
            ))
        }
    }

    fn string(&self, key: &str) -> PyResult<String> {
        self.typed(key, "a str")
    }

    fn sub(&self, key: &str) -> PyResult<Block<'py>> {
        Block::new(&self.item(key)?, &self.field_path(key))
    }

    fn optional_sub(&self, key: &str) -> PyResult<Option<Block<'py>>> {
        let v = self.item(key)?;
        if v.is_none() {
            Ok(None)
        } else {
            Block::new(&v, &self.field_path(key)).map(Some)
        }
    }

    fn choice(&self, key: &str, allowed: &[&str]) -> PyResult<String> {
        let v = self.string(key)?;
        if allowed.contains(&v.as_str()) {
            Ok(v)
        } else {
            let list = allowed
                .iter()
                .map(|a| format!("'{a}'"))
                .collect::<Vec<_>>()
                .join(", ");
            Err(parameter_error(
                self.dict.py(),
                &self.field_path(key),
                &format!("'{v}'"),
                &format!("one of {list}"),
            ))
        }
    }
}

fn display_path(path: &str) -> &str {
    if path.is_empty() {
        "scenario"
    } else {
        path
    }
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map_or_else(|_| "?".to_owned(), |n| n.to_string())
}

/// The robot block: `kind = "urdf"` is a URDF chain, anything else the three-link arm.
fn robot_config_from(b: &Block) -> PyResult<RobotConfig> {
    let is_urdf = match b.dict.get_item("kind")? {
        Some(k) => k.extract::<String>().map(|k| k == "urdf").unwrap_or(false),
        None => false,
    };
    Ok(if is_urdf {
        RobotConfig::Urdf(urdf_arm_from(b)?)
    } else {
        RobotConfig::ThreeLink(robot_from(b)?)
    })
}

/// One number or a sequence of numbers, as a list.
fn numbers(b: &Block, key: &str) -> PyResult<Vec<f64>> {
    let v = b.item(key)?;
    match v.extract::<f64>() {
        Ok(x) => Ok(vec![x]),
        Err(_) => b.vec(key),
    }
}

fn urdf_arm_from(b: &Block) -> PyResult<UrdfArmParams> {
    let q0 = b.item("q0")?;
    Ok(UrdfArmParams {
        urdf: b.string("urdf")?,
        tip_link: b.string("tip_link")?,
        base_link: b.typed("base_link", "a str or None")?,
        q0: if q0.is_none() {
            None
        } else {
            Some(b.vec("q0")?)
        },
        viscous_friction: numbers(b, "viscous_friction")?,
        coulomb_friction: numbers(b, "coulomb_friction")?,
        friction_smoothing: b.f64("friction_smoothing")?,
        gravity: b.f64("gravity")?,
        orientation_gains: {
            let g = b.item("orientation_gains")?;
            if g.is_none() {
                None
            } else {
                let v = b.vec("orientation_gains")?;
                match v.as_slice() {
                    [kp, kd] => Some((*kp, *kd)),
                    _ => {
                        return Err(parameter_error(
                            b.dict.py(),
                            &b.field_path("orientation_gains"),
                            &format!("{v:?}"),
                            "two numbers (K_P, K_D) or None",
                        ))
                    }
                }
            }
        },
        damping: b.f64("damping")?,
        task: match b.item("task")?.is_none() {
            true => None,
            false => Some(match b.choice("task", &["position", "pose"])?.as_str() {
                "position" => TaskKind::Position,
                _ => TaskKind::Pose,
            }),
        },
    })
}

fn robot_from(b: &Block) -> PyResult<RobotParams> {
    Ok(RobotParams {
        lengths: b.vec3("lengths")?,
        masses: b.vec3("masses")?,
        mass_model: match b.choice("mass_model", &["rod", "point"])?.as_str() {
            "rod" => MassModel::Rod,
            _ => MassModel::Point,
        },
        viscous_friction: b.vec3("viscous_friction")?,
        coulomb_friction: b.vec3("coulomb_friction")?,
        friction_smoothing: b.f64("friction_smoothing")?,
        gravity: b.f64("gravity")?,
        q0: b.vec3("q0")?,
    })
}

fn wall_from(b: &Block) -> PyResult<WallParams> {
    Ok(WallParams {
        stiffness: b.f64("stiffness")?,
        damping: b.f64("damping")?,
        model: match b
            .choice("model", &["kelvin_voigt", "hunt_crossley"])?
            .as_str()
        {
            "kelvin_voigt" => ContactModel::KelvinVoigt,
            _ => ContactModel::HuntCrossley,
        },
        exponent: b.f64("exponent")?,
        normal: b.vec3("normal")?,
        position: b.opt_f64("position")?,
        position_error: b.f64("position_error")?,
    })
}

fn sensor_from(b: &Block) -> PyResult<SensorParams> {
    Ok(SensorParams {
        bias: b.f64("bias")?,
        noise_std: b.f64("noise_std")?,
        resolution: b.f64("resolution")?,
        cutoff: b.opt_f64("cutoff")?,
        latency: b.count("latency", crate::world::sensor::MAX_LATENCY)?,
    })
}

fn actuator_from(b: &Block) -> PyResult<ActuatorParams> {
    let limit = b.item("torque_limit")?;
    let torque_limit = if limit.is_none() {
        None
    } else if let Ok(v) = limit.extract::<f64>() {
        Some(vec![v])
    } else {
        Some(b.vec("torque_limit")?)
    };
    Ok(ActuatorParams {
        torque_limit,
        rate_limit: b.opt_f64("rate_limit")?,
        delay: b.count("delay", crate::world::actuator::MAX_DELAY)?,
    })
}

fn gains_from(b: &Block) -> PyResult<PositionGains> {
    Ok(PositionGains {
        ka: b.f64("ka")?,
        kd: b.f64("kd")?,
        kp: b.f64("kp")?,
        scale_feedforward: b.bool("scale_feedforward")?,
    })
}

fn model_from(b: &Block) -> PyResult<ModelError> {
    Ok(ModelError {
        mass_scale: b.f64("mass_scale")?,
        friction_scale: b.f64("friction_scale")?,
    })
}

/// `inertia`: one number (D̄ = α I), one per joint (D̄ = diag) or rows of a matrix.
fn inertia_from(b: &Block) -> PyResult<(f64, Option<PerJoint>)> {
    let item = b.item("inertia")?;
    let v = match item.extract::<Vec<Vec<f64>>>() {
        Ok(rows) if !rows.is_empty() && rows.iter().all(|r| r.len() == rows.len()) => rows.concat(),
        _ => numbers(b, "inertia")?,
    };
    match v.as_slice() {
        [one] => Ok((*one, None)),
        many => match PerJoint::from_slice(many) {
            Some(p) if !many.is_empty() => Ok((many[0], Some(p))),
            _ => Err(parameter_error(
                b.dict.py(),
                &b.field_path("inertia"),
                &format!("{many:?}"),
                &format!("one number, one per joint or an n×n matrix (n ≤ {MAX_JOINTS})"),
            )),
        },
    }
}

fn controller_from(b: &Block) -> PyResult<ControllerParams> {
    let kind = b.choice("kind", &["computed_torque", "model_free", "time_delay"])?;
    Ok(match kind.as_str() {
        "computed_torque" => ControllerParams::ComputedTorque(ComputedTorqueParams {
            gains: gains_from(b)?,
            contact_compensation: b.bool("contact_compensation")?,
            model: model_from(&b.sub("model")?)?,
        }),
        "model_free" => ControllerParams::ModelFree(ModelFreeParams {
            gains: gains_from(b)?,
            inertia: inertia_from(b)?.0,
            joint_inertia: inertia_from(b)?.1,
            torque_constant: b.f64("torque_constant")?,
        }),
        _ => ControllerParams::TimeDelay(TimeDelayParams {
            gains: gains_from(b)?,
            inertia: inertia_from(b)?.0,
            joint_inertia: inertia_from(b)?.1,
            torque_constant: b.f64("torque_constant")?,
            law: match b
                .choice("law", &["jacobian_transpose", "inverse_jacobian"])?
                .as_str()
            {
                "jacobian_transpose" => TdcLaw::JacobianTranspose,
                _ => TdcLaw::InverseJacobian,
            },
            model: model_from(&b.sub("model")?)?,
        }),
    })
}

fn admittance_params_from(b: &Block) -> PyResult<AdmittanceParams> {
    Ok(AdmittanceParams {
        m: b.f64("m")?,
        b: b.f64("b")?,
        k: b.f64("k")?,
        ka: b.f64("ka")?,
    })
}

fn force_control_from(b: &Block) -> PyResult<ForceControlParams> {
    Ok(
        match b.choice("kind", &["admittance", "impedance"])?.as_str() {
            "admittance" => ForceControlParams::Admittance(admittance_params_from(b)?),
            _ => ForceControlParams::Impedance(ImpedanceParams {
                k: b.f64("k")?,
                assumed_stiffness: b.f64("assumed_stiffness")?,
            }),
        },
    )
}

fn signal_from(b: &Block) -> PyResult<Signal> {
    Ok(
        match b.choice("kind", &["step", "sine", "sampled"])?.as_str() {
            "step" => Signal::Step {
                value: b.f64("value")?,
                time: b.f64("time")?,
                initial: b.f64("initial")?,
            },
            "sine" => Signal::Sine {
                offset: b.f64("offset")?,
                amplitude: b.f64("amplitude")?,
                omega: b.f64("omega")?,
                phase: b.f64("phase")?,
            },
            _ => Signal::Sampled {
                times: b.vec("times")?,
                values: b.vec("values")?,
            },
        },
    )
}

pub(super) fn scenario_from(obj: &Bound<'_, PyAny>) -> PyResult<ScenarioConfig> {
    let b = Block::new(obj, "")?;
    let substeps = b.f64("substeps")?;
    if !(substeps.fract() == 0.0 && substeps >= 1.0 && substeps <= MAX_SUBSTEPS as f64) {
        return Err(parameter_error(
            obj.py(),
            "substeps",
            &substeps.to_string(),
            &format!("an integer from 1 to {MAX_SUBSTEPS}"),
        ));
    }
    let seed = b.f64("seed")?;
    // Seeds are integers below 2^53 (exact in a float; Python checks the int first).
    if !(seed.fract() == 0.0 && (0.0..=9_007_199_254_740_992.0).contains(&seed)) {
        return Err(parameter_error(
            obj.py(),
            "seed",
            &seed.to_string(),
            "an integer from 0 to 2^53",
        ));
    }
    let config = ScenarioConfig {
        robot: robot_config_from(&b.sub("robot")?)?,
        wall: b.optional_sub("wall")?.map(|w| wall_from(&w)).transpose()?,
        controller: controller_from(&b.sub("controller")?)?,
        admittance: b
            .optional_sub("admittance")?
            .map(|a| force_control_from(&a))
            .transpose()?,
        force_reference: signal_from(&b.sub("force_reference")?)?,
        z_reference: signal_from(&b.sub("z_reference")?)?,
        sensor: sensor_from(&b.sub("sensor")?)?,
        actuator: actuator_from(&b.sub("actuator")?)?,
        seed: seed as u64,
        period: b.f64("period")?,
        substeps: substeps as usize,
        duration: b.f64("duration")?,
        velocity_limit: b.f64("velocity_limit")?,
    };
    config.validate().map_err(|e| to_py_err(obj.py(), e))?;
    Ok(config)
}

/// Serde's value as plain Python objects (dicts, lists, floats, strings, None).
fn to_python<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    pythonize::pythonize(py, value).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The core's default parameters, block by block: each block's `Default` serialised by its
/// serde declaration (`schema::defaults`), the one source the Python dataclass defaults are
/// tested against.
#[pyfunction]
pub(super) fn defaults(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_python(py, &crate::schema::defaults())
}

/// Every block's JSON schema (`schema::schemas`): field names, types, docs and defaults.
#[pyfunction]
pub(super) fn schema(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_python(py, &crate::schema::schemas())
}

/// Validates one building block on its own, so a dataclass can fail at construction.
#[pyfunction]
pub(super) fn check_block(kind: &str, params: &Bound<'_, PyAny>) -> PyResult<()> {
    let py = params.py();
    let b = Block::new(params, "")?;
    let checked = match kind {
        "robot" => robot_config_from(&b)?.validate().map(|_| ()),
        "wall" => wall_from(&b)?.validate(),
        "controller" => controller_from(&b)?.validate(),
        // The discretisation is checked with the scenario's period, in `validate`.
        "admittance" => match force_control_from(&b)? {
            ForceControlParams::Admittance(p) => p.validate(),
            ForceControlParams::Impedance(p) => p.validate(),
        },
        "sensor" => sensor_from(&b)?.validate(),
        // On its own an actuator may serve any arm: one limit, or one per joint of a 1- to
        // 8-joint arm; the scenario checks the count against its arm.
        "actuator" => {
            let a = actuator_from(&b)?;
            let n = a.torque_limit.as_ref().map_or(1, Vec::len);
            a.validate(if (1..=MAX_JOINTS).contains(&n) { n } else { 3 })
        }
        "signal" => signal_from(&b)?.validate(),
        "model" => model_from(&b)?.validate(),
        other => {
            return Err(PyValueError::new_err(format!(
                "unknown block kind '{other}'"
            )))
        }
    };
    checked.map_err(|e| to_py_err(py, e))
}

/// Validates a whole scenario dict (cross-field checks included).
#[pyfunction]
pub(super) fn validate(scenario: &Bound<'_, PyAny>) -> PyResult<()> {
    scenario_from(scenario).map(|_| ())
}

/// A three-link arm block on its own (`robot_terms`, `forward_dynamics`).
pub(super) fn robot_params(robot: &Bound<'_, PyAny>) -> PyResult<RobotParams> {
    robot_from(&Block::new(robot, "robot")?)
}

/// A URDF arm block on its own (`urdf_terms`, `urdf_info`).
pub(super) fn urdf_params(robot: &Bound<'_, PyAny>) -> PyResult<UrdfArmParams> {
    urdf_arm_from(&Block::new(robot, "robot")?)
}

/// An admittance filter block on its own (`filter_discretize`, `filter_response`).
pub(super) fn admittance_params(params: &Bound<'_, PyAny>) -> PyResult<AdmittanceParams> {
    admittance_params_from(&Block::new(params, "admittance")?)
}
