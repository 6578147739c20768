"""What every metric of a run means: definition, unit, window, python-control equivalent.

:data:`METRICS` maps each name of ``Result.metrics`` (and of a sweep table's metric
columns) to a :class:`Metric`. Plots and the command line label axes from it, and
``docs/metrics.md`` is generated from it (:func:`markdown`), so the three cannot drift.

Example:
    >>> import admit_rs as ar
    >>> m = ar.METRICS["contact_loss"]
    >>> m.unit, m.window
    ('fraction (0–1)', 'from first contact + 1 s (t ≥ 1 s for a run that starts touching)')
    >>> ar.METRICS["z_rms_error"].label
    'z_rms_error [m]'
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

__all__ = [
    "METRICS",
    "Metric",
    "markdown",
]


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
_LAST = "last 2 s, from first contact + 1 s (t ≥ 1 s for a run that starts touching)"
_LATE = "from first contact + 1 s (t ≥ 1 s for a run that starts touching)"
_STEP = "runs whose f_d is a Step"

METRICS: Mapping[str, Metric] = MappingProxyType({
    m.name: m
    for m in [
        Metric("force_ss_error", "N", "mean(f_d − f): the force offset left at the end",
               "last 2 s (no earlier than first contact + 1 s for a run that starts apart)",
               "≈ f_d − SteadyStateValue"),
        Metric("force_rms_error", "N", "RMS of f_d − f", _LATE, "–"),
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
        Metric("peak_time", "s", "time of the whole run's maximum |f| (the sample where "
               "force_peak is first reached). With motion along the wall this can be a bump "
               "long after the step (fig. 14: 1.716 s); the step's own first peak is "
               "step_peak_time", _WHOLE, "PeakTime (the whole run's maximum)", _STEP),
        Metric("step_overshoot_pct", "%", "the step response's own overshoot: 100 (p − "
               "f_d,final) / f_d,final with p the step's first peak, the first local maximum "
               "of f at or after f first reaches f_d (fig. 14: 12.57 N at 0.321 s); 0 when f "
               "never reaches f_d. Unlike overshoot_pct, later bumps and bounces do not count",
               _WHOLE, "– (Overshoot takes the whole run's maximum: overshoot_pct)", _STEP),
        Metric("step_peak_time", "s", "time of the step's first peak (fig. 14: 0.321 s); NaN "
               "when f never reaches f_d", _WHOLE,
               "– (PeakTime is the whole run's maximum: peak_time)", _STEP),
        Metric("z_rms_error", "m", "RMS of the motion error t̂·(X_d − X) along the wall's "
               "tangent t̂: z_d − z for the paper's wall (metres, not mm)", _WHOLE, "–",
               "every run"),
        Metric("x_rms_error", "m", "RMS of the error n·(X_d − X) along the wall normal n (x_d − x "
               "for the paper's wall), X_d including the admittance output x_a", _WHOLE, "–",
               "every run"),
        Metric("path_rms_error", "m", "RMS of the tip's position error within the wall's "
               "tangent plane, |(X_d − X) − n·(X_d − X) n|, in force-controlled runs (the "
               "motion the task asks for); in position-only runs the whole error |X_d − X|. "
               "What Criteria.max_path_error judges", _WHOLE, "–", "every run"),
        Metric("contact_loss", "fraction (0–1)", "fraction of samples with f = 0 (a fraction, "
               "not a percentage: 0.36 means 36 % of the samples). The approach through free space "
               "before first contact does not count", _LATE, "–"),
        Metric("force_oscillation", "fraction (0–1)", "std(f − f_d) / mean |f_d|: the force's "
               "spread about its reference relative to the reference. With a constant f_d in the "
               "window this is std(f) / |final f_d|; measuring the spread about f_d keeps a run "
               "that tracks a sine from counting as oscillating. NaN when the window is empty "
               "(runs ≤ 1 s) or f_d ≡ 0 there", _LAST, "–"),
        Metric("tangential_force_mean", "N", "mean |F_t|, the Coulomb friction force along "
               "the surface (Wall.friction and the other surfaces' friction, SPEC §15): "
               "about μ f_d while the tool slides faster than stiction_velocity, 0 on a "
               "frictionless surface", "last 2 s (no earlier than first contact + 1 s for a run "
               "that starts apart), as force_ss_error", "–"),
        Metric("bounces", "count", "number of times contact is lost (f > 0 followed by f = "
               "0) after first contact. Tells bouncing (many) from ripple in contact (0)",
               _WHOLE, "–"),
        Metric("first_contact_time", "s", "time of the first sample with f > 0; NaN if the "
               "tool never touches. The contact phase starts here for a run that starts apart "
               "(Wall.gap > 0, or a wall placed beyond the tip)", _WHOLE, "–"),
        Metric("impact_peak", "N", "max f within 0.5 s after first contact (also reported for "
               "a run that diverged); NaN if the tool never touches. For a run that starts "
               "touching this is the step's first peak", "0.5 s from first contact", "–"),
        Metric("assessed_time", "s", "span of the window the force criteria judge, from 1 s "
               "into the contact phase (t = 1 s for a run that starts touching, first contact "
               "+ 1 s for one that starts apart) to the end of the run; a run with less than "
               "Criteria.min_assessed is \"not assessed\"", _LATE, "–"),
        Metric("torque_saturation", "fraction (0–1)", "fraction of samples with any joint's "
               "applied torque at the actuator's torque_limit (0 without a limit)", _WHOLE, "–",
               "every run"),
        Metric("joint_limit_violation", "rad or m", "largest excursion of any joint beyond its "
               "URDF position limit (rad for revolute joints, m for prismatic ones); 0 if none, "
               "and 0 for arms without limits (the three-link arm)", _WHOLE, "–",
               "every run"),
        Metric("stable", "bool or null", "the loop's dynamics (SPEC §23): False when the "
               "run diverged, or fails max_force_oscillation, max_contact_loss or max_bounces "
               "of Scenario.criteria (ar.Criteria) and still fails it in the same run with "
               "its drives held (the motion held at its start, f_d held, no sensor noise): an "
               "oscillation or a loss of contact the loop sustains by itself; None (null in "
               "tables) when a force-controlled run is not assessed (assessed_time < "
               "min_assessed, or f_d ≡ 0 in the window); True otherwise, a ripple the motion "
               "drives included", _WHOLE, "–", "every run"),
        Metric("passed", "bool or null", "every criterion of Scenario.criteria met: False "
               "when the run diverged or any criterion that is set fails, driven or not (by "
               "default force_oscillation ≤ 0.1 and contact_loss ≤ 0.05 for force-controlled "
               "runs); None when not assessed; True otherwise. Result.verdict (a sweep's "
               "verdict column) says \"unstable: …\" or \"out of tolerance: …\" and names each "
               "failed criterion with its value and limit", _WHOLE, "–", "every run"),
        Metric("diverged", "bool", "the run stopped early: a non-finite state, a singular "
               "Jacobian or a joint speed |q̇| ≥ the velocity limit (100 rad/s); its error metrics "
               "are NaN and diverged_at / divergence_cause say when and why", _WHOLE, "–",
               "every run"),
    ]
})  # fmt: skip


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
