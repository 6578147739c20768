//! Batches of independent runs on all cores (rayon). Runs share nothing, so a batch gives
//! bit-identical results on 1 thread or many, and in any chunking.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::sim::dispatch::AnySimulation;
use crate::sim::metrics::Metrics;
use crate::sim::simulation::{Outcome, ScenarioConfig};
use crate::sim::trace::Trace;

/// What a batch keeps of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSummary {
    pub metrics: Metrics,
    pub outcome: Outcome,
    /// The full trace, when asked for.
    pub trace: Option<Trace>,
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
    // Every config is checked before anything runs; the runs are then built one at a time
    // inside the workers, so a large batch never holds more than one pipeline per thread.
    for (index, c) in configs.iter().enumerate() {
        AnySimulation::new(c).map_err(|error| BatchError { index, error })?;
    }
    let run_all = move || -> std::result::Result<Vec<RunSummary>, BatchError> {
        configs
            .par_iter()
            .enumerate()
            .map(|(index, c)| {
                let sim = AnySimulation::new(c).map_err(|error| BatchError { index, error })?;
                // Without traces a run keeps nothing but its online metrics.
                let mut sim = if keep_traces {
                    sim
                } else {
                    sim.without_trace()
                };
                let r = sim.run();
                Ok(RunSummary {
                    metrics: r.metrics,
                    outcome: r.outcome,
                    trace: keep_traces.then_some(r.trace),
                })
            })
            .collect()
    };
    match threads {
        None => run_all(),
        Some(n) => thread_pool(n)
            .map_err(|error| BatchError { index: 0, error })?
            .install(run_all),
    }
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
                wall: Some(WallParams {
                    stiffness: k,
                    ..WallParams::default()
                }),
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
        for (cfg, s) in c.iter().zip(&one) {
            let alone = crate::sim::simulation::simulate(cfg).unwrap();
            assert!(s.trace.as_ref() == Some(&alone.trace));
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
}
