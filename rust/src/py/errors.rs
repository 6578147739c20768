//! Core errors as Python exceptions. The classes live in Python (`admit_rs/errors.py`) so
//! that `ParameterError` can be both a `ValueError` and an `admit_rs.AdmitError`, which
//! `create_exception!` cannot express.

use pyo3::import_exception;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::error::Error;

import_exception!(admit_rs.errors, AdmitError);
import_exception!(admit_rs.errors, ParameterError);
import_exception!(admit_rs.errors, AnalysisError);
// A value of the wrong type: an `AdmitError` that is also a `TypeError`.
import_exception!(admit_rs.errors, ParameterTypeError);

pub(crate) fn parameter_error(py: Python<'_>, field: &str, value: &str, allowed: &str) -> PyErr {
    let err = ParameterError::new_err(format!("{field} = {value} is invalid: must be {allowed}"));
    let obj = err.value(py);
    // Attributes for programmatic use; failing to set them must not hide the error itself.
    let _ = obj.setattr("field", field);
    let _ = obj.setattr("value", value);
    let _ = obj.setattr("allowed", allowed);
    err
}

/// `e` again, of its own class, with `message` and the attributes it carries (its
/// `__dict__`: `field`, `suggestions`, ...).
pub(crate) fn with_message(py: Python<'_>, e: &PyErr, message: String) -> PyErr {
    let new = PyErr::from_type(e.get_type(py), message);
    if let Ok(attrs) = e.value(py).getattr("__dict__") {
        if let Ok(dict) = attrs.cast::<PyDict>() {
            for (key, value) in dict.iter() {
                // Failing to copy an attribute must not hide the error itself.
                if let Ok(key) = key.extract::<String>() {
                    let _ = new.value(py).setattr(key.as_str(), value);
                }
            }
        }
    }
    new
}

pub(crate) fn to_py_err(py: Python<'_>, e: Error) -> PyErr {
    match e {
        Error::Parameter {
            field,
            value,
            allowed,
        } => parameter_error(py, &field, &value, &allowed),
    }
}

pub(crate) fn analysis_err(py: Python<'_>, e: crate::analysis::AnalysisError) -> PyErr {
    match e {
        crate::analysis::AnalysisError::Parameter(p) => to_py_err(py, p),
        other => AnalysisError::new_err(other.to_string()),
    }
}
