"""Tuning (SPEC §12, §17): the gains that minimise the worst-case predicted settling time
over a box of uncertain parameters, verified by simulating the box's corners and centre.
Reached as :func:`admit_rs.analysis.tune`."""

from __future__ import annotations

import itertools
import math
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import polars as pl

from admit_rs import _core
from admit_rs.analysis._checks import _check_friction, _check_scenario
from admit_rs.analysis.linear import _cell_configs, _numeric_axis, _predict_points
from admit_rs.blocks._base import _parameter_error
from admit_rs.config import Scenario, Step
from admit_rs.errors import AnalysisError, ArgumentError, ParameterError, ParameterTypeError

__all__ = ["TuneResult", "tune"]


@dataclass(frozen=True)
class TuneResult:
    """What :func:`tune` found and how the simulator judged it."""

    gains: dict[str, float]
    """The chosen values of the ``vary`` parameters."""
    predicted: pl.DataFrame
    """Predictions at every ``over`` grid point with the chosen gains: the step metrics
    with friction at rest (small signal), ``stable`` and ``spectral_radius`` with
    ``friction="step"`` (large signal)."""
    verification: pl.DataFrame
    """The box's corners and centre simulated with the chosen gains and the motion held
    (the linearised setup): the ``over`` parameters, predicted and simulated ``stable``
    (the simulated one: the loop's dynamics, SPEC §23, null if not assessed), ``passed``
    (the scenario's ``criteria`` met) with its ``verdict``, ``overshoot_pct``,
    ``settling_time``; and the scenario as given, its motion reference included:
    ``stable_with_motion``, ``passed_with_motion``, ``verdict_with_motion``,
    ``overshoot_pct_with_motion``; the first-contact figures of both, ``impact_peak``,
    ``bounces``, ``impact_peak_with_motion``, ``bounces_with_motion``."""
    worst_settling_time: float
    """Predicted worst-case settling time over the box [s] (the search's objective)."""
    verified: bool
    """Every verification run passes its criteria (so is stable too), with the motion held
    and with it, the runs with
    the motion held are within the overshoot limit, and every run within ``max_impact_peak``
    and ``max_bounces`` when they are set."""
    max_overshoot_pct: float
    stability_margin: float
    evaluated: int
    """Number of predictions made."""
    predicted_overshoot_limit: float = math.nan
    """The tightest overshoot limit the predictions had to meet in the last round."""
    rounds: int = 1
    """Search rounds (1 + corrections after a failed verification)."""
    max_impact_peak: float | None = None
    """The bound on the simulated ``impact_peak`` [N] (None: not bounded)."""
    max_bounces: int | None = None
    """The bound on the simulated ``bounces`` (None: not bounded)."""

    def worst(self, name: str) -> tuple[float, float]:
        """(predicted, simulated) worst value of ``overshoot_pct`` or ``settling_time`` over
        every point that was predicted (the box grid and the verified corners and centre)
        and every point simulated with the motion held (NaN: none)."""
        pred = [self.predicted[name]]
        if self.verification.height:
            pred.append(self.verification[f"predicted_{name}"])
        predicted = pl.concat(pred).drop_nans().max()
        simulated = (self.verification[name].drop_nans().max() if self.verification.height
                     else None)  # fmt: skip
        return (math.nan if predicted is None else float(predicted),  # type: ignore[arg-type]
                math.nan if simulated is None else float(simulated))  # type: ignore[arg-type]

    def summary(self) -> str:
        """A few lines of text: the gains, the true worst case predicted and simulated over
        every point, the verification and, if it fails, why."""
        return "\n".join(self._head() + [f"  {reason}" for reason in self._failures()])

    def _head(self) -> list[str]:
        """The summary's lines before the failures."""
        gains = ", ".join(f"{k} = {v:.4g}" for k, v in self.gains.items())
        v = self.verification
        over_pred, over_sim = self.worst("overshoot_pct")
        settle_pred, settle_sim = self.worst("settling_time")
        points = self.predicted.height + v.height
        lines = [
            f"gains: {gains}",
            f"predicted at {points} points (the box grid, its corners and centre): worst "
            f"overshoot {over_pred:.2f} %, worst settling {settle_pred:.3f} s, max spectral "
            f"radius {float(self.predicted['spectral_radius'].max()):.5f} "  # type: ignore[arg-type]
            f"(round {self.rounds}, predicted overshoot limit "
            f"{self.predicted_overshoot_limit:.3g} %)",
        ]
        if v.height:
            held = int(v["passed"].fill_null(False).sum())
            moving = int(v["passed_with_motion"].fill_null(False).sum())
            moving_stable = int(v["stable_with_motion"].fill_null(False).sum())
            lines.append(
                f"simulated at {v.height} points (corners and centre), motion held: {held} "
                f"passed, worst overshoot {over_sim:.2f} % (limit {self.max_overshoot_pct:g} "
                f"%), worst settling {settle_sim:.3f} s; with the scenario's motion: "
                f"{moving} passed, {moving_stable} stable -> "
                + ("verified" if self.verified else "NOT verified")
            )
        return lines

    def report(self, width: int = 80) -> str:
        """:meth:`summary` and one block per verification point, every line at most
        ``width`` characters (at least 40): a terminal's report (``admit-rs tune``)."""
        width = max(40, width)

        def wrap(text: str, indent: str = "") -> list[str]:
            return textwrap.wrap(text, width, initial_indent=indent,
                                 subsequent_indent=indent + "    ", break_long_words=True,
                                 break_on_hyphens=False)  # fmt: skip

        lines = [w for line in self._head() for w in wrap(line)]
        v = self.verification
        if v.height == 0:
            return "\n".join(lines)
        over = list(v.columns[: v.columns.index("point")])
        lines.append("verification (simulated; predicted in brackets):")

        def state(stable: bool | None, passed: bool | None, verdict: str) -> str:
            judged = {True: "stable", False: "unstable", None: "stability not assessed"}
            said = f"{judged[stable]}, {'passed' if passed else 'not passed'}"
            return said if passed else f"{said}: {verdict}"

        def seconds(t: float) -> str:
            return f"{t:.3f} s" if math.isfinite(t) else "not within the run"

        for r in v.iter_rows(named=True):
            at = ", ".join(f"{k} = {r[k]:.4g}" for k in over)
            lines += wrap(f"{r['point']}: {at}", "  ")
            too_much = r["overshoot_pct"] > self.max_overshoot_pct
            lines += wrap(
                f"motion held: {state(r['stable'], r['passed'], r['verdict'])}; overshoot "
                f"{r['overshoot_pct']:.2f} % ({r['predicted_overshoot_pct']:.2f} %)"
                + (f" > {self.max_overshoot_pct:g} %" if too_much else "")
                + f", settling {seconds(r['settling_time'])} "
                f"({seconds(r['predicted_settling_time'])})", "    ")  # fmt: skip
            lines += wrap(
                "with motion: " + state(r["stable_with_motion"], r["passed_with_motion"],
                                        r["verdict_with_motion"]), "    ")  # fmt: skip
        return "\n".join(lines)

    def _failures(self) -> list[str]:
        """Why the verification failed, one line per failing point."""
        out = []
        over = list(self.verification.columns[: self.verification.columns.index("point")])
        for r in self.verification.iter_rows(named=True):
            at = ", ".join(f"{k} = {r[k]:.4g}" for k in over) + f" ({r['point']})"
            if r["passed"] is not True:
                out.append(f"{at}, motion held: {r['verdict']}")
            elif r["overshoot_pct"] > self.max_overshoot_pct:
                out.append(f"{at}, motion held: overshoot {r['overshoot_pct']:.2f} % > "
                           f"{self.max_overshoot_pct:g} %")  # fmt: skip
            if r["passed_with_motion"] is not True:
                out.append(f"{at}, with motion: {r['verdict_with_motion']}")
        return out


def _axis_points(lo: float, hi: float, n: int) -> list[float]:
    if lo > 0 and hi / lo >= 4:
        return [float(v) for v in np.geomspace(lo, hi, n)]
    return [float(v) for v in np.linspace(lo, hi, n)]


def _box(scenario: Scenario, spec: Any, name: str) -> dict[str, tuple[float, float]]:
    if not isinstance(spec, Mapping) or not spec:
        raise ParameterTypeError(f"{name} must be a non-empty dict {{path: (lo, hi)}}")
    out = {}
    for path, bounds in spec.items():
        p, _ = _numeric_axis(scenario, {path: [0.0]}, name)
        if hasattr(bounds, "low") and hasattr(bounds, "high"):
            # A distribution (ar.Uniform, ar.LogUniform; CellFit.box()): its support.
            bounds = (bounds.low, bounds.high)
        try:
            lo, hi = (float(v) for v in bounds)
        except (TypeError, ValueError):
            raise ParameterError(
                f"{name}[{path!r}] = {bounds!r} is invalid: must be a pair (lo, hi) of numbers"
            ) from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ParameterError(f"{name}[{path!r}] = {bounds!r} is invalid: must be lo <= hi")
        out[p] = (lo, hi)
    return out


def _held(scenario: Scenario) -> Scenario:
    """The scenario with its motion held at s(0), as the linearisation freezes it."""
    s0 = float(_core_signal_at(scenario, 0.0))
    return scenario.replace(z_reference=Step(value=s0, time=0.0, initial=s0))


def _core_signal_at(scenario: Scenario, t: float) -> float:
    from admit_rs.config import Sine

    z = scenario.z_reference
    if isinstance(z, Step):
        return float(z.value if t >= z.time else z.initial)
    if isinstance(z, Sine):
        return float(z.offset + z.amplitude * math.sin(z.omega * t + z.phase))
    return float(np.interp(t, z.times, z.values))


def _predict_both(
    scenario: Scenario, points: Sequence[Mapping[str, float]], threads: int | None
) -> pl.DataFrame:
    """Predictions with ``friction="step"``: a force step from rest is a large signal."""
    return _predict_points(scenario, points, threads, "step")


def _check_count(name: str, value: Any, low: int, high: int) -> None:
    """A whole-number argument from ``low`` to ``high``, else a ParameterError naming it."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise _parameter_error(name, repr(value), f"an integer from {low} to {high}")


def tune(
    scenario: Scenario,
    vary: Mapping[str, tuple[float, float]],
    over: Mapping[str, Any],
    max_overshoot_pct: float = 10.0,
    stability_margin: float = 0.001,
    grid: int = 7,
    over_points: int = 4,
    refine: int = 2,
    verify: bool = True,
    verify_duration: float | None = None,
    threads: int | None = None,
    corrections: int = 3,
    max_impact_peak: float | None = None,
    max_bounces: int | None = None,
) -> TuneResult:
    """Gains that minimise the worst-case predicted settling time over the ``over`` box
    while every point of it is predicted stable with a margin (ρ ≤ 1 − ``stability_margin``)
    and within ``max_overshoot_pct``; then verified by simulating the box's corners and
    centre.

    ``vary``: ``{path: (lo, hi)}`` of the gains to choose (e.g. ``admittance.b``,
    ``admittance.ka``). ``over``: ``{path: (lo, hi)}`` of what is uncertain (e.g.
    ``wall.stiffness``); a ``Uniform`` or ``LogUniform`` stands for its (low, high), so a
    fitted cell's ``CellFit.box()`` is a box. The search is a ``grid``-point grid per gain
    (geometric when hi/lo ≥ 4) refined ``refine`` times around the best cell; the box is
    sampled with ``over_points`` values per parameter (its corners included), and each candidate is
    judged by its worst case there. Predictions use ``friction="step"`` (a force step from
    rest is a large signal). The force step is judged with the motion held at s(0), as
    linearised; the verification simulates that, and also the scenario as given
    (``passed_with_motion``): the gains are chosen on ``passed`` (the scenario's criteria
    met) and ``stable`` is reported beside it (SPEC §23). If the simulated overshoot exceeds
    the limit (or a run fails its criteria), the excess of the simulated over the predicted
    overshoot is carried to the nearest grid points as a tighter limit there (the margin
    doubled after an unstable run) and the search repeated, at most ``corrections`` times;
    ``predicted_overshoot_limit`` (the tightest limit used) and ``rounds`` say what was
    needed. ``max_impact_peak`` [N] and ``max_bounces`` bound the first contact (SPEC §16):
    the linear model cannot predict an impact, so they are judged on the verification runs
    (held and with motion); an impact above its bound is carried back as an overshoot limit
    100 (impact_peak − max_impact_peak) / f_d tighter at the nearest grid points, as an
    overshoot excess is. Raises :class:`AnalysisError` if no candidate qualifies.

    Example (docs/analysis.md): ``ar.analysis.tune(sc, vary={"admittance.b": (100, 3000),
    "admittance.ka": (0.2, 5)}, over={"wall.stiffness": (1e4, 1e5)}, max_overshoot_pct=10)``.
    """
    scenario = _check_scenario(scenario, "tune")
    _check_friction(scenario)
    if not (isinstance(max_overshoot_pct, int | float) and math.isfinite(max_overshoot_pct)):
        raise ParameterError(f"max_overshoot_pct = {max_overshoot_pct!r} is invalid: must be "
                             "a finite number")  # fmt: skip
    for name, value, low, high in (("grid", grid, 2, 100), ("over_points", over_points, 1, 100),
                                   ("refine", refine, 0, 20), ("corrections", corrections, 0, 20)):
        _check_count(name, value, low, high)
    for name, bound in (("max_impact_peak", max_impact_peak), ("max_bounces", max_bounces)):
        if bound is not None and not (
            isinstance(bound, int | float) and not isinstance(bound, bool)
            and math.isfinite(bound) and bound >= 0
        ):
            raise ParameterError(f"{name} = {bound!r} is invalid: must be a finite number "
                                 ">= 0 or None")  # fmt: skip
    vbox = _box(scenario, vary, "vary")
    obox = _box(scenario, over, "over")
    if set(vbox) & set(obox):
        raise ArgumentError(f"{sorted(set(vbox) & set(obox))} given in both vary and over")
    over_grid = [
        dict(zip(obox, combo, strict=True))
        for combo in itertools.product(*(_axis_points(lo, hi, over_points)
                                         for lo, hi in obox.values()))
    ]  # fmt: skip
    evaluated = 0
    # Per over-grid point: what the simulator showed beyond the prediction (overshoot).
    offset = np.zeros(len(over_grid))
    rounds = 0
    last: tuple[Any, ...] | None = None
    while True:
        rounds += 1
        try:
            gains, worst_settling, n = _search(scenario, vbox, obox, over_grid,
                                               max_overshoot_pct - offset, stability_margin,
                                               grid, refine, threads)  # fmt: skip
        except AnalysisError:
            if last is None:
                raise
            # The corrected constraints leave nothing: report the last, unverified answer.
            rounds -= 1
            gains, worst_settling, predicted, verification, verified, offset = last
            break
        evaluated += n
        predicted = _predict_both(scenario, [{**gains, **o} for o in over_grid], threads)
        evaluated += predicted.height
        verification = (_verify(scenario, gains, obox, verify_duration, threads) if verify
                        else pl.DataFrame())  # fmt: skip
        # Null (not assessed) counts as not stable.
        within = _within_contact_bounds(verification, max_impact_peak, max_bounces, "")
        held = bool(
            verify
            and verification.height > 0
            and verification["passed"].fill_null(False).all()
            and (verification["overshoot_pct"] <= max_overshoot_pct).all()
            and within
        )
        verified = held and bool(
            verification["passed_with_motion"].fill_null(False).all()
            and _within_contact_bounds(verification, max_impact_peak, max_bounces,
                                       "_with_motion")
        )  # fmt: skip
        # The corrections below act on the held step; the motion's verdict cannot be
        # corrected by an overshoot limit, so a held pass ends the search.
        if not verify or held or rounds > corrections:
            break
        last = (gains, worst_settling, predicted, verification, verified, offset.copy())
        # The simulator disagrees: carry its excess over the prediction to the nearest
        # grid points (plus 0.5 %), double the margin if a run was unstable, search again.
        seen = (verification["overshoot_pct"] - verification["predicted_overshoot_pct"])
        near = _nearest(obox, over_grid, verification.select(list(obox)).rows(named=True))
        if max_impact_peak is not None:
            # An impact above its bound, as the overshoot it would take to stay below it.
            fd = _final_force(scenario)
            impact = 100.0 * (verification["impact_peak"] - max_impact_peak) / fd
            seen = pl.Series([max(a, b) for a, b in zip(seen.fill_nan(-math.inf),
                                                         impact.fill_nan(-math.inf),
                                                         strict=True)])  # fmt: skip
        for g, v in enumerate(near):
            excess = float(seen[v])
            if math.isfinite(excess):
                offset[g] = max(offset[g], excess + 0.5)
        if not verification["stable"].fill_null(False).all():
            stability_margin *= 2
    limit = float(np.min(max_overshoot_pct - offset))
    return TuneResult(
        gains=gains,
        predicted=predicted,
        verification=verification,
        worst_settling_time=worst_settling,
        verified=verified,
        max_overshoot_pct=max_overshoot_pct,
        stability_margin=stability_margin,
        evaluated=evaluated,
        predicted_overshoot_limit=limit,
        rounds=rounds,
        max_impact_peak=max_impact_peak,
        max_bounces=max_bounces,
    )


def _within_contact_bounds(
    verification: pl.DataFrame, max_impact: float | None, max_bounces: int | None, suffix: str
) -> bool:
    """Every verification run's impact peak and bounces within their bounds (if set)."""
    if verification.height == 0:
        return max_impact is None and max_bounces is None
    ok = True
    if max_impact is not None:
        ok &= bool((verification[f"impact_peak{suffix}"].fill_nan(math.inf) <= max_impact).all())
    if max_bounces is not None:
        ok &= bool((verification[f"bounces{suffix}"].fill_nan(math.inf) <= max_bounces).all())
    return ok


def _final_force(scenario: Scenario) -> float:
    """|f_d| at the end of the run (the scale of an overshoot in %), at least 1e-12 N."""
    end = scenario.force_reference(scenario.duration)
    return max(abs(float(np.asarray(end))), 1e-12)


def _nearest(
    obox: Mapping[str, tuple[float, float]],
    grid: Sequence[Mapping[str, float]],
    probes: Sequence[Mapping[str, float]],
) -> list[int]:
    """For each grid point, the index of the nearest probe in the box's normalised (log
    where geometric) coordinates."""

    def coords(p: Mapping[str, float]) -> np.ndarray:
        out = []
        for k, (lo, hi) in obox.items():
            if lo > 0 and hi / lo >= 4:
                out.append((math.log(p[k]) - math.log(lo)) / (math.log(hi) - math.log(lo)))
            else:
                out.append((p[k] - lo) / (hi - lo) if hi > lo else 0.0)
        return np.array(out)

    pc = np.array([coords(p) for p in probes])
    return [int(np.argmin(np.sum((pc - coords(g)) ** 2, axis=1))) for g in grid]


def _search(
    scenario: Scenario,
    vbox: Mapping[str, tuple[float, float]],
    obox: Mapping[str, tuple[float, float]],
    over_grid: Sequence[Mapping[str, float]],
    limit: Any,
    stability_margin: float,
    grid: int,
    refine: int,
    threads: int | None,
) -> tuple[dict[str, float], float, int]:
    """Grid search with zoom: the gains with the least worst-case predicted settling time
    that meet the constraints at every point of ``over_grid``."""
    evaluated = 0
    ranges = dict(vbox)
    best: tuple[float, dict[str, float]] | None = None
    for _ in range(refine + 1):
        axes = {p: _axis_points(lo, hi, grid) for p, (lo, hi) in ranges.items()}
        candidates = [dict(zip(axes, c, strict=True)) for c in itertools.product(*axes.values())]
        points = [{**c, **o} for c in candidates for o in over_grid]
        table = _predict_both(scenario, points, threads)
        evaluated += table.height
        m = len(over_grid)
        rho = table["spectral_radius"].to_numpy().reshape(-1, m)
        over_pct = table["overshoot_pct"].to_numpy().reshape(-1, m)
        settle = table["settling_time"].to_numpy().reshape(-1, m)
        # Stable by ar.analysis.Margins() (damping, gain, phase and delay margins) too.
        margins_ok = table["stable"].to_numpy().astype(bool).reshape(-1, m)
        with np.errstate(invalid="ignore"):
            ok = (
                np.all(margins_ok, axis=1)
                & np.all(rho <= 1 - stability_margin, axis=1)
                & np.all(over_pct <= np.asarray(limit)[None, :] if np.ndim(limit) else
                         over_pct <= limit, axis=1)
                & np.all(np.isfinite(settle), axis=1)
            )
        worst = np.where(ok, np.max(np.where(np.isfinite(settle), settle, np.inf), axis=1),
                         np.inf)  # fmt: skip
        i = int(np.argmin(worst))
        if np.isfinite(worst[i]) and (best is None or worst[i] <= best[0]):
            best = (float(worst[i]), candidates[i])
        if best is None:
            raise AnalysisError(
                f"no gains in {dict(vbox)} keep every point of {dict(obox)} predicted stable "
                f"(margin {stability_margin}) within {np.min(limit):.3g} % overshoot"
            )
        # Zoom in: one grid cell either side of the best, inside the original bounds.
        new = {}
        for p, (lo, hi) in ranges.items():
            pts = axes[p]
            j = pts.index(best[1][p]) if best[1][p] in pts else None
            new[p] = (lo, hi) if j is None else (pts[max(j - 1, 0)], pts[min(j + 1, len(pts) - 1)])
        ranges = new
    assert best is not None
    return best[1], best[0], evaluated


def _verify(
    scenario: Scenario,
    gains: Mapping[str, float],
    obox: Mapping[str, tuple[float, float]],
    duration: float | None,
    threads: int | None,
) -> pl.DataFrame:
    corners = [dict(zip(obox, c, strict=True)) for c in itertools.product(*obox.values())]
    centre = {p: (math.sqrt(lo * hi) if lo > 0 and hi / lo >= 4 else (lo + hi) / 2)
              for p, (lo, hi) in obox.items()}  # fmt: skip
    points = [{**gains, **p} for p in [*corners, centre]]
    given = scenario if duration is None else scenario.replace(duration=duration)
    held = _held(given)
    sim = _core.simulate_batch(_cell_configs(held, points), threads, False)
    moving = _core.simulate_batch(_cell_configs(given, points), threads, False)
    pred = _predict_both(held, points, threads)
    columns: dict[str, Any] = {p: [pt[p] for pt in [*corners, centre]] for p in obox}
    columns["point"] = ["corner"] * len(corners) + ["centre"]
    columns["predicted_stable"] = pred["stable"]
    columns["stable"] = pl.Series(sim["stable"], dtype=pl.Boolean)
    columns["passed"] = pl.Series(sim["passed"], dtype=pl.Boolean)
    columns["verdict"] = pl.Series(sim["verdict"], dtype=pl.String)
    columns["predicted_overshoot_pct"] = pred["overshoot_pct"]
    columns["overshoot_pct"] = sim["metrics"]["overshoot_pct"]
    columns["predicted_settling_time"] = pred["settling_time"]
    columns["settling_time"] = sim["metrics"]["settling_time"]
    columns["stable_with_motion"] = pl.Series(moving["stable"], dtype=pl.Boolean)
    columns["passed_with_motion"] = pl.Series(moving["passed"], dtype=pl.Boolean)
    columns["verdict_with_motion"] = pl.Series(moving["verdict"], dtype=pl.String)
    columns["overshoot_pct_with_motion"] = moving["metrics"]["overshoot_pct"]
    for name in ("impact_peak", "bounces"):
        columns[name] = sim["metrics"][name]
        columns[f"{name}_with_motion"] = moving["metrics"][name]
    return pl.DataFrame(columns)
