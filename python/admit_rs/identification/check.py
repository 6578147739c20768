"""A fitted cell checked against a log it was not fitted on (issue #58 part 4): the recorded
motion replayed through the fitted contact law and sensor, the force read predicted, and the
error against the force recorded."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from admit_rs.identification.least_squares import Array, alpha_of, low_pass_delay
from admit_rs.identification.log_arrays import LogArrays
from admit_rs.identification.model import contact_geometry, friction_direction, normal_force


@dataclass(frozen=True)
class CellCheck:
    """How well a fitted cell predicts a recording: the force read along the fitted normal,
    recorded and predicted (``trace``: ``t``, ``recorded``, ``predicted``, ``residual`` [N]),
    its RMS and peak error [N] over the samples after the filter has settled (the first
    ``settle`` samples start from the recording's first reading and are left out), and the
    tangential force's RMS error [N]."""

    trace: pl.DataFrame
    rms_error: float
    peak_error: float
    tangential_rms_error: float
    force_range: float
    settle: int
    noise_as_read: float
    """The fitted sensor noise as it reads after the low-pass [N]: σ √(α/(2 − α)). An RMS
    error near it leaves nothing but noise unexplained."""

    def __str__(self) -> str:
        return (f"force along n: RMS error {self.rms_error:.3g} N (the fitted noise reads "
                f"{self.noise_as_read:.3g} N), peak error {self.peak_error:.3g} N (the recorded "
                f"force spans {self.force_range:.3g} N); tangential RMS error "
                f"{self.tangential_rms_error:.3g} N")  # fmt: skip


def predicted_reading(values: Mapping[str, Any], cell: LogArrays, stiction: float) -> Array:
    """The sensor's reading (its own frame) the fitted cell gives for the recorded motion:
    the law's normal force and Coulomb friction on the fitted plane, the tool's weight and
    the bias, the low-pass and the latency (SPEC §10, §15)."""
    v = values
    depth, n = contact_geometry(v, cell.x)
    exponent = v.get("wall.exponent", 1.0) if v.get("wall.model") == "hunt_crossley" else 1.0
    force = normal_force(depth, np.sum(cell.v * n, axis=1), v["wall.stiffness"],
                         v["wall.damping"], exponent)  # fmt: skip
    world = force[:, None] * n
    if "wall.friction" in v:
        world = world + v["wall.friction"] * force[:, None] * friction_direction(
            cell.v, n, stiction)  # fmt: skip
    weight = np.array([0.0, 0.0, v.get("sensor.tool_mass", 0.0) * cell.gravity])
    if cell.tip_frame:
        u = np.einsum("kji,kj->ki", cell.rotation, world + weight)
    else:
        u = world + weight
    u = u + np.asarray(v["sensor.bias"], dtype=float)
    alpha = alpha_of(v.get("sensor.cutoff"), cell.period)
    return low_pass_delay(u, alpha, int(v.get("sensor.latency", 0)))


def check(values: Mapping[str, Any], cell: LogArrays, stiction: float) -> CellCheck:
    """The fitted cell's (``values``) prediction of ``cell``'s recording, compared."""
    predicted = predicted_reading(values, cell, stiction)
    _, n = contact_geometry(values, cell.x)
    static = np.asarray(values["sensor.bias"], dtype=float) + values.get(
        "sensor.tool_mass", 0.0) * cell.up_in_sensor()  # fmt: skip
    recorded_w = cell.to_world(cell.reading - static)
    predicted_w = cell.to_world(predicted - static)
    recorded, model = np.sum(recorded_w * n, axis=1), np.sum(predicted_w * n, axis=1)
    alpha = alpha_of(values.get("sensor.cutoff"), cell.period)
    settle = int(values.get("sensor.latency", 0)) + int(math.ceil(5 / max(alpha, 1e-9)))
    keep = np.arange(len(recorded)) >= settle
    residual = recorded - model
    tangential = (recorded_w - recorded[:, None] * n) - (predicted_w - model[:, None] * n)
    trace = pl.DataFrame({"t": cell.t, "recorded": recorded, "predicted": model,
                          "residual": residual})  # fmt: skip
    return CellCheck(
        trace=trace,
        rms_error=float(np.sqrt(np.mean(residual[keep] ** 2))),
        peak_error=float(np.max(np.abs(residual[keep]))),
        tangential_rms_error=float(np.sqrt(np.mean(np.sum(tangential[keep] ** 2, axis=1)))),
        force_range=float(np.ptp(recorded[keep])),
        settle=settle,
        noise_as_read=float(values.get("sensor.noise_std", math.nan)
                            * math.sqrt(alpha / (2 - alpha))),  # fmt: skip
    )


def write_report(table: pl.DataFrame, confidence: float, result: CellCheck, out: Path,
                 title: str, doubts: tuple[str, ...] = ()) -> Path:  # fmt: skip
    """``report.md`` and ``check.png`` in ``out``: the fitted cell's table, the check's errors,
    the recorded and predicted force and the residual."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    tr = result.trace
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
    t = tr["t"].to_numpy()
    axes[0].plot(t, tr["recorded"].to_numpy(), lw=0.7, label="recorded")
    axes[0].plot(t, tr["predicted"].to_numpy(), lw=0.9, ls="--", label="fitted cell, replayed")
    axes[0].set(ylabel="force read along n [N]",
                title=f"{title}: the fitted cell against the held-out log")  # fmt: skip
    axes[0].legend(fontsize=8)
    axes[1].plot(t, tr["residual"].to_numpy(), lw=0.6, color="C3")
    axes[1].axvspan(t[0], t[min(result.settle, len(t) - 1)], color="0.85",
                    label="filter settling (left out)")  # fmt: skip
    axes[1].set(xlabel="t [s] (the held-out part's own clock)",
                ylabel="recorded − predicted [N]")  # fmt: skip
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "check.png", dpi=110)
    plt.close(fig)
    rows = ["| path | fitted | 95 % interval | how |", "|---|---|---|---|"]
    for row in table.iter_rows(named=True):
        rows.append(f"| `{row['path']}` | {row['value']} | {row['interval']} | {row['how']} |")
    text = "\n".join([
        f"# {title}", "",
        *[f"**Not trustworthy**: {d}.\n" for d in doubts],
        f"The cell fitted from the log, with {100 * confidence:.0f} % intervals:", "",
        *rows, "",
        "## Checked against the held-out log", "",
        "The recorded joint motion replayed through the fitted plane, contact law, friction "
        "and sensor (bias, weight, low-pass, latency); the force read along the fitted normal "
        f"compared with the recorded one after the first {result.settle} samples (the filter "
        "starting from the first reading):", "",
        f"- RMS error **{result.rms_error:.3g} N** (the fitted sensor noise reads "
        f"{result.noise_as_read:.3g} N: an error near it leaves only noise unexplained), "
        f"peak error **{result.peak_error:.3g} N**; the recorded force spans "
        f"{result.force_range:.3g} N;",
        f"- tangential force RMS error {result.tangential_rms_error:.3g} N.", "",
        "![recorded and predicted force](check.png)", "",
    ])  # fmt: skip
    path = out / "report.md"
    path.write_text(text, encoding="utf-8")
    return path

