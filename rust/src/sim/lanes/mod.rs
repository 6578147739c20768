//! SIMD lanes for sweeps (SPEC §13): runs of one structure advance four or eight at a time.
//!
//! Each lane is one ordinary `Simulation`, built by the ordinary constructor; it keeps the run's
//! trace, online metrics and outcome. Stage 9, the plant's RK4 substeps, runs once for all lanes on
//! a lane type `W` ([`F64x4`](crate::scalar::F64x4), or eight lanes, see [`LanePath`]): the same
//! `rk4_period` and the same [`ArmModel`] code (the three-link closed form, a chain's ABA) and
//! `Wall` code the scalar plant runs, with the arms' and walls' parameters packed
//! ([`RobotModel::pack`]). Stages 1–8 (environment, sensor, references, filter, controller,
//! actuator, record) run in lanes too (`stages::LaneStages`: the same
//! `sim::pipeline::Pipeline` a scalar run steps, over `W`). An arm brings nothing else: what runs
//! in lanes is its `ArmModel<W, N>`. Sweeps take the lanes for the arms whose
//! [`RobotModel::LANES`] holds (the three-link arm, 6- and 7-joint chains) and run other arms
//! one run at a time. A group whose runs do not share one stage structure (a
//! caller's mixed group; sweeps group by [`LaneKey`]) runs its stages lane by lane through
//! `Simulation::step_to_plant`.
//!
//! The loop is written once, generic over the lane type and its width `L`, and compiled
//! three times (issue #25): portable 4-wide, AVX2 + FMA 4-wide, AVX-512 8-wide; a runtime
//! check picks one ([`lane_path`]). Every operation is element-wise IEEE arithmetic (Rust
//! never fuses a multiply and an add on its own) and no lane's value depends on another's,
//! so the three give the same bits.
//!
//! A lane whose run ends (completed or diverged) takes the next run at the next period; at
//! the tail an idle lane repeats an active one and is discarded. No operation mixes lanes,
//! so a run's result does not depend on which runs share its group: tables do not depend
//! on grouping, threads or chunking. They differ from `simulate` of the same run only
//! through `exp` (a lane polynomial, within 2 ulp of libm's), far below SPEC §13's 1e-9.

use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};

use nalgebra::SVector;

use crate::robot::chain::TaskKind;
use crate::robot::{ArmModel, LaneConfigOf, RobotModel};
use crate::scalar::{lane, pack_vector, Real, Wide};
use crate::sim::pipeline::StageKey;
use crate::sim::plant::{rk4_period_on, Plant, PlantState};
use crate::sim::simulation::{RunResult, Simulation};
use crate::world::surface::{Environment, EnvironmentKey};
use stages::LaneStages;

mod builds;
#[cfg(test)]
mod chain;
#[cfg(test)]
mod paths;
pub mod stages;

/// What runs must share to advance in one group of lanes, each part given by its block:
/// the arm's structure, the RK4 loop count, the contact law's branch structure and the
/// stages' structure ([`StageKey`]). Everything else (every parameter) may differ between
/// lanes. Sweeps group runs by it (`AnySimulation::lane_key`); a group of one key always
/// packs into lanes (tested for every controller, outer loop and arm kind).
#[derive(Debug, Clone, PartialEq)]
pub struct LaneKey {
    pub arm: ArmKey,
    pub substeps: usize,
    pub environment: EnvironmentKey,
    pub stages: StageKey,
}

/// An arm's structure: the three-link closed form, or a URDF chain (its document, base and
/// tip links and task kind, `None`: the chain's default).
#[derive(Debug, Clone, PartialEq)]
pub enum ArmKey {
    ThreeLink,
    Urdf {
        document: String,
        base_link: Option<String>,
        tip_link: String,
        task: Option<TaskKind>,
    },
}

/// How `run_lanes` advanced a group's stages 1–8.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StagePath {
    /// In lanes: the group's runs share one [`StageKey`].
    Lanes,
    /// Lane by lane through `Simulation::step_to_plant` (only the RK4 plant in lanes): the
    /// explicit fallback for a caller's group whose runs do not share one stage structure.
    /// Sweeps never take it.
    PerLane,
}

/// The plants' parameters in lanes of `W`, rebuilt whenever a lane takes a new run.
pub struct PackedPlant<W: Real, A> {
    pub(crate) arm: A,
    pub(crate) environment: Environment<W>,
    substep: W,
    substeps: usize,
}

impl<W: Real, A> PackedPlant<W, A> {
    /// Out of line and cold, as every step below that runs only when a lane takes a new
    /// run: inlined, they spread the lane loop's hot code over more instruction cache
    /// (cachegrind: 47 % more L1i misses in `lanes_avx2` than before issue #20).
    #[cold]
    #[inline(never)]
    fn new<R: RobotModel<N, Lanes<W> = A>, const N: usize, const L: usize>(
        plants: [&Plant<R, N>; L],
    ) -> Self
    where
        W: Wide<L>,
    {
        let environment = match Environment::pack(plants.map(|p| p.environment())) {
            Some(e) => e,
            None => unreachable!("run_lanes_on checked one environment key"),
        };
        Self {
            arm: R::pack::<W, L>(plants.map(|p| p.arm().model())),
            environment,
            substep: W::from_lanes(|i| plants[i].substep()),
            substeps: plants[0].substeps(),
        }
    }
}

/// Runs every simulation of `sims` from its start to its end, four or eight at a time (on
/// the [`lane_path`]), and returns their results in order. All must share one [`LaneKey`]
/// (the scheduler's grouping).
pub fn run_lanes<R: RobotModel<N>, const N: usize>(
    sims: &mut [Simulation<R, N>],
) -> Vec<RunResult> {
    run_lanes_on(sims).0
}

/// `run_lanes`, saying how stages 1–8 advanced ([`StagePath`]).
pub fn run_lanes_on<R: RobotModel<N>, const N: usize>(
    sims: &mut [Simulation<R, N>],
) -> (Vec<RunResult>, StagePath) {
    run_lanes_via(sims, lane_path())
}

/// `run_lanes_on` on the build `path`, which this CPU must run ([`LanePath::available`];
/// one it cannot runs portably instead).
pub fn run_lanes_via<R: RobotModel<N>, const N: usize>(
    sims: &mut [Simulation<R, N>],
    path: LanePath,
) -> (Vec<RunResult>, StagePath) {
    // Plants of different structures cannot share RK4 lanes: a caller's mixed group runs
    // one by one (sweeps group by `LaneKey`, which holds these).
    let one_plant = sims.windows(2).all(|w| {
        let (a, b) = (w[0].plant(), w[1].plant());
        a.arm().same_structure(b.arm())
            && a.substeps() == b.substeps()
            && a.environment().lane_key() == b.environment().lane_key()
    });
    if !one_plant {
        return (
            sims.iter_mut().map(|s| s.run()).collect(),
            StagePath::PerLane,
        );
    }
    for s in sims.iter_mut() {
        s.reset();
    }
    let path = if path.available() {
        path
    } else {
        LanePath::Portable
    };
    let stages = match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `available` detected the features `builds::avx2::run` is compiled for.
        LanePath::Avx2 => unsafe { builds::avx2::run(sims) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above, for `builds::avx512::run`'s.
        LanePath::Avx512 => unsafe { builds::avx512::run(sims) },
        _ => builds::portable::run(sims),
    };
    if stages == StagePath::Lanes {
        RUNS[path as usize].fetch_add(sims.len() as u64, Ordering::Relaxed);
    }
    (sims.iter_mut().map(|s| s.take_result()).collect(), stages)
}

/// A build of the lane loop: the lane type it runs and the instructions it may use. All
/// three give the same bits (tested); they differ only in speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LanePath {
    /// [`F64x4`](crate::scalar::F64x4) in baseline x86-64 (SSE2) or the target's own code:
    /// any CPU.
    Portable = 0,
    /// [`F64x4Avx2`](crate::scalar::F64x4Avx2) (one ymm register per value) with AVX2 and
    /// FMA instructions available (the compiler never contracts a multiply and an add: FMA
    /// only speeds up what it emits on its own, e.g. none).
    Avx2 = 1,
    /// [`F64x8Avx512`](crate::scalar::F64x8Avx512) (one AVX-512 register per value) with
    /// AVX-512 F, DQ and VL.
    Avx512 = 2,
}

impl LanePath {
    pub const ALL: [LanePath; 3] = [LanePath::Portable, LanePath::Avx2, LanePath::Avx512];

    /// The name `ADMIT_RS_LANES` and `_core._lane_path` take.
    pub fn name(self) -> &'static str {
        match self {
            LanePath::Portable => "portable",
            LanePath::Avx2 => "avx2",
            LanePath::Avx512 => "avx512",
        }
    }

    /// The path of a name (`None` for any other).
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Runs per lane group.
    pub fn width(self) -> usize {
        match self {
            LanePath::Avx512 => 8,
            _ => 4,
        }
    }

    /// Whether this CPU runs this build (std caches the feature checks).
    pub fn available(self) -> bool {
        match self {
            LanePath::Portable => true,
            #[cfg(target_arch = "x86_64")]
            LanePath::Avx2 => crate::sim::plant::has_avx2_fma(),
            #[cfg(target_arch = "x86_64")]
            LanePath::Avx512 => {
                crate::sim::plant::has_avx2_fma()
                    && std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx512vl")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The default on this CPU: the 8-wide AVX-512 build where AVX-512 F, DQ and VL exist, else
    /// AVX2, else portable. With its native lane type ([`F64x8Avx512`](crate::scalar::F64x8Avx512))
    /// the 8-wide build ran fig. 19 sweeps 1.4× and Panda sweeps 1.7× faster than the 4-wide AVX2
    /// one on an Intel Xeon (docs/performance-history.md §23); on Zen 4, which splits each 512-bit
    /// operation in two, it is not measured (`ADMIT_RS_LANES=avx2` picks the 4-wide build).
    pub fn fastest() -> Self {
        [LanePath::Avx512, LanePath::Avx2, LanePath::Portable]
            .into_iter()
            .find(|p| p.available())
            .unwrap_or(LanePath::Portable)
    }
}

/// The forced path: `FORCE_UNSET` until `set_lane_path` or the first `lane_path` (which
/// reads `ADMIT_RS_LANES`), `FORCE_AUTO` for the default, else a `LanePath` as u8.
static FORCED: AtomicU8 = AtomicU8::new(FORCE_UNSET);
const FORCE_UNSET: u8 = u8::MAX;
const FORCE_AUTO: u8 = u8::MAX - 1;

/// Runs whose stages ran in lanes, per [`LanePath`] (since the process started): how tests
/// check which build a sweep really took.
static RUNS: [AtomicU64; 3] = [AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0)];

/// The build lane groups take: the one forced by [`set_lane_path`] or, at the first call,
/// by the environment variable `ADMIT_RS_LANES` (`portable`, `avx2`, `avx512`; `auto`,
/// unset, unknown or one this CPU lacks: the default), else [`LanePath::fastest`].
pub fn lane_path() -> LanePath {
    let mut forced = FORCED.load(Ordering::Relaxed);
    if forced == FORCE_UNSET {
        let from_env = std::env::var("ADMIT_RS_LANES")
            .ok()
            .and_then(|v| LanePath::parse(v.trim()))
            .filter(|p| p.available());
        let value = from_env.map_or(FORCE_AUTO, |p| p as u8);
        // A concurrent `set_lane_path` wins over the environment.
        forced =
            match FORCED.compare_exchange(FORCE_UNSET, value, Ordering::Relaxed, Ordering::Relaxed)
            {
                Ok(_) => value,
                Err(current) => current,
            };
    }
    LanePath::ALL
        .into_iter()
        .find(|p| *p as u8 == forced)
        .unwrap_or_else(LanePath::fastest)
}

/// Forces the build lane groups take from now on (`None`: the default). False, with
/// nothing changed, if this CPU cannot run `path`.
pub fn set_lane_path(path: Option<LanePath>) -> bool {
    if path.is_some_and(|p| !p.available()) {
        return false;
    }
    FORCED.store(path.map_or(FORCE_AUTO, |p| p as u8), Ordering::Relaxed);
    true
}

/// Runs whose stages 1–8 ran in lanes on each path, in [`LanePath::ALL`]'s order.
pub fn lane_runs() -> [u64; 3] {
    RUNS.each_ref().map(|r| r.load(Ordering::Relaxed))
}

#[inline(always)]
fn lanes_loop<W: Wide<L>, const L: usize, R: RobotModel<N>, const N: usize>(
    sims: &mut [Simulation<R, N>],
) -> StagePath {
    // Stages 1–8 in lanes only if every run of the group has one stage structure (sweeps
    // group by it; a caller's mixed group still runs, its stages lane by lane).
    let one_structure = sims
        .iter()
        .all(|s| s.stages().lane_key() == sims[0].stages().lane_key());
    let mut next = 0;
    let mut slot: [Option<usize>; L] = [None; L];
    let mut packed: Packed<W, L, R, N> = None;
    // The lane stages, once packed; `tried`: whether this group's structure has them (the
    // lane key makes it the same for every run of the group).
    let (mut front, mut tried): (Option<LaneStages<W, R, N>>, bool) = (None, false);
    loop {
        // A lane whose run is over takes the next one.
        let mut fresh = [false; L];
        for (l, s) in slot.iter_mut().enumerate() {
            while s.is_none() && next < sims.len() {
                if sims[next].outcome().is_none() {
                    *s = Some(next);
                    fresh[l] = true;
                }
                next += 1;
            }
        }
        let Some(first) = slot.iter().position(Option::is_some) else {
            break;
        };
        // Idle lanes repeat an active run (their results are discarded).
        let run: [usize; L] = slot.map(|s| s.or(slot[first]).unwrap_or(0));
        let plant = repack(&mut packed, sims, run);
        let mut start = LaneStart::gather(plant, sims, run);
        if !tried {
            front = if one_structure {
                LaneStages::pack(run.map(|i| &sims[i]))
            } else {
                None
            };
            tried = true;
        } else if let Some(f) = &mut front {
            for l in (0..L).filter(|&l| fresh[l]) {
                let fits = put_lane(f, l, &sims[run[l]]);
                // Every run of the group was checked to fit one pack before it began.
                debug_assert!(fits, "a run that does not fit its lane group");
            }
        }
        // Stages 1–8: in lanes, or lane by lane.
        let tau = match &mut front {
            Some(f) => f.step(plant, &start, sims, &slot, &run),
            None => per_lane(sims, &slot),
        };
        for (s, t) in slot.iter_mut().zip(&tau) {
            if t.is_none() {
                *s = None;
            }
        }
        let Some(first) = slot.iter().position(Option::is_some) else {
            continue;
        };
        let moved = slot.map(|s| s.or(slot[first]).unwrap_or(0));
        let lane_tau: [SVector<f64, N>; L] = std::array::from_fn(|l| {
            tau[if slot[l].is_some() { l } else { first }].unwrap_or_else(SVector::zeros)
        });
        let plant = repack(&mut packed, sims, moved);
        // Stage 9 in lanes, from the state stage 1 read (gathered again only if a lane's
        // run ended at this sample and the lane now repeats another).
        if moved != run {
            start = LaneStart::gather(plant, sims, moved);
        }
        let (q, qd) = rk4_period_on(
            &plant.arm,
            &plant.environment,
            (start.q, start.qd),
            start.config,
            plant.substep,
            plant.substeps,
            &pack_vector(std::array::from_fn(|l| &lane_tau[l])),
        );
        // Stage 9's write-back and the divergence check, per lane. Each run's own
        // configuration values are computed once its run is done (the lanes evaluate
        // theirs from q), unless its stages run lane by lane.
        let deferred = front.is_some();
        // Each value's lanes once, then each run's state written value by value: built
        // whole on the stack, a state was stored as scalars and copied as wide words, a
        // stalled store-to-load forward per lane (docs/performance-history.md §34).
        let lanes = |v: &SVector<W, N>| v.map(|x| std::array::from_fn::<f64, L, _>(|l| lane(x, l)));
        let (q, qd) = (lanes(&q), lanes(&qd));
        for (l, s) in slot.iter_mut().enumerate() {
            if let Some(i) = *s {
                let plant = sims[i].plant_mut();
                plant.write_state(|j| q[j][l], |j| qd[j][l]);
                if !deferred {
                    plant.refresh_config();
                }
                sims[i].after_plant();
                if sims[i].outcome().is_some() {
                    *s = None;
                }
            }
        }
    }
    for s in sims.iter_mut() {
        s.plant_mut().refresh_config();
    }
    if front.is_some() || sims.is_empty() {
        StagePath::Lanes
    } else {
        StagePath::PerLane
    }
}

/// The explicit fallback's stages 1–8, lane by lane (cold: see `PackedPlant::new`).
#[cold]
#[inline(never)]
fn per_lane<R: RobotModel<N>, const N: usize, const L: usize>(
    sims: &mut [Simulation<R, N>],
    slot: &[Option<usize>; L],
) -> [Option<SVector<f64, N>>; L] {
    std::array::from_fn(|l| slot[l].and_then(|i| sims[i].step_to_plant()))
}

/// Lane `l` of the stages takes the fresh run `sim` (cold: see `PackedPlant::new`).
#[cold]
#[inline(never)]
fn put_lane<W: Real, R: RobotModel<N>, const N: usize>(
    stages: &mut LaneStages<W, R, N>,
    l: usize,
    sim: &Simulation<R, N>,
) -> bool {
    stages.put_lane(l, sim)
}

/// The lanes' plant state at a period's start: stage 1 measures it, stage 9 integrates
/// from it. The configuration values (the three-link arm's trig, a chain's frames) are
/// evaluated once, in lanes, from q: for the three-link arm the same bits as each run's own
/// (`scalar::libm_sincos`).
pub struct LaneStart<W: Real, R: RobotModel<N>, const N: usize, const L: usize> {
    pub(crate) states: [PlantState<N>; L],
    pub(crate) q: SVector<W, N>,
    pub(crate) qd: SVector<W, N>,
    pub(crate) config: LaneConfigOf<R, W, N>,
}

impl<W: Wide<L>, R: RobotModel<N>, const N: usize, const L: usize> LaneStart<W, R, N, L> {
    #[inline(always)]
    fn gather(
        plant: &PackedPlant<W, R::Lanes<W>>,
        sims: &[Simulation<R, N>],
        run: [usize; L],
    ) -> Self {
        let states = run.map(|i| *sims[i].plant().state());
        let q = pack_vector(states.each_ref().map(|s| &s.q));
        let qd = pack_vector(states.each_ref().map(|s| &s.qd));
        let config = plant.arm.configure(&q);
        Self {
            states,
            q,
            qd,
            config,
        }
    }
}

/// The packed plants and the runs they were packed from.
type Packed<W, const L: usize, R, const N: usize> =
    Option<(PackedPlant<W, <R as RobotModel<N>>::Lanes<W>>, [usize; L])>;

/// The plants of `run` packed, rebuilt only when the lanes' runs changed.
#[inline(always)]
fn repack<'a, W: Wide<L>, const L: usize, R: RobotModel<N>, const N: usize>(
    packed: &'a mut Packed<W, L, R, N>,
    sims: &[Simulation<R, N>],
    run: [usize; L],
) -> &'a PackedPlant<W, R::Lanes<W>> {
    if packed.as_ref().is_some_and(|(_, runs)| *runs != run) {
        *packed = None;
    }
    &packed
        .get_or_insert_with(|| (PackedPlant::new(run.map(|i| sims[i].plant())), run))
        .0
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::robot::ThreeLinkArm;
    use crate::sim::scenario::ScenarioConfig;
    use crate::world::environment::WallParams;

    fn sims(stiffness: &[f64]) -> Vec<Simulation<ThreeLinkArm, 3>> {
        stiffness
            .iter()
            .map(|&k| {
                let config = ScenarioConfig {
                    wall: Some(
                        WallParams {
                            stiffness: k,
                            ..WallParams::default()
                        }
                        .into(),
                    ),
                    duration: 0.4,
                    ..ScenarioConfig::default()
                };
                Simulation::new(&config).expect("a valid scenario")
            })
            .collect()
    }

    /// Every metric and every trace value, as bits.
    pub(crate) fn bits(runs: &[RunResult]) -> Vec<u64> {
        runs.iter()
            .flat_map(|r| {
                let trace = r.trace.clone().into_named_columns().into_iter();
                r.metrics
                    .values()
                    .into_iter()
                    .chain(trace.flat_map(|(_, column)| column))
                    .collect::<Vec<_>>()
            })
            .map(f64::to_bits)
            .collect()
    }

    /// Runs `f` on a thread with a 256 MB stack: unoptimised (debug) builds give every
    /// temporary of the inlined lane loop its own stack slot, beyond a test thread's 2 MB.
    pub(crate) fn with_stack(f: fn()) {
        std::thread::Builder::new()
            .stack_size(256 << 20)
            .spawn(f)
            .expect("a test thread")
            .join()
            .expect("the test passes");
    }

    /// A run's result does not depend on the runs sharing its lanes, nor on its lane.
    #[test]
    fn a_lane_does_not_depend_on_its_neighbours() {
        with_stack(neighbours);
    }

    fn neighbours() {
        let alone = run_lanes(&mut sims(&[3e4]));
        let crowd = run_lanes(&mut sims(&[1e4, 3e4, 2e5, 7e4, 9e4, 3e4, 1.5e4]));
        assert_eq!(bits(&alone), bits(&crowd[1..2]));
        assert_eq!(bits(&alone), bits(&crowd[5..6]));
    }
}
