"""What the tuning page says in words: the simulated and predicted verdicts, the pole table
and the run's metrics, as HTML (pure functions of a run and a prediction)."""

from __future__ import annotations

import html
import math
from typing import Any

from admit_rs.metrics import METRICS
from admit_rs.ui import runs


def number(x: Any, digits: int = 4) -> str:
    if x is None:
        return "–"
    if isinstance(x, bool):
        return str(x)
    if not isinstance(x, int | float) or not math.isfinite(x):
        return "–"
    return f"{x:.{digits}g}"


def radius_words(radius: object) -> str:
    """What ρ says on its own: below 1 the linear loop decays, at or above 1 it does not (the
    margins of the verdict line may still fail a loop whose ρ is below 1)."""
    if not isinstance(radius, int | float) or radius != radius:
        return ""
    return "(< 1: decays)" if radius < 1.0 else "(≥ 1: unstable)"


def simulated_html(view: runs.RunView) -> str:
    if not view.complete:
        return ("<b>Simulated:</b> <span style='color:#8a6d00'>cancelled</span> "
                "(the plots show the run up to then; move a slider to run again)")  # fmt: skip
    # Green: passed; orange: stable but out of tolerance; red: unstable; amber: not
    # assessed (SPEC §23).
    if view.passed is True:
        color = "#137333"
    elif view.stable is True:
        color = "#b45309"
    else:
        color = {False: "#c5221f", None: "#8a6d00"}[view.stable]
    words = {True: "yes", False: "no", None: "not assessed"}
    both = (f"stable: <span class='stable'>{words[view.stable]}</span>, passed: "
            f"<span class='passed'>{words[view.passed]}</span>")
    return (f"<b>Simulated:</b> <span style='color:{color};font-weight:bold' "
            f"class='verdict'>{html.escape(view.verdict)}</span> ({both})")  # fmt: skip


def prediction_html(pred: runs.Prediction) -> str:
    if pred.values is None:
        return ("<br><b>Predicted:</b> not available: "
                f"{html.escape(pred.error or 'no linear model')}")  # fmt: skip
    v = pred.values
    stable = bool(v.get("stable"))
    color = "#137333" if stable else "#c5221f"
    margins = (
        f"spectral radius ρ = {number(v.get('spectral_radius'), 5)}; "
        f"gain margin {number(v.get('gain_margin'), 3)}×, "
        f"phase margin {number(v.get('phase_margin'), 3)}°, "
        f"delay margin {number(v.get('delay_margin'), 3)} samples"
    )
    passed = v.get("passed")
    # Green: predicted to pass; orange: out of tolerance; red: unstable with the motion
    # running; amber: not predicted.
    if passed is True:
        tint, words = "#137333", "yes"
    elif passed is False:
        unstable = str(v.get("tolerance_verdict", "")).startswith("unstable")
        tint, words = ("#c5221f" if unstable else "#b45309"), "no"
    else:
        tint, words = "#8a6d00", "not predicted"
    running = (f"<br><b>Predicted with the motion running:</b> <span style='color:{tint};"
               f"font-weight:bold' class='predicted-passed'>"
               f"{html.escape(str(v.get('tolerance_verdict', '')))}</span> (passed: "
               f"{words})")  # fmt: skip
    return (f"<br><b>Predicted:</b> <span style='color:{color};font-weight:bold'>"
            f"{html.escape(str(v.get('verdict', '')))}</span> ({margins})"
            + running)  # fmt: skip


def pole_html(pred: runs.Prediction) -> str:
    if pred.values is None:
        return f"No linear model: {html.escape(pred.error or '')}"
    v = pred.values
    pole = pred.dominant()
    if pole is not None:
        rows = runs.dominant_words(pole, pred.period)
    else:  # no eigenvalues (see the note below): predict's own numbers
        rows = [
            ("dominant pole frequency", number(v.get("dominant_frequency"), 4), "Hz"),
            ("dominant pole damping ζ", number(v.get("dominant_damping"), 3), ""),
        ]
    rows += [
        ("spectral radius ρ", number(v.get("spectral_radius"), 6),
         radius_words(v.get("spectral_radius"))),
        # Of the step 0 → f_d with the motion held (issue #53 item 11: 0.397 s stood
        # beside the run's 9.488 s, whose ±2 % band the motion's ripple keeps leaving).
        ("predicted overshoot (step, motion held)", number(v.get("overshoot_pct"), 3),
         "%"),
        ("predicted settling time (step, motion held)", number(v.get("settling_time"), 3),
         "s"),
        # An unstable loop reaches no steady state: its "steady" error is no prediction.
        ("predicted force error", number(v.get("force_ss_error"), 3)
         if radius_words(v.get("spectral_radius")) == "(< 1: decays)" else "–", "N"),
    ]
    body = "".join(f"<tr><td>{a}</td><td style='text-align:right'>{b}</td><td>{c}</td></tr>"
                   for a, b, c in rows)  # fmt: skip
    extra = f"<br><i>{html.escape(pred.error)}</i>" if pred.error else ""
    return f"<table style='font-size:90%'>{body}</table>{extra}"


def metrics_html(view: runs.RunView) -> str:
    if not view.metrics:
        return ""
    rows = []
    for name, value in view.metrics.items():
        if name in ("stable", "passed", "diverged"):
            continue
        m = METRICS.get(name)
        unit = m.unit if m is not None and not m.unit.startswith("bool") else ""
        tip = html.escape(m.description, quote=True) if m is not None else ""
        rows.append(f"<tr title='{tip}'><td>{name}</td><td style='text-align:right'>"
                    f"{number(value)}</td><td>{html.escape(unit)}</td></tr>")  # fmt: skip
    return ("<b>Metrics of the run</b><table style='font-size:85%;line-height:1.15'>"
            + "".join(rows) + "</table>")  # fmt: skip

# -- buttons --------------------------------------------------------------------------
