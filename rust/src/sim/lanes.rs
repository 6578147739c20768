//! SIMD lanes for sweeps (SPEC §13): runs of one structure advance four at a time.
//!
//! Each lane is one ordinary `Simulation`, built by the ordinary constructor. Stages 1–8 of
//! a period (environment, sensor, references, filter, controller, actuator, record, online
//! metrics) run lane by lane; stage 9, the plant's RK4 substeps (about 90 % of a period),
//! runs once for all four lanes on [`F64x4`]: the same `rk4_period`, `ClosedForm` and
//! `Wall` code the scalar plant runs, with the four arms' and walls' parameters packed.
//!
//! A lane whose run ends (completed or diverged) takes the next run at once; at the tail an
//! idle lane repeats an active one and is discarded. No operation mixes lanes, so a run's
//! result does not depend on which runs share its group: tables do not depend on grouping,
//! threads or chunking. They differ from `simulate` of the same run only through `exp`
//! (a lane polynomial, within 2 ulp of libm's), far below SPEC §13's 1e-9.

use crate::robot::three_link::{ClosedForm, Trig};
use crate::robot::ThreeLinkArm;
use crate::scalar::{splat, F64x4, Real, LANES};
use crate::sim::plant::{rk4_period, PlantState, Stages};
use crate::sim::simulation::{RunResult, Simulation};
use crate::world::environment::{ContactModel, Wall};
use nalgebra::Vector3;

type ThreeLinkSim = Simulation<ThreeLinkArm, 3>;

/// What runs must share to advance in one group of lanes: the RK4 loop count and the
/// contact law's branch structure. Everything else (parameters, controllers, filters,
/// sensors, actuators) may differ between lanes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LaneKey {
    pub substeps: usize,
    pub wall: Option<ContactModel>,
}

impl LaneKey {
    pub fn of(sim: &ThreeLinkSim) -> Self {
        Self {
            substeps: sim.plant().substeps(),
            wall: sim.plant().wall().map(|w| w.model),
        }
    }
}

/// Four plants' parameters in lanes, rebuilt whenever a lane takes a new run.
struct PackedPlant {
    form: ClosedForm<F64x4>,
    wall: Option<Wall<F64x4>>,
    needs_rate: bool,
    substep: F64x4,
    substeps: usize,
}

impl PackedPlant {
    fn new(sims: [&ThreeLinkSim; LANES]) -> Self {
        let plants = sims.map(|s| s.plant());
        let wall = plants[0].wall().map(|_| {
            Wall::pack(std::array::from_fn(|i| {
                plants[i]
                    .wall()
                    .expect("a lane group shares wall presence (LaneKey)")
            }))
        });
        Self {
            form: ClosedForm::pack(plants.map(|p| p.arm().closed_form())),
            needs_rate: plants
                .iter()
                .any(|p| p.wall().is_some_and(|w| w.needs_rate())),
            wall,
            substep: F64x4::from_lanes(|i| plants[i].substep()),
            substeps: plants[0].substeps(),
        }
    }
}

impl Stages<F64x4, 3> for PackedPlant {
    type Config = Trig<F64x4>;

    #[inline(always)]
    fn acceleration(
        &self,
        c: &Trig<F64x4>,
        qd: &Vector3<F64x4>,
        tau: &Vector3<F64x4>,
    ) -> Vector3<F64x4> {
        match &self.wall {
            Some(w) => {
                let contact = |along, rate| w.force_along(along, rate);
                self.form
                    .accelerate(c, qd, tau, &contact, &w.normal, self.needs_rate)
                    .0
            }
            None => {
                let free = |_, _| splat::<F64x4>(0.0);
                let x = Vector3::x().map(splat::<F64x4>);
                self.form.accelerate(c, qd, tau, &free, &x, false).0
            }
        }
    }

    #[inline(always)]
    fn shift(
        &self,
        c: &Trig<F64x4>,
        delta: &Vector3<F64x4>,
        shifted: &Vector3<F64x4>,
    ) -> Trig<F64x4> {
        c.shifted(delta, shifted)
    }
}

/// Runs every simulation of `sims` from its start to its end, four at a time, and returns
/// their results in order. All must share one [`LaneKey`] (the scheduler's grouping).
pub fn run_lanes(sims: &mut [ThreeLinkSim]) -> Vec<RunResult> {
    debug_assert!(sims
        .windows(2)
        .all(|w| LaneKey::of(&w[0]) == LaneKey::of(&w[1])));
    for s in sims.iter_mut() {
        s.reset();
    }
    #[cfg(target_arch = "x86_64")]
    if crate::sim::plant::has_avx2_fma() {
        // SAFETY: the features `lanes_avx2` is compiled for were detected just above.
        unsafe { lanes_avx2(sims) };
        return sims.iter_mut().map(|s| s.take_result()).collect();
    }
    lanes_loop(sims);
    sims.iter_mut().map(|s| s.take_result()).collect()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn lanes_avx2(sims: &mut [ThreeLinkSim]) {
    lanes_loop(sims)
}

#[inline(always)]
fn lanes_loop(sims: &mut [ThreeLinkSim]) {
    if sims.is_empty() {
        return;
    }
    let mut next = 0;
    let mut slot: [Option<usize>; LANES] = [None; LANES];
    let mut tau = [Vector3::<f64>::zeros(); LANES];
    let mut packed: Option<(PackedPlant, [usize; LANES])> = None;
    loop {
        // Stages 1–8 in every lane; a lane whose run is over takes the next one.
        for l in 0..LANES {
            loop {
                let i = match slot[l] {
                    Some(i) => i,
                    None if next < sims.len() => {
                        next += 1;
                        next - 1
                    }
                    None => break,
                };
                slot[l] = None;
                if sims[i].outcome().is_some() {
                    continue;
                }
                if let Some(t) = sims[i].step_to_plant() {
                    tau[l] = t;
                    slot[l] = Some(i);
                    break;
                }
            }
        }
        let Some(first) = slot.iter().position(Option::is_some) else {
            break;
        };
        // Idle lanes repeat an active run (their results are discarded).
        let run: [usize; LANES] = slot.map(|s| s.or(slot[first]).unwrap_or(0));
        let lane_tau: [Vector3<f64>; LANES] =
            std::array::from_fn(|l| tau[if slot[l].is_some() { l } else { first }]);
        if packed.as_ref().is_none_or(|(_, runs)| *runs != run) {
            packed = Some((PackedPlant::new(run.map(|i| &sims[i])), run));
        }
        let Some((plant, _)) = packed.as_ref() else {
            break;
        };
        let pack =
            |v: [&Vector3<f64>; LANES]| Vector3::from_fn(|j, _| F64x4::from_lanes(|i| v[i][j]));
        let states = run.map(|i| sims[i].plant().state());
        let (q, qd) = rk4_period(
            plant,
            (pack(states.map(|s| &s.q)), pack(states.map(|s| &s.qd))),
            Trig::pack(run.map(|i| sims[i].plant().config())),
            plant.substep,
            plant.substeps,
            &pack(std::array::from_fn(|l| &lane_tau[l])),
        );
        // Stage 9's write-back and the divergence check, per lane.
        for (l, active) in slot.iter().enumerate() {
            if let Some(i) = *active {
                let unpack = |v: &Vector3<F64x4>| v.map(|x| crate::scalar::lane(x, l));
                sims[i].plant_mut().set_state(PlantState {
                    q: unpack(&q),
                    qd: unpack(&qd),
                });
                sims[i].after_plant();
            }
        }
    }
}
