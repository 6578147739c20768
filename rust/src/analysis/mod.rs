//! Predict before simulating (SPEC §12): the one-period closed-loop map linearised about
//! its steady contact equilibrium, and what its poles and step response predict.
//!
//! Uses `sim` only (the map is `Simulation::step`); generic over the arm `R` of `N` joints.

pub mod linearize;
pub mod stability;

pub use linearize::{linearize, AnalysisError, AnalysisResult, Linearization};
pub use stability::{predict, predict_batch, predict_from, Prediction, PREDICTION_NAMES};
