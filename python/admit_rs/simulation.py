"""Running a scenario: :func:`simulate` and its :class:`Result`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import polars as pl

from admit_rs import _core
from admit_rs._names import MetricsDict
from admit_rs.config import Scenario
from admit_rs.metrics import verdict

if TYPE_CHECKING:
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class Result:
    """One run: the trace, its metrics (see :data:`admit_rs.METRICS` and docs/metrics.md)
    and how it ended.

    ``metrics`` is a dict whose unknown keys raise :class:`admit_rs.UnknownNameError`
    (a ``KeyError``) naming the closest metric. ``trace`` columns: t, q1..q3, qd1..qd3,
    x, y, z, x_ref, y_ref, z_ref, f, f_d, x_a, tau1..tau3, xa_dot (SI units: s, rad,
    rad/s, m, N, N·m, m/s).
    """

    scenario: Scenario
    trace: pl.DataFrame
    metrics: dict[str, float | bool]
    diverged_at: float | None
    """Time [s] at which the run stopped as unstable, ``None`` if it completed."""
    divergence_cause: str | None
    """Why it stopped (velocity limit, non-finite state, singular Jacobian)."""

    @property
    def diverged(self) -> bool:
        """The run stopped early (non-finite state, singular Jacobian or velocity limit)."""
        return self.diverged_at is not None

    @property
    def stable(self) -> bool:
        """Not diverged and, for force-controlled runs, ``force_oscillation`` ≤ 0.1 and
        ``contact_loss`` ≤ 0.05. :attr:`verdict` says which criterion failed."""
        return bool(self.metrics["stable"])

    @property
    def verdict(self) -> str:
        """``"stable"``, or ``"unstable: ..."`` naming each failed criterion in words.

        Example:
            >>> import admit_rs as ar
            >>> sc = ar.paper.scenario("fig14")
            >>> ar.simulate(sc.replace(**{"wall.stiffness": 7e5, "admittance.b": 200})).verdict
            'unstable: contact lost in 88 % of samples after 1 s (limit 5 %); force oscillates...'
        """
        return verdict(self.metrics, self.diverged_at, self.divergence_cause)

    def step_info(self) -> dict[str, float]:
        """Force step metrics under python-control's ``step_info`` names."""
        m = self.metrics
        return {
            "RiseTime": float(m["rise_time_10_90"]),
            "SettlingTime": float(m["settling_time"]),
            "Overshoot": max(float(m["overshoot_pct"]), 0.0),
            "Peak": float(m["force_peak"]),
            "PeakTime": float(m["peak_time"]),
        }

    def plot(self, title: str | None = None) -> Figure:
        """Force vs f_d, x and z against their references, and x_a (a matplotlib Figure)."""
        from admit_rs.plot import plot_result

        return plot_result(self, title=title)

    def __repr__(self) -> str:
        status = self.verdict
        label = f" {self.scenario.label!r}" if self.scenario.label else ""
        return f"<Result{label}: {self.trace.height} samples, {status}>"


def simulate(scenario: Scenario) -> Result:
    """Runs one scenario in the Rust core (GIL released) and returns its :class:`Result`.

    Example:
        >>> import admit_rs as ar
        >>> r = ar.simulate(ar.paper.scenario("fig14").replace(duration=1.0))
        >>> r.trace.height, r.stable
        (1001, True)
    """
    if not isinstance(scenario, Scenario):
        raise TypeError(f"simulate() takes an admit_rs.Scenario, got {type(scenario).__name__}")
    raw = _core.simulate(scenario._to_core())
    return Result(
        scenario=scenario,
        trace=pl.DataFrame(raw["columns"]),
        metrics=MetricsDict(raw["metrics"]),
        diverged_at=raw["diverged_at"],
        divergence_cause=raw["divergence_cause"],
    )
