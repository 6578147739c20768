//! The block registry (SPEC §14): every family of parameter blocks and every kind in it,
//! listed once. The schema rows ([`super::schemas`]), the defaults ([`super::defaults`]),
//! the Python blocks (their fields are generated from these rows by `admit_rs._codegen`),
//! their kind tags, the TOML reader's tables and the type each scenario field holds all
//! follow from [`FAMILIES`]. A new kind of an existing family is its own file plus one
//! [`Kind`] line here (and its variant in the family's enum).

use schemars::JsonSchema;
use serde::Serialize;
use serde_json::{json, Map, Value};

use crate::control::approach::ApproachParams;
use crate::control::filter::{AdmittanceParams, ForceControlParams, ImpedanceParams};
use crate::control::params::{
    ComputedTorqueParams, ControllerParams, ModelError, ModelFreeBlock, ModelFreeParams,
    TimeDelayBlock, TimeDelayParams,
};
use crate::control::reference::Signal;
use crate::robot::chain::UrdfArmParams;
use crate::robot::RobotParams;
use crate::sim::criteria::CriteriaParams;
use crate::sim::scenario::{RobotConfig, ScenarioConfig};
use crate::world::actuator::ActuatorParams;
use crate::world::height_field::HeightFieldParams;
use crate::world::round::{CylinderParams, SphereParams};
use crate::world::sensor::SensorParams;
use crate::world::surface::SurfaceParams;

/// One kind of block: a struct (or an enum variant) of the core, a class of the Python API.
pub struct Kind {
    /// Its key in the schema and the defaults: the Python/TOML `kind` tag where it has
    /// one, else the block's own name.
    pub key: &'static str,
    /// The Python class.
    pub class: &'static str,
    /// The `kind` tag a Python block and a TOML table carry; `None`: untagged (the
    /// family's only kind, or the plane: a surface table without a kind is a Wall).
    pub tag: Option<&'static str>,
    /// The tag the core's enum decodes it by, where the family is an enum.
    pub core_tag: Option<&'static str>,
    /// Its JSON schema (fields in declaration order, docs, types, defaults, slider hints).
    pub schema: fn(&Kind) -> Value,
    /// Its `Default`, serialised as it crosses to Python.
    pub default: fn(&Kind) -> Value,
}

/// A family: the kinds one scenario field may hold (the arm, the surface, the inner loop, …).
pub struct Family {
    /// The name `check_block` and the Python blocks use for it.
    pub name: &'static str,
    /// The Python type of a field holding this family: a type alias of the union of its
    /// classes where it has several kinds, else its one class.
    pub python: &'static str,
    /// The Rust type's schema name (the `$defs` entry a field holding the family refers to).
    pub type_name: fn() -> String,
    pub kinds: &'static [Kind],
}

fn type_name<T: JsonSchema>() -> String {
    T::schema_name().into_owned()
}

fn schema_of<T: JsonSchema>(_: &Kind) -> Value {
    schemars::schema_for!(T).to_value()
}

/// A tagged block's schema: its struct's, with the `kind` it is tagged by.
fn tagged<T: JsonSchema>(k: &Kind) -> Value {
    let mut v = schema_of::<T>(k);
    if let Some(props) = v.get_mut("properties").and_then(Value::as_object_mut) {
        props.insert("kind".into(), json!({"type": "string", "const": k.tag}));
    }
    v
}

fn default_of<T: Default + Serialize>(_: &Kind) -> Value {
    // Every block serialises to JSON (plain numbers, strings, lists and maps).
    serde_json::to_value(T::default()).unwrap_or(Value::Null)
}

/// A signal's variant of the `Signal` enum's schema (its `kind` const included).
fn signal_schema(k: &Kind) -> Value {
    let schema = schemars::schema_for!(Signal);
    let defs = schema.get("$defs").cloned();
    let variant = schema
        .get("oneOf")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .find(|v| v.pointer("/properties/kind/const").and_then(Value::as_str) == k.core_tag);
    let mut out = variant.cloned().unwrap_or(Value::Null);
    if let (Some(defs), Some(obj)) = (defs, out.as_object_mut()) {
        obj.insert("$defs".into(), defs);
    }
    out
}

/// A signal with every field at its serde default: decoded from its tag alone.
fn signal_default(k: &Kind) -> Value {
    serde_json::from_value::<Signal>(json!({"kind": k.core_tag}))
        .and_then(serde_json::to_value)
        .unwrap_or(Value::Null)
}

/// Every family and its kinds, in the order the Python API lists them.
pub const FAMILIES: &[Family] = &[
    Family {
        name: "robot",
        python: "Robot | UrdfArm",
        type_name: type_name::<RobotConfig>,
        kinds: &[
            Kind {
                key: "three_link",
                class: "Robot",
                tag: Some("three_link"),
                core_tag: Some("three_link"),
                schema: schema_of::<RobotParams>,
                default: default_of::<RobotParams>,
            },
            Kind {
                key: "urdf",
                class: "UrdfArm",
                tag: Some("urdf"),
                core_tag: Some("urdf"),
                schema: schema_of::<UrdfArmParams>,
                default: default_of::<UrdfArmParams>,
            },
        ],
    },
    Family {
        name: "surface",
        python: "Surface",
        type_name: type_name::<SurfaceParams>,
        kinds: &[
            Kind {
                key: "wall",
                class: "Wall",
                tag: None,
                core_tag: Some("plane"),
                schema: schema_of::<crate::world::environment::WallParams>,
                default: default_of::<crate::world::environment::WallParams>,
            },
            Kind {
                key: "sphere",
                class: "Sphere",
                tag: Some("sphere"),
                core_tag: Some("sphere"),
                schema: tagged::<SphereParams>,
                default: default_of::<SphereParams>,
            },
            Kind {
                key: "cylinder",
                class: "Cylinder",
                tag: Some("cylinder"),
                core_tag: Some("cylinder"),
                schema: tagged::<CylinderParams>,
                default: default_of::<CylinderParams>,
            },
            Kind {
                key: "height_field",
                class: "HeightField",
                tag: Some("height_field"),
                core_tag: Some("height_field"),
                schema: tagged::<HeightFieldParams>,
                default: default_of::<HeightFieldParams>,
            },
        ],
    },
    Family {
        name: "sensor",
        python: "ForceSensor",
        type_name: type_name::<SensorParams>,
        kinds: &[Kind {
            key: "sensor",
            class: "ForceSensor",
            tag: None,
            core_tag: None,
            schema: schema_of::<SensorParams>,
            default: default_of::<SensorParams>,
        }],
    },
    Family {
        name: "actuator",
        python: "Actuator",
        type_name: type_name::<ActuatorParams>,
        kinds: &[Kind {
            key: "actuator",
            class: "Actuator",
            tag: None,
            core_tag: None,
            schema: schema_of::<ActuatorParams>,
            default: default_of::<ActuatorParams>,
        }],
    },
    Family {
        name: "model",
        python: "ModelError",
        type_name: type_name::<ModelError>,
        kinds: &[Kind {
            key: "model",
            class: "ModelError",
            tag: None,
            core_tag: None,
            schema: schema_of::<ModelError>,
            default: default_of::<ModelError>,
        }],
    },
    Family {
        name: "controller",
        python: "Controller",
        type_name: type_name::<ControllerParams>,
        kinds: &[
            Kind {
                key: "computed_torque",
                class: "ComputedTorque",
                tag: Some("computed_torque"),
                core_tag: Some("computed_torque"),
                schema: schema_of::<ComputedTorqueParams>,
                default: default_of::<ComputedTorqueParams>,
            },
            Kind {
                key: "model_free",
                class: "ModelFree",
                tag: Some("model_free"),
                core_tag: Some("model_free"),
                schema: schema_of::<ModelFreeBlock>,
                default: default_of::<ModelFreeParams>,
            },
            Kind {
                key: "time_delay",
                class: "TimeDelayControl",
                tag: Some("time_delay"),
                core_tag: Some("time_delay"),
                schema: schema_of::<TimeDelayBlock>,
                default: default_of::<TimeDelayParams>,
            },
        ],
    },
    Family {
        name: "force_control",
        python: "ForceControl",
        type_name: type_name::<ForceControlParams>,
        kinds: &[
            Kind {
                key: "admittance",
                class: "AdmittanceFilter",
                tag: Some("admittance"),
                core_tag: Some("admittance"),
                schema: schema_of::<AdmittanceParams>,
                default: default_of::<AdmittanceParams>,
            },
            Kind {
                key: "impedance",
                class: "ImpedanceReference",
                tag: Some("impedance"),
                core_tag: Some("impedance"),
                schema: schema_of::<ImpedanceParams>,
                default: default_of::<ImpedanceParams>,
            },
        ],
    },
    Family {
        name: "signal",
        python: "Signal",
        type_name: type_name::<Signal>,
        kinds: &[
            Kind {
                key: "step",
                class: "Step",
                tag: Some("step"),
                core_tag: Some("step"),
                schema: signal_schema,
                default: signal_default,
            },
            Kind {
                key: "sine",
                class: "Sine",
                tag: Some("sine"),
                core_tag: Some("sine"),
                schema: signal_schema,
                default: signal_default,
            },
            Kind {
                key: "sampled",
                class: "Sampled",
                tag: Some("sampled"),
                core_tag: Some("sampled"),
                schema: signal_schema,
                default: signal_default,
            },
        ],
    },
    Family {
        name: "criteria",
        python: "Criteria",
        type_name: type_name::<CriteriaParams>,
        kinds: &[Kind {
            key: "criteria",
            class: "Criteria",
            tag: None,
            core_tag: None,
            schema: schema_of::<CriteriaParams>,
            default: default_of::<CriteriaParams>,
        }],
    },
    Family {
        name: "approach",
        python: "GuardedApproach",
        type_name: type_name::<ApproachParams>,
        kinds: &[Kind {
            key: "approach",
            class: "GuardedApproach",
            tag: None,
            core_tag: None,
            schema: schema_of::<ApproachParams>,
            default: default_of::<ApproachParams>,
        }],
    },
    Family {
        name: "scenario",
        python: "Scenario",
        type_name: type_name::<ScenarioConfig>,
        kinds: &[Kind {
            key: "scenario",
            class: "Scenario",
            tag: None,
            core_tag: None,
            schema: schema_of::<ScenarioConfig>,
            default: default_of::<ScenarioConfig>,
        }],
    },
];

/// Every kind of every family.
pub fn kinds() -> impl Iterator<Item = (&'static Family, &'static Kind)> {
    FAMILIES
        .iter()
        .flat_map(|f| f.kinds.iter().map(move |k| (f, k)))
}

/// The registry as data, for the Python side: each family's name, Python type, Rust schema
/// name and kinds (key, class, tag, core tag), in order.
pub fn registry() -> Value {
    let families: Vec<Value> = FAMILIES
        .iter()
        .map(|f| {
            let kinds: Vec<Value> = f
                .kinds
                .iter()
                .map(|k| {
                    json!({"key": k.key, "class": k.class, "tag": k.tag,
                           "core_tag": k.core_tag})
                })
                .collect();
            json!({"name": f.name, "python": f.python, "type_name": (f.type_name)(),
                   "kinds": kinds})
        })
        .collect();
    Value::Array(families)
}

/// `f(kind)` for every kind, keyed by its key.
pub fn by_key(f: impl Fn(&Kind) -> Value) -> Value {
    let mut out = Map::new();
    for (_, k) in kinds() {
        out.insert(k.key.to_owned(), f(k));
    }
    Value::Object(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_classes_and_tags_are_unique() {
        let mut keys: Vec<_> = kinds().map(|(_, k)| k.key).collect();
        let mut classes: Vec<_> = kinds().map(|(_, k)| k.class).collect();
        let n = keys.len();
        keys.sort_unstable();
        keys.dedup();
        classes.sort_unstable();
        classes.dedup();
        assert_eq!((keys.len(), classes.len()), (n, n));
        for f in FAMILIES {
            let mut tags: Vec<_> = f.kinds.iter().filter_map(|k| k.core_tag).collect();
            let tagged = tags.len();
            tags.sort_unstable();
            tags.dedup();
            assert_eq!(tags.len(), tagged, "{}", f.name);
            // A family of several kinds is an enum the core decodes by tag.
            assert!(f.kinds.len() == 1 || tagged == f.kinds.len(), "{}", f.name);
        }
    }

    /// Each tagged kind's schema names the tag the core's enum decodes it by, and the
    /// family's enum schema holds exactly the registry's tags.
    #[test]
    fn core_tags_are_the_enums_tags() {
        for f in FAMILIES.iter().filter(|f| f.kinds.len() > 1) {
            let schema = match f.name {
                "robot" => schemars::schema_for!(RobotConfig),
                "surface" => schemars::schema_for!(SurfaceParams),
                "controller" => schemars::schema_for!(ControllerParams),
                "force_control" => schemars::schema_for!(ForceControlParams),
                "signal" => schemars::schema_for!(Signal),
                other => panic!("no enum for {other}"),
            };
            let tags: Vec<&str> = schema
                .get("oneOf")
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
                .filter_map(|v| v.pointer("/properties/kind/const").and_then(Value::as_str))
                .collect();
            let listed: Vec<&str> = f.kinds.iter().filter_map(|k| k.core_tag).collect();
            assert_eq!(
                tags, listed,
                "{}: the enum's tags and the registry's",
                f.name
            );
        }
    }

    #[test]
    fn every_kind_has_a_schema_and_a_default() {
        for (f, k) in kinds() {
            let s = (k.schema)(k);
            assert!(s.get("properties").is_some(), "{}.{}", f.name, k.key);
            assert!((k.default)(k).is_object(), "{}.{}", f.name, k.key);
        }
    }
}
