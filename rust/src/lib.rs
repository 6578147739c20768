//! admit_rs: admittance force tracking control of robot manipulators (Jung & Jeong).
//!
//! One module per concept. The numerics know nothing of Python; the pyo3 layer lives in
//! `python` behind the `python` feature, which maturin switches on.

pub mod controller;
pub mod environment;
pub mod error;
pub mod filter;
pub mod integrator;
pub mod metrics;
pub mod reference;
pub mod robot;
pub mod simulation;
pub mod sweep;

#[cfg(feature = "python")]
mod python;

pub use error::{Error, Result};
pub use simulation::{simulate, RunResult, ScenarioConfig, Simulation};
