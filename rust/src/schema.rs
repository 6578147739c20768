//! The parameter blocks' one declaration, as data: each block is a serde struct (defaults
//! from its `Default`, unknown keys refused, enum tags spelled as the Python API spells them)
//! whose JSON schema carries the field docs. This module holds the few serde helpers the
//! blocks need (one number or many, whole numbers given as integral floats, the constant
//! inertia D̄ as one field) and the two tables the Python blocks are checked against:
//! [`schemas`] (fields, types, docs) and [`defaults`] (every block's `Default`, serialised).
//! Nothing here knows Python.

use schemars::{JsonSchema, Schema};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use serde_json::{Map, Value};

use crate::control::filter::{AdmittanceParams, ImpedanceParams};
use crate::control::params::{
    ComputedTorqueParams, ModelError, ModelFreeParams, PerJoint, PositionGains, TdcLaw,
    TimeDelayParams, MAX_JOINTS,
};
use crate::control::reference::Signal;
use crate::error::Error;
use crate::robot::chain::UrdfArmParams;
use crate::robot::RobotParams;
use crate::sim::scenario::ScenarioConfig;
use crate::world::actuator::ActuatorParams;
use crate::world::environment::WallParams;
use crate::world::sensor::SensorParams;

/// One number for every joint, or one per joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum Numbers {
    One(f64),
    Many(Vec<f64>),
}

impl From<Numbers> for Vec<f64> {
    fn from(n: Numbers) -> Self {
        match n {
            Numbers::One(x) => vec![x],
            Numbers::Many(v) => v,
        }
    }
}

impl From<&[f64]> for Numbers {
    fn from(v: &[f64]) -> Self {
        match v {
            [one] => Numbers::One(*one),
            many => Numbers::Many(many.to_vec()),
        }
    }
}

/// `#[serde(with)]` for a `Vec<f64>` given as one number or a list (one is written as a number).
pub mod numbers {
    use super::*;

    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        Numbers::from(v).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        Numbers::deserialize(d).map(Vec::from)
    }
}

/// `#[serde(with)]` for an `Option<Vec<f64>>` given as None, one number or a list.
pub mod optional_numbers {
    use super::*;

    pub fn serialize<S: Serializer>(v: &Option<Vec<f64>>, s: S) -> Result<S::Ok, S::Error> {
        v.as_deref().map(Numbers::from).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Vec<f64>>, D::Error> {
        Option::<Numbers>::deserialize(d).map(|n| n.map(Vec::from))
    }
}

/// Largest whole number a float holds exactly (2^53).
const MAX_EXACT: f64 = 9_007_199_254_740_992.0;

/// A whole number from `lo` to `hi`, given as an int or an integral float (TOML and NumPy
/// write `2.0`); anything else is a parameter error (see [`parameter_message`]).
fn whole<'de, D, T>(d: D, lo: u64, hi: u64, allowed: &str) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    T: TryFrom<u64>,
{
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Whole {
        Int(u64),
        Float(f64),
    }
    let bad = |shown: String| serde::de::Error::custom(Error::parameter("", shown, allowed));
    let n = match Whole::deserialize(d)? {
        Whole::Int(n) => n,
        Whole::Float(v) if v.fract() == 0.0 && (0.0..=MAX_EXACT).contains(&v) => v as u64,
        Whole::Float(v) => return Err(bad(v.to_string())),
    };
    if n < lo || n > hi {
        return Err(bad(n.to_string()));
    }
    T::try_from(n).map_err(|_| bad(n.to_string()))
}

/// `Scenario.seed`: a whole number from 0 to 2^53 (exact in a float).
pub fn seed<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
    whole(d, 0, MAX_EXACT as u64, "an integer from 0 to 2^53")
}

/// `Scenario.substeps`: a whole number from 1 to `MAX_SUBSTEPS`.
pub fn substeps<'de, D: Deserializer<'de>>(d: D) -> Result<usize, D::Error> {
    let max = crate::sim::scenario::MAX_SUBSTEPS;
    whole(d, 1, max as u64, &format!("an integer from 1 to {max}"))
}

/// `ForceSensor.latency`: a whole number of samples from 0 to `MAX_LATENCY`.
pub fn latency<'de, D: Deserializer<'de>>(d: D) -> Result<usize, D::Error> {
    let max = crate::world::sensor::MAX_LATENCY;
    whole(d, 0, max as u64, &format!("an integer from 0 to {max}"))
}

/// `Actuator.delay`: a whole number of samples from 0 to `MAX_DELAY`.
pub fn delay<'de, D: Deserializer<'de>>(d: D) -> Result<usize, D::Error> {
    let max = crate::world::actuator::MAX_DELAY;
    whole(d, 0, max as u64, &format!("an integer from 0 to {max}"))
}

/// The field an enum of the blocks is held in, named by its first variant: serde's
/// "unknown variant" message names the variants but not the field when the enum sits
/// inside a `kind`-tagged block. Tags themselves are `kind`.
pub fn enum_field(first_variant: &str) -> &'static str {
    match first_variant {
        "rod" => "mass_model",
        "jacobian_transpose" => "law",
        "kelvin_voigt" => "model",
        "position" => "task",
        _ => "kind",
    }
}

/// The text of a parameter error raised inside a deserializer: `Error`'s own display with
/// the field left empty (`" = 2.5 is invalid: must be …"`); the caller puts the dotted path
/// in front. [`parse_parameter_message`] reads it back.
pub fn parameter_message(e: &Error) -> String {
    e.to_string()
}

/// (field, value, allowed) of a message written by `Error`'s display, if it is one.
pub fn parse_parameter_message(msg: &str) -> Option<(String, String, String)> {
    let (field, rest) = msg.split_once(" = ")?;
    let (value, allowed) = rest.rsplit_once(" is invalid: must be ")?;
    Some((field.to_owned(), value.to_owned(), allowed.to_owned()))
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
    fn split(self) -> Result<(f64, Option<PerJoint>), Error> {
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
    fn try_from(b: ModelFreeBlock) -> Result<Self, String> {
        let (inertia, joint_inertia) = b.inertia.split().map_err(|e| parameter_message(&e))?;
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
    fn try_from(b: TimeDelayBlock) -> Result<Self, String> {
        let (inertia, joint_inertia) = b.inertia.split().map_err(|e| parameter_message(&e))?;
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

fn schema_value<T: JsonSchema>() -> Value {
    schemars::schema_for!(T).to_value()
}

/// The variants of a `kind`-tagged enum's schema, by tag.
fn variants(schema: &Schema) -> Map<String, Value> {
    let mut out = Map::new();
    let defs = schema.get("$defs").cloned();
    for v in schema
        .get("oneOf")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
    {
        if let Some(kind) = v.pointer("/properties/kind/const").and_then(Value::as_str) {
            let mut v = v.clone();
            if let (Some(defs), Some(obj)) = (&defs, v.as_object_mut()) {
                obj.insert("$defs".into(), defs.clone());
            }
            out.insert(kind.to_owned(), v);
        }
    }
    out
}

/// Every block's JSON schema (draft 2020-12: properties with `description` from the doc
/// comments, `type`, `default` where the block has a `Default`), keyed as the Python blocks
/// are tagged: `three_link`, `urdf`, `wall`, `sensor`, `actuator`, `model`,
/// `computed_torque`, `model_free`, `time_delay`, `admittance`, `impedance`, `step`, `sine`,
/// `sampled` and `scenario`.
pub fn schemas() -> Value {
    let mut out = Map::new();
    out.insert("three_link".into(), schema_value::<RobotParams>());
    out.insert("urdf".into(), schema_value::<UrdfArmParams>());
    out.insert("wall".into(), schema_value::<WallParams>());
    out.insert("sensor".into(), schema_value::<SensorParams>());
    out.insert("actuator".into(), schema_value::<ActuatorParams>());
    out.insert("model".into(), schema_value::<ModelError>());
    out.insert(
        "computed_torque".into(),
        schema_value::<ComputedTorqueParams>(),
    );
    out.insert("model_free".into(), schema_value::<ModelFreeBlock>());
    out.insert("time_delay".into(), schema_value::<TimeDelayBlock>());
    out.insert("admittance".into(), schema_value::<AdmittanceParams>());
    out.insert("impedance".into(), schema_value::<ImpedanceParams>());
    out.extend(variants(&schemars::schema_for!(Signal)));
    out.insert("scenario".into(), schema_value::<ScenarioConfig>());
    Value::Object(out)
}

fn to_value<T: Serialize>(v: &T) -> Value {
    // Every block serialises to JSON (plain numbers, strings, lists and maps).
    serde_json::to_value(v).unwrap_or(Value::Null)
}

/// Every block's `Default`, serialised as the blocks cross to Python (keys as in
/// [`schemas`]; blocks without a `Default` — impedance, the signals — are absent).
pub fn defaults() -> Value {
    let mut out = Map::new();
    out.insert("three_link".into(), to_value(&RobotParams::default()));
    out.insert("urdf".into(), to_value(&UrdfArmParams::default()));
    out.insert("wall".into(), to_value(&WallParams::default()));
    out.insert("sensor".into(), to_value(&SensorParams::default()));
    out.insert("actuator".into(), to_value(&ActuatorParams::default()));
    out.insert("model".into(), to_value(&ModelError::default()));
    out.insert(
        "computed_torque".into(),
        to_value(&ComputedTorqueParams::default()),
    );
    out.insert("model_free".into(), to_value(&ModelFreeParams::default()));
    out.insert("time_delay".into(), to_value(&TimeDelayParams::default()));
    out.insert("admittance".into(), to_value(&AdmittanceParams::default()));
    out.insert("scenario".into(), to_value(&ScenarioConfig::default()));
    Value::Object(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::params::ControllerParams;

    #[test]
    fn every_default_round_trips() {
        let sc = ScenarioConfig::default();
        let back: ScenarioConfig = serde_json::from_value(to_value(&sc)).expect("round trip");
        assert_eq!(back, sc);
    }

    #[test]
    fn inertia_is_one_field() {
        let v = serde_json::json!({"kind": "time_delay", "command_divisor": 5.0, "kd": 20.0,
            "kp": 100.0, "scale_feedforward": true, "inertia": [[2.0, 0.0], [0.0, 1.0]]});
        let c: ControllerParams = serde_json::from_value(v).expect("tdc");
        let ControllerParams::TimeDelay(p) = c else {
            panic!("not TDC")
        };
        assert_eq!(p.inertia, 2.0);
        assert_eq!(
            p.joint_inertia.map(|j| j.as_slice().to_vec()),
            Some(vec![2.0, 0.0, 0.0, 1.0])
        );
        assert_eq!(
            to_value(&c)["inertia"],
            serde_json::json!([[2.0, 0.0], [0.0, 1.0]])
        );
    }

    #[test]
    fn unknown_keys_are_refused() {
        let v = serde_json::json!({"stiffness": 1.0, "stiffnes": 2.0});
        let e = serde_json::from_value::<WallParams>(v).expect_err("unknown key");
        assert!(e.to_string().contains("stiffnes"), "{e}");
    }

    #[test]
    fn counts_take_integral_floats_only() {
        let ok: SensorParams =
            serde_json::from_value(serde_json::json!({"latency": 2.0})).expect("integral float");
        assert_eq!(ok.latency, 2);
        let e = serde_json::from_value::<SensorParams>(serde_json::json!({"latency": 2.5}))
            .expect_err("fraction");
        let (_, value, allowed) =
            parse_parameter_message(&e.to_string()).expect("a parameter message");
        assert_eq!(
            (value.as_str(), allowed.as_str()),
            ("2.5", "an integer from 0 to 100000")
        );
    }

    #[test]
    fn every_enum_names_its_field() {
        let s = schemas().to_string();
        for (first, field) in [
            ("rod", "mass_model"),
            ("jacobian_transpose", "law"),
            ("kelvin_voigt", "model"),
            ("position", "task"),
        ] {
            assert_eq!(enum_field(first), field);
            assert!(s.contains(&format!("\"{first}\"")), "{first}");
        }
    }

    #[test]
    fn every_python_block_has_a_schema_with_docs() {
        let s = schemas();
        for key in [
            "three_link",
            "wall",
            "sensor",
            "actuator",
            "step",
            "sine",
            "sampled",
        ] {
            let props = s[key]["properties"].as_object().expect(key);
            for (name, p) in props {
                if name != "kind" {
                    assert!(p.get("description").is_some(), "{key}.{name} has no doc");
                }
            }
        }
    }
}
