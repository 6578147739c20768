//! Running the loop: the scenario, the plant integrator, the stage pipeline, its trace,
//! outcome and metrics, and batches of runs on all cores.
//!
//! Dependencies run one way: `scenario`, `outcome` and `trace` are plain data; `metrics`
//! reads them; `simulation` drives `plant` and records into `trace`, then calls `metrics`; `held`
//! builds a run's held twin (SPEC §23) and judges the run by it;
//! `lanes` advances four `simulation`s' plants together in SIMD lanes; `substep_choice`
//! searches the substep count of `substeps = "auto"` from finished runs; `dispatch` and
//! `sweep` run `simulation`s (in lanes where their structure allows) and feed it.

pub mod criteria;
pub mod dispatch;
pub mod held;
pub mod lanes;
pub mod metrics;
pub mod outcome;
pub mod pipeline;
pub mod plant;
pub mod scenario;
pub mod simulation;
pub mod substep_choice;
pub mod sweep;
pub mod trace;
