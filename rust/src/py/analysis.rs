//! Analysis (SPEC §12): the linearised closed loop and batched predictions, with the GIL
//! released.

use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use super::errors::analysis_err;
use super::params::scenario_from;
use crate::world::height_field::HeightsInterner;

fn dmatrix<'py>(
    py: Python<'py>,
    m: &nalgebra::DMatrix<f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
        .collect();
    if rows.is_empty() {
        return Ok(PyArray2::zeros(py, [0, m.ncols()], false));
    }
    PyArray2::from_vec2(py, &rows).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The one-period closed loop linearised about its equilibrium (or the state at `at`).
#[pyfunction]
#[pyo3(signature = (scenario, at=None, driven=false))]
pub(super) fn linearize<'py>(
    scenario: &Bound<'py, PyAny>,
    at: Option<f64>,
    driven: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let py = scenario.py();
    let config = scenario_from(scenario)?;
    let lin = py
        .detach(move || crate::analysis::linearize_scenario(&config, at, driven))
        .map_err(|e| analysis_err(py, e))?;
    let b = nalgebra::DMatrix::from_column_slice(lin.b.len(), 1, lin.b.as_slice());
    let d = nalgebra::DMatrix::from_column_slice(lin.d.len(), 1, lin.d.as_slice());
    let out = py_dict!(py, {
        "a": dmatrix(py, &lin.a)?,
        "b": dmatrix(py, &b)?,
        "c": dmatrix(py, &lin.c)?,
        "d": dmatrix(py, &d)?,
        "c_measured": PyArray1::from_vec(py, lin.c_measured.as_slice().to_vec()),
        "labels": lin.labels,
        "state": PyArray1::from_vec(py, lin.state),
        "force_desired": lin.force_desired,
        "outputs": lin.outputs.to_vec(),
        "reference_normal": lin.reference_normal,
        "penetration": lin.penetration,
        "period": lin.period,
        "equilibrium": lin.equilibrium,
        "iterations": lin.iterations,
        "caveats": lin.caveats,
    });
    if let Some(drive) = &lin.drive {
        out.set_item("b_drive", dmatrix(py, &drive.b)?)?;
        out.set_item("d_drive", dmatrix(py, &drive.d)?)?;
        out.set_item(
            "c_measured_drive",
            PyArray1::from_vec(py, drive.c_measured.as_slice().to_vec()),
        )?;
        out.set_item("drive_labels", drive.labels.clone())?;
        let curvature = drive
            .curvature
            .iter()
            .map(|m| dmatrix(py, m))
            .collect::<PyResult<Vec<_>>>()?;
        out.set_item("curvature", curvature)?;
    }
    Ok(out)
}

/// The scenario's references at each sample t_k = k·T: f_d, and the motion s with its
/// rates ṡ, s̈ (`Signal::at`, as the loop reads them), for the forced response (SPEC §23).
#[pyfunction]
pub(super) fn reference_samples<'py>(scenario: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
    let py = scenario.py();
    let config = scenario_from(scenario)?;
    let n = config.samples();
    let at = |k: usize| k as f64 * config.period;
    let force: Vec<f64> = (0..n)
        .map(|k| config.force_reference.at(at(k)).value)
        .collect();
    let motion: Vec<_> = (0..n).map(|k| config.z_reference.at(at(k))).collect();
    Ok(py_dict!(py, {
        "force": PyArray1::from_vec(py, force),
        "motion": PyArray1::from_vec(py, motion.iter().map(|m| m.value).collect()),
        "motion_rate": PyArray1::from_vec(py, motion.iter().map(|m| m.rate).collect()),
        "motion_accel": PyArray1::from_vec(py, motion.iter().map(|m| m.accel).collect()),
    }))
}

/// `predict` for many scenarios on all cores with the GIL released. Returns one column
/// per prediction field (`stable` as bool) and `error` (None, or why a cell has no
/// prediction). `transient_only`: only the poles and `peak_joint_speed` (the rest NaN),
/// what a map's friction iteration reads between its steps.
#[pyfunction]
#[pyo3(signature = (scenarios, threads=None, transient_only=false))]
pub(super) fn predict_batch<'py>(
    scenarios: &Bound<'py, PyList>,
    threads: Option<usize>,
    transient_only: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let py = scenarios.py();
    let mut interner = HeightsInterner::default();
    let configs = scenarios
        .iter()
        .map(|s| {
            let mut config = scenario_from(&s)?;
            config.share_heights(&mut interner);
            Ok(config)
        })
        .collect::<PyResult<Vec<_>>>()?;
    let extent = if transient_only {
        crate::analysis::Extent::Transient
    } else {
        crate::analysis::Extent::Full
    };
    let results = py.detach(move || crate::analysis::predict_scenarios(&configs, threads, extent));
    let names = crate::analysis::PREDICTION_NAMES;
    let mut columns: Vec<Vec<f64>> = vec![Vec::with_capacity(results.len()); names.len()];
    let errors = PyList::empty(py);
    for r in results {
        let (p, err) = match r {
            Ok(p) => (p, None),
            Err(e) => (crate::analysis::Prediction::missing(), Some(e.to_string())),
        };
        for (c, v) in columns.iter_mut().zip(p.values()) {
            c.push(v);
        }
        errors.append(err)?;
    }
    let out = PyDict::new(py);
    for (name, col) in names.iter().zip(columns) {
        if *name == "stable" {
            let b: Vec<bool> = col.iter().map(|v| *v == 1.0).collect();
            out.set_item(name, PyArray1::from_vec(py, b))?;
        } else {
            out.set_item(name, PyArray1::from_vec(py, col))?;
        }
    }
    out.set_item("error", errors)?;
    Ok(out)
}
