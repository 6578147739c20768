//! One error type for the whole core. The pyo3 layer maps it onto Python exceptions
//! (`ParameterError` subclasses `ValueError`).

use std::fmt;

/// Everything that can go wrong before a run starts. A run that diverges is not an
/// error: it is an outcome (`simulation::Outcome`), reported with its time and cause.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A parameter outside its allowed range. `field` is the dotted path of the
    /// parameter in the scenario (`wall.stiffness`), `allowed` a human-readable range.
    #[error("{field} = {value} is invalid: must be {allowed}")]
    Parameter {
        field: String,
        value: String,
        allowed: String,
    },
}

pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    pub fn parameter(field: &str, value: impl fmt::Display, allowed: &str) -> Self {
        Error::Parameter {
            field: field.to_owned(),
            value: value.to_string(),
            allowed: allowed.to_owned(),
        }
    }

    /// The same error with `prefix.` put in front of the field, so that a block
    /// validated on its own reports its place in the scenario.
    pub fn within(self, prefix: &str) -> Self {
        match self {
            Error::Parameter {
                field,
                value,
                allowed,
            } => Error::Parameter {
                field: if prefix.is_empty() {
                    field
                } else {
                    format!("{prefix}.{field}")
                },
                value,
                allowed,
            },
        }
    }
}

/// Small checks shared by every parameter block.
pub(crate) mod check {
    use super::{Error, Result};

    pub fn finite(field: &str, v: f64) -> Result<()> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(Error::parameter(field, v, "a finite number"))
        }
    }

    pub fn positive(field: &str, v: f64) -> Result<()> {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(Error::parameter(field, v, "finite and > 0"))
        }
    }

    pub fn non_negative(field: &str, v: f64) -> Result<()> {
        if v.is_finite() && v >= 0.0 {
            Ok(())
        } else {
            Err(Error::parameter(field, v, "finite and >= 0"))
        }
    }

    pub fn all<const N: usize>(
        field: &str,
        v: &[f64; N],
        f: fn(&str, f64) -> Result<()>,
    ) -> Result<()> {
        for (i, x) in v.iter().enumerate() {
            f(&format!("{field}[{i}]"), *x)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn message_names_field_value_and_range() {
        let e = check::positive("stiffness", -1.0)
            .unwrap_err()
            .within("wall");
        assert_eq!(
            e.to_string(),
            "wall.stiffness = -1 is invalid: must be finite and > 0"
        );
    }

    #[test]
    fn nan_is_rejected_everywhere() {
        assert!(check::finite("a", f64::NAN).is_err());
        assert!(check::positive("a", f64::NAN).is_err());
        assert!(check::non_negative("a", f64::INFINITY).is_err());
        assert!(check::non_negative("a", 0.0).is_ok());
        assert!(check::positive("a", 0.0).is_err());
    }
}
