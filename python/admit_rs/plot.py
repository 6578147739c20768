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


def plot_paper_figure(
    results: list[Result], title: str, size: tuple[float, float] = (15.0, 8.0)
) -> Figure:
    """A paper figure: every curve overlaid, panels like the paper's (a), (b), ...

    Force runs: force and f_d, force error, x and x_ref, z and z_ref, x_a, joint torques
    (of the first curve). Position-only runs: x, z, their errors and the joint torques.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    axes = list(fig.subplots(2, 3, sharex=True).flat)
    force_control = results[0].scenario.admittance is not None
    many = len(results) > 1
    for i, r in enumerate(results):
        tr = r.trace
        t = tr["t"].to_numpy()
        label = r.scenario.label or f"curve {i + 1}"
        color = f"C{i}"
        ref_style = {"color": color if many else "k", "ls": "--", "lw": 1}
        ref_label = f"reference ({label})" if many else "reference"
        if force_control:
            ax = axes[0]
            ax.plot(t, tr["f"].to_numpy(), color=color, label=label)
            if i == 0:
                ax.plot(t, tr["f_d"].to_numpy(), "k--", lw=1, label="f_d")
            axes[1].plot(t, (tr["f_d"] - tr["f"]).to_numpy(), color=color, label=label)
            axes[4].plot(t, 1e3 * tr["x_a"].to_numpy(), color=color, label=label)
        else:
            axes[0].plot(t, 1e3 * (tr["x_ref"] - tr["x"]).to_numpy(), color=color, label=label)
            axes[1].plot(t, 1e3 * (tr["z_ref"] - tr["z"]).to_numpy(), color=color, label=label)
        axes[2].plot(t, tr["x"].to_numpy(), color=color, label=label)
        axes[2].plot(t, tr["x_ref"].to_numpy(), label=ref_label, **ref_style)
        axes[3].plot(t, tr["z"].to_numpy(), color=color, label=label)
        if i == 0 or many:
            axes[3].plot(t, tr["z_ref"].to_numpy(), label=ref_label if i == 0 else None,
                         **ref_style)  # fmt: skip
        if i == 0:
            for j in range(1, 4):
                axes[5].plot(t, tr[f"tau{j}"].to_numpy(), label=f"τ{j}")
        if r.diverged_at is not None:
            for ax in axes:
                ax.axvline(r.diverged_at, color="r", lw=1)
    if force_control:
        names = ["(a) contact force [N]", "(b) force error f_d − f [N]", "(c) x position [m]",
                 "(d) z position [m]", "(e) admittance output x_a [mm]"]  # fmt: skip
    else:
        names = ["(a) x error x_d − x [mm]", "(b) z error z_d − z [mm]", "(c) x position [m]",
                 "(d) z position [m]", ""]  # fmt: skip
        axes[4].set_visible(False)
    tau_title = "joint torques [N·m]" + (f" ({results[0].scenario.label})" if many else "")
    names.append(("(f) " if force_control else "(e) ") + tau_title)
    for ax, name in zip(axes, names, strict=True):
        ax.set_title(name, fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=9)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="best")
    for ax in axes[3:]:
        ax.set_xlabel("t [s]")
    fig.suptitle(title, fontsize=12)
    return fig
