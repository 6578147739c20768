//! One error type for the whole core. The pyo3 layer maps it onto Python exceptions
//! (`ParameterError` subclasses `ValueError`).

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

/// A value as an error message shows it. Numbers are shown by [`short`], so a message stays
/// short whatever the value (`1e300`, not 301 digits); text is shown as it is.
pub trait Shown {
    fn shown(&self) -> String;
}

impl Shown for f64 {
    fn shown(&self) -> String {
        short(*self)
    }
}

impl Shown for str {
    fn shown(&self) -> String {
        self.to_owned()
    }
}

impl Shown for String {
    fn shown(&self) -> String {
        self.clone()
    }
}

macro_rules! shown_by_display {
    ($($t:ty),*) => {$(
        impl Shown for $t {
            fn shown(&self) -> String {
                self.to_string()
            }
        }
    )*};
}
shown_by_display!(usize, u64, u32, i64, i32);

impl<T: Shown + ?Sized> Shown for &T {
    fn shown(&self) -> String {
        (**self).shown()
    }
}

/// `v` in few characters, exactly: the shortest decimal that reads back as `v`, positional
/// from 1e-4 to 1e16 (Rust's `Display`: `0.1`, `-1`, `123456.789`) and scientific beyond
/// (`1e300`, `-1.5e-300`, `2.5e-7`), where Python's `repr` switches too. `Display` alone
/// writes 1e300 as 301 digits.
pub fn short(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || !a.is_finite() || (1e-4..1e16).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// `v` to six significant figures, trailing zeros dropped, for measured values (a velocity,
/// a force) whose last digits are noise: positional from 1e-4 to 1e6, scientific beyond
/// (`100.523`, `0.00425239`, `3.33333e299`), as C's `%g`.
pub fn approx(v: f64) -> String {
    let a = v.abs();
    let trim = |s: String| {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            s
        }
    };
    if a == 0.0 || !a.is_finite() {
        format!("{v}")
    } else if (1e-4..1e6).contains(&a) {
        // Six significant figures: digits after the point = 5 - floor(log10 |v|).
        let decimals = (5 - a.log10().floor() as i32).max(0) as usize;
        trim(format!("{v:.decimals$}"))
    } else {
        let s = format!("{v:.5e}");
        match s.split_once('e') {
            Some((m, e)) => format!("{}e{e}", trim(m.to_owned())),
            None => s,
        }
    }
}

impl Error {
    pub fn parameter(field: &str, value: impl Shown, allowed: &str) -> Self {
        Error::Parameter {
            field: field.to_owned(),
            value: value.shown(),
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

    /// 0 < v ≤ `max` [unit]: a physical size whose square or product must stay finite.
    pub fn positive_up_to(field: &str, v: f64, max: f64, unit: &str) -> Result<()> {
        if v.is_finite() && v > 0.0 && v <= max {
            Ok(())
        } else {
            Err(Error::parameter(
                field,
                v,
                &format!("> 0 and <= {} {unit}", super::short(max)),
            ))
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

    /// Values print in few characters and read back exactly; text is kept as given.
    #[test]
    fn values_print_short_and_exact() {
        let e = check::positive("stiffness", -1e300)
            .unwrap_err()
            .within("wall");
        assert_eq!(
            e.to_string(),
            "wall.stiffness = -1e300 is invalid: must be finite and > 0"
        );
        for (v, text) in [
            (-1.0, "-1"),
            (0.1, "0.1"),
            (0.0, "0"),
            (1e-4, "0.0001"),
            (2.5e-7, "2.5e-7"),
            (123_456.789, "123456.789"),
            (1e16, "1e16"),
            (-1.5e-300, "-1.5e-300"),
            (f64::NAN, "NaN"),
            (f64::NEG_INFINITY, "-inf"),
        ] {
            assert_eq!(short(v), text);
        }
        for v in [0.1 + 0.2, 1.0 / 3.0, 1e300, 5e-324, f64::MAX, -123.456e-200] {
            let s = short(v);
            assert!(s.len() <= 24, "{s}");
            assert_eq!(s.parse::<f64>().ok(), Some(v), "{s}");
        }
        assert_eq!(
            Error::parameter("urdf", "text", "x").to_string(),
            "urdf = text is invalid: must be x"
        );
        assert_eq!(
            Error::parameter("latency", 7usize, "x").to_string(),
            "latency = 7 is invalid: must be x"
        );
    }

    #[test]
    fn approximate_values_keep_six_figures() {
        for (v, text) in [
            (100.523_452_345, "100.523"),
            (-0.001_234_567_8, "-0.00123457"),
            (12.0, "12"),
            (1e300 / 3.0, "3.33333e299"),
            (-2.5e-9, "-2.5e-9"),
            (999_999.7, "1000000"),
            (f64::INFINITY, "inf"),
        ] {
            assert_eq!(approx(v), text, "{v}");
        }
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
