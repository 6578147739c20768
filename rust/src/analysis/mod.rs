//! Predict before simulating (SPEC §12): the one-period closed-loop map linearised about
//! its steady contact equilibrium, and what its poles and step response predict.
//!
//! Uses `sim` only (the map is `Simulation::step`); generic over the arm `R` of `N` joints.

pub mod linearize;
pub mod stability;

pub use linearize::{
    linearize, linearize_driven, AnalysisError, AnalysisResult, DriveColumns, Linearization,
};
pub use stability::{
    predict, predict_batch, predict_extent, predict_from, Extent, Prediction, PREDICTION_NAMES,
};

use crate::sim::dispatch::{visit_arm, ArmVisitor};
use crate::sim::scenario::ScenarioConfig;
use crate::sim::simulation::Simulation;

/// [`linearize`] for the scenario's own arm, whichever it is; `driven` adds
/// [`Linearization::drive`] ([`linearize_driven`]).
pub fn linearize_scenario(
    config: &ScenarioConfig,
    at: Option<f64>,
    driven: bool,
) -> AnalysisResult<Linearization> {
    struct Visit<'a>(&'a ScenarioConfig, Option<f64>, bool);
    impl ArmVisitor for Visit<'_> {
        type Output = AnalysisResult<Linearization>;
        fn visit<R: crate::robot::RobotModel<N>, const N: usize>(
            self,
            build: &(dyn Fn(&ScenarioConfig) -> crate::error::Result<Simulation<R, N>> + Sync),
        ) -> Self::Output {
            if self.2 {
                linearize_driven(self.0, self.1, build)
            } else {
                linearize(self.0, self.1, build)
            }
        }
    }
    visit_arm(&config.robot, Visit(config, at, driven))?
}

/// [`predict_batch`] for scenarios that share the first one's kind of arm (a stability map
/// varies parameters, not the arm); a scenario with another arm gets an error of its own.
pub fn predict_scenarios(
    configs: &[ScenarioConfig],
    threads: Option<usize>,
    extent: Extent,
) -> Vec<AnalysisResult<Prediction>> {
    struct Visit<'a>(&'a [ScenarioConfig], Option<usize>, Extent);
    impl ArmVisitor for Visit<'_> {
        type Output = Vec<AnalysisResult<Prediction>>;
        fn visit<R: crate::robot::RobotModel<N>, const N: usize>(
            self,
            build: &(dyn Fn(&ScenarioConfig) -> crate::error::Result<Simulation<R, N>> + Sync),
        ) -> Self::Output {
            predict_batch(self.0, self.1, self.2, build)
        }
    }
    let Some(first) = configs.first() else {
        return Vec::new();
    };
    match visit_arm(&first.robot, Visit(configs, threads, extent)) {
        Ok(predictions) => predictions,
        Err(e) => configs.iter().map(|_| Err(e.clone().into())).collect(),
    }
}
