//! The pyo3 layer: converts plain Python dicts (made by `admit_rs.config`) into core
//! structs, releases the GIL for the numerics and hands columns back as NumPy arrays.
//! No numerics here.

use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::import_exception;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::control::filter::{
    AdmittanceFilter, AdmittanceParams, ForceControlParams, ImpedanceParams,
};
use crate::control::params::{
    ComputedTorqueParams, ControllerParams, ModelError, ModelFreeParams, PerJoint, PositionGains,
    TdcLaw, TimeDelayParams,
};
use crate::control::reference::Signal;
use crate::error::Error;
use crate::robot::chain::arm::{chain_info, chain_terms};
use crate::robot::chain::urdf::MAX_JOINTS;
use crate::robot::chain::{TaskKind, UrdfArmParams};
use crate::robot::three_link::{Mat3, Vec3};
use crate::robot::{MassModel, RobotModel, RobotParams, ThreeLinkArm};
use crate::sim::dispatch::AnySimulation;
use crate::sim::metrics::{Metrics, METRIC_NAMES};
use crate::sim::scenario::RobotConfig;
use crate::sim::simulation::{Outcome, RunResult, ScenarioConfig, MAX_SUBSTEPS};
use crate::sim::trace::{trace_columns, Trace};
use crate::world::actuator::ActuatorParams;
use crate::world::environment::{ContactModel, WallParams};
use crate::world::sensor::SensorParams;

// The exception classes live in Python (admit_rs/errors.py) so that ParameterError can be
// both a ValueError and an admit_rs.AdmitError, which create_exception! cannot express.
import_exception!(admit_rs.errors, ParameterError);

fn parameter_error(py: Python<'_>, field: &str, value: &str, allowed: &str) -> PyErr {
    let err = ParameterError::new_err(format!("{field} = {value} is invalid: must be {allowed}"));
    let obj = err.value(py);
    // Attributes for programmatic use; failing to set them must not hide the error itself.
    let _ = obj.setattr("field", field);
    let _ = obj.setattr("value", value);
    let _ = obj.setattr("allowed", allowed);
    err
}

fn to_py_err(py: Python<'_>, e: Error) -> PyErr {
    match e {
        Error::Parameter {
            field,
            value,
            allowed,
        } => parameter_error(py, &field, &value, &allowed),
    }
}

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

fn scenario_from(obj: &Bound<'_, PyAny>) -> PyResult<ScenarioConfig> {
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

/// Builds a Python dict from (key, value) pairs.
macro_rules! py_dict {
    ($py:expr, { $($key:literal : $value:expr),* $(,)? }) => {{
        let d = PyDict::new($py);
        $(d.set_item($key, $value)?;)*
        d
    }};
}

/// Serde's value as plain Python objects (dicts, lists, floats, strings, None).
fn to_python<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    pythonize::pythonize(py, value).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The core's default parameters, block by block: each block's `Default` serialised by its
/// serde declaration (`schema::defaults`), the one source the Python dataclass defaults are
/// tested against.
#[pyfunction]
fn defaults(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_python(py, &crate::schema::defaults())
}

/// Every block's JSON schema (`schema::schemas`): field names, types, docs and defaults.
#[pyfunction]
fn schema(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_python(py, &crate::schema::schemas())
}

/// Validates one building block on its own, so a dataclass can fail at construction.
#[pyfunction]
fn check_block(kind: &str, params: &Bound<'_, PyAny>) -> PyResult<()> {
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
fn validate(scenario: &Bound<'_, PyAny>) -> PyResult<()> {
    scenario_from(scenario).map(|_| ())
}

fn run_to_dict<'py>(py: Python<'py>, run: RunResult) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("columns", trace_dict(py, run.trace)?)?;
    outcome_into(py, &out, run.metrics, run.outcome)?;
    Ok(out)
}

/// Puts a run's metrics, `diverged_at` and `divergence_cause` into `out`.
fn outcome_into(
    py: Python<'_>,
    out: &Bound<'_, PyDict>,
    run_metrics: Metrics,
    outcome: Outcome,
) -> PyResult<()> {
    let metrics = PyDict::new(py);
    for (name, v) in METRIC_NAMES.iter().zip(run_metrics.values()) {
        metrics.set_item(name, v)?;
    }
    metrics.set_item("stable", run_metrics.stable)?;
    metrics.set_item("diverged", run_metrics.diverged)?;
    out.set_item("metrics", metrics)?;
    match outcome {
        Outcome::Completed => {
            out.set_item("diverged_at", py.None())?;
            out.set_item("divergence_cause", py.None())?;
        }
        Outcome::Diverged { time, cause } => {
            out.set_item("diverged_at", time)?;
            out.set_item("divergence_cause", cause.to_string())?;
        }
    }
    Ok(())
}

/// Samples stepped between checks for Ctrl-C (about 20 ms of the paper's run).
const STEP_CHUNK: usize = 1000;

/// The loop of one scenario, stepped from Python (`admit_rs.Simulation`).
#[pyclass(module = "admit_rs._core", name = "Stepper")]
struct Stepper {
    sim: AnySimulation,
}

#[pymethods]
impl Stepper {
    #[new]
    fn new(scenario: &Bound<'_, PyAny>) -> PyResult<Self> {
        let config = scenario_from(scenario)?;
        let sim = AnySimulation::new(&config).map_err(|e| to_py_err(scenario.py(), e))?;
        Ok(Self { sim })
    }

    fn reset(&mut self) {
        self.sim.reset();
    }

    /// Takes up to `n` samples with the GIL released, checking for Ctrl-C between chunks.
    /// Returns the number taken.
    fn step(&mut self, py: Python<'_>, n: usize) -> PyResult<usize> {
        let start = self.sim.sample();
        let mut left = n;
        while left > 0 && self.sim.outcome().is_none() {
            let chunk = left.min(STEP_CHUNK);
            let sim = &mut self.sim;
            py.detach(move || sim.step(chunk));
            left -= chunk;
            py.check_signals()?;
        }
        Ok(self.sim.sample() - start)
    }

    fn sample(&self) -> usize {
        self.sim.sample()
    }

    fn samples(&self) -> usize {
        self.sim.samples()
    }

    fn state<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.sim.state())
    }

    fn state_labels(&self) -> Vec<String> {
        self.sim.state_labels()
    }

    fn set_state(&mut self, py: Python<'_>, values: Vec<f64>) -> PyResult<()> {
        self.sim.set_state(&values).map_err(|e| to_py_err(py, e))
    }

    /// The trace so far as a dict of columns (copies).
    fn trace<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        trace_dict(py, self.sim.trace().clone())
    }

    /// `None` while the run goes on; once it is over, the metrics and how it ended.
    fn outcome<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(outcome) = self.sim.outcome() else {
            return Ok(None);
        };
        let sim = &self.sim;
        let metrics = sim.metrics(&outcome);
        let out = PyDict::new(py);
        outcome_into(py, &out, metrics, outcome)?;
        Ok(Some(out))
    }
}

/// Runs one scenario; the whole run happens in Rust with the GIL released.
#[pyfunction]
fn simulate<'py>(scenario: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
    let py = scenario.py();
    let config = scenario_from(scenario)?;
    let run = py.detach(move || crate::sim::simulation::simulate(&config));
    run_to_dict(py, run.map_err(|e| to_py_err(py, e))?)
}

fn trace_dict<'py>(py: Python<'py>, trace: Trace) -> PyResult<Bound<'py, PyDict>> {
    let columns = PyDict::new(py);
    for (name, col) in trace.into_named_columns() {
        columns.set_item(name, PyArray1::from_vec(py, col))?;
    }
    Ok(columns)
}

/// Runs a batch of scenario dicts on `threads` threads (None: all cores) with the GIL
/// released. Returns metric columns (one entry per run, in order), `stable`, `diverged`,
/// `diverged_at` (NaN when stable), `divergence_cause` and, with `traces`, one column
/// dict per run. An invalid scenario raises before anything runs, naming its index.
/// `lanes`: three-link runs advance four at a time in SIMD lanes (within 1e-9 of off).
#[pyfunction]
#[pyo3(signature = (scenarios, threads=None, traces=false, lanes=true))]
fn simulate_batch<'py>(
    scenarios: &Bound<'py, PyList>,
    threads: Option<usize>,
    traces: bool,
    lanes: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let py = scenarios.py();
    let configs = scenarios
        .iter()
        .enumerate()
        .map(|(i, s)| {
            scenario_from(&s).map_err(|e| {
                let msg = format!("scenario {i}: {}", e.value(py));
                if e.is_instance_of::<ParameterError>(py) {
                    let new = ParameterError::new_err(msg);
                    for attr in ["field", "value", "allowed"] {
                        if let Ok(v) = e.value(py).getattr(attr) {
                            let _ = new.value(py).setattr(attr, v);
                        }
                    }
                    let _ = new.value(py).setattr("index", i);
                    new
                } else {
                    PyTypeError::new_err(msg)
                }
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let runs = py
        .detach(move || crate::sim::sweep::run_batch_with(&configs, threads, traces, lanes))
        .map_err(|e| to_py_err(py, e.error))?;
    let out = PyDict::new(py);
    let n = runs.len();
    let mut columns: Vec<Vec<f64>> = vec![Vec::with_capacity(n); METRIC_NAMES.len()];
    let mut stable = Vec::with_capacity(n);
    let mut diverged = Vec::with_capacity(n);
    let mut diverged_at = Vec::with_capacity(n);
    let causes = PyList::empty(py);
    let trace_list = PyList::empty(py);
    for run in runs {
        for (c, v) in columns.iter_mut().zip(run.metrics.values()) {
            c.push(v);
        }
        stable.push(run.metrics.stable);
        diverged.push(run.metrics.diverged);
        match run.outcome {
            Outcome::Completed => {
                diverged_at.push(f64::NAN);
                causes.append(py.None())?;
            }
            Outcome::Diverged { time, cause } => {
                diverged_at.push(time);
                causes.append(cause.to_string())?;
            }
        }
        if let Some(trace) = run.trace {
            trace_list.append(trace_dict(py, trace)?)?;
        }
    }
    let metrics = PyDict::new(py);
    for (name, col) in METRIC_NAMES.iter().zip(columns) {
        metrics.set_item(name, PyArray1::from_vec(py, col))?;
    }
    out.set_item("metrics", metrics)?;
    out.set_item("stable", PyArray1::from_vec(py, stable))?;
    out.set_item("diverged", PyArray1::from_vec(py, diverged))?;
    out.set_item("diverged_at", PyArray1::from_vec(py, diverged_at))?;
    out.set_item("divergence_cause", causes)?;
    out.set_item(
        "traces",
        if traces {
            trace_list.into_any()
        } else {
            py.None().into_bound(py)
        },
    )?;
    Ok(out)
}

fn matrix<'py>(py: Python<'py>, m: &Mat3) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = (0..3)
        .map(|i| (0..3).map(|j| m[(i, j)]).collect())
        .collect();
    PyArray2::from_vec2(py, &rows).map_err(|e| PyValueError::new_err(e.to_string()))
}

fn vector<'py>(py: Python<'py>, v: &Vec3) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v.as_slice())
}

fn checked_robot(robot: &Bound<'_, PyAny>) -> PyResult<ThreeLinkArm> {
    let params = robot_from(&Block::new(robot, "robot")?)?;
    params
        .validate()
        .map_err(|e| to_py_err(robot.py(), e.within("robot")))?;
    Ok(ThreeLinkArm::new(&params))
}

fn state3(v: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec3> {
    let a: [f64; 3] = v
        .extract()
        .map_err(|_| PyTypeError::new_err(format!("{name} must be a sequence of 3 numbers")))?;
    Ok(Vec3::from(a))
}

/// D, C, G, J, J̇q̇, tip position and friction of the arm at (q, q̇).
#[pyfunction]
fn robot_terms<'py>(
    robot: &Bound<'py, PyAny>,
    q: &Bound<'py, PyAny>,
    qd: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let py = robot.py();
    let arm = checked_robot(robot)?;
    let (q, qd) = (state3(q, "q")?, state3(qd, "qd")?);
    let (k, d) = arm.evaluate(&q, &qd);
    let out = PyDict::new(py);
    out.set_item("position", vector(py, &k.position))?;
    out.set_item("jacobian", matrix(py, &k.jacobian)?)?;
    out.set_item("jdot_qd", vector(py, &k.jdot_qd))?;
    out.set_item("inertia", matrix(py, &d.inertia)?)?;
    out.set_item("coriolis", vector(py, &d.coriolis))?;
    out.set_item("gravity", vector(py, &d.gravity))?;
    out.set_item("friction", vector(py, &arm.friction(&qd)))?;
    Ok(out)
}

/// q̈ of eq. (1) for joint torques `tau` and a Cartesian force `tip_force` on the tip.
#[pyfunction]
fn forward_dynamics<'py>(
    robot: &Bound<'py, PyAny>,
    q: &Bound<'py, PyAny>,
    qd: &Bound<'py, PyAny>,
    tau: &Bound<'py, PyAny>,
    tip_force: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let arm = checked_robot(robot)?;
    let qdd = arm.forward_dynamics_at(
        &state3(q, "q")?,
        &state3(qd, "qd")?,
        &state3(tau, "tau")?,
        &state3(tip_force, "tip_force")?,
    );
    Ok(vector(robot.py(), &qdd))
}

fn urdf_params(robot: &Bound<'_, PyAny>) -> PyResult<UrdfArmParams> {
    urdf_arm_from(&Block::new(robot, "robot")?)
}

fn rows<'py>(py: Python<'py>, flat: &[f64], cols: usize) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = flat.chunks(cols).map(<[f64]>::to_vec).collect();
    PyArray2::from_vec2(py, &rows).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// A URDF arm's D, C q̇, G, J (6×n), J̇q̇ (6), tip position and rotation, friction at (q, q̇);
/// with `tau` also q̈ (ABA) for that torque and the world force `tip_force` on the tip.
#[pyfunction]
#[pyo3(signature = (robot, q, qd, tau=None, tip_force=[0.0; 3]))]
fn urdf_terms<'py>(
    robot: &Bound<'py, PyAny>,
    q: Vec<f64>,
    qd: Vec<f64>,
    tau: Option<Vec<f64>>,
    tip_force: [f64; 3],
) -> PyResult<Bound<'py, PyDict>> {
    let py = robot.py();
    let p = urdf_params(robot)?;
    let forward = tau.as_deref().map(|t| (t, tip_force));
    let t = py
        .detach(|| chain_terms(&p, &q, &qd, forward))
        .map_err(|e| to_py_err(py, e.within("robot")))?;
    let n = t.joints;
    let out = PyDict::new(py);
    out.set_item("inertia", rows(py, &t.inertia, n)?)?;
    out.set_item("coriolis", PyArray1::from_vec(py, t.coriolis))?;
    out.set_item("gravity", PyArray1::from_vec(py, t.gravity))?;
    out.set_item("jacobian", rows(py, &t.jacobian, n)?)?;
    out.set_item("jdot_qd", PyArray1::from_vec(py, t.jdot_qd))?;
    out.set_item("position", PyArray1::from_vec(py, t.position))?;
    out.set_item("rotation", rows(py, &t.rotation, 3)?)?;
    out.set_item("friction", PyArray1::from_vec(py, t.friction))?;
    if let Some(a) = t.acceleration {
        out.set_item("acceleration", PyArray1::from_vec(py, a))?;
    }
    Ok(out)
}

/// A URDF arm's joint names, position and effort limits, default q0 and task.
#[pyfunction]
fn urdf_info<'py>(robot: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
    let py = robot.py();
    let p = urdf_params(robot)?;
    let i = chain_info(&p).map_err(|e| to_py_err(py, e.within("robot")))?;
    Ok(py_dict!(py, {
        "joint_names": i.joint_names,
        "lower": i.lower,
        "upper": i.upper,
        "effort": i.effort,
        "q0": i.q0,
        "task": match i.task { TaskKind::Position => "position", TaskKind::Pose => "pose" },
    }))
}

fn checked_admittance(params: &Bound<'_, PyAny>, period: f64) -> PyResult<AdmittanceParams> {
    let py = params.py();
    let p = admittance_params_from(&Block::new(params, "admittance")?)?;
    p.validate().map_err(|e| to_py_err(py, e))?;
    crate::error::check::positive("period", period).map_err(|e| to_py_err(py, e))?;
    Ok(p)
}

type ZohPair<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

/// The exact ZOH matrices (Ad, Bd) of an admittance filter for period T.
#[pyfunction]
fn filter_discretize<'py>(params: &Bound<'py, PyAny>, period: f64) -> PyResult<ZohPair<'py>> {
    let py = params.py();
    let (ad, bd) = checked_admittance(params, period)?.discretize(period);
    let rows = vec![vec![ad[(0, 0)], ad[(0, 1)]], vec![ad[(1, 0)], ad[(1, 1)]]];
    let ad = PyArray2::from_vec2(py, &rows).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok((ad, PyArray1::from_slice(py, bd.as_slice())))
}

/// Runs the discrete filter on a force-error sequence: returns (x_a, ẋ_a, ẍ_a) per sample.
#[pyfunction]
fn filter_response<'py>(
    params: &Bound<'py, PyAny>,
    period: f64,
    force_error: Vec<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let py = params.py();
    let mut filter = AdmittanceFilter::new(checked_admittance(params, period)?, period);
    let n = force_error.len();
    let (mut xa, mut xa_dot, mut xa_ddot) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    for e in force_error {
        let s = filter.step(e);
        xa.push(s.value);
        xa_dot.push(s.rate);
        xa_ddot.push(s.accel);
    }
    let out = PyDict::new(py);
    out.set_item("x_a", PyArray1::from_vec(py, xa))?;
    out.set_item("xa_dot", PyArray1::from_vec(py, xa_dot))?;
    out.set_item("xa_ddot", PyArray1::from_vec(py, xa_ddot))?;
    Ok(out)
}

// ---- Analysis (SPEC §12) ----

import_exception!(admit_rs.errors, AnalysisError);

fn analysis_err(py: Python<'_>, e: crate::analysis::AnalysisError) -> PyErr {
    match e {
        crate::analysis::AnalysisError::Parameter(p) => to_py_err(py, p),
        other => AnalysisError::new_err(other.to_string()),
    }
}

fn dmatrix<'py>(
    py: Python<'py>,
    m: &nalgebra::DMatrix<f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
        .collect();
    if rows.is_empty() {
        return Ok(PyArray2::zeros(py, [0, m.ncols()], false));
    }
    PyArray2::from_vec2(py, &rows).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The one-period closed loop linearised about its equilibrium (or the state at `at`).
#[pyfunction]
#[pyo3(signature = (scenario, at=None))]
fn linearize<'py>(scenario: &Bound<'py, PyAny>, at: Option<f64>) -> PyResult<Bound<'py, PyDict>> {
    let py = scenario.py();
    let config = scenario_from(scenario)?;
    let lin = py
        .detach(move || crate::analysis::linearize_scenario(&config, at))
        .map_err(|e| analysis_err(py, e))?;
    let b = nalgebra::DMatrix::from_column_slice(lin.b.len(), 1, lin.b.as_slice());
    let d = nalgebra::DMatrix::from_column_slice(lin.d.len(), 1, lin.d.as_slice());
    Ok(py_dict!(py, {
        "a": dmatrix(py, &lin.a)?,
        "b": dmatrix(py, &b)?,
        "c": dmatrix(py, &lin.c)?,
        "d": dmatrix(py, &d)?,
        "labels": lin.labels,
        "state": PyArray1::from_vec(py, lin.state),
        "force_desired": lin.force_desired,
        "outputs": lin.outputs.to_vec(),
        "reference_normal": lin.reference_normal,
        "penetration": lin.penetration,
        "period": lin.period,
        "equilibrium": lin.equilibrium,
        "iterations": lin.iterations,
        "caveats": lin.caveats,
    }))
}

/// `predict` for many scenarios on all cores with the GIL released. Returns one column
/// per prediction field (`stable` as bool) and `error` (None, or why a cell has no
/// prediction).
#[pyfunction]
#[pyo3(signature = (scenarios, threads=None))]
fn predict_batch<'py>(
    scenarios: &Bound<'py, PyList>,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let py = scenarios.py();
    let configs = scenarios
        .iter()
        .map(|s| scenario_from(&s))
        .collect::<PyResult<Vec<_>>>()?;
    let results = py.detach(move || crate::analysis::predict_scenarios(&configs, threads));
    let names = crate::analysis::PREDICTION_NAMES;
    let mut columns: Vec<Vec<f64>> = vec![Vec::with_capacity(results.len()); names.len()];
    let errors = PyList::empty(py);
    for r in results {
        let (p, err) = match r {
            Ok(p) => (p, None),
            Err(e) => (crate::analysis::Prediction::missing(), Some(e.to_string())),
        };
        for (c, v) in columns.iter_mut().zip(p.values()) {
            c.push(v);
        }
        errors.append(err)?;
    }
    let out = PyDict::new(py);
    for (name, col) in names.iter().zip(columns) {
        if *name == "stable" {
            let b: Vec<bool> = col.iter().map(|v| *v == 1.0).collect();
            out.set_item(name, PyArray1::from_vec(py, b))?;
        } else {
            out.set_item(name, PyArray1::from_vec(py, col))?;
        }
    }
    out.set_item("error", errors)?;
    Ok(out)
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // rust-numpy loads NumPy's C API on first use and panics if the Python code that runs
    // then raises, as a Ctrl-C pending at that moment does. Load it at import instead of in
    // the first simulation, after raising any pending interrupt as an ordinary exception.
    py.check_signals()?;
    PyArray1::<f64>::zeros(py, 0, false);
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("TRACE_COLUMNS", PyList::new(py, trace_columns(3))?)?;
    m.add("METRIC_NAMES", PyList::new(py, METRIC_NAMES)?)?;
    m.add(
        "PREDICTION_NAMES",
        PyList::new(py, crate::analysis::PREDICTION_NAMES)?,
    )?;
    m.add_class::<Stepper>()?;
    m.add_function(wrap_pyfunction!(defaults, m)?)?;
    m.add_function(wrap_pyfunction!(schema, m)?)?;
    m.add_function(wrap_pyfunction!(check_block, m)?)?;
    m.add_function(wrap_pyfunction!(validate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_batch, m)?)?;
    m.add_function(wrap_pyfunction!(robot_terms, m)?)?;
    m.add_function(wrap_pyfunction!(forward_dynamics, m)?)?;
    m.add_function(wrap_pyfunction!(urdf_terms, m)?)?;
    m.add_function(wrap_pyfunction!(urdf_info, m)?)?;
    m.add_function(wrap_pyfunction!(filter_discretize, m)?)?;
    m.add_function(wrap_pyfunction!(filter_response, m)?)?;
    m.add_function(wrap_pyfunction!(linearize, m)?)?;
    m.add_function(wrap_pyfunction!(predict_batch, m)?)?;
    Ok(())
}
