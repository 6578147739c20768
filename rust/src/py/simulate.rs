//! Runs: one scenario, a batch on all cores, and the stepped loop (`Stepper`); each copies
//! its scenario into Rust first and runs with the GIL released.

use std::sync::{Mutex, MutexGuard, TryLockError};

use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use super::errors::{to_py_err, with_message, AdmitError, ParameterError};
use super::params::scenario_from;
use crate::sim::dispatch::{run_held, AnySimulation};
use crate::sim::metrics::{Metrics, METRIC_NAMES};
use crate::sim::outcome::SubstepChoice;
use crate::sim::simulation::{Outcome, RunResult};
use crate::sim::trace::Trace;
use crate::world::height_field::HeightsInterner;

fn run_to_dict<'py>(py: Python<'py>, run: RunResult) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("columns", trace_dict(py, run.trace)?)?;
    outcome_into(py, &out, run.metrics, run.outcome)?;
    choice_into(&out, run.choice.as_ref())?;
    Ok(out)
}

/// What `substeps = "auto"` chose (`substeps`, `substep_error`, `substep_standing`,
/// `substep_note`); nothing for a fixed count.
fn choice_into(out: &Bound<'_, PyDict>, choice: Option<&SubstepChoice>) -> PyResult<()> {
    if let Some(c) = choice {
        out.set_item("substeps", c.substeps)?;
        out.set_item("substep_error", c.error)?;
        out.set_item("substep_standing", c.standing.name())?;
        out.set_item("substep_note", c.describe())?;
    }
    Ok(())
}

/// Puts a run's metrics, `diverged_at` and `divergence_cause` into `out`.
fn outcome_into(
    py: Python<'_>,
    out: &Bound<'_, PyDict>,
    run_metrics: Metrics,
    outcome: Outcome,
) -> PyResult<()> {
    let metrics = PyDict::new(py);
    for (name, v) in METRIC_NAMES.iter().zip(run_metrics.values()) {
        metrics.set_item(name, v)?;
    }
    metrics.set_item("stable", run_metrics.stable)?;
    metrics.set_item("passed", run_metrics.passed)?;
    metrics.set_item("diverged", run_metrics.diverged)?;
    out.set_item("metrics", metrics)?;
    out.set_item("verdict", run_metrics.judgement(&outcome).verdict)?;
    match outcome {
        Outcome::Completed => {
            out.set_item("diverged_at", py.None())?;
            out.set_item("divergence_cause", py.None())?;
        }
        Outcome::Diverged { time, cause } => {
            out.set_item("diverged_at", time)?;
            out.set_item("divergence_cause", cause.to_string())?;
        }
    }
    Ok(())
}

/// Samples stepped between checks for Ctrl-C (about 20 ms of the paper's run).
const STEP_CHUNK: usize = 1000;

/// The loop of one scenario, stepped from Python (`admit_rs.Simulation`).
///
/// `step` releases the GIL, so another Python thread can call in meanwhile. The run sits
/// behind a mutex that every method only tries: a second caller gets an `AdmitError` saying
/// what happened (waiting would deadlock: the stepping thread needs the GIL the waiter holds
/// to return), instead of pyo3's bare "Already borrowed".
#[pyclass(module = "admit_rs._core", name = "Stepper", frozen)]
pub(super) struct Stepper {
    sim: Mutex<AnySimulation>,
}

impl Stepper {
    /// The run, or an `AdmitError` if another thread is using it.
    fn sim(&self) -> PyResult<MutexGuard<'_, AnySimulation>> {
        match self.sim.try_lock() {
            Ok(sim) => Ok(sim),
            // A panic mid-step already raised in Python; the run is still a run.
            Err(TryLockError::Poisoned(e)) => Ok(e.into_inner()),
            Err(TryLockError::WouldBlock) => Err(AdmitError::new_err(
                "this Simulation is being stepped by another thread: one Simulation is one \
                 run, used by one thread at a time; give each thread its own \
                 ar.Simulation(scenario)",
            )),
        }
    }
}

#[pymethods]
impl Stepper {
    #[new]
    fn new(scenario: &Bound<'_, PyAny>) -> PyResult<Self> {
        let config = scenario_from(scenario)?;
        let sim = AnySimulation::new(&config).map_err(|e| to_py_err(scenario.py(), e))?;
        Ok(Self {
            sim: Mutex::new(sim),
        })
    }

    fn reset(&self) -> PyResult<()> {
        self.sim()?.reset();
        Ok(())
    }

    /// Takes up to `n` samples with the GIL released, checking for Ctrl-C between chunks.
    /// Returns the number taken.
    fn step(&self, py: Python<'_>, n: usize) -> PyResult<usize> {
        let mut guard = self.sim()?;
        let start = guard.sample();
        let mut left = n;
        while left > 0 && guard.outcome().is_none() {
            let chunk = left.min(STEP_CHUNK);
            let sim = &mut *guard;
            py.detach(move || sim.step(chunk));
            left -= chunk;
            py.check_signals()?;
        }
        Ok(guard.sample() - start)
    }

    fn sample(&self) -> PyResult<usize> {
        Ok(self.sim()?.sample())
    }

    fn samples(&self) -> PyResult<usize> {
        Ok(self.sim()?.samples())
    }

    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(PyArray1::from_vec(py, self.sim()?.state()))
    }

    fn state_labels(&self) -> PyResult<Vec<String>> {
        Ok(self.sim()?.state_labels())
    }

    fn set_state(&self, py: Python<'_>, values: Vec<f64>) -> PyResult<()> {
        self.sim()?.set_state(&values).map_err(|e| to_py_err(py, e))
    }

    /// The trace so far (a copy), as `simulate` gives it.
    fn trace<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let trace = self.sim()?.trace().clone();
        trace_dict(py, trace)
    }

    /// `None` while the run goes on; once it is over, the metrics and how it ended.
    fn outcome<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let sim = self.sim()?;
        let Some(outcome) = sim.outcome() else {
            return Ok(None);
        };
        let mut metrics = sim.metrics(&outcome);
        // A run that failed a criterion the loop may sustain is judged by its held run
        // (SPEC §23), run here once with the GIL released.
        let config = sim.config().clone();
        let count = config.substeps.count();
        py.detach(|| crate::sim::held::settle(&config, &mut metrics, &outcome, count, run_held))
            .map_err(|e| to_py_err(py, e))?;
        let out = PyDict::new(py);
        outcome_into(py, &out, metrics, outcome)?;
        Ok(Some(out))
    }
}

/// Runs one scenario; the whole run happens in Rust with the GIL released.
#[pyfunction]
pub(super) fn simulate<'py>(scenario: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
    let py = scenario.py();
    let config = scenario_from(scenario)?;
    let run = py.detach(move || crate::sim::dispatch::simulate(&config));
    run_to_dict(py, run.map_err(|e| to_py_err(py, e))?)
}

/// A trace as `{"names": [...], "len": n, "data": ndarray}`: column c is
/// `data[c * n:(c + 1) * n]`, one array that polars slices into columns without a copy.
fn trace_dict<'py>(py: Python<'py>, trace: Trace) -> PyResult<Bound<'py, PyDict>> {
    let flat = trace.into_flat();
    let out = PyDict::new(py);
    out.set_item("names", PyList::new(py, flat.names)?)?;
    out.set_item("len", flat.len)?;
    out.set_item("data", PyArray1::from_vec(py, flat.data))?;
    Ok(out)
}

/// Runs a batch of scenario dicts on `threads` threads (None: all cores) with the GIL
/// released. Returns metric columns (one entry per run, in order), `stable` and `passed`
/// (lists of True, False or None: not assessed), `verdict` (words), `diverged`,
/// `diverged_at` (NaN when stable), `divergence_cause` and, with `traces`, one flat trace
/// per run (as `simulate` gives it). An invalid scenario raises before anything runs, naming its index.
/// `lanes`: runs advance four or eight at a time in SIMD lanes (within 1e-9 of off).
#[pyfunction]
#[pyo3(signature = (scenarios, threads=None, traces=false, lanes=true))]
pub(super) fn simulate_batch<'py>(
    scenarios: &Bound<'py, PyList>,
    threads: Option<usize>,
    traces: bool,
    lanes: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let py = scenarios.py();
    let mut interner = HeightsInterner::default();
    let configs = scenarios
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let mut config = scenario_from(&s).map_err(|e| {
                let msg = format!("scenario {i}: {}", e.value(py));
                if e.is_instance_of::<ParameterError>(py) {
                    let new = ParameterError::new_err(msg);
                    for attr in ["field", "value", "allowed"] {
                        if let Ok(v) = e.value(py).getattr(attr) {
                            let _ = new.value(py).setattr(attr, v);
                        }
                    }
                    let _ = new.value(py).setattr("index", i);
                    new
                } else {
                    // The same class (UnknownParameterError, ParameterTypeError, ...) with its
                    // attributes (suggestions, ...), the run's index in front of the message.
                    with_message(py, &e, msg)
                }
            })?;
            // One copy of each part's heights however many runs touch it (the duplicate
            // just decoded is dropped here, before the next run is decoded).
            config.share_heights(&mut interner);
            Ok(config)
        })
        .collect::<PyResult<Vec<_>>>()?;
    let counts: Vec<Option<usize>> = configs.iter().map(|c| c.substeps.count()).collect();
    let runs = py
        .detach(move || crate::sim::sweep::run_batch_with(&configs, threads, traces, lanes))
        .map_err(|e| to_py_err(py, e.error))?;
    let out = PyDict::new(py);
    let n = runs.len();
    let mut columns: Vec<Vec<f64>> = vec![Vec::with_capacity(n); METRIC_NAMES.len()];
    let stable = PyList::empty(py);
    let passed = PyList::empty(py);
    let verdicts = PyList::empty(py);
    let mut diverged = Vec::with_capacity(n);
    let mut diverged_at = Vec::with_capacity(n);
    let causes = PyList::empty(py);
    let trace_list = PyList::empty(py);
    // The count each run was integrated with, and for "auto" its estimated error (NaN for
    // a fixed count) and how its search ended (None for a fixed count).
    let mut substeps = Vec::with_capacity(n);
    let mut substep_error = Vec::with_capacity(n);
    let standings = PyList::empty(py);
    for (config, run) in counts.iter().zip(runs) {
        match &run.choice {
            Some(c) => {
                substeps.push(c.substeps as i64);
                substep_error.push(c.error);
                standings.append(c.standing.name())?;
            }
            None => {
                substeps.push(config.map_or(0, |n| n as i64));
                substep_error.push(f64::NAN);
                standings.append(py.None())?;
            }
        }
        for (c, v) in columns.iter_mut().zip(run.metrics.values()) {
            c.push(v);
        }
        stable.append(run.metrics.stable)?;
        passed.append(run.metrics.passed)?;
        verdicts.append(run.metrics.judgement(&run.outcome).verdict)?;
        diverged.push(run.metrics.diverged);
        match run.outcome {
            Outcome::Completed => {
                diverged_at.push(f64::NAN);
                causes.append(py.None())?;
            }
            Outcome::Diverged { time, cause } => {
                diverged_at.push(time);
                causes.append(cause.to_string())?;
            }
        }
        if let Some(trace) = run.trace {
            trace_list.append(trace_dict(py, trace)?)?;
        }
    }
    let metrics = PyDict::new(py);
    for (name, col) in METRIC_NAMES.iter().zip(columns) {
        metrics.set_item(name, PyArray1::from_vec(py, col))?;
    }
    out.set_item("metrics", metrics)?;
    out.set_item("stable", stable)?;
    out.set_item("passed", passed)?;
    out.set_item("verdict", verdicts)?;
    out.set_item("diverged", PyArray1::from_vec(py, diverged))?;
    out.set_item("diverged_at", PyArray1::from_vec(py, diverged_at))?;
    out.set_item("divergence_cause", causes)?;
    out.set_item("substeps", PyArray1::from_vec(py, substeps))?;
    out.set_item("substep_error", PyArray1::from_vec(py, substep_error))?;
    out.set_item("substep_standing", standings)?;
    out.set_item(
        "traces",
        if traces {
            trace_list.into_any()
        } else {
            py.None().into_bound(py)
        },
    )?;
    Ok(out)
}

/// Hidden, for tests and benches (issue #25): the build of the lane loop sweeps take.
/// `path` ("portable", "avx2", "avx512"; "auto": the default) forces it from now on, in
/// this process; returns the name of the build in effect. A name this CPU cannot run, or
/// none of these, raises ValueError. `ADMIT_RS_LANES` sets the same at import time.
#[pyfunction]
#[pyo3(name = "_lane_path", signature = (path=None))]
pub(super) fn lane_path(path: Option<&str>) -> PyResult<&'static str> {
    use crate::sim::lanes::{set_lane_path, LanePath};
    if let Some(name) = path {
        let forced = match name {
            "auto" => None,
            _ => Some(LanePath::parse(name).ok_or_else(|| {
                PyValueError::new_err(format!(
                    "lane path {name:?}: one of auto, portable, avx2, avx512"
                ))
            })?),
        };
        if !set_lane_path(forced) {
            return Err(PyValueError::new_err(format!(
                "lane path {name:?}: this CPU cannot run it"
            )));
        }
    }
    Ok(crate::sim::lanes::lane_path().name())
}

/// Hidden: the builds of the lane loop this CPU runs, and the number of runs whose stages
/// ran in lanes on each since the process started (how tests see which build ran).
#[pyfunction]
#[pyo3(name = "_lane_runs")]
pub(super) fn lane_runs(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    use crate::sim::lanes::{lane_runs, LanePath};
    let out = PyDict::new(py);
    for (p, n) in LanePath::ALL.into_iter().zip(lane_runs()) {
        if p.available() {
            out.set_item(p.name(), n)?;
        }
    }
    Ok(out)
}
