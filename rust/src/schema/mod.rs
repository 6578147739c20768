//! The parameter blocks' one declaration, as data: each block is a serde struct (defaults
//! from its `Default`, unknown keys refused, enum tags spelled as the Python API spells them)
//! whose JSON schema carries the field docs. This module holds the few serde helpers the
//! blocks need (one number or many, whole numbers given as integral floats, the constant
//! inertia D̄ as one field) and the two tables the Python blocks are checked against:
//! [`schemas`] (fields, types, docs) and [`defaults`] (every block's `Default`, serialised).
//! Nothing here knows Python. The field helpers the blocks use are in [`fields`].

pub mod fields;

use schemars::{JsonSchema, Schema};
use serde::Serialize;
use serde_json::{Map, Value};

use crate::control::approach::ApproachParams;
use crate::control::filter::{AdmittanceParams, ImpedanceParams};
use crate::control::params::{
    ComputedTorqueParams, ModelError, ModelFreeBlock, ModelFreeParams, TimeDelayBlock,
    TimeDelayParams,
};
use crate::control::reference::Signal;
use crate::error::Error;
use crate::robot::chain::UrdfArmParams;
use crate::robot::RobotParams;
use crate::sim::criteria::CriteriaParams;
use crate::sim::scenario::ScenarioConfig;
use crate::world::actuator::ActuatorParams;
use crate::world::environment::WallParams;
use crate::world::height_field::HeightFieldParams;
use crate::world::round::{CylinderParams, SphereParams};
use crate::world::sensor::SensorParams;

/// The field an enum of the blocks is held in, named by its first variant: serde's
/// "unknown variant" message names the variants but not the field when the enum sits
/// inside a `kind`-tagged block. Tags themselves are `kind`.
pub fn enum_field(first_variant: &str) -> &'static str {
    match first_variant {
        "rod" => "mass_model",
        "jacobian_transpose" => "law",
        "kelvin_voigt" => "model",
        "position" => "task",
        "hold" => "orientation",
        "normal" => "frame",
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

fn schema_value<T: JsonSchema>() -> Value {
    schemars::schema_for!(T).to_value()
}

/// A tagged block's schema: its struct's, with the `kind` it is tagged by.
fn tagged_schema<T: JsonSchema>(kind: &str) -> Value {
    let mut v = schema_value::<T>();
    if let Some(props) = v.get_mut("properties").and_then(Value::as_object_mut) {
        props.insert(
            "kind".into(),
            serde_json::json!({"type": "string", "const": kind}),
        );
    }
    v
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
/// are tagged: `three_link`, `urdf`, `wall`, `sphere`, `cylinder`, `height_field`, `sensor`, `actuator`, `model`,
/// `computed_torque`, `model_free`, `time_delay`, `admittance`, `impedance`, `step`, `sine`,
/// `sampled`, `criteria`, `approach` and `scenario`.
pub fn schemas() -> Value {
    let mut out = Map::new();
    out.insert("three_link".into(), schema_value::<RobotParams>());
    out.insert("urdf".into(), schema_value::<UrdfArmParams>());
    out.insert("wall".into(), schema_value::<WallParams>());
    out.insert("sphere".into(), tagged_schema::<SphereParams>("sphere"));
    out.insert(
        "cylinder".into(),
        tagged_schema::<CylinderParams>("cylinder"),
    );
    out.insert(
        "height_field".into(),
        tagged_schema::<HeightFieldParams>("height_field"),
    );
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
    out.insert("criteria".into(), schema_value::<CriteriaParams>());
    out.insert("approach".into(), schema_value::<ApproachParams>());
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
    out.insert("sphere".into(), to_value(&SphereParams::default()));
    out.insert("cylinder".into(), to_value(&CylinderParams::default()));
    out.insert(
        "height_field".into(),
        to_value(&HeightFieldParams::default()),
    );
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
    out.insert("criteria".into(), to_value(&CriteriaParams::default()));
    out.insert("approach".into(), to_value(&ApproachParams::default()));
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
            ("hold", "orientation"),
            ("normal", "frame"),
        ] {
            assert_eq!(enum_field(first), field);
            assert!(s.contains(&format!("\"{first}\"")), "{first}");
        }
        // Every string enum of every block is in that table (a new one fails here until
        // its field is named): its first variant, from `enum` or a `oneOf` of consts.
        fn firsts(v: &Value, out: &mut Vec<String>) {
            match v {
                Value::Object(m) => {
                    if let Some(Value::Array(e)) = m.get("enum") {
                        if let Some(Value::String(f)) = e.first() {
                            out.push(f.clone());
                        }
                    }
                    if let Some(Value::Array(alts)) = m.get("oneOf") {
                        let consts: Vec<_> = alts.iter().filter_map(|a| a.get("const")).collect();
                        if consts.len() == alts.len() && consts.len() > 1 {
                            if let Some(Value::String(f)) = consts.first() {
                                out.push(f.clone());
                            }
                        }
                    }
                    m.values().for_each(|x| firsts(x, out));
                }
                Value::Array(a) => a.iter().for_each(|x| firsts(x, out)),
                _ => {}
            }
        }
        let mut found = Vec::new();
        firsts(&schemas(), &mut found);
        assert!(found.len() >= 6, "{found:?}");
        for first in found {
            assert_ne!(
                enum_field(&first),
                "kind",
                "an enum whose first variant is {first}"
            );
        }
    }

    /// Every `x-ui` hint (the tuning page's slider: a typical range, a scale, a unit when the
    /// doc has no bracket) is a usable range that holds the field's default.
    #[test]
    fn slider_hints_are_ranges_holding_the_default() {
        fn walk(v: &Value, path: &str, found: &mut Vec<String>) {
            match v {
                Value::Object(map) => {
                    if let Some(ui) = map.get("x-ui") {
                        let lo = ui["min"].as_f64().expect("min");
                        let hi = ui["max"].as_f64().expect("max");
                        let scale = ui["scale"].as_str().expect("scale");
                        assert!(lo < hi, "{path}: {lo} >= {hi}");
                        assert!(scale == "linear" || (scale == "log" && lo > 0.0), "{path}");
                        if let Some(d) = map.get("default").and_then(Value::as_f64) {
                            assert!((lo..=hi).contains(&d), "{path}: default {d} outside");
                        }
                        let doc = map["description"].as_str().unwrap_or("");
                        assert!(
                            doc.contains('[') || ui.get("unit").is_some(),
                            "{path}: unit"
                        );
                        found.push(path.to_owned());
                    }
                    for (k, x) in map {
                        walk(x, &format!("{path}.{k}"), found);
                    }
                }
                Value::Array(items) => items.iter().for_each(|x| walk(x, path, found)),
                _ => {}
            }
        }
        let s = schemas();
        let mut found = Vec::new();
        walk(&s, "", &mut found);
        for field in [
            ".admittance.properties.b",
            ".admittance.properties.ka",
            ".wall.properties.stiffness",
            ".wall.properties.position_error",
            ".sensor.properties.noise_std",
            ".sensor.properties.cutoff",
            ".sensor.properties.latency",
            ".actuator.properties.torque_limit",
            ".actuator.properties.delay",
            ".time_delay.properties.kp",
            ".time_delay.properties.command_divisor",
            ".scenario.properties.duration",
            ".scenario.properties.seed",
        ] {
            assert!(found.iter().any(|f| f == field), "{field} has no x-ui");
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
