//! Running the loop: the plant integrator, the stage pipeline, its trace and metrics, and
//! batches of runs on all cores.

pub mod metrics;
pub mod plant;
pub mod simulation;
pub mod sweep;
pub mod trace;
