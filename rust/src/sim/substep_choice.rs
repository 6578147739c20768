//! `Scenario.substeps = "auto"`: the fewest RK4 substeps per period whose force trace is
//! within `Scenario.tolerance` of the exact one (issue #25, docs/substeps.md).
//!
//! The error is estimated over whole runs, by Richardson's argument: runs at n < m substeps
//! differ by D = max_k max(|Δf(t_k)|, |Δf_t(t_k)|), and while both are in the integrator's
//! asymptotic range (error ≈ C·hᵖ)
//!
//! ```text
//! E(n) = D / (1 − (n/m)ᵖ)          the coarser run's error, measured against the finer
//! E(m) = D / ((m/n)ᵖ − 1)          the finer run's, extrapolated (used only to aim)
//! ```
//!
//! p is not assumed: it is the order three runs show (`observed_order`), at most RK4's 4.
//! A contact that switches on inside a substep, or a damper that does, converges at a lower
//! order, and an error estimated as RK4's would then be too small.
//!
//! The search climbs counts 1, 2, 4, then as the extrapolated error aims (at half the
//! tolerance, at most doubling) until the finest run's extrapolated error meets the
//! tolerance at an order of at least 0.5. Then it returns the fewest count whose error is
//! *measured* against a finer run: the climb's runs, then up to two counts between the
//! fewest passing and the last failing one, as the error model aims (`descend`); if none
//! is measured, the finest run is measured against one of twice its count first. A run
//! that diverges at both counts of a pair, traces that stop converging (a bouncing, chaotic
//! contact) and [`MAX_AUTO_SUBSTEPS`] end the search with the finest run and a
//! [`Standing`] that says so.
//!
//! Every decision reads the run's own traces only, so a sweep's choice for a run does not
//! depend on its neighbours, the thread count or the chunking.

use crate::sim::outcome::{Standing, SubstepChoice, MAX_AUTO_SUBSTEPS, MIN_ORDER};
use crate::sim::scenario::{ScenarioConfig, DEFAULT_SUBSTEPS};
use crate::sim::simulation::RunResult;
use crate::sim::trace::ForceLog;

/// Classical RK4's order: the most the estimate credits, however fast the runs converge.
const ORDER: f64 = 4.0;
/// Runs that diverge at this many substeps and at the count before are the loop's
/// divergence, not the integrator's.
const RESOLVED: usize = 16;
/// The most counts measured between a failing and a passing one.
const MAX_DESCENT_PROBES: usize = 2;
/// The climb aims at this fraction of the tolerance: the estimate has its own error.
const AIM: f64 = 0.5;

/// The next thing the search needs.
#[derive(Debug, Clone, PartialEq)]
pub enum Next {
    /// A run at this count.
    Run(usize),
    /// The choice; `run` is the index, in the order they were asked for, of the run to return.
    Done { choice: SubstepChoice, run: usize },
}

#[derive(Debug, Clone)]
struct Probe {
    count: usize,
    /// Its order among the runs asked for.
    run: usize,
    forces: ForceLog,
    diverged: bool,
}

/// The count between a passing run and a failing one being measured.
#[derive(Debug, Clone)]
struct Descent {
    /// The fewest count known to meet the tolerance, and its estimate.
    best: Probe,
    best_error: f64,
    /// Whether `best_error` was measured against a finer run (else extrapolated).
    measured: bool,
    /// The largest count known not to.
    fails: usize,
    order: f64,
    /// Runs measured so far between the two.
    probes: usize,
}

/// The search for one run's count, fed one run at a time (`observe`).
#[derive(Debug, Clone)]
pub struct SubstepSearch {
    tolerance: f64,
    /// The climb's runs, counts increasing.
    climb: Vec<Probe>,
    /// `gaps[j − 1]`: D between `climb[j − 1]` and `climb[j]`.
    gaps: Vec<f64>,
    /// `orders[j − 2]`: the order observed over `climb[j − 2..=j]` (NaN: not measurable).
    orders: Vec<f64>,
    descent: Option<Descent>,
    /// The largest count a descent measured and found not to meet the tolerance.
    known_fail: usize,
    /// The first two runs had no contact force: the default count's run was asked for.
    untouched: bool,
    tried: Vec<usize>,
}

impl SubstepSearch {
    /// The counts every climb starts with, in order: 1 and 2, then 4 unless those two
    /// already settle the search (`observe`). A driver may start them early (`dispatch`).
    pub const CLIMB_START: [usize; 3] = [1, 2, 4];

    /// A search for `tolerance` [N], and the count of its first run.
    pub fn new(tolerance: f64) -> (Self, usize) {
        let search = Self {
            tolerance,
            climb: Vec::new(),
            gaps: Vec::new(),
            orders: Vec::new(),
            descent: None,
            known_fail: 0,
            untouched: false,
            tried: vec![Self::CLIMB_START[0]],
        };
        (search, Self::CLIMB_START[0])
    }

    /// The run just asked for (`count`), by its forces and whether it diverged; returns
    /// what comes next.
    pub fn observe(&mut self, count: usize, forces: ForceLog, diverged: bool) -> Next {
        let probe = Probe {
            count,
            run: self.tried.len() - 1,
            forces,
            diverged,
        };
        if let Some(d) = self.descent.take() {
            return self.descend_from(d, probe);
        }
        if std::mem::take(&mut self.untouched) && !probe.diverged && !probe.forces.touches() {
            return self.finish(&probe, f64::NAN, f64::NAN, Standing::NotAssessed);
        }
        // (A default-count run that touches joins the climb as its third run: the order
        // three runs show needs no particular counts.)
        self.climb.push(probe);
        let j = self.climb.len() - 1;
        // Only the last three climb runs can be returned or measured against (`descend`):
        // older force logs are dropped, so a search holds a few traces, not one per run.
        if j >= 3 {
            self.climb[j - 3].forces = ForceLog::default();
        }
        if j == 0 {
            return self.ask(Self::CLIMB_START[1]);
        }
        let gap = self.climb[j].forces.distance(&self.climb[j - 1].forces);
        self.gaps.push(gap);
        let (coarse, fine) = (&self.climb[j - 1], &self.climb[j]);
        let (c, f) = (coarse.count, fine.count);
        let untouched = |p: &Probe| !p.diverged && !p.forces.touches();
        if j == 1 && untouched(coarse) && untouched(fine) {
            // Forces of 0 N agree at any count, whatever the positions and torques do
            // (issue #53, item 5): the tolerance cannot judge these runs.
            self.untouched = true;
            return self.ask(DEFAULT_SUBSTEPS);
        }
        if j == 1 && coarse.diverged == fine.diverged {
            // Two runs so close that the coarser meets the tolerance at the slowest order
            // credited: no third run is needed to measure the order.
            let e = gap / coarse_factor(c, f, MIN_ORDER);
            if e <= self.tolerance {
                let coarse = coarse.clone();
                return self.finish(&coarse, e, f64::NAN, Standing::Met);
            }
        }
        if j >= 2 {
            let order = observed_order(self.climb[j - 2].count, c, f, self.gaps[j - 2], gap);
            self.orders.push(order);
        }
        // The order credited: the observed one (at most RK4's); before three runs, none
        // is known, and only a run that does not move at all is accepted.
        let order = self.orders.last().map_or(f64::NAN, |o| o.min(ORDER));
        let e_fine = if gap == 0.0 {
            0.0
        } else {
            gap / fine_factor(c, f, order)
        };
        // Both runs diverged: at one sample, the loop diverges and more substeps will not
        // change that; at different samples, coarse counts may be the integrator's own
        // instability, so the climb goes on while the period is coarsely resolved.
        if coarse.diverged && fine.diverged {
            let same_end = coarse.forces.len() == fine.forces.len();
            if same_end || f >= RESOLVED {
                // With no order measured yet, the slowest a converging run may have.
                let order = if order.is_nan() { MIN_ORDER } else { order };
                let e_fine = gap / fine_factor(c, f, order);
                let fine = fine.clone();
                return if e_fine <= self.tolerance {
                    self.finish(&fine, e_fine, order, Standing::Met)
                } else {
                    self.finish(&fine, gap, order, Standing::Diverged)
                };
            }
        }
        let converging = gap == 0.0 || order >= MIN_ORDER;
        if e_fine <= self.tolerance && converging {
            return self.descend(j, e_fine, order);
        }
        let fine = fine.clone();
        let slow = |o: &f64| o.is_finite() && *o < MIN_ORDER;
        if self.orders.len() >= 2 && self.orders.iter().rev().take(2).all(slow) {
            return self.finish(&fine, gap, order, Standing::NotConverging);
        }
        if f >= MAX_AUTO_SUBSTEPS {
            return self.finish(&fine, e_fine, order, Standing::Limit);
        }
        // Aim at the count the error model says meets half the tolerance, at most twice
        // this one (the model is fitted on coarser runs).
        let aim = f as f64 * (e_fine / (AIM * self.tolerance)).powf(1.0 / order);
        // Before an order is measured (j = 1) the model cannot aim: the climb doubles.
        let next = if j == 1 {
            Self::CLIMB_START[2]
        } else if aim.is_finite() {
            (aim.ceil() as usize).clamp(f + 1, 2 * f)
        } else {
            2 * f
        };
        self.ask(next.min(MAX_AUTO_SUBSTEPS))
    }

    /// The finer run of climb pair `j` meets the tolerance: the fewest passing count among
    /// the climb's last three runs (each measured against the next), then the counts between
    /// it and the count below, as the error model aims. Older runs are not looked at: their
    /// force logs are dropped and the driver keeps only these runs (`may_return`); one that
    /// passed at the order credited now would, at its own step, almost always have passed
    /// as the finer run of its pair and ended the climb there.
    fn descend(&mut self, j: usize, e_fine: f64, order: f64) -> Next {
        let mut best = (j, e_fine);
        for i in (j.saturating_sub(2)..j).rev() {
            let e = match self.gaps[i] {
                0.0 => 0.0,
                gap => gap / coarse_factor(self.climb[i].count, self.climb[i + 1].count, order),
            };
            let same_end = self.climb[i].diverged == self.climb[i + 1].diverged;
            if !(e <= self.tolerance && same_end) {
                break;
            }
            best = (i, e);
        }
        let (i, best_error) = best;
        let below = if i == 0 { 0 } else { self.climb[i - 1].count };
        let d = Descent {
            best: self.climb[i].clone(),
            best_error,
            measured: i < j,
            fails: below.max(self.known_fail),
            order,
            probes: 0,
        };
        let (count, error) = (d.best.count, d.best_error);
        self.aim_between(d, count, error)
    }

    /// The next count to measure between `d.fails` and `d.best`, aimed by the error model
    /// through (`count`, `error`), or the choice.
    fn aim_between(&mut self, d: Descent, count: usize, error: f64) -> Next {
        let fewest = count as f64 * (error / self.tolerance).powf(1.0 / d.order);
        let fewest = if fewest.is_finite() {
            (fewest.ceil() as usize).max(d.fails + 1)
        } else {
            d.fails + 1
        };
        if fewest >= d.best.count || d.probes >= MAX_DESCENT_PROBES {
            if !d.measured && d.best.count < MAX_AUTO_SUBSTEPS {
                // The fewest is the climb's last run, whose error is only extrapolated
                // (it leans on the order seen at coarser counts): measure it against a
                // run of twice its count first. That run goes on with the climb.
                return self.ask((2 * d.best.count).min(MAX_AUTO_SUBSTEPS));
            }
            return self.finish(&d.best, d.best_error, d.order, Standing::Met);
        }
        self.descent = Some(Descent {
            probes: d.probes + 1,
            ..d
        });
        self.ask(fewest)
    }

    /// A run between a failing and a passing count: measured against the passing one.
    fn descend_from(&mut self, mut d: Descent, probe: Probe) -> Next {
        let e = probe.forces.distance(&d.best.forces)
            / coarse_factor(probe.count, d.best.count, d.order);
        if e <= self.tolerance && probe.diverged == d.best.diverged {
            return self.finish(&probe, e, d.order, Standing::Met);
        }
        d.fails = probe.count;
        self.known_fail = self.known_fail.max(probe.count);
        self.aim_between(d, probe.count, e)
    }

    fn ask(&mut self, count: usize) -> Next {
        self.tried.push(count);
        Next::Run(count)
    }

    fn finish(&self, probe: &Probe, error: f64, order: f64, standing: Standing) -> Next {
        Next::Done {
            choice: SubstepChoice {
                substeps: probe.count,
                error,
                tolerance: self.tolerance,
                standing,
                order,
                tried: self.tried.clone(),
            },
            run: probe.run,
        }
    }

    /// Whether the run asked for as number `run` may still be the one returned (a driver
    /// keeps only those): the climb's last three and the descent's runs.
    pub fn may_return(&self, run: usize) -> bool {
        let descending = self.descent.as_ref().is_some_and(|d| d.best.run == run);
        let climb_tail = self.climb.iter().rev().take(3).any(|p| p.run == run);
        run + 1 == self.tried.len() || descending || climb_tail
    }
}

/// The order p that makes the model D = C·|a⁻ᵖ − b⁻ᵖ| give the two gaps observed over
/// counts a < b < c (`gap_ab`, `gap_bc`); at most 8 (pre-asymptotic runs can look faster
/// than any order), 0 when the gaps do not shrink as any positive order would, NaN when a
/// gap is infinite or both vanish.
fn observed_order(a: usize, b: usize, c: usize, gap_ab: f64, gap_bc: f64) -> f64 {
    let ratio = gap_ab / gap_bc;
    if !gap_ab.is_finite() || !gap_bc.is_finite() || ratio.is_nan() {
        return f64::NAN;
    }
    let (a, b, c) = (a as f64, b as f64, c as f64);
    // g(p) = (a⁻ᵖ − b⁻ᵖ)/(b⁻ᵖ − c⁻ᵖ) grows with p from ln(b/a)/ln(c/b) at p → 0.
    let g = |p: f64| (a.powf(-p) - b.powf(-p)) / (b.powf(-p) - c.powf(-p));
    let (mut lo, mut hi) = (1e-6, 8.0);
    if ratio <= g(lo) {
        return 0.0;
    }
    if ratio >= g(hi) {
        return hi;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if g(mid) < ratio {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// 1 − (n/m)ᵖ: D over this is the coarser run's error.
fn coarse_factor(n: usize, m: usize, order: f64) -> f64 {
    1.0 - (n as f64 / m as f64).powf(order)
}

/// (m/n)ᵖ − 1: D over this is the finer run's error.
fn fine_factor(n: usize, m: usize, order: f64) -> f64 {
    (m as f64 / n as f64).powf(order) - 1.0
}

/// One run a round asks for: `configs[index]` at `count` substeps, keeping its forces
/// (`RunResult::forces`) when `forces`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Request {
    pub index: usize,
    pub count: usize,
    pub forces: bool,
}

/// Runs every config: a fixed count once, `"auto"` by its search. Runs are asked for in
/// rounds (`round` runs a round's requests and returns their results in order: one by
/// one, or in lanes where their structure allows); every search takes its next count in
/// the next round. Results in the order of `configs`, an `"auto"` run's `choice` set.
pub fn run_all<E>(
    configs: &[ScenarioConfig],
    mut round: impl FnMut(&[Request]) -> std::result::Result<Vec<RunResult>, E>,
) -> std::result::Result<Vec<RunResult>, E> {
    struct Auto {
        search: SubstepSearch,
        runs: Vec<Option<RunResult>>,
    }
    let mut out: Vec<Option<RunResult>> = configs.iter().map(|_| None).collect();
    let mut autos: Vec<Option<Auto>> = configs.iter().map(|_| None).collect();
    let mut requests: Vec<Request> = Vec::with_capacity(configs.len());
    for (index, c) in configs.iter().enumerate() {
        let count = match c.substeps.count() {
            Some(count) => count,
            None => {
                let (search, count) = SubstepSearch::new(c.tolerance);
                autos[index] = Some(Auto {
                    search,
                    runs: Vec::new(),
                });
                count
            }
        };
        let forces = autos[index].is_some();
        requests.push(Request {
            index,
            count,
            forces,
        });
    }
    while !requests.is_empty() {
        let results = round(&requests)?;
        let mut next_round = Vec::new();
        let mut rerun = Vec::new();
        for (req, mut run) in requests.iter().zip(results) {
            let Some(auto) = &mut autos[req.index] else {
                out[req.index] = Some(run);
                continue;
            };
            let forces = run.forces.take().unwrap_or_default();
            let next = auto
                .search
                .observe(req.count, forces, run.outcome.is_diverged());
            auto.runs.push(Some(run));
            for (k, r) in auto.runs.iter_mut().enumerate() {
                if !auto.search.may_return(k) {
                    *r = None;
                }
            }
            match next {
                Next::Run(count) => next_round.push(Request {
                    index: req.index,
                    count,
                    forces: true,
                }),
                Next::Done { choice, run } => {
                    match auto.runs.get_mut(run).and_then(Option::take) {
                        Some(mut r) => {
                            r.choice = Some(choice);
                            out[req.index] = Some(r);
                        }
                        // Not reached (`may_return` keeps it); deterministic all the same.
                        None => rerun.push((req.index, choice)),
                    }
                    autos[req.index] = None;
                }
            }
        }
        for (index, choice) in rerun {
            let request = Request {
                index,
                count: choice.substeps,
                forces: false,
            };
            if let Some(mut r) = round(&[request])?.pop() {
                r.choice = Some(choice);
                out[index] = Some(r);
            }
        }
        requests = next_round;
    }
    Ok(out.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A force trace with an error C/nᵖ on top of a fixed signal.
    fn log_p(n: usize, c: f64, p: f64) -> ForceLog {
        let mut f = ForceLog::default();
        for k in 0..50 {
            let exact = (k as f64 * 0.1).sin() * 10.0;
            f.push(
                exact + c * (k as f64 * 0.37).cos() / (n as f64).powf(p),
                0.0,
            );
        }
        f
    }

    /// RK4's error, C/n⁴.
    fn log(n: usize, c: f64) -> ForceLog {
        log_p(n, c, 4.0)
    }

    #[test]
    fn the_observed_order_is_the_model_s() {
        for p in [0.5, 1.0, 2.0, 3.0, 4.0, 6.0] {
            for (a, b, c) in [(1, 2, 4), (2, 4, 7), (8, 11, 16)] {
                let d = |n: usize, m: usize| (n as f64).powf(-p) - (m as f64).powf(-p);
                let o = observed_order(a, b, c, 3.0 * d(a, b), 3.0 * d(b, c));
                assert!((o - p).abs() < 1e-9, "{p} over {a},{b},{c}: {o}");
            }
        }
        assert_eq!(observed_order(1, 2, 4, 1.0, 1.0), 0.0); // not shrinking
        assert_eq!(observed_order(1, 2, 4, 1.0, 1e-9), 8.0); // faster than any order
        assert!(observed_order(1, 2, 4, f64::INFINITY, 1.0).is_nan());
    }

    /// A long climb holds the force logs of its last three runs only: a 10⁷-sample run
    /// would otherwise keep one trace per count tried.
    #[test]
    fn a_long_climb_keeps_three_force_logs() {
        let (mut s, mut n) = SubstepSearch::new(1e-9);
        let mut runs = 0;
        while let Next::Run(next) = s.observe(n, log_p(n, 1e3, 1.0), false) {
            let kept = s.climb.iter().filter(|p| !p.forces.is_empty()).count();
            assert_eq!(kept, s.climb.len().min(3), "after {:?}", s.tried);
            n = next;
            runs += 1;
        }
        assert!(runs >= 5, "{:?}", s.tried);
        // The climb starts as it says (a driver starts these runs early).
        assert_eq!(s.tried[..3], SubstepSearch::CLIMB_START);
    }

    /// A run converging at a lower order (a contact onset within a substep, a damper
    /// that switches on) is estimated at the order it shows, so its error is not
    /// underestimated as an RK4 error would be.
    #[test]
    fn a_lower_order_is_measured_not_assumed() {
        for p in [1.0, 2.0, 3.0] {
            let amp = (0..50).fold(0.0_f64, |m, k| m.max((k as f64 * 0.37).cos().abs()));
            let tol = 1e-3;
            let choice = search(tol, |n| (log_p(n, 0.05, p), false));
            let truth = 0.05 * amp / (choice.substeps as f64).powf(p);
            assert!(choice.met(), "{p}: {choice:?}");
            assert!(
                truth <= tol * (1.0 + 1e-9),
                "order {p}: {choice:?}, true {truth:e}"
            );
            assert!((choice.order - p).abs() < 1e-6, "{choice:?}");
            let below = 0.05 * amp / ((choice.substeps - 1) as f64).powf(p);
            // The count below misses, or meets the tolerance by less than 1 % (the order
            // is measured to rounding, and the count rounded up).
            assert!(
                below > 0.99 * tol,
                "order {p}: {choice:?} is not the fewest"
            );
        }
    }

    /// Runs with no contact force agree at any count, so the force tolerance cannot judge
    /// them (issue #53, item 5): the default count's run, "not assessed", no error figure.
    #[test]
    fn runs_without_contact_force_are_not_assessed() {
        let zero = |n: usize| {
            let mut f = ForceLog::default();
            for _ in 0..50 {
                f.push(0.0, if n == 1 { f64::NAN } else { 0.0 });
            }
            (f, false)
        };
        let choice = search(1e-4, zero);
        assert_eq!(choice.standing, Standing::NotAssessed);
        assert_eq!(choice.substeps, DEFAULT_SUBSTEPS);
        assert_eq!(choice.tried, [1, 2, DEFAULT_SUBSTEPS]);
        assert!(choice.error.is_nan() && !choice.met());
        assert!(
            choice.describe().contains("could not assess"),
            "{}",
            choice.describe()
        );
        // A default-count run that touches after all joins the climb, which goes on.
        let late = search(1e-4, |n| {
            if n < DEFAULT_SUBSTEPS {
                zero(n)
            } else {
                (log(n, 1.0), false)
            }
        });
        assert_eq!(late.tried[..3], [1, 2, DEFAULT_SUBSTEPS]);
        assert!(
            late.tried.len() > 3 && late.standing != Standing::NotAssessed,
            "{late:?}"
        );
    }

    /// Drives a search over synthetic runs; returns the choice.
    fn search(tolerance: f64, run: impl Fn(usize) -> (ForceLog, bool)) -> SubstepChoice {
        let (mut s, first) = SubstepSearch::new(tolerance);
        let mut next = Next::Run(first);
        for _ in 0..100 {
            match next {
                Next::Run(n) => {
                    let (f, d) = run(n);
                    next = s.observe(n, f, d);
                }
                Next::Done { choice, run } => {
                    assert_eq!(choice.tried[run], choice.substeps);
                    return choice;
                }
            }
        }
        panic!("the search did not end");
    }

    /// On an exact h⁴ error the search returns the fewest count meeting the tolerance
    /// and an estimate equal to the true error.
    #[test]
    fn an_exact_fourth_order_error_gives_the_fewest_count() {
        let amp = (0..50).fold(0.0_f64, |m, k| m.max((k as f64 * 0.37).cos().abs()));
        let c = 0.2 * amp; // the largest error at n: c/n⁴
        for tol in [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7] {
            let choice = search(tol, |n| (log(n, 0.2), false));
            let fewest = (1..)
                .find(|&n: &usize| c / (n as f64).powi(4) <= tol)
                .unwrap();
            assert_eq!(choice.substeps, fewest, "tol {tol}: {choice:?}");
            let truth = c / (fewest as f64).powi(4);
            assert!(
                (choice.error - truth).abs() <= 1e-9 * truth.max(1e-12),
                "{choice:?}"
            );
            assert!(choice.met());
            // The climb runs each count once, at most one past the pair plus one between.
            let cost: usize = choice.tried.iter().sum();
            assert!(
                cost <= 4 * fewest + 3,
                "tol {tol}: tried {:?}",
                choice.tried
            );
        }
    }

    #[test]
    fn a_run_that_diverges_at_every_count_ends_once_resolved() {
        // Diverges at a sample that moves with the count.
        let choice = search(1e-6, |n| {
            let mut f = log(n, 1.0);
            f.f.truncate(10 + n);
            f.f_t.truncate(10 + n);
            (f, true)
        });
        assert_eq!(choice.standing, Standing::Diverged);
        assert_eq!(choice.tried, vec![1, 2, 4, 8, 16]);
        assert_eq!(choice.substeps, 16);
        assert!(choice.error.is_infinite());
        assert!(choice.describe().contains("diverges at every count"));
        // At one sample: the first pair decides, on its measured difference.
        let at_once = |c: f64| {
            search(1e-3, move |n| {
                let mut f = log(n, c);
                f.f.truncate(20);
                f.f_t.truncate(20);
                (f, true)
            })
        };
        assert_eq!(at_once(1.0).standing, Standing::Diverged);
        assert_eq!(at_once(1.0).tried, vec![1, 2]);
        assert_eq!(at_once(1e-5).standing, Standing::Met);
    }

    #[test]
    fn differences_that_stop_shrinking_end_the_search() {
        // Chaotic: every count gives a trace 0.1 N from every other.
        let choice = search(1e-6, |n| {
            let mut f = log(1, 0.0);
            f.f[7] += 0.1 * (n % 3) as f64 + 0.05;
            (f, false)
        });
        assert_eq!(choice.standing, Standing::NotConverging);
        assert_eq!(choice.tried, vec![1, 2, 4, 8]);
        assert!(!choice.met());
    }

    /// Coarse counts that blow up (an unstable integrator) are climbed past by doubling.
    #[test]
    fn an_unstable_integrator_at_few_substeps_is_climbed_past() {
        let choice = search(1e-4, |n| {
            if n < 8 {
                let mut f = log(n, 0.0);
                f.f.truncate(3 + n);
                f.f_t.truncate(3 + n);
                (f, true)
            } else {
                (log(n, 50.0), false)
            }
        });
        assert!(choice.met(), "{choice:?}");
        assert_eq!(&choice.tried[..4], &[1, 2, 4, 8]);
        assert!(50.0 / (choice.substeps as f64).powi(4) <= 1e-4);
    }

    /// The climb's last run is never returned on its extrapolated error alone: it is
    /// measured against twice its count first.
    #[test]
    fn the_finest_run_is_measured_before_it_is_returned() {
        let amp = (0..50).fold(0.0_f64, |m, k| m.max((k as f64 * 0.37).cos().abs()));
        let tol = 1.01 * 0.2 * amp / 256.0; // 4 substeps meet it, 3 do not
        let choice = search(tol, |n| (log(n, 0.2), false));
        assert_eq!(choice.substeps, 4, "{choice:?}");
        assert_eq!(choice.tried, vec![1, 2, 4, 8]);
        let truth = 0.2 * amp / 256.0;
        assert!((choice.error - truth).abs() <= 1e-9 * truth, "{choice:?}");
    }

    /// Two runs that agree far inside the tolerance settle it: the coarser meets it even
    /// at the slowest order credited, so no third run measures the order.
    #[test]
    fn two_close_runs_settle_it_at_the_slowest_order() {
        let choice = search(1e-3, |n| (log(n, 1e-6), false));
        assert_eq!((choice.substeps, choice.tried.clone()), (1, vec![1, 2]));
        assert!(choice.order.is_nan() && choice.met());
        let gap = 1e-6 * (1.0 - 1.0 / 16.0);
        assert!(choice.error >= gap / (1.0 - 0.5_f64.sqrt()) * (1.0 - 1e-3));
        assert!(choice.describe().contains("slowest order credited, 0.5"));
    }

    #[test]
    fn an_unreachable_tolerance_stops_at_the_limit() {
        let choice = search(1e-300, |n| (log(n, 1.0), false));
        assert_eq!(choice.standing, Standing::Limit);
        assert_eq!(choice.substeps, MAX_AUTO_SUBSTEPS);
    }
}
