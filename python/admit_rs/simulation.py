"""Running a scenario: :func:`simulate` and its :class:`Result`, or :class:`Simulation` to
step the same loop one period at a time."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import polars as pl

from admit_rs import _core
from admit_rs._names import MetricsDict, UnknownNameError
from admit_rs._trace import trace_frame
from admit_rs.blocks._base import _parameter_error
from admit_rs.config import Scenario
from admit_rs.errors import AdmitError, ParameterTypeError
from admit_rs.plot import plot_result

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from admit_rs._core import FlatTrace


@dataclass(frozen=True)
class Result:
    """One run: the trace, its metrics (see :data:`admit_rs.METRICS` and docs/metrics.md)
    and how it ended.

    ``metrics`` is a dict whose unknown keys raise :class:`admit_rs.UnknownNameError`
    (a ``KeyError``) naming the closest metric. ``trace`` columns: t, q1..q3, qd1..qd3,
    x, y, z, x_ref, y_ref, z_ref, f (true force along the wall normal), f_measured (what
    the sensor reported), f_d, penetration (n·X − x_e; NaN without a wall), x_a, xa_dot,
    fx, fy, fz (the true force on the surface, f N − F_t, world frame), f_t (the friction
    force's magnitude |F_t|), slip_speed (|v_t|, the tip's speed within the contact's
    tangent plane; NaN without a surface), tau1..tau3 (applied torque), tau_cmd1..tau_cmd3
    (commanded torque). SI units: s, rad, rad/s, m, N, N·m, m/s.
    """

    scenario: Scenario
    trace: pl.DataFrame
    metrics: dict[str, float | bool | None]
    diverged_at: float | None
    """Time [s] at which the run stopped as unstable, ``None`` if it completed."""
    divergence_cause: str | None
    """Why it stopped (velocity limit, non-finite state, singular Jacobian)."""
    verdict: str = ""
    """``"stable"`` (every criterion met), ``"unstable: ..."`` (the loop's dynamics: it
    diverged, or sustains a force oscillation or a loss of contact by itself),
    ``"out of tolerance: ..."`` (a stable run that fails a criterion: a ripple the motion
    drives, an impact peak, a path error), naming each failed criterion of
    ``scenario.criteria`` with its value and limit, or ``"not assessed: ..."``
    (SPEC §17, §23). A failed force oscillation or loss of contact says whether it is
    driven or self-sustained, by the same run with its drives held
    (docs/analysis.md, "Unstable or out of tolerance").

    Example:
        >>> import admit_rs as ar
        >>> sc = ar.paper.scenario("fig14")
        >>> ar.simulate(sc.replace(**{"wall.stiffness": 7e5, "admittance.b": 200})).verdict
        'unstable: loss of contact: f = 0 in 88 % of samples after t = 1 s, ...'
    """
    substeps: int = 0
    """RK4 substeps per period the trace was integrated with: the scenario's count, or the
    one ``substeps="auto"`` chose."""
    substep_error: float | None = None
    """``substeps="auto"``: the estimated largest error [N] of f and f_t over the run
    (Richardson's estimate, docs/substeps.md); ``None`` for a fixed count.

    Example:
        >>> import admit_rs as ar
        >>> r = ar.simulate(ar.paper.scenario("fig14").replace(substeps="auto", tolerance=1e-4))
        >>> r.substeps, f"{r.substep_error:.1e}"
        (3, '3.7e-05')
    """
    substep_standing: str | None = None
    """``substeps="auto"``: how its search ended: ``"met"`` (the estimate is within the
    tolerance), ``"diverged"`` (the run diverges at every count), ``"not converging"``
    (the traces stop converging: a bouncing, chaotic contact), ``"limit"`` (256
    substeps did not meet it) or ``"not assessed"`` (no run tried had any contact force,
    so the force tolerance could not judge it: the default 10 substeps); a
    :class:`SubstepWarning` says so for all but ``"met"``. ``None`` for a fixed count."""
    substep_note: str | None = None
    """``substeps="auto"``: what it chose, the estimate and the counts tried, in words, and
    why the tolerance is not met when it is not."""

    @property
    def diverged(self) -> bool:
        """The run stopped early (non-finite state, singular Jacobian or velocity limit)."""
        return self.diverged_at is not None

    @property
    def stable(self) -> bool | None:
        """The loop's dynamics (SPEC §23): ``False`` if the run diverged, or fails
        ``max_force_oscillation``, ``max_contact_loss`` or ``max_bounces`` of
        ``scenario.criteria`` and still fails it with its drives held (the motion held at
        its start, f_d held, no sensor noise); ``None`` if it is too short to assess, else
        ``True``. A ripple the motion drives is stable and fails :attr:`passed`.
        :attr:`verdict` says why."""
        value = self.metrics["stable"]
        return None if value is None else bool(value)

    @property
    def passed(self) -> bool | None:
        """Every criterion of ``scenario.criteria`` (:class:`admit_rs.Criteria`) met:
        ``False`` if the run diverged or any criterion fails, driven or not; ``None`` if it
        is too short to assess, else ``True``. :attr:`verdict` says why."""
        value = self.metrics["passed"]
        return None if value is None else bool(value)

    def step_info(self) -> dict[str, float]:
        """Force step metrics under python-control's ``step_info`` names."""
        m: Mapping[str, Any] = self.metrics
        return {
            "RiseTime": float(m["rise_time_10_90"]),
            "SettlingTime": float(m["settling_time"]),
            "Overshoot": max(float(m["overshoot_pct"]), 0.0),
            "Peak": float(m["force_peak"]),
            "PeakTime": float(m["peak_time"]),
        }

    def plot(self, title: str | None = None) -> Figure:
        """Force vs f_d, x and z against their references, and x_a (a matplotlib Figure)."""
        return plot_result(self, title=title)

    def __repr__(self) -> str:
        label = f" {self.scenario.label!r}" if self.scenario.label else ""
        return f"<Result{label}: {self.trace.height} samples, {self.verdict}>"


class SubstepWarning(UserWarning):
    """``substeps="auto"`` could not meet or could not assess its tolerance; the message says
    why (the run diverges at every count, its traces stop converging, the count limit, or
    no contact force to judge)."""


def _result(scenario: Scenario, trace: FlatTrace, raw: Mapping[str, Any]) -> Result:
    fixed = scenario.substeps if isinstance(scenario.substeps, int) else 0
    note = raw.get("substep_note")
    if note is not None and raw.get("substep_standing") != "met":
        warnings.warn(note, SubstepWarning, stacklevel=3)
    return Result(
        scenario=scenario,
        trace=trace_frame(trace),
        metrics=MetricsDict(raw["metrics"]),
        diverged_at=raw["diverged_at"],
        divergence_cause=raw["divergence_cause"],
        verdict=str(raw["verdict"]),
        substeps=int(raw.get("substeps", fixed)),
        substep_error=raw.get("substep_error"),
        substep_standing=raw.get("substep_standing"),
        substep_note=note,
    )


def simulate(scenario: Scenario) -> Result:
    """Runs one scenario in the Rust core (GIL released) and returns its :class:`Result`.

    Example:
        >>> import admit_rs as ar
        >>> r = ar.simulate(ar.paper.scenario("fig14").replace(duration=3.0))
        >>> r.trace.height, r.stable
        (3001, True)
        >>> ar.simulate(ar.paper.scenario("fig14").replace(duration=1.0)).verdict
        'not assessed: only 0 s of the run after t = 1 s, min_assessed is 1 s'

    """
    if not isinstance(scenario, Scenario):
        raise ParameterTypeError(
            f"simulate() takes an admit_rs.Scenario, got {type(scenario).__name__}"
        )
    raw = _core.simulate(scenario._to_core())
    return _result(scenario, raw["columns"], raw)


class Simulation:
    """The loop of one scenario, one controller period at a time.

    The same code :func:`simulate` runs (SPEC §10 order: plant → wall → sensor → references
    → force control → control law → actuator → record → plant integration), so stepping to
    the end gives :func:`simulate`'s trace bit for bit. Between steps the whole state can be
    read and changed: pause, inspect, perturb, resume.

    Example:
        >>> import admit_rs as ar
        >>> sim = ar.Simulation(ar.paper.scenario("fig14").replace(duration=1.0))
        >>> sim.step(500)
        500
        >>> round(sim.state["plant.q2"], 4)
        0.7818
        >>> sim.set_state({"plant.qd2": 0.05})      # a kick to the shoulder
        >>> sim.step(10_000)                        # runs to the end (sample 1000)
        501
        >>> sim.done, sim.trace.height
        (True, 1001)

    One run, one thread at a time: :meth:`step` releases the GIL, and any call from another
    thread meanwhile raises :class:`~admit_rs.AdmitError` saying so. Give each thread its
    own ``Simulation``.
    """

    def __init__(self, scenario: Scenario) -> None:
        if not isinstance(scenario, Scenario):
            raise ParameterTypeError(
                f"Simulation() takes an admit_rs.Scenario, got {type(scenario).__name__}"
            )
        self.scenario = scenario
        self._core = _core.Stepper(scenario._to_core())
        self._labels: list[str] = self._core.state_labels()

    def reset(self) -> None:
        """Back to t = 0 with every stage at its initial state and an empty trace."""
        self._core.reset()

    def step(self, n: int = 1) -> int:
        """Takes up to ``n`` samples (fewer when the run ends or diverges); returns how many.

        Each sample records the state at t_k, then integrates the plant to t_{k+1} (the last
        sample of the run is recorded without integrating further)."""
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ParameterTypeError(f"step(n): n must be an int >= 0, got {n!r}")
        return int(self._core.step(n))

    @property
    def sample(self) -> int:
        """Index k of the next sample (its time is k·period)."""
        return int(self._core.sample())

    @property
    def time(self) -> float:
        """Time of the next sample [s]."""
        return self.sample * self.scenario.period

    @property
    def done(self) -> bool:
        """Whether the run is over (all samples taken, or diverged)."""
        return self._core.outcome() is not None

    @property
    def state_labels(self) -> list[str]:
        """Names of the state entries, in order: ``sample``, ``plant.q1..``, ``plant.qd1..``,
        the filter (``filter.x_a``, ``filter.xa_dot``), the controller's memory (TDC:
        ``controller.tau_prev*``, ``controller.qd_prev*``), the sensor and the actuator."""
        return list(self._labels)

    @property
    def state(self) -> dict[str, float]:
        """The whole state as a flat labelled vector (a dict in :attr:`state_labels` order)."""
        return dict(zip(self._labels, self._core.state().tolist(), strict=True))

    def state_vector(self) -> npt.NDArray[np.float64]:
        """The state as an array in :attr:`state_labels` order."""
        return self._core.state()

    def set_state(
        self, state: Mapping[str, float] | Sequence[float] | npt.NDArray[np.float64]
    ) -> None:
        """Sets the state: a mapping of some labels (the others keep their values) or a full
        vector in :attr:`state_labels` order. The trace keeps the samples before ``sample``.

        A simulation that has taken no sample yet starts at any ``sample`` (another run's
        state carried over): its trace's first row is that sample and its metrics count from
        it. One that has taken samples goes back to any of them, never forward past them
        (its trace would have a hole): that raises :class:`admit_rs.ParameterError`.

        Unknown labels raise :class:`admit_rs.UnknownNameError` (a ``KeyError``) naming the
        closest valid ones; a bool is refused (it would be taken as 0 or 1)."""
        if isinstance(state, Mapping):
            values = self._core.state().tolist()
            index = {name: i for i, name in enumerate(self._labels)}
            for name, value in state.items():
                if name not in index:
                    raise UnknownNameError("state entry", str(name), self._labels)
                if isinstance(value, bool | np.bool_):  # True would be taken as 1
                    raise _parameter_error(str(name), repr(value), "a number, not a bool")
                values[index[name]] = float(value)
        else:
            if any(isinstance(v, bool | np.bool_) for v in np.ravel(np.asarray(state, object))):
                raise _parameter_error("state", "a vector holding a bool", "numbers")
            values = [float(v) for v in np.ravel(np.asarray(state, dtype=float))]
        self._core.set_state(values)

    @property
    def trace(self) -> pl.DataFrame:
        """The samples recorded so far (columns as :attr:`Result.trace`)."""
        return trace_frame(self._core.trace())

    def result(self) -> Result:
        """The finished run as a :class:`Result` (trace, metrics, outcome).

        Raises ``AdmitError`` while the run goes on: metrics of part of a run would not
        mean what their names say."""
        raw = self._core.outcome()
        if raw is None:
            raise AdmitError(
                f"the run is not over (next sample {self.sample} of {self._core.samples()}); "
                "step() to the end first"
            )
        return _result(self.scenario, self._core.trace(), raw)

    def __repr__(self) -> str:
        label = f" {self.scenario.label!r}" if self.scenario.label else ""
        try:
            return (
                f"<Simulation{label}: sample {self.sample} of {self._core.samples()}"
                f"{', done' if self.done else ''}>"
            )
        except AdmitError:  # a repr must not fail while another thread steps the run
            return f"<Simulation{label}: being stepped by another thread>"
