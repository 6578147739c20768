//! admit_rs: admittance force tracking control of robot manipulators (Jung & Jeong).
//!
//! One module per concept, dependencies pointing down only:
//! `robot` (arm models) and `world` (wall, sensor, actuator) at the bottom; `control`
//! (references, filters, task directions, control laws) uses `robot`; `sim` (plant, the
//! stage pipeline, metrics, sweeps) uses all three. The numerics know nothing of Python;
//! the pyo3 layer lives in `py` behind the `python` feature, which maturin switches on.

pub mod analysis;
pub mod contact;
pub mod control;
pub mod error;
pub mod jet;
pub mod robot;
pub mod scalar;
pub mod schema;
pub mod sim;
pub mod world;

#[cfg(feature = "python")]
mod py;

pub use error::{Error, Result};
pub use sim::dispatch::simulate;
pub use sim::simulation::{RunResult, ScenarioConfig, Simulation};
