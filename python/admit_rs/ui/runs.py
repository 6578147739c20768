"""The page's work, off the server's event loop: a run and a prediction per state, each on
its own worker thread (both release the GIL in Rust, so they use both cores), coalesced.

:class:`Coalescer` keeps at most one job running and one waiting: a new state replaces the
waiting one (the last value always wins; fast drags never queue stale runs), and a long run
sees it between chunks (:class:`Job.stale`) and stops. Nothing here knows Bokeh.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from admit_rs import _core, analysis
from admit_rs.analysis.linear import _with_friction
from admit_rs.config import Scenario, Wall
from admit_rs.errors import AdmitError
from admit_rs.simulation import Result, Simulation, simulate

log = logging.getLogger("admit_rs.ui")

FIRST_CHUNK = 1000
"""Samples stepped before the run's length is estimated."""
CHUNK_SECONDS = 0.1
"""A long run is stepped in chunks of about this many seconds (progress, cancel)."""
PROGRESS_AFTER = 0.3
"""A run shows progress once it is estimated to take longer than this [s]."""


@dataclass
class Job:
    """One state to compute. ``stale()`` is true once a newer state waits or the user
    pressed cancel; ``cancelled`` tells the two apart."""

    generation: int
    scenario: Scenario
    _coalescer: Coalescer | None = field(default=None, repr=False)
    cancelled: bool = False

    def stale(self) -> bool:
        c = self._coalescer
        return self.cancelled or (c is not None and c.newer_than(self.generation))


class Coalescer:
    """One worker thread; ``submit`` replaces any waiting job; ``work(job)`` runs on the
    thread. Jobs run in submission order, so results arrive in order."""

    IDLE_EXIT = 30.0
    """The worker thread ends after this many seconds without a job (a new one starts on
    the next submit); between jobs of a drag it waits, so no thread is started per job."""

    def __init__(self, work: Callable[[Job], None], name: str) -> None:
        self._work = work
        self._name = name
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._waiting: Job | None = None
        self._running: Job | None = None
        self._latest = 0
        self._thread: threading.Thread | None = None
        self._closed = False

    def submit(self, generation: int, scenario: Scenario) -> None:
        with self._lock:
            if self._closed:
                return
            self._latest = max(self._latest, generation)
            self._waiting = Job(generation, scenario, self)
            if self._thread is None:
                self._thread = threading.Thread(target=self._loop, name=self._name, daemon=True)
                self._thread.start()
            else:
                self._wake.notify()

    def newer_than(self, generation: int) -> bool:
        return self._latest > generation

    def cancel(self) -> bool:
        """Cancels the running job (a long run stops at its next chunk); True if one ran."""
        with self._lock:
            job = self._running
            if job is not None:
                job.cancelled = True
            return job is not None

    def close(self) -> None:
        with self._lock:
            self._closed = True
            self._waiting = None
            if self._running is not None:
                self._running.cancelled = True
            self._wake.notify()

    def _loop(self) -> None:
        while True:
            with self._lock:
                if self._waiting is None and not self._closed:
                    self._wake.wait(self.IDLE_EXIT)
                job, self._waiting = self._waiting, None
                self._running = job
                if job is None or self._closed:
                    self._thread = None
                    self._running = None
                    return
            try:
                self._work(job)
            except Exception:  # a bug in the page's code: logged, the worker lives on
                log.exception("admit-rs ui: %s failed", self._name)
            finally:
                with self._lock:
                    self._running = None


# -- what a run shows ----------------------------------------------------------------------


@dataclass
class RunView:
    """A run's columns as the plots draw them, and its words."""

    columns: dict[str, npt.NDArray[np.float64]]
    joints: int
    metrics: dict[str, Any]
    verdict: str
    stable: bool | None
    passed: bool | None
    torque_limits: tuple[float, ...] | None
    duration: float
    complete: bool
    """False when the run was cancelled: ``columns`` hold the samples up to then."""
    plotted: dict[str, npt.NDArray[np.float64]] | None = None
    """``columns`` at :func:`plot_indices` (what the browser draws), once computed."""


def _directions(scenario: Scenario) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    wall = scenario.wall if scenario.wall is not None else Wall()
    return wall.directions()


def view_of(scenario: Scenario, trace: Any, joints: int) -> dict[str, npt.NDArray[np.float64]]:
    """The plotted columns of a trace: t; f, f_measured, f_d; the tip and its reference
    along n (``pos_n``, ``ref_n``) and along t̂ (``pos_t``, ``ref_t``); x_a; tau1..n."""
    n, t = _directions(scenario)

    def col(name: str) -> npt.NDArray[np.float64]:
        return np.ascontiguousarray(trace[name].to_numpy(), dtype=np.float64)

    xyz = [col("x"), col("y"), col("z")]
    ref = [col("x_ref"), col("y_ref"), col("z_ref")]
    out = {
        "t": col("t"),
        "f": col("f"),
        "f_measured": col("f_measured"),
        "f_d": col("f_d"),
        "pos_n": n[0] * xyz[0] + n[1] * xyz[1] + n[2] * xyz[2],
        "ref_n": n[0] * ref[0] + n[1] * ref[1] + n[2] * ref[2],
        "pos_t": t[0] * xyz[0] + t[1] * xyz[1] + t[2] * xyz[2],
        "ref_t": t[0] * ref[0] + t[1] * ref[1] + t[2] * ref[2],
        "x_a": col("x_a"),
    }
    for j in range(1, joints + 1):
        out[f"tau{j}"] = col(f"tau{j}")
    return out


PLOT_BUCKETS = 600
"""Buckets of :func:`plot_indices`: more than the plots' inner width in pixels."""


def plot_indices(columns: dict[str, npt.NDArray[np.float64]],
                 buckets: int = PLOT_BUCKETS) -> npt.NDArray[np.int64]:  # fmt: skip
    """The samples the plots draw: per bucket of consecutive samples, its first and last
    and, for every column, the sample of its minimum and of its maximum. A line through
    these is the full line at the plots' resolution (every peak kept, sample for sample),
    with a few times fewer points for the browser to index and paint; every plotted point is
    a sample of the run, unchanged."""
    n = len(columns["t"])
    if n <= 2 * buckets:
        return np.arange(n, dtype=np.int64)
    size = -(-n // buckets)
    starts = np.arange(0, n, size, dtype=np.int64)
    padded = len(starts) * size
    picks = [starts, np.minimum(starts + size - 1, n - 1)]
    for name, y in columns.items():
        if name == "t":
            continue
        v = np.pad(np.nan_to_num(y, nan=0.0), (0, padded - n), mode="edge").reshape(-1, size)
        picks.append(starts + np.argmin(v, axis=1))
        picks.append(starts + np.argmax(v, axis=1))
    return np.unique(np.minimum(np.concatenate(picks), n - 1))


def decimated(columns: dict[str, npt.NDArray[np.float64]]) -> dict[str, npt.NDArray[np.float64]]:
    """The columns at :func:`plot_indices`."""
    idx = plot_indices(columns)
    return {k: np.ascontiguousarray(v[idx]) for k, v in columns.items()}


def joint_count(trace_columns: list[str]) -> int:
    return sum(1 for c in trace_columns if c.startswith("tau") and c[3:].isdigit())


def run(job: Job, progress: Callable[[float, float], None]) -> RunView | None:
    """Steps ``job.scenario`` to its end (the same code as :func:`admit_rs.simulate`, bit
    for bit); a long run is stepped in chunks of about :data:`CHUNK_SECONDS`, reporting
    ``progress(done_s, total_s)`` and stopping early when the job goes stale: ``None`` if a
    newer state waits, a partial view if the user cancelled. Parameter errors raise."""
    sc = job.scenario
    if sc.substeps == "auto":
        # "auto" chooses its count by comparing whole runs (issue #53 item 10: every run of
        # such a scenario failed here): the run goes whole, as ar.simulate gives it, without
        # progress or cancel.
        res = simulate(sc)
        return _view(res, joint_count(res.trace.columns))
    sim = Simulation(sc)
    total = sc.samples
    start = time.perf_counter()
    taken = sim.step(min(FIRST_CHUNK, total))
    shown = False
    while not sim.done:
        elapsed = time.perf_counter() - start
        rate = taken / max(elapsed, 1e-6)  # samples per second
        remaining = total - sim.sample
        if not shown and remaining / rate + elapsed < PROGRESS_AFTER:
            taken += sim.step(remaining)
            continue
        if job.stale():
            if not job.cancelled:
                return None
            trace = sim.trace
            joints = joint_count(trace.columns)
            return RunView(view_of(sc, trace, joints), joints, {}, "cancelled", None, None,
                           _limits(sc, joints), sc.duration, complete=False)  # fmt: skip
        shown = True
        progress(sim.time, sc.duration)
        taken += sim.step(max(FIRST_CHUNK, int(rate * CHUNK_SECONDS)))
    res = sim.result()
    joints = joint_count(res.trace.columns)
    return _view(res, joints)


def _limits(sc: Scenario, joints: int) -> tuple[float, ...] | None:
    lim = sc.actuator.torque_limit
    if lim is None:
        return None
    values = tuple(float(v) for v in np.atleast_1d(np.asarray(lim, dtype=float)))
    return values * joints if len(values) == 1 else values


def _view(res: Result, joints: int) -> RunView:
    sc = res.scenario
    return RunView(
        columns=view_of(sc, res.trace, joints), joints=joints, metrics=dict(res.metrics),
        verdict=res.verdict, stable=res.stable, passed=res.passed,
        torque_limits=_limits(sc, joints), duration=sc.duration, complete=True,
    )  # fmt: skip


# -- what the linear model predicts -------------------------------------------------------


@dataclass
class Prediction:
    """``predict``'s numbers, the poles of the model they come from, or why there are none."""

    values: dict[str, float | bool | str | None] | None
    poles: npt.NDArray[np.complex128] | None
    error: str | None = None
    period: float = 0.0
    """The model's sample period T [s] (the poles are of z = e^(sT))."""

    def dominant(self) -> complex | None:
        """The pole of largest modulus (the page's red cross), or None without poles."""
        if self.poles is None or len(self.poles) == 0:
            return None
        return complex(self.poles[int(np.argmax(np.abs(self.poles)))])


REAL_POLE_TOL = 1e-9
"""A pole is real when its imaginary part is below this fraction of its modulus (the
eigenvalues of a real matrix come as exact conjugate pairs or with imaginary part 0)."""


def dominant_words(pole: complex, period: float) -> list[tuple[str, str, str]]:
    """(what, value, unit) rows that describe the dominant pole truthfully.

    A complex pair is a damped oscillation: its frequency and damping ratio ζ (the s-plane
    pole s = ln(z)/T). A real pole does not oscillate, so a frequency of 0 Hz and ζ = 1
    would mislead: it is described by z and its time constant τ = −T / ln|z| (the time
    its mode takes to fall to 1/e; a pole outside the unit circle grows by e every
    T / ln|z| instead). A negative real pole flips sign every sample."""
    r = abs(pole)
    if r == 0.0:
        return [("dominant pole", "real, z = 0", "(gone after one sample)")]
    if abs(pole.imag) > REAL_POLE_TOL * r:
        s = complex(np.log(pole)) / period
        freq = abs(s.imag) / (2 * math.pi)
        zeta = -s.real / abs(s)
        return [
            ("dominant pole pair", f"{pole.real:.5g} ± {abs(pole.imag):.3g}j", ""),
            ("dominant pole frequency", f"{freq:.4g}", "Hz"),
            ("dominant pole damping ζ", f"{zeta:.3g}", ""),
        ]
    z = pole.real
    rows = [("dominant pole", f"real, z = {z:.6g}",
             "(flips sign every sample)" if z < 0 else "")]  # fmt: skip
    log_r = math.log(r)
    if log_r < 0:
        rows.append(("time constant τ", f"{-period / log_r:.4g}", "s"))
    elif log_r > 0:
        rows.append(("grows by e every", f"{period / log_r:.4g}", "s"))
    else:
        rows.append(("time constant τ", "∞", "(on the unit circle)"))
    return rows


def predict(scenario: Scenario) -> Prediction:
    """:func:`admit_rs.analysis.predict` and the eigenvalues of the same linear model
    (friction at the describing-function amplitude that ``predict`` used)."""
    try:
        values = analysis.predict(scenario)
    except (AdmitError, ValueError, TypeError) as e:
        return Prediction(None, None, str(e), scenario.period)
    amp = float(values.get("friction_amplitude", 0.0))  # type: ignore[arg-type]
    try:
        model = _with_friction(scenario, amp) if amp > 0 else scenario
        raw = _core.linearize(model._to_core(), None)
        poles = np.linalg.eigvals(np.asarray(raw["a"], dtype=float))
    except (AdmitError, ValueError, np.linalg.LinAlgError) as e:
        return Prediction(values, None, str(e), scenario.period)
    return Prediction(values, poles.astype(np.complex128), None, scenario.period)


def disagreement(view: RunView, pred: Prediction) -> str | None:
    """One line on why the predicted and the simulated ``stable`` differ (SPEC §23), or
    ``None`` when they agree or one of them is missing."""
    if not view.complete or view.stable is None or pred.values is None:
        return None
    predicted = bool(pred.values.get("stable"))
    if predicted == view.stable:
        return None
    radius = pred.values.get("spectral_radius")
    rho = float(radius) if isinstance(radius, int | float) else math.nan
    verdict = str(pred.values.get("verdict", ""))
    if predicted:
        return _large_signal(view, "the linear model") or (
            "the run oscillates by itself at an amplitude the linear model, exact only for "
            "small signals about the equilibrium, does not reach")
    if verdict.startswith("unstable: no contact equilibrium"):
        return (f"the linearisation found no contact equilibrium ({verdict.split(': ', 2)[-1]}) "
                "where the run settles in contact")  # fmt: skip
    if math.isfinite(rho) and rho < 1.0:
        return (f"the linear model is stable (ρ = {rho:.5g}) but misses a margin of "
                f"ar.analysis.Margins ({verdict.removeprefix('unstable: ')}); the run has no "
                "margin to miss")  # fmt: skip
    return (f"the linear model is unstable about the equilibrium (ρ = {rho:.5g} ≥ 1); in the "
            "run the oscillation is held by what the model leaves out (Coulomb friction "
            "beyond its describing-function gain, the contact clamp), or grows too slowly to "
            f"fail within {view.duration:g} s")  # fmt: skip


def _large_signal(view: RunView, model: str) -> str | None:
    """Why a run fails where ``model`` (about the contact equilibrium, contact kept) does
    not: it diverged, or it left the surface; None otherwise."""
    if view.metrics.get("diverged"):
        return ("the run diverged: a large-signal transient (the first contact, a saturation) "
                f"that {model} about the contact equilibrium does not see")  # fmt: skip
    if "loss of contact" in view.verdict or "bounce" in view.verdict:
        return (f"{model} assumes contact is kept; the run leaves the surface and bounces (the "
                "clamp of the force at zero is not in the model)")  # fmt: skip
    return None


def passed_disagreement(view: RunView, pred: Prediction) -> str | None:
    """One line on why the predicted ``passed`` (the forced response with the motion
    running, docs/analysis.md §3b) and the simulated one differ, or ``None`` when they
    agree or one of them is missing or not predicted."""
    if not view.complete or view.passed is None or pred.values is None:
        return None
    predicted = pred.values.get("passed")
    if not isinstance(predicted, bool) or predicted == view.passed:
        return None
    words = str(pred.values.get("tolerance_verdict", ""))
    ripple = pred.values.get("force_oscillation")
    simulated = view.metrics.get("force_oscillation")
    both = ""
    if isinstance(ripple, float) and isinstance(simulated, float) and finite(ripple) \
            and finite(simulated):
        both = f" (predicted {100 * ripple:.3g} %, simulated {100 * simulated:.3g} %)"
    if predicted:
        return _large_signal(view, "the forced response") or (
            "the run fails a criterion the forced response misses or does not judge"
            f"{both}: the ripple beyond second order, or the run's first transient")
    if words.startswith("unstable with the motion running"):
        return ("the loop with friction at its describing-function gain for the motion's joint "
                "speeds is unstable; in the run the friction's steep slope near each reversal "
                "damps it")  # fmt: skip
    return f"the forced response overestimates the run's ripple{both}"


def finite(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
