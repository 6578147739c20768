//! One simulation type for every arm: the three-link arm (closed form) or a URDF chain of 1
//! to 8 joints, each a `Simulation<R, N>` compiled for its joint count (const generics:
//! fixed-size workspaces, no allocation per step). The joint count is matched once, in
//! [`visit_arm`], when a simulation is built; every call after that goes through one small
//! object interface to the typed simulation, whose step loop is monomorphised.

use std::any::Any;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{Error, Result};
use crate::robot::chain::{unsupported_joints, with_joints, JointCount, UrdfArm};
use crate::robot::RobotModel;
use crate::sim::held;
use crate::sim::lanes::{run_lanes, ArmKey, LaneKey};
use crate::sim::metrics::Metrics;
use crate::sim::outcome::Outcome;
use crate::sim::scenario::{RobotConfig, ScenarioConfig};
use crate::sim::simulation::{RunResult, Simulation};
use crate::sim::substep_choice::{run_all, Request, SubstepSearch};
use crate::sim::trace::Trace;

/// The count `substeps = "auto"` climbs to third, the longest of the runs its search
/// always starts with (unless the first two settle it).
const RUN_AHEAD: usize = SubstepSearch::CLIMB_START[2];

/// Validates, builds and runs one scenario, whatever its arm; `substeps = "auto"` runs
/// the candidates of `sim::substep_choice` and returns the chosen one.
///
/// For `"auto"`, when rayon has more than one thread and this call is not on one of its
/// workers, the search's 4-substep run starts on a second thread beside the 1 and the 2
/// (the longest of the three, so the climb's wall time is about that run's); if the search
/// ends without it, it is stopped. Each run is the same function of the config on either
/// thread, so the choice and the result are the same bits as one after another
/// (docs/substeps.md, "Time").
///
/// A run that fails a criterion the loop may sustain is judged by its held run too
/// (`sim::held`, SPEC §23).
pub fn simulate(config: &ScenarioConfig) -> Result<RunResult> {
    let mut run = if config.substeps.count().is_some() {
        AnySimulation::new(config)?.run()
    } else {
        config.validate()?;
        let ahead = rayon::current_num_threads() > 1 && rayon::current_thread_index().is_none();
        search_substeps(config, ahead)?
    };
    let count = run.choice.as_ref().map(|c| c.substeps);
    held::settle(config, &mut run.metrics, &run.outcome, count, run_held)?;
    Ok(run)
}

/// A held run (`sim::held`): its metrics and outcome, no trace.
pub fn run_held(config: &ScenarioConfig) -> Result<(Metrics, Outcome)> {
    let run = match config.substeps.count() {
        Some(_) => AnySimulation::new(config)?.without_trace().run(),
        None => search_substeps(config, false)?,
    };
    Ok((run.metrics, run.outcome))
}

/// `"auto"`'s search for a validated `config`, with the 4-substep run started ahead on a
/// second thread or not (the same result either way: tested).
fn search_substeps(config: &ScenarioConfig, ahead: bool) -> Result<RunResult> {
    let run_at = |count: usize, stop: &AtomicBool| -> Result<Option<RunResult>> {
        let request = Request {
            index: 0,
            count,
            forces: true,
        };
        Ok(AnySimulation::for_request(config, &request, true)?.run_unless(stop))
    };
    let stop = AtomicBool::new(false);
    let mut runs = std::thread::scope(|scope| {
        let mut early = ahead.then(|| scope.spawn(|| run_at(RUN_AHEAD, &stop)));
        let runs = run_all(std::slice::from_ref(config), |requests| {
            requests
                .iter()
                .map(|r| {
                    if r.count == RUN_AHEAD {
                        if let Some(Ok(done)) = early.take().map(|h| h.join()) {
                            if let Some(run) = done? {
                                return Ok(run);
                            }
                        }
                    }
                    Ok(AnySimulation::for_request(config, r, true)?.run())
                })
                .collect::<Result<Vec<_>>>()
        });
        // The search is over: a 4-substep run it did not ask for stops here.
        stop.store(true, Ordering::Relaxed);
        runs
    })?;
    // `run_all` returns one run per config; an empty answer would be a bug of the search.
    runs.pop().ok_or_else(|| {
        Error::parameter(
            "substeps",
            "\"auto\"",
            "a count the search settles on (internal error: it returned no run; please report)",
        )
    })
}

/// A simulation of any supported arm: the typed `Simulation<R, N>` behind one small
/// object interface ([`TypedRun`]). Calls go through it once per call, never per step.
#[derive(Debug)]
pub struct AnySimulation(Box<dyn TypedRun>);

impl Clone for AnySimulation {
    fn clone(&self) -> Self {
        Self(self.0.clone_box())
    }
}

/// What the typed simulation of any arm answers (object safe: [`AnySimulation`] holds one).
trait TypedRun: Send + Sync + std::fmt::Debug {
    fn run(&mut self) -> RunResult;
    fn run_unless(&mut self, stop: &AtomicBool) -> Option<RunResult>;
    fn reset(&mut self);
    fn step(&mut self, n: usize) -> Option<Outcome>;
    fn sample(&self) -> usize;
    fn samples(&self) -> usize;
    fn outcome(&self) -> Option<Outcome>;
    fn trace(&self) -> &Trace;
    fn config(&self) -> &ScenarioConfig;
    fn metrics(&self, outcome: &Outcome) -> Metrics;
    fn stop_recording(&mut self);
    fn keep_forces(&mut self);
    fn state(&self) -> Vec<f64>;
    fn state_labels(&self) -> Vec<String>;
    fn set_state(&mut self, values: &[f64]) -> Result<()>;
    fn lane_key(&self) -> LaneKey;
    fn clone_box(&self) -> Box<dyn TypedRun>;
    fn as_any(&self) -> &dyn Any;
    fn into_any(self: Box<Self>) -> Box<dyn Any>;
    /// Runs this run and `rest` (of its lane key, so of its arm type) in lanes; results in
    /// order, this run's first.
    fn run_lanes_with(self: Box<Self>, rest: Vec<AnySimulation>) -> Vec<RunResult>;
}

impl<R: RobotModel<N>, const N: usize> TypedRun for Simulation<R, N> {
    fn run(&mut self) -> RunResult {
        Simulation::run(self)
    }

    fn run_unless(&mut self, stop: &AtomicBool) -> Option<RunResult> {
        Simulation::run_unless(self, stop)
    }

    fn reset(&mut self) {
        Simulation::reset(self)
    }

    fn step(&mut self, n: usize) -> Option<Outcome> {
        Simulation::step(self, n)
    }

    fn sample(&self) -> usize {
        Simulation::sample(self)
    }

    fn samples(&self) -> usize {
        Simulation::samples(self)
    }

    fn outcome(&self) -> Option<Outcome> {
        Simulation::outcome(self)
    }

    fn trace(&self) -> &Trace {
        Simulation::trace(self)
    }

    fn config(&self) -> &ScenarioConfig {
        Simulation::config(self)
    }

    fn metrics(&self, outcome: &Outcome) -> Metrics {
        Simulation::metrics(self, outcome)
    }

    fn stop_recording(&mut self) {
        Simulation::stop_recording(self)
    }

    fn keep_forces(&mut self) {
        Simulation::keep_forces(self)
    }

    fn state(&self) -> Vec<f64> {
        Simulation::state(self)
    }

    fn state_labels(&self) -> Vec<String> {
        Simulation::state_labels(self)
    }

    fn set_state(&mut self, values: &[f64]) -> Result<()> {
        Simulation::set_state(self, values)
    }

    fn lane_key(&self) -> LaneKey {
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
        LaneKey {
            arm,
            substeps: self.plant().substeps(),
            environment: self.plant().environment().lane_key(),
            stages: self.stages().lane_key(),
        }
    }

    fn clone_box(&self) -> Box<dyn TypedRun> {
        Box::new(self.clone())
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn into_any(self: Box<Self>) -> Box<dyn Any> {
        self
    }

    fn run_lanes_with(self: Box<Self>, rest: Vec<AnySimulation>) -> Vec<RunResult> {
        let mut typed = vec![*self];
        let mut others = Vec::new();
        for (k, mut other) in rest.into_iter().enumerate() {
            if other.0.as_any().is::<Simulation<R, N>>() {
                if let Ok(s) = other.0.into_any().downcast::<Simulation<R, N>>() {
                    typed.push(*s);
                }
            } else {
                // Not reached (one key is one arm type); right all the same: it runs alone.
                others.push((k + 1, other.run()));
            }
        }
        // A constant per arm type: the lane loop is not even compiled for an arm without it
        // (rustc collects no item from a branch a constant rules out).
        let mut results = if R::LANES {
            run_lanes(&mut typed)
        } else {
            typed.iter_mut().map(|s| s.run()).collect()
        };
        for (k, r) in others {
            results.insert(k, r);
        }
        results
    }
}

impl AnySimulation {
    /// Validates `config` and builds the simulation of its arm.
    pub fn new(config: &ScenarioConfig) -> Result<Self> {
        config.validate()?;
        struct Build<'a>(&'a ScenarioConfig);
        impl ArmVisitor for Build<'_> {
            type Output = Result<AnySimulation>;
            fn visit<R: RobotModel<N>, const N: usize>(
                self,
                build: &(dyn Fn(&ScenarioConfig) -> Result<Simulation<R, N>> + Sync),
            ) -> Result<AnySimulation> {
                Ok(AnySimulation(Box::new(build(self.0)?)))
            }
        }
        visit_arm(&config.robot, Build(config))?
    }

    /// The joint count.
    pub fn joints(&self) -> usize {
        self.0.trace().joints()
    }

    pub fn run(&mut self) -> RunResult {
        self.0.run()
    }

    /// [`Simulation::run_unless`]: the run, or `None` if `stop` was set before it ended.
    pub fn run_unless(&mut self, stop: &AtomicBool) -> Option<RunResult> {
        self.0.run_unless(stop)
    }

    pub fn reset(&mut self) {
        self.0.reset()
    }

    pub fn step(&mut self, n: usize) -> Option<Outcome> {
        self.0.step(n)
    }

    pub fn sample(&self) -> usize {
        self.0.sample()
    }

    pub fn samples(&self) -> usize {
        self.0.samples()
    }

    pub fn outcome(&self) -> Option<Outcome> {
        self.0.outcome()
    }

    pub fn trace(&self) -> &Trace {
        self.0.trace()
    }

    pub fn config(&self) -> &ScenarioConfig {
        self.0.config()
    }

    /// The metrics of the samples taken so far, for a run that ended with `outcome`.
    pub fn metrics(&self, outcome: &Outcome) -> Metrics {
        self.0.metrics(outcome)
    }

    /// The run `request` asks of `config`: at the request's count where `config` says
    /// `"auto"`, with the force log if the search reads it, and with its trace only if
    /// `keep_trace` (else it keeps its online metrics alone).
    pub fn for_request(
        config: &ScenarioConfig,
        request: &Request,
        keep_trace: bool,
    ) -> Result<Self> {
        let sim = match config.substeps.count() {
            Some(_) => Self::new(config)?,
            None => Self::new(&config.with_substeps(request.count))?,
        };
        let sim = if request.forces {
            sim.with_forces()
        } else {
            sim
        };
        Ok(if keep_trace { sim } else { sim.without_trace() })
    }

    /// Keeps no trace: the run is judged by its online metrics alone.
    pub fn without_trace(mut self) -> Self {
        self.0.stop_recording();
        self
    }

    /// Also keeps f and f_t of every sample (`RunResult::forces`), trace or not.
    pub fn with_forces(mut self) -> Self {
        self.0.keep_forces();
        self
    }

    pub fn state(&self) -> Vec<f64> {
        self.0.state()
    }

    pub fn state_labels(&self) -> Vec<String> {
        self.0.state_labels()
    }

    pub fn set_state(&mut self, values: &[f64]) -> Result<()> {
        self.0.set_state(values)
    }

    /// Which runs this one may share lanes with: the arm's structure from its block, the
    /// plant's substeps and contact law, and the stages' own [`crate::sim::pipeline::StageKey`].
    pub fn lane_key(&self) -> LaneKey {
        self.0.lane_key()
    }

    /// Runs `sims`, one lane group (runs of one [`LaneKey`], so of one arm type), in lanes;
    /// results in the order of `sims`.
    pub fn run_lanes(sims: Vec<AnySimulation>) -> Vec<RunResult> {
        let mut sims = sims.into_iter();
        match sims.next() {
            Some(first) => first.0.run_lanes_with(sims.collect()),
            None => Vec::new(),
        }
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

/// Calls `visitor` with the builder of `robot`'s simulation type: the one match on the arm
/// (and, through `with_joints`, on a chain's joint count).
pub fn visit_arm<V: ArmVisitor>(robot: &RobotConfig, visitor: V) -> Result<V::Output> {
    struct Chain<V>(V);
    impl<V: ArmVisitor> JointCount for Chain<V> {
        type Output = V::Output;
        fn visit<const N: usize>(self) -> V::Output {
            self.0.visit(&build_chain::<N>)
        }
    }
    match robot {
        RobotConfig::ThreeLink(_) => Ok(visitor.visit(&Simulation::new)),
        RobotConfig::Urdf(p) => {
            let n = p.dof().map_err(|e| e.within("robot"))?;
            with_joints(n, Chain(visitor)).ok_or_else(|| unsupported_joints(n))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::scenario::Substeps;

    /// Equal to the bit: `{:?}` prints every float's shortest round trip, and NaN metrics
    /// (no settling in a short run) compare equal, as `==` would not have them.
    fn same(a: &RunResult, b: &RunResult) -> bool {
        format!("{a:?}") == format!("{b:?}")
    }

    fn auto(tolerance: f64) -> ScenarioConfig {
        ScenarioConfig {
            duration: 0.3,
            substeps: Substeps::Auto,
            tolerance,
            ..ScenarioConfig::default()
        }
    }

    /// The 4-substep run started ahead gives the search's choice and run bit for bit,
    /// whether the search asks for it (a tight tolerance) or stops it unasked (a loose one,
    /// met by the 1 and the 2 alone).
    #[test]
    fn running_ahead_changes_no_bit() {
        for (tolerance, asks_for_four) in [(1e-7, true), (10.0, false)] {
            let config = auto(tolerance);
            let alone = search_substeps(&config, false).unwrap();
            let ahead = search_substeps(&config, true).unwrap();
            let tried = &alone.choice.as_ref().unwrap().tried;
            assert_eq!(tried.contains(&RUN_AHEAD), asks_for_four, "{tried:?}");
            assert!(same(&ahead, &alone), "tolerance {tolerance}");
        }
    }

    /// Sweeps run the three-link arm and 6- and 7-joint chains in lanes, other chains one
    /// run at a time: a 3-joint chain's batch gives each run's `run` bits exactly (the lanes'
    /// `exp` would differ in the last bits), and the lane loop is not compiled for it.
    #[test]
    fn only_the_three_link_arm_and_six_or_seven_joints_run_in_lanes() {
        use crate::robot::chain::UrdfArmParams;
        use crate::robot::three_link::ThreeLinkArm;
        let lanes = |n| with_joints(n, Lanes).unwrap_or(true);
        assert!(ThreeLinkArm::LANES && lanes(6) && lanes(7));
        assert!(!(1..=5).any(lanes) && !lanes(8));
        let arm = UrdfArmParams {
            urdf: include_str!("../../../examples/data/three_link.urdf").to_owned(),
            tip_link: "tip".to_owned(),
            ..UrdfArmParams::default()
        };
        let configs: Vec<ScenarioConfig> = (0..5)
            .map(|i| {
                let mut c = ScenarioConfig {
                    robot: RobotConfig::Urdf(arm.clone()),
                    duration: 0.2,
                    ..ScenarioConfig::default()
                };
                c.sensor.noise_std = 0.1 * i as f64;
                c
            })
            .collect();
        let batch = AnySimulation::run_lanes(
            configs
                .iter()
                .map(|c| AnySimulation::new(c).unwrap())
                .collect(),
        );
        for (c, r) in configs.iter().zip(&batch) {
            assert!(same(r, &AnySimulation::new(c).unwrap().run()));
        }
    }

    struct Lanes;
    impl JointCount for Lanes {
        type Output = bool;
        fn visit<const N: usize>(self) -> bool {
            <UrdfArm<N> as RobotModel<N>>::LANES
        }
    }

    /// A run told to stop gives nothing; one never told finishes with `run`'s bits.
    #[test]
    fn run_unless_stops_or_equals_run() {
        let config = ScenarioConfig {
            duration: 0.2,
            ..ScenarioConfig::default()
        };
        let mut sim = AnySimulation::new(&config).unwrap();
        let whole = sim.run();
        let unstopped = sim.run_unless(&AtomicBool::new(false)).unwrap();
        assert!(same(&unstopped, &whole));
        assert!(sim.run_unless(&AtomicBool::new(true)).is_none());
    }
}
