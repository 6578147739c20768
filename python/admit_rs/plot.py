"""Plots people expect from a force-control run."""

from __future__ import annotations

from typing import TYPE_CHECKING

import matplotlib

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from admit_rs.simulation import Result


def plot_result(result: Result, title: str | None = None) -> Figure:
    """Four panels: force and f_d; x and its reference; z and its reference; x_a.

    Position-only runs show joint torques in place of the force panels.
    """
    from matplotlib.figure import Figure

    matplotlib.rcParams.setdefault("figure.dpi", 100)
    tr = result.trace
    t = tr["t"].to_numpy()
    force_control = result.scenario.admittance is not None
    fig = Figure(figsize=(11, 7.5), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True)
    (ax_f, ax_x), (ax_z, ax_a) = axes
    if force_control:
        ax_f.plot(t, tr["f"].to_numpy(), label="f")
        ax_f.plot(t, tr["f_d"].to_numpy(), "--", color="k", lw=1, label="f_d")
        ax_f.set_ylabel("force [N]")
        ax_f.set_title("contact force")
        ax_a.plot(t, 1e3 * tr["x_a"].to_numpy(), color="C2")
        ax_a.set_ylabel("x_a [mm]")
        ax_a.set_title("admittance output x_a")
    else:
        for i in range(1, 4):
            ax_f.plot(t, tr[f"tau{i}"].to_numpy(), label=f"τ{i}")
        ax_f.set_ylabel("torque [N·m]")
        ax_f.set_title("joint torques")
        ax_a.plot(t, 1e3 * (tr["z_ref"] - tr["z"]).to_numpy(), color="C3")
        ax_a.set_ylabel("z_d − z [mm]")
        ax_a.set_title("z tracking error")
    ax_x.plot(t, tr["x"].to_numpy(), label="x")
    ax_x.plot(t, tr["x_ref"].to_numpy(), "--", color="k", lw=1, label="x_ref")
    ax_x.set_ylabel("x [m]")
    ax_x.set_title("x position")
    ax_z.plot(t, tr["z"].to_numpy(), label="z")
    ax_z.plot(t, tr["z_ref"].to_numpy(), "--", color="k", lw=1, label="z_ref")
    ax_z.set_ylabel("z [m]")
    ax_z.set_title("z position")
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=8)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    if result.diverged_at is not None:
        for ax in axes.flat:
            ax.axvline(result.diverged_at, color="r", lw=1)
    heading = title or result.scenario.label or "admit_rs run"
    if result.diverged_at is not None:
        heading += f" — diverged at {result.diverged_at:.3g} s: {result.divergence_cause}"
    fig.suptitle(heading)
    return fig
