"""What every metric of a run means: definition, unit, window, python-control equivalent.

:data:`METRICS` maps each name of ``Result.metrics`` (and of a sweep table's metric
columns) to a :class:`Metric`. Plots and the command line label axes from it, and
``docs/metrics.md`` is generated from it (:func:`markdown`), so the three cannot drift.

Example:
    >>> import admit_rs as ar
    >>> m = ar.METRICS["contact_loss"]
    >>> m.unit, m.window
    ('fraction (0–1)', 't ≥ 1 s')
    >>> ar.METRICS["z_rms_error"].label
    'z_rms_error [m]'
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

__all__ = [
    "CONTACT_LOSS_LIMIT",
    "METRICS",
    "OSCILLATION_LIMIT",
    "Metric",
    "markdown",
    "verdict",
]

OSCILLATION_LIMIT = 0.1
"""A force-controlled run with ``force_oscillation`` above this is not stable."""
CONTACT_LOSS_LIMIT = 0.05
"""A force-controlled run with ``contact_loss`` above this is not stable."""


@dataclass(frozen=True)
class Metric:
    """One metric's definition."""

    name: str
    unit: str
    """Unit as written in headers and axis labels ("" for a bool)."""
    description: str
    window: str
    """Which samples it is computed over."""
    step_info: str
    """The python-control ``step_info`` key it corresponds to, and how it differs ("–": none)."""
    applies_to: str = "force-controlled runs"

    @property
    def label(self) -> str:
        """``name [unit]`` for axis labels and table headers (just the name if unitless)."""
        short = self.unit.split(" ")[0]
        return f"{self.name} [{short}]" if self.unit and short != "bool" else self.name


_WHOLE = "whole run"
_LAST = "last 2 s (t ≥ 1 s)"
_STEP = "runs whose f_d is a Step"

METRICS: Mapping[str, Metric] = MappingProxyType({
    m.name: m
    for m in [
        Metric("force_ss_error", "N", "mean(f_d − f): the force offset left at the end",
               "last 2 s", "≈ f_d − SteadyStateValue"),
        Metric("force_rms_error", "N", "RMS of f_d − f", "t ≥ 1 s", "–"),
        Metric("force_peak", "N", "max f, the largest contact force (also reported for a run "
               "that diverged)", _WHOLE, "Peak (max |f|)"),
        Metric("overshoot_pct", "%", "100 (force_peak − f_d,final) / f_d,final. Negative when f "
               "never reaches f_d. Values of hundreds or thousands of % (1339 % in fig. 12) mean "
               "the peak is many times f_d: impacts or bouncing on the wall, not the overshoot of "
               "a step response", _WHOLE, "Overshoot (python-control clips at 0 and divides by "
               "the final value of f rather than f_d; see Result.step_info())", _STEP),
        Metric("settling_time", "s", "first time after which |f − f_d| ≤ 2 % of f_d to the end; "
               "NaN if f is outside the band at the end", _WHOLE,
               "SettlingTime (2 % band, of the final value of f rather than f_d)", _STEP),
        Metric("rise_time_63", "s", "first time f ≥ 63.2 % of f_d (one time constant)", _WHOLE,
               "–", _STEP),
        Metric("rise_time_10_90", "s", "time from f ≥ 10 % to f ≥ 90 % of f_d", _WHOLE,
               "RiseTime (10 %–90 % of the final value)", _STEP),
        Metric("peak_time", "s", "time of the first maximum of |f|", _WHOLE, "PeakTime", _STEP),
        Metric("z_rms_error", "m", "RMS of the motion error t̂·(X_d − X) along the wall's "
               "tangent t̂: z_d − z for the paper's wall (metres, not mm)", _WHOLE, "–",
               "every run"),
        Metric("x_rms_error", "m", "RMS of the error n·(X_d − X) along the wall normal n (x_d − x "
               "for the paper's wall), X_d including the admittance output x_a", _WHOLE, "–",
               "every run"),
        Metric("contact_loss", "fraction (0–1)", "fraction of samples with f = 0 (a fraction, "
               "not a percentage: 0.36 means 36 % of the samples)", "t ≥ 1 s", "–"),
        Metric("force_oscillation", "fraction (0–1)", "std(f − f_d) / mean |f_d|: the force's "
               "spread about its reference relative to the reference. With a constant f_d in the "
               "window this is std(f) / |final f_d|; measuring the spread about f_d keeps a run "
               "that tracks a sine from counting as oscillating. NaN when the window is empty "
               "(runs ≤ 1 s) or f_d ≡ 0 there", _LAST, "–"),
        Metric("torque_saturation", "fraction (0–1)", "fraction of samples with any joint's "
               "applied torque at the actuator's torque_limit (0 without a limit)", _WHOLE, "–",
               "every run"),
        Metric("joint_limit_violation", "rad or m", "largest excursion of any joint beyond its "
               "URDF position limit (rad for revolute joints, m for prismatic ones); 0 if none, "
               "and 0 for arms without limits (the three-link arm)", _WHOLE, "–",
               "every run"),
        Metric("stable", "bool", "not diverged and, for force-controlled runs, "
               f"force_oscillation ≤ {OSCILLATION_LIMIT} and contact_loss ≤ "
               f"{CONTACT_LOSS_LIMIT} (a criterion whose metric is NaN is not applied); "
               "Result.verdict says which criterion failed", _WHOLE, "–", "every run"),
        Metric("diverged", "bool", "the run stopped early: a non-finite state, a singular "
               "Jacobian or a joint speed |q̇| ≥ the velocity limit (100 rad/s); its error metrics "
               "are NaN and diverged_at / divergence_cause say when and why", _WHOLE, "–",
               "every run"),
    ]
})  # fmt: skip


def _pct(v: float) -> str:
    return f"{100 * v:.0f} %" if v >= 0.01 else f"{100 * v:.2g} %"


def verdict(
    metrics: Mapping[str, object],
    diverged_at: float | None = None,
    divergence_cause: str | None = None,
) -> str:
    """Why a run is (not) stable, in words: ``"stable"`` or ``"unstable: ..."`` naming each
    failed criterion with its value and limit.

    Example:
        >>> verdict({"stable": False, "diverged": False, "contact_loss": 0.78,
        ...          "force_oscillation": 0.05})
        'unstable: contact lost in 78 % of samples after 1 s (limit 5 %)'
    """
    if metrics.get("diverged") or diverged_at is not None:
        when = "" if diverged_at is None else f" at t = {diverged_at:.4g} s"
        why = f" ({divergence_cause})" if divergence_cause else ""
        return f"unstable: diverged{when}{why}"
    failed = []
    osc = float(metrics.get("force_oscillation", math.nan))  # type: ignore[arg-type]
    loss = float(metrics.get("contact_loss", math.nan))  # type: ignore[arg-type]
    if loss > CONTACT_LOSS_LIMIT:
        failed.append(f"contact lost in {_pct(loss)} of samples after 1 s"
                      f" (limit {_pct(CONTACT_LOSS_LIMIT)})")  # fmt: skip
    if osc > OSCILLATION_LIMIT:
        failed.append(f"force oscillates: std over the last 2 s is {_pct(osc)} of f_d"
                      f" (limit {_pct(OSCILLATION_LIMIT)})")  # fmt: skip
    if failed:
        return "unstable: " + "; ".join(failed)
    return "stable"


def markdown() -> str:
    """The table of ``docs/metrics.md`` (one row per metric)."""
    lines = [
        "| metric | unit | definition | window | applies to | python-control `step_info` |",
        "|---|---|---|---|---|---|",
    ]
    for m in METRICS.values():
        lines.append(f"| `{m.name}` | {m.unit or '–'} | {m.description} | {m.window} |"
                     f" {m.applies_to} | {m.step_info} |")  # fmt: skip
    return "\n".join(lines) + "\n"
