//! One simulation type for every arm: the three-link arm (closed form) or a URDF chain of 1
//! to 8 joints, each a `Simulation<R, N>` compiled for its joint count (const generics:
//! fixed-size workspaces, no allocation per step). The match on the joint count happens
//! once, when the simulation is built; every call after that goes straight to the typed one.

use crate::error::{Error, Result};
use crate::robot::chain::{UrdfArm, UrdfArmParams};
use crate::robot::{RobotModel, ThreeLinkArm};
use crate::sim::lanes::{ArmKey, LaneKey};
use crate::sim::metrics::Metrics;
use crate::sim::outcome::Outcome;
use crate::sim::scenario::{RobotConfig, ScenarioConfig};
use crate::sim::simulation::{RunResult, Simulation};
use crate::sim::trace::Trace;

/// Validates, builds and runs one scenario, whatever its arm.
pub fn simulate(config: &ScenarioConfig) -> Result<RunResult> {
    Ok(AnySimulation::new(config)?.run())
}

/// A simulation of any supported arm.
#[derive(Debug, Clone)]
pub enum AnySimulation {
    ThreeLink(Box<Simulation<ThreeLinkArm, 3>>),
    Chain1(Box<Simulation<UrdfArm<1>, 1>>),
    Chain2(Box<Simulation<UrdfArm<2>, 2>>),
    Chain3(Box<Simulation<UrdfArm<3>, 3>>),
    Chain4(Box<Simulation<UrdfArm<4>, 4>>),
    Chain5(Box<Simulation<UrdfArm<5>, 5>>),
    Chain6(Box<Simulation<UrdfArm<6>, 6>>),
    Chain7(Box<Simulation<UrdfArm<7>, 7>>),
    Chain8(Box<Simulation<UrdfArm<8>, 8>>),
}

/// Runs `$body` with `$s` bound to the typed simulation inside `$sim`.
macro_rules! dispatch {
    ($sim:expr, $s:ident => $body:expr) => {
        match $sim {
            AnySimulation::ThreeLink($s) => $body,
            AnySimulation::Chain1($s) => $body,
            AnySimulation::Chain2($s) => $body,
            AnySimulation::Chain3($s) => $body,
            AnySimulation::Chain4($s) => $body,
            AnySimulation::Chain5($s) => $body,
            AnySimulation::Chain6($s) => $body,
            AnySimulation::Chain7($s) => $body,
            AnySimulation::Chain8($s) => $body,
        }
    };
}

/// A chain's simulation, boxed (as the three-link one): the variants differ in size by
/// kilobytes, and a simulation is built once per run, so the indirection costs nothing.
fn chain<const N: usize>(
    config: &ScenarioConfig,
    p: &UrdfArmParams,
) -> Result<Box<Simulation<UrdfArm<N>, N>>> {
    let arm = UrdfArm::<N>::new(p).map_err(|e| e.within("robot"))?;
    Simulation::with_robot(config, arm).map(Box::new)
}

impl AnySimulation {
    /// Validates `config` and builds the simulation of its arm.
    pub fn new(config: &ScenarioConfig) -> Result<Self> {
        config.validate()?;
        Ok(match &config.robot {
            RobotConfig::ThreeLink(_) => {
                AnySimulation::ThreeLink(Box::new(Simulation::new(config)?))
            }
            RobotConfig::Urdf(p) => {
                let n = p.dof().map_err(|e| e.within("robot"))?;
                match n {
                    1 => AnySimulation::Chain1(chain(config, p)?),
                    2 => AnySimulation::Chain2(chain(config, p)?),
                    3 => AnySimulation::Chain3(chain(config, p)?),
                    4 => AnySimulation::Chain4(chain(config, p)?),
                    5 => AnySimulation::Chain5(chain(config, p)?),
                    6 => AnySimulation::Chain6(chain(config, p)?),
                    7 => AnySimulation::Chain7(chain(config, p)?),
                    8 => AnySimulation::Chain8(chain(config, p)?),
                    _ => {
                        return Err(Error::parameter(
                            "robot.tip_link",
                            format!("a chain of {n} joints"),
                            "a chain of 1 to 8 joints",
                        ))
                    }
                }
            }
        })
    }

    /// The joint count.
    pub fn joints(&self) -> usize {
        dispatch!(self, s => s.trace().joints())
    }

    pub fn run(&mut self) -> RunResult {
        dispatch!(self, s => s.run())
    }

    pub fn reset(&mut self) {
        dispatch!(self, s => s.reset())
    }

    pub fn step(&mut self, n: usize) -> Option<Outcome> {
        dispatch!(self, s => s.step(n))
    }

    pub fn sample(&self) -> usize {
        dispatch!(self, s => s.sample())
    }

    pub fn samples(&self) -> usize {
        dispatch!(self, s => s.samples())
    }

    pub fn outcome(&self) -> Option<Outcome> {
        dispatch!(self, s => s.outcome())
    }

    pub fn trace(&self) -> &Trace {
        dispatch!(self, s => s.trace())
    }

    pub fn config(&self) -> &ScenarioConfig {
        dispatch!(self, s => s.config())
    }

    /// The metrics of the samples taken so far, for a run that ended with `outcome`.
    pub fn metrics(&self, outcome: &Outcome) -> Metrics {
        dispatch!(self, s => s.metrics(outcome))
    }

    /// Keeps no trace: the run is judged by its online metrics alone.
    pub fn without_trace(mut self) -> Self {
        dispatch!(&mut self, s => s.stop_recording());
        self
    }

    pub fn state(&self) -> Vec<f64> {
        dispatch!(self, s => s.state())
    }

    pub fn state_labels(&self) -> Vec<String> {
        dispatch!(self, s => s.state_labels())
    }

    pub fn set_state(&mut self, values: &[f64]) -> Result<()> {
        dispatch!(self, s => s.set_state(values))
    }

    /// Which runs this one may share lanes with: the arm's structure from its block, the
    /// plant's substeps and contact law, and the stages' own [`crate::sim::pipeline::StageKey`].
    pub fn lane_key(&self) -> LaneKey {
        let arm = match &self.config().robot {
            RobotConfig::ThreeLink(_) => ArmKey::ThreeLink,
            // The task kind decides the orientation rows and the posture term (SPEC §11).
            RobotConfig::Urdf(p) => ArmKey::Urdf {
                document: p.urdf.clone(),
                base_link: p.base_link.clone(),
                tip_link: p.tip_link.clone(),
                task: p.task,
            },
        };
        dispatch!(self, s => LaneKey {
            arm,
            substeps: s.plant().substeps(),
            environment: s.plant().environment().lane_key(),
            stages: s.stages().lane_key(),
        })
    }
}

/// Code that needs the typed simulation of a scenario's arm (the analysis builds many from
/// one scenario): `visit` is called once, with a builder for the arm's `Simulation<R, N>`.
pub trait ArmVisitor {
    type Output;
    fn visit<R: RobotModel<N>, const N: usize>(
        self,
        build: &(dyn Fn(&ScenarioConfig) -> Result<Simulation<R, N>> + Sync),
    ) -> Self::Output;
}

/// Builds the chain of `N` joints a config names (an error for any other arm).
fn build_chain<const N: usize>(config: &ScenarioConfig) -> Result<Simulation<UrdfArm<N>, N>> {
    config.validate()?;
    match &config.robot {
        RobotConfig::Urdf(p) => {
            let arm = UrdfArm::<N>::new(p).map_err(|e| e.within("robot"))?;
            Simulation::with_robot(config, arm)
        }
        RobotConfig::ThreeLink(_) => Err(Error::parameter(
            "robot",
            "the three-link arm",
            &format!("a URDF chain of {N} joints, as the scenario this one was derived from"),
        )),
    }
}

/// Calls `visitor` with the builder of `robot`'s simulation type.
pub fn visit_arm<V: ArmVisitor>(robot: &RobotConfig, visitor: V) -> Result<V::Output> {
    Ok(match robot {
        RobotConfig::ThreeLink(_) => visitor.visit(&Simulation::new),
        RobotConfig::Urdf(p) => match p.dof().map_err(|e| e.within("robot"))? {
            1 => visitor.visit(&build_chain::<1>),
            2 => visitor.visit(&build_chain::<2>),
            3 => visitor.visit(&build_chain::<3>),
            4 => visitor.visit(&build_chain::<4>),
            5 => visitor.visit(&build_chain::<5>),
            6 => visitor.visit(&build_chain::<6>),
            7 => visitor.visit(&build_chain::<7>),
            8 => visitor.visit(&build_chain::<8>),
            n => {
                return Err(Error::parameter(
                    "robot.tip_link",
                    format!("a chain of {n} joints"),
                    "a chain of 1 to 8 joints",
                ))
            }
        },
    })
}
