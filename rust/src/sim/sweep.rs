//! Batches of independent runs on all cores (rayon). Runs share nothing, so a batch gives
//! bit-identical results on 1 thread or many, and in any chunking.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::sim::criteria::Holds;
use crate::sim::dispatch::AnySimulation;
use crate::sim::held;
use crate::sim::lanes::LaneKey;
use crate::sim::metrics::Metrics;
use crate::sim::outcome::SubstepChoice;
use crate::sim::simulation::{Outcome, RunResult, ScenarioConfig};
use crate::sim::substep_choice::{run_all, Request};
use crate::sim::trace::Trace;

/// What a batch keeps of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSummary {
    pub metrics: Metrics,
    pub outcome: Outcome,
    /// The full trace, when asked for.
    pub trace: Option<Trace>,
    /// What `substeps = "auto"` chose; `None` for a fixed count.
    pub choice: Option<SubstepChoice>,
}

/// A parameter error in one run of a batch: its index in the batch and the error.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchError {
    pub index: usize,
    pub error: Error,
}

/// Validates every config first (nothing runs if one is invalid), then runs them all on
/// `threads` threads (`None`: rayon's global pool, one thread per core).
pub fn run_batch(
    configs: &[ScenarioConfig],
    threads: Option<usize>,
    keep_traces: bool,
) -> std::result::Result<Vec<RunSummary>, BatchError> {
    run_batch_with(configs, threads, keep_traces, true)
}

/// `run_batch`, with the SIMD lanes (`sim::lanes`) on or off. Off is the scalar path, each
/// run bit-identical to `simulate`; on, runs agree with it to SPEC §13's 1e-9
/// (`exp` differs in the last bits). Either way a run's result does not depend on the
/// batch, its chunking or the thread count.
pub fn run_batch_with(
    configs: &[ScenarioConfig],
    threads: Option<usize>,
    keep_traces: bool,
    lanes: bool,
) -> std::result::Result<Vec<RunSummary>, BatchError> {
    // Every config is checked before anything runs; the runs are then built one at a time
    // inside the workers, so a large batch never holds more than one pipeline per thread.
    for (index, c) in configs.iter().enumerate() {
        check(c).map_err(|error| BatchError { index, error })?;
    }
    let run_all = move || -> std::result::Result<Vec<RunSummary>, BatchError> {
        let mut runs = run_blocks(configs, keep_traces, lanes)?;
        settle(configs, &mut runs, lanes)?;
        Ok(runs)
    };
    match threads {
        None => run_all(),
        Some(n) => thread_pool(n)
            .map_err(|error| BatchError { index: 0, error })?
            .install(run_all),
    }
}

/// Every config's run, in blocks on the current pool's threads; results in run order.
fn run_blocks(
    configs: &[ScenarioConfig],
    keep_traces: bool,
    lanes: bool,
) -> std::result::Result<Vec<RunSummary>, BatchError> {
    let blocks = blocks(configs.len(), block_size(configs.len(), lanes));
    let runs: Vec<Vec<RunSummary>> = blocks
        .par_iter()
        .map(|block| run_block(configs, block.clone(), keep_traces, lanes))
        .collect::<std::result::Result<_, _>>()?;
    Ok(runs.into_iter().flatten().collect())
}

/// Judges the runs that need their held run (`sim::held`, SPEC §23): the held runs go as one
/// more batch (in lanes where they fit), each a function of its own config alone, so the
/// verdicts do not depend on the batch either.
fn settle(
    configs: &[ScenarioConfig],
    runs: &mut [RunSummary],
    lanes: bool,
) -> std::result::Result<(), BatchError> {
    let mut wanted: Vec<(usize, Holds)> = Vec::new();
    let mut held_configs: Vec<ScenarioConfig> = Vec::new();
    for (index, (config, run)) in configs.iter().zip(runs.iter_mut()).enumerate() {
        let count = run.choice.as_ref().map(|c| c.substeps);
        if let Some((held, holds)) = held::plan(config, &mut run.metrics, &run.outcome, count) {
            wanted.push((index, holds));
            held_configs.push(held);
        }
    }
    if held_configs.is_empty() {
        return Ok(());
    }
    let held_runs = run_blocks(&held_configs, false, lanes).map_err(|e| BatchError {
        index: wanted.get(e.index).map_or(0, |w| w.0),
        error: e.error,
    })?;
    for ((index, holds), h) in wanted.into_iter().zip(held_runs) {
        let run = &mut runs[index];
        held::attach(
            &mut run.metrics,
            &run.outcome,
            &h.metrics,
            &h.outcome,
            holds,
        );
    }
    Ok(())
}

/// Runs per block: with lanes, every thread of the pool gets the same number of equal
/// blocks (a thread with one block more than another would leave a core idle at the end of
/// the call); without, one run per block.
fn block_size(runs: usize, lanes: bool) -> usize {
    if !lanes {
        return 1;
    }
    let per_worker = runs.div_ceil(rayon::current_num_threads().max(1)).max(1);
    per_worker.div_ceil(per_worker.div_ceil(LANE_BLOCK))
}

/// Most runs per block of the lane scheduler: a block's runs of one [`LaneKey`] advance four
/// at a time (`sim::lanes`); blocks are the parallel tasks, so a batch is cut into blocks of
/// at most its share per thread.
const LANE_BLOCK: usize = 64;

/// What runs may share lanes: one arm structure (the three-link arm, or one URDF chain with
/// one task kind), substep count and contact law, and one stage structure (`StageKey`), as
/// every arm's stages 1–8 run in lanes. Every parameter may differ (lanes carry their own).
/// Consecutive runs, at most `size` per block, in run order.
fn blocks(n: usize, size: usize) -> Vec<std::ops::Range<usize>> {
    (0..n.div_ceil(size))
        .map(|b| b * size..((b + 1) * size).min(n))
        .collect()
}

/// Validates a config as a run: `"auto"` as its first candidate count.
fn check(c: &ScenarioConfig) -> Result<()> {
    match c.substeps.count() {
        Some(_) => AnySimulation::new(c).map(drop),
        None => AnySimulation::new(&c.with_substeps(1)).map(drop),
    }
}

fn summary(r: RunResult, keep_traces: bool) -> RunSummary {
    RunSummary {
        metrics: r.metrics,
        outcome: r.outcome,
        trace: keep_traces.then_some(r.trace),
        choice: r.choice,
    }
}

/// One block's runs, in rounds (`substep_choice::run_all`: a fixed count runs in the
/// first round, `"auto"` runs its candidates round after round). With `lanes`, a round's
/// runs of each lane key advance in lanes (even a lone run, in an otherwise idle group, so
/// a run takes the same path in any chunking); the rest, and every run without `lanes`,
/// one by one. Results come back in run order.
fn run_block(
    configs: &[ScenarioConfig],
    block: std::ops::Range<usize>,
    keep_traces: bool,
    lanes: bool,
) -> std::result::Result<Vec<RunSummary>, BatchError> {
    let start = block.start;
    let build = |r: &Request| {
        let i = start + r.index;
        AnySimulation::for_request(&configs[i], r, keep_traces)
            .map_err(|error| BatchError { index: i, error })
    };
    let round = |requests: &[Request]| -> std::result::Result<Vec<RunResult>, BatchError> {
        let sims: Vec<AnySimulation> = requests
            .iter()
            .map(build)
            .collect::<std::result::Result<_, _>>()?;
        Ok(run_round(sims, lanes))
    };
    let runs = run_all(&configs[block], round)?;
    Ok(runs.into_iter().map(|r| summary(r, keep_traces)).collect())
}

/// Runs `sims`: with `lanes`, those of one [`LaneKey`] together in lanes (keys grouped in
/// order of first appearance), else one by one. Results in the order of `sims`.
fn run_round(sims: Vec<AnySimulation>, lanes: bool) -> Vec<RunResult> {
    if !lanes {
        return sims.into_iter().map(|mut s| s.run()).collect();
    }
    // Each run's key comes from its built stages, so grouping and packing cannot disagree.
    let keys: Vec<LaneKey> = sims.iter().map(AnySimulation::lane_key).collect();
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (k, key) in keys.iter().enumerate() {
        match groups.iter_mut().find(|g| keys[g[0]] == *key) {
            Some(g) => g.push(k),
            None => groups.push(vec![k]),
        }
    }
    let mut sims: Vec<Option<AnySimulation>> = sims.into_iter().map(Some).collect();
    let mut out: Vec<Option<RunResult>> = sims.iter().map(|_| None).collect();
    for members in groups {
        let group: Vec<AnySimulation> = members.iter().filter_map(|&k| sims[k].take()).collect();
        for (&k, r) in members.iter().zip(AnySimulation::run_lanes(group)) {
            out[k] = Some(r);
        }
    }
    out.into_iter().flatten().collect()
}

fn thread_pool(threads: usize) -> Result<rayon::ThreadPool> {
    if threads == 0 {
        return Err(Error::parameter("threads", threads, "an integer >= 1"));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| {
            Error::parameter(
                "threads",
                threads,
                &format!("a thread count the OS allows ({e})"),
            )
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::environment::WallParams;

    fn configs() -> Vec<ScenarioConfig> {
        [1e4, 3e4, 1e5, 2e5]
            .iter()
            .map(|&k| ScenarioConfig {
                wall: Some(
                    WallParams {
                        stiffness: k,
                        ..WallParams::default()
                    }
                    .into(),
                ),
                duration: 0.3,
                ..ScenarioConfig::default()
            })
            .collect()
    }

    /// Bit patterns of everything a run produced (NaN metrics compare equal to themselves).
    fn bits(runs: &[RunSummary]) -> Vec<u64> {
        runs.iter()
            .flat_map(|r| {
                let trace = r
                    .trace
                    .iter()
                    .flat_map(|t| t.clone().into_named_columns())
                    .flat_map(|(_, column)| column);
                r.metrics
                    .values()
                    .into_iter()
                    .chain(trace)
                    .collect::<Vec<_>>()
            })
            .map(f64::to_bits)
            .collect()
    }

    #[test]
    fn identical_on_one_and_many_threads() {
        let c = configs();
        let one = run_batch(&c, Some(1), true).unwrap();
        let two = run_batch(&c, Some(2), true).unwrap();
        let global = run_batch(&c, None, true).unwrap();
        assert!(bits(&one) == bits(&two), "1 vs 2 threads differ");
        assert!(
            bits(&one) == bits(&global),
            "1 thread vs global pool differ"
        );
        // Chunked: the last two on their own give the same as within the batch.
        let tail = run_batch(&c[2..], Some(2), true).unwrap();
        assert!(bits(&one[2..]) == bits(&tail), "chunking changed results");
        // The scalar path is `simulate` bit for bit; lanes agree with it to 1e-9 (SPEC §13).
        let scalar = run_batch_with(&c, Some(2), true, false).unwrap();
        for ((cfg, s), l) in c.iter().zip(&scalar).zip(&one) {
            let alone = crate::sim::dispatch::simulate(cfg).unwrap();
            assert!(s.trace.as_ref() == Some(&alone.trace));
            let (Some(a), Some(b)) = (&s.trace, &l.trace) else {
                panic!("traces were kept");
            };
            for ((name, x), (_, y)) in a
                .clone()
                .into_named_columns()
                .into_iter()
                .zip(b.clone().into_named_columns())
            {
                let scale = x.iter().fold(1e-12_f64, |m, v| m.max(v.abs()));
                let worst = x
                    .iter()
                    .zip(&y)
                    .fold(0.0_f64, |m, (p, q)| m.max((p - q).abs()));
                assert!(worst <= 1e-9 * scale, "{name}: {worst:e} of {scale:e}");
            }
        }
    }

    #[test]
    fn invalid_run_is_reported_by_index_and_nothing_runs() {
        let mut c = configs();
        c[2].period = -1.0;
        let e = run_batch(&c, Some(2), false).unwrap_err();
        assert_eq!(e.index, 2);
        assert!(e.error.to_string().starts_with("period = -1"));
        assert!(run_batch(&configs(), Some(0), false).is_err());
    }

    /// URDF runs group by their stage structure and task kind as well as their chain (their
    /// stages 1–8 run in lanes); parameters do not split groups.
    #[test]
    fn urdf_lane_key_holds_the_stage_structure() {
        use crate::control::params::{ControllerParams, ModelFreeParams, TimeDelayParams};
        use crate::robot::chain::{TaskKind, UrdfArmParams};
        use crate::sim::scenario::RobotConfig;
        let arm = UrdfArmParams {
            urdf: include_str!("../../../examples/data/three_link.urdf").to_owned(),
            tip_link: "tip".to_owned(),
            ..UrdfArmParams::default()
        };
        let run = |arm: &UrdfArmParams, controller: ControllerParams, latency: usize| {
            let mut c = ScenarioConfig {
                robot: RobotConfig::Urdf(arm.clone()),
                controller,
                ..ScenarioConfig::default()
            };
            c.sensor.latency = latency;
            AnySimulation::new(&c).unwrap().lane_key()
        };
        let tdc = |inertia: f64| {
            ControllerParams::TimeDelay(TimeDelayParams {
                inertia,
                ..TimeDelayParams::default()
            })
        };
        let key = run(&arm, tdc(0.1), 0);
        assert_eq!(key, run(&arm, tdc(0.2), 0));
        assert_ne!(key, run(&arm, tdc(0.1), 1));
        let mf = ControllerParams::ModelFree(ModelFreeParams::default());
        assert_ne!(key, run(&arm, mf, 0));
        let pose = UrdfArmParams {
            task: Some(TaskKind::Pose),
            ..arm.clone()
        };
        assert_ne!(key, run(&pose, tdc(0.1), 0));
    }
}
