//! The admittance filter on its own: its exact ZOH matrices and its response to a
//! force-error sequence.

use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::errors::to_py_err;
use super::params::admittance_params;
use crate::control::filter::{AdmittanceParams, ForceControl, ForceControlParams};
use crate::control::reference::Sample;

fn checked_admittance(params: &Bound<'_, PyAny>, period: f64) -> PyResult<AdmittanceParams> {
    let py = params.py();
    let p = admittance_params(params)?;
    p.validate().map_err(|e| to_py_err(py, e))?;
    crate::error::check::positive("period", period).map_err(|e| to_py_err(py, e))?;
    Ok(p)
}

type ZohPair<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

/// The exact ZOH matrices (Ad, Bd) of an admittance filter for period T.
#[pyfunction]
pub(super) fn filter_discretize<'py>(
    params: &Bound<'py, PyAny>,
    period: f64,
) -> PyResult<ZohPair<'py>> {
    let py = params.py();
    let (ad, bd) = checked_admittance(params, period)?.discretize(period);
    let rows = vec![vec![ad[(0, 0)], ad[(0, 1)]], vec![ad[(1, 0)], ad[(1, 1)]]];
    let ad = PyArray2::from_vec2(py, &rows).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok((ad, PyArray1::from_slice(py, bd.as_slice())))
}

/// Runs the discrete filter (adaptive when σ > 0) on a force-error sequence: returns
/// (x_a, ẋ_a, ẍ_a) per sample.
#[pyfunction]
pub(super) fn filter_response<'py>(
    params: &Bound<'py, PyAny>,
    period: f64,
    force_error: Vec<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let py = params.py();
    let p = ForceControlParams::Admittance(checked_admittance(params, period)?);
    let mut filter = ForceControl::new(&p, period);
    let n = force_error.len();
    let (mut xa, mut xa_dot, mut xa_ddot) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    for e in force_error {
        // e_f = f_d − f with f_d = e and f = 0: exactly e.
        let desired = Sample {
            value: e,
            ..Sample::default()
        };
        let s = filter.step(&desired, 0.0);
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
