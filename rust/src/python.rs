//! The pyo3 layer: converts plain Python dicts (made by `admit_rs.config`) into core
//! structs, releases the GIL for the numerics and hands columns back as NumPy arrays.
//! No numerics here.

use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::import_exception;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::controller::{
    ComputedTorqueParams, ControllerParams, ModelError, ModelFreeParams, PositionGains, TdcLaw,
    TimeDelayParams,
};
use crate::environment::WallParams;
use crate::error::Error;
use crate::filter::{AdmittanceFilter, AdmittanceParams, ForceControlParams, ImpedanceParams};
use crate::metrics::METRIC_NAMES;
use crate::reference::Signal;
use crate::robot::{MassModel, RobotModel, RobotParams, ThreeLinkArm, Vec3};
use crate::simulation::{Outcome, RunResult, ScenarioConfig, MAX_SUBSTEPS, TRACE_COLUMNS};

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
        position: b.opt_f64("position")?,
        position_error: b.f64("position_error")?,
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
            inertia: b.f64("inertia")?,
            torque_constant: b.f64("torque_constant")?,
        }),
        _ => ControllerParams::TimeDelay(TimeDelayParams {
            gains: gains_from(b)?,
            inertia: b.f64("inertia")?,
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
    let config = ScenarioConfig {
        robot: robot_from(&b.sub("robot")?)?,
        wall: b.optional_sub("wall")?.map(|w| wall_from(&w)).transpose()?,
        controller: controller_from(&b.sub("controller")?)?,
        admittance: b
            .optional_sub("admittance")?
            .map(|a| force_control_from(&a))
            .transpose()?,
        force_reference: signal_from(&b.sub("force_reference")?)?,
        z_reference: signal_from(&b.sub("z_reference")?)?,
        period: b.f64("period")?,
        substeps: substeps as usize,
        duration: b.f64("duration")?,
        velocity_limit: b.f64("velocity_limit")?,
    };
    config.validate().map_err(|e| to_py_err(obj.py(), e))?;
    Ok(config)
}

/// Validates one building block on its own, so a dataclass can fail at construction.
#[pyfunction]
fn check_block(kind: &str, params: &Bound<'_, PyAny>) -> PyResult<()> {
    let py = params.py();
    let b = Block::new(params, "")?;
    let checked = match kind {
        "robot" => robot_from(&b)?.validate(),
        "wall" => wall_from(&b)?.validate(),
        "controller" => controller_from(&b)?.validate(),
        "admittance" => force_control_from(&b)?.validate(),
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
    let metrics = PyDict::new(py);
    for (name, v) in METRIC_NAMES.iter().zip(run.metrics.values()) {
        metrics.set_item(name, v)?;
    }
    metrics.set_item("stable", run.metrics.stable)?;
    out.set_item("metrics", metrics)?;
    match run.outcome {
        Outcome::Completed => {
            out.set_item("diverged_at", py.None())?;
            out.set_item("divergence_cause", py.None())?;
        }
        Outcome::Diverged { time, cause } => {
            out.set_item("diverged_at", time)?;
            out.set_item("divergence_cause", cause.to_string())?;
        }
    }
    Ok(out)
}

/// Runs one scenario; the whole run happens in Rust with the GIL released.
#[pyfunction]
fn simulate<'py>(scenario: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
    let py = scenario.py();
    let config = scenario_from(scenario)?;
    let run = py.detach(move || crate::simulation::simulate(&config));
    run_to_dict(py, run.map_err(|e| to_py_err(py, e))?)
}

fn trace_dict<'py>(
    py: Python<'py>,
    trace: crate::simulation::Trace,
) -> PyResult<Bound<'py, PyDict>> {
    let columns = PyDict::new(py);
    for (name, col) in TRACE_COLUMNS.iter().zip(trace.columns) {
        columns.set_item(name, PyArray1::from_vec(py, col))?;
    }
    Ok(columns)
}

/// Runs a batch of scenario dicts on `threads` threads (None: all cores) with the GIL
/// released. Returns metric columns (one entry per run, in order), `stable`,
/// `diverged_at` (NaN when stable), `divergence_cause` and, with `traces`, one column
/// dict per run. An invalid scenario raises before anything runs, naming its index.
#[pyfunction]
#[pyo3(signature = (scenarios, threads=None, traces=false))]
fn simulate_batch<'py>(
    scenarios: &Bound<'py, PyList>,
    threads: Option<usize>,
    traces: bool,
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
        .detach(move || crate::sweep::run_batch(&configs, threads, traces))
        .map_err(|e| to_py_err(py, e.error))?;
    let out = PyDict::new(py);
    let n = runs.len();
    let mut columns: Vec<Vec<f64>> = vec![Vec::with_capacity(n); METRIC_NAMES.len()];
    let mut stable = Vec::with_capacity(n);
    let mut diverged_at = Vec::with_capacity(n);
    let causes = PyList::empty(py);
    let trace_list = PyList::empty(py);
    for run in runs {
        for (c, v) in columns.iter_mut().zip(run.metrics.values()) {
            c.push(v);
        }
        stable.push(run.metrics.stable);
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

fn matrix<'py>(py: Python<'py>, m: &crate::robot::Mat3) -> PyResult<Bound<'py, PyArray2<f64>>> {
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
    let qdd = arm.forward_dynamics(
        &state3(q, "q")?,
        &state3(qd, "qd")?,
        &state3(tau, "tau")?,
        &state3(tip_force, "tip_force")?,
    );
    Ok(vector(robot.py(), &qdd))
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

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // rust-numpy loads NumPy's C API on first use and panics if the Python code that runs
    // then raises, as a Ctrl-C pending at that moment does. Load it at import instead of in
    // the first simulation, after raising any pending interrupt as an ordinary exception.
    py.check_signals()?;
    PyArray1::<f64>::zeros(py, 0, false);
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("TRACE_COLUMNS", PyList::new(py, TRACE_COLUMNS)?)?;
    m.add("METRIC_NAMES", PyList::new(py, METRIC_NAMES)?)?;
    m.add_function(wrap_pyfunction!(check_block, m)?)?;
    m.add_function(wrap_pyfunction!(validate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_batch, m)?)?;
    m.add_function(wrap_pyfunction!(robot_terms, m)?)?;
    m.add_function(wrap_pyfunction!(forward_dynamics, m)?)?;
    m.add_function(wrap_pyfunction!(filter_discretize, m)?)?;
    m.add_function(wrap_pyfunction!(filter_response, m)?)?;
    Ok(())
}
