//! The pyo3 layer, one thin file per concept: `params` (blocks in and out), `simulate`
//! (runs and the stepped loop), `robot` (arm terms), `filter`, `analysis`, and `errors`
//! (core errors as the Python exceptions). Each converts, releases the GIL for the numerics
//! and maps errors; no numerics here.

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyList;

use crate::sim::metrics::METRIC_NAMES;
use crate::sim::trace::trace_columns;

/// Builds a Python dict from (key, value) pairs.
macro_rules! py_dict {
    ($py:expr, { $($key:literal : $value:expr),* $(,)? }) => {{
        let d = PyDict::new($py);
        $(d.set_item($key, $value)?;)*
        d
    }};
}

mod analysis;
mod errors;
mod filter;
mod params;
mod robot;
mod simulate;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // rust-numpy loads NumPy's C API on first use and panics if the Python code that runs
    // then raises, as a Ctrl-C pending at that moment does. Load it at import instead of in
    // the first simulation, after raising any pending interrupt as an ordinary exception.
    py.check_signals()?;
    PyArray1::<f64>::zeros(py, 0, false);
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("TRACE_COLUMNS", PyList::new(py, trace_columns(3))?)?;
    m.add("METRIC_NAMES", PyList::new(py, METRIC_NAMES)?)?;
    m.add(
        "PREDICTION_NAMES",
        PyList::new(py, crate::analysis::PREDICTION_NAMES)?,
    )?;
    m.add_class::<simulate::Stepper>()?;
    m.add_function(wrap_pyfunction!(params::defaults, m)?)?;
    m.add_function(wrap_pyfunction!(params::schema, m)?)?;
    m.add_function(wrap_pyfunction!(params::registry, m)?)?;
    m.add_function(wrap_pyfunction!(params::check_block, m)?)?;
    m.add_function(wrap_pyfunction!(params::validate, m)?)?;
    m.add_function(wrap_pyfunction!(params::surface_directions, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate_batch, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::lane_path, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::lane_runs, m)?)?;
    m.add_function(wrap_pyfunction!(robot::robot_terms, m)?)?;
    m.add_function(wrap_pyfunction!(robot::forward_dynamics, m)?)?;
    m.add_function(wrap_pyfunction!(robot::urdf_terms, m)?)?;
    m.add_function(wrap_pyfunction!(robot::urdf_info, m)?)?;
    m.add_function(wrap_pyfunction!(filter::filter_discretize, m)?)?;
    m.add_function(wrap_pyfunction!(filter::filter_response, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::linearize, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::predict_batch, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::reference_samples, m)?)?;
    Ok(())
}
