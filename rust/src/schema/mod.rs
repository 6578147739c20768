//! The parameter blocks' one declaration, as data: each block is a serde struct (defaults
//! from its `Default`, unknown keys refused, enum tags spelled as the Python API spells them)
//! whose JSON schema carries the field docs. This module holds the few serde helpers the
//! blocks need (one number or many, whole numbers given as integral floats, the constant
//! inertia D̄ as one field), the [`registry`] of block families and kinds, and the two
//! tables the Python blocks are generated from (`admit_rs._codegen`): [`schemas`] (fields,
//! types, docs, defaults) and [`defaults`] (every block's `Default`, serialised). Nothing
//! here knows Python. The field helpers the blocks use are in [`fields`].

pub mod fields;
pub mod registry;

use serde_json::Value;

use crate::error::Error;

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

/// Every block's JSON schema (draft 2020-12: properties in declaration order with
/// `description` from the doc comments, `type`, `default`, and `x-ui` slider hints), keyed
/// by the registry's keys (`three_link`, `urdf`, `wall`, `sphere`, …, `scenario`).
pub fn schemas() -> Value {
    registry::by_key(|k| (k.schema)(k))
}

/// Every block's `Default`, serialised as the blocks cross to Python (keys as in
/// [`schemas`]); tagged blocks carry their `kind`.
pub fn defaults() -> Value {
    registry::by_key(|k| (k.default)(k))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::params::ControllerParams;
    use crate::sim::scenario::ScenarioConfig;
    use crate::world::environment::WallParams;
    use crate::world::sensor::SensorParams;

    fn to_value<T: serde::Serialize>(v: &T) -> Value {
        serde_json::to_value(v).expect("serialises")
    }

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
