//! Parameter blocks in and out, by their serde declaration (`crate::schema`): pythonize's
//! `Depythonizer` walks the dicts made by `admit_rs.config` straight into the core's
//! structs, `serde_path_to_error` records where a value failed, and the failure becomes the
//! exception the Python API promises — `ParameterError` (a `ValueError`: field, value,
//! allowed range), `UnknownParameterError` (a `TypeError` naming the closest valid keys,
//! through `admit_rs.errors.unknown`) or a `TypeError` naming the field and what it must be.
//! Ranges are checked by the structs' own `validate()`, after decoding.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use serde::de::DeserializeOwned;

use super::errors::{parameter_error, to_py_err, ParameterTypeError};
use crate::control::filter::{AdmittanceParams, ForceControlParams};
use crate::control::params::ControllerParams;
use crate::control::reference::Signal;
use crate::robot::chain::urdf::MAX_JOINTS;
use crate::robot::chain::UrdfArmParams;
use crate::robot::RobotParams;
use crate::schema::parse_parameter_message;
use crate::sim::scenario::RobotConfig;
use crate::sim::simulation::ScenarioConfig;
use crate::world::actuator::ActuatorParams;
use crate::world::sensor::SensorParams;
use crate::world::surface::SurfaceParams;

fn join(prefix: &str, field: &str) -> String {
    match (prefix.is_empty(), field.is_empty()) {
        (true, _) => field.to_owned(),
        (_, true) => prefix.to_owned(),
        _ => format!("{prefix}.{field}"),
    }
}

/// The names between backticks in a serde message (`unknown field `x`, expected `a` or `b``).
fn quoted(msg: &str) -> Vec<String> {
    msg.split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_owned)
        .collect()
}

/// What a serde "expected …" names, in the words of the Python API.
fn expected(what: &str) -> String {
    let what = what.trim();
    match what {
        "f64" => "a number".to_owned(),
        "a boolean" => "a bool".to_owned(),
        "a string" => "a str".to_owned(),
        "u64" | "usize" => "an integer".to_owned(),
        w if w.starts_with("an array of length") || w.starts_with("a tuple of size") => {
            format!(
                "a sequence of {} numbers",
                w.rsplit(' ').next().unwrap_or("?")
            )
        }
        w if w.starts_with("data did not match any variant") => {
            "a number or a sequence of numbers of the right shape".to_owned()
        }
        w => w.to_owned(),
    }
}

/// serde's "floating point `1000…0.0`" (every digit of 1e300) as "floating point `1e300`".
fn short_floats(got: &str) -> String {
    got.strip_prefix("floating point `")
        .and_then(|r| r.strip_suffix('`'))
        .and_then(|v| v.parse::<f64>().ok())
        .map_or_else(
            || got.to_owned(),
            |v| format!("floating point `{}`", crate::error::short(v)),
        )
}

/// The Python exception for a block that failed to decode at `path` (dotted, may be empty).
fn decode_error(
    py: Python<'_>,
    path: &str,
    e: serde_path_to_error::Error<pythonize::PythonizeError>,
) -> PyErr {
    let inner = e.path().to_string();
    let at = if inner == "." { String::new() } else { inner };
    let field = join(path, &at);
    let msg = e.inner().to_string();
    // A range or shape error raised while decoding (whole numbers, D̄): "field = v is
    // invalid: must be …", its field relative to where it was raised.
    if let Some((f, value, allowed)) = parse_parameter_message(&msg) {
        return parameter_error(py, &join(&field, &f), &value, &allowed);
    }
    if let Some(rest) = msg.strip_prefix("unknown variant ") {
        let names = quoted(rest);
        if let Some((value, allowed)) = names.split_first() {
            let list = allowed
                .iter()
                .map(|a| format!("'{a}'"))
                .collect::<Vec<_>>()
                .join(", ");
            // Inside a tagged block serde loses the path below the block: the variants
            // name the field.
            let name = allowed
                .first()
                .map_or("kind", |f| crate::schema::enum_field(f));
            let key = if field.rsplit('.').next() == Some(name) {
                field.clone()
            } else {
                join(&field, name)
            };
            return parameter_error(py, &key, &format!("'{value}'"), &format!("one of {list}"));
        }
    }
    if let Some(rest) = msg.strip_prefix("unknown field ") {
        let names = quoted(rest);
        if let Some((key, valid)) = names.split_first() {
            let parent = field
                .strip_suffix(key.as_str())
                .map_or(field.as_str(), |p| p.trim_end_matches('.'));
            let parent = if parent.is_empty() {
                "scenario"
            } else {
                parent
            };
            let message = format!("{parent}: unknown key '{key}'");
            // Below a flattened or tagged block serde lists no valid keys: offer every
            // field name of the blocks.
            let valid = if valid.is_empty() {
                every_field_name()
            } else {
                valid.to_vec()
            };
            return unknown_key(py, &message, key, &valid);
        }
    }
    let shown = if field.is_empty() { "scenario" } else { &field };
    // pyo3's own extraction message, passed on by pythonize ("must be real number, not str").
    if let Some((_, got)) = msg.split_once("must be real number, not ") {
        return ParameterTypeError::new_err(format!("{shown} must be a number, got {got}"));
    }
    if let Some(rest) = msg.strip_prefix("invalid type: ") {
        if let Some((got, want)) = rest.rsplit_once(", expected ") {
            let got = match got {
                "unit value" => "None".to_owned(),
                g if g.starts_with("boolean") => "a bool".to_owned(),
                g => short_floats(g),
            };
            return ParameterTypeError::new_err(format!(
                "{shown} must be {}, got {got}",
                expected(want)
            ));
        }
    }
    if let Some(rest) = msg.strip_prefix("invalid length ") {
        return ParameterTypeError::new_err(format!("{shown}: wrong number of elements ({rest})"));
    }
    if let Some(rest) = msg.strip_prefix("missing field ") {
        return ParameterTypeError::new_err(format!(
            "missing field {}",
            join(&field, rest.trim_matches('`'))
        ));
    }
    ParameterTypeError::new_err(format!("{shown}: {}", expected(&msg)))
}

/// Every field name of every block (the schema's properties), sorted.
fn every_field_name() -> Vec<String> {
    let schemas = crate::schema::schemas();
    let mut names: Vec<String> = schemas
        .as_object()
        .into_iter()
        .flat_map(|m| m.values())
        .filter_map(|s| s.get("properties").and_then(|p| p.as_object()))
        .flat_map(|p| p.keys().cloned())
        .collect();
    names.sort();
    names.dedup();
    names
}

/// `admit_rs.errors.unknown`: the one did-you-mean helper, so the suggestion is the same
/// as for a keyword or a dotted path.
fn unknown_key(py: Python<'_>, message: &str, key: &str, valid: &[String]) -> PyErr {
    let made = py
        .import("admit_rs.errors")
        .and_then(|m| m.getattr("unknown"))
        .and_then(|f| f.call1((message, key, valid.to_vec())));
    match made {
        Ok(err) => PyErr::from_value(err),
        Err(e) => e,
    }
}

/// One block (or the whole scenario) by its serde declaration; `path` is its place in the
/// scenario, for the messages.
fn decode<T: DeserializeOwned>(obj: &Bound<'_, PyAny>, path: &str) -> PyResult<T> {
    let mut de = pythonize::Depythonizer::from_object(obj);
    serde_path_to_error::deserialize(&mut de).map_err(|e| decode_error(obj.py(), path, e))
}

/// A surface block by its `kind`, decoded as its own struct so that an error names the
/// field inside it (below serde's tagged enum the path stops at the block).
fn decode_surface(obj: &Bound<'_, PyAny>, path: &str) -> PyResult<SurfaceParams> {
    use pyo3::types::PyDict;
    let Ok(dict) = obj.cast::<PyDict>() else {
        return decode(obj, path);
    };
    let kind: String = match dict.get_item("kind")? {
        Some(k) => match k.extract() {
            Ok(k) => k,
            Err(_) => return decode(obj, path),
        },
        None => "plane".to_owned(),
    };
    let body = dict.copy()?;
    if body.contains("kind")? {
        body.del_item("kind")?;
    }
    Ok(match kind.as_str() {
        "plane" => SurfaceParams::Plane(decode(&body, path)?),
        "sphere" => SurfaceParams::Sphere(decode(&body, path)?),
        "cylinder" => SurfaceParams::Cylinder(decode(&body, path)?),
        "height_field" => SurfaceParams::HeightField(decode(&body, path)?),
        _ => return decode(obj, path),
    })
}

/// A whole scenario dict, decoded and validated (cross-field checks included).
pub(super) fn scenario_from(obj: &Bound<'_, PyAny>) -> PyResult<ScenarioConfig> {
    // The surfaces first, by kind: their errors then name the field inside them.
    if let Ok(dict) = obj.cast::<pyo3::types::PyDict>() {
        for key in ["wall", "wall_estimate"] {
            if let Some(block) = dict.get_item(key)? {
                if !block.is_none() {
                    decode_surface(&block, key)?;
                }
            }
        }
    }
    let config: ScenarioConfig = decode(obj, "")?;
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

/// The block registry (`schema::registry`): each family's name, Python type, Rust schema
/// name and kinds (key, class, tag, core tag).
#[pyfunction]
pub(super) fn registry(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_python(py, &crate::schema::registry::registry())
}

/// Validates one building block of `family` (a registry family) on its own, so a block
/// can fail at construction.
#[pyfunction]
pub(super) fn check_block(family: &str, params: &Bound<'_, PyAny>) -> PyResult<()> {
    let py = params.py();
    let checked = match family {
        "robot" => decode::<RobotConfig>(params, "")?.validate().map(|_| ()),
        "surface" => decode_surface(params, "")?.validate(),
        "controller" => decode::<ControllerParams>(params, "")?.validate(),
        // The discretisation is checked with the scenario's period, in `validate`.
        "force_control" => match decode::<ForceControlParams>(params, "")? {
            ForceControlParams::Admittance(p) => p.validate(),
            ForceControlParams::Impedance(p) => p.validate(),
        },
        "sensor" => decode::<SensorParams>(params, "")?.validate(),
        // On its own an actuator may serve any arm: one limit, or one per joint of a 1- to
        // 8-joint arm; the scenario checks the count against its arm.
        "actuator" => {
            let a = decode::<ActuatorParams>(params, "")?;
            let n = a.torque_limit.as_ref().map_or(1, Vec::len);
            a.validate(if (1..=MAX_JOINTS).contains(&n) { n } else { 3 })
        }
        "signal" => decode::<Signal>(params, "")?.validate(),
        "model" => decode::<crate::control::params::ModelError>(params, "")?.validate(),
        "criteria" => decode::<crate::sim::criteria::CriteriaParams>(params, "")?.validate(),
        "approach" => decode::<crate::control::approach::ApproachParams>(params, "")?.validate(),
        other => {
            return Err(PyValueError::new_err(format!(
                "unknown block family '{other}'"
            )))
        }
    };
    checked.map_err(|e| to_py_err(py, e))
}

/// (n, t̂) of a surface block: the inward normal at the surface's point nearest the tip's
/// start, and the motion direction for it (SPEC §10, §15) — the task frame the controller
/// builds when this surface is its belief.
#[pyfunction]
pub(super) fn surface_directions(params: &Bound<'_, PyAny>) -> PyResult<([f64; 3], [f64; 3])> {
    let py = params.py();
    let p = decode::<SurfaceParams>(params, "")?;
    p.validate().map_err(|e| to_py_err(py, e))?;
    let start = crate::robot::TaskVector::zeros();
    let env = crate::world::surface::Environment::new(&p, &start).map_err(|e| to_py_err(py, e))?;
    let n = env.normal();
    let t = crate::control::task::motion_direction(&n);
    Ok((n.into(), t.into()))
}

/// Validates a whole scenario dict (cross-field checks included).
#[pyfunction]
pub(super) fn validate(scenario: &Bound<'_, PyAny>) -> PyResult<()> {
    scenario_from(scenario).map(|_| ())
}

/// A three-link arm block on its own (`robot_terms`, `forward_dynamics`).
pub(super) fn robot_params(robot: &Bound<'_, PyAny>) -> PyResult<RobotParams> {
    match decode::<RobotConfig>(robot, "robot")? {
        RobotConfig::ThreeLink(p) => Ok(p),
        RobotConfig::Urdf(_) => Err(ParameterTypeError::new_err(
            "robot: expected the three-link arm (kind 'three_link'), got kind 'urdf'",
        )),
    }
}

/// A URDF arm block on its own (`urdf_terms`, `urdf_info`).
pub(super) fn urdf_params(robot: &Bound<'_, PyAny>) -> PyResult<UrdfArmParams> {
    match decode::<RobotConfig>(robot, "robot")? {
        RobotConfig::Urdf(p) => Ok(p),
        RobotConfig::ThreeLink(_) => Err(ParameterTypeError::new_err(
            "robot: expected a URDF arm (kind 'urdf'), got kind 'three_link'",
        )),
    }
}

/// An admittance filter block on its own (`filter_discretize`, `filter_response`).
pub(super) fn admittance_params(params: &Bound<'_, PyAny>) -> PyResult<AdmittanceParams> {
    match decode::<ForceControlParams>(params, "admittance")? {
        ForceControlParams::Admittance(p) => Ok(p),
        ForceControlParams::Impedance(_) => Err(ParameterTypeError::new_err(
            "admittance: expected an admittance filter (kind 'admittance'), got 'impedance'",
        )),
    }
}
