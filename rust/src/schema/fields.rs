//! Serde helpers for the parameter blocks' fields: one number or many, and whole numbers
//! given as ints or integral floats. A leaf: the blocks use it, it knows no block.

use schemars::JsonSchema;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::error::{short, Error};

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
/// write `2.0`); anything else is a parameter error (`Error`'s display, field left empty; `schema::parse_parameter_message` reads it back).
pub fn whole<'de, D, T>(d: D, lo: u64, hi: u64, allowed: &str) -> Result<T, D::Error>
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
        Whole::Float(v) => return Err(bad(short(v))),
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
