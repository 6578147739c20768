"""Plots people expect: one run, a paper figure, and sweep tables."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import matplotlib
import numpy as np
import numpy.typing as npt
import polars as pl
from matplotlib.patches import Rectangle

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


def _stable_mask(table: pl.DataFrame) -> npt.NDArray[np.bool_]:
    return table["stable"].to_numpy().astype(bool)


def sweep_scatter(table: pl.DataFrame, x: str, metric: str, *, logx: bool | None = None) -> Figure:
    """A metric against one parameter, one dot per run; unstable runs as red crosses at
    the top of the axis (their metrics are NaN)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.subplots()
    stable = _stable_mask(table)
    xs, ys = table[x].to_numpy(), table[metric].to_numpy()
    ax.scatter(xs[stable], ys[stable], s=8, alpha=0.6, label=f"stable ({stable.sum()})")
    if (~stable).any():
        top = np.nanmax(ys[stable]) if stable.any() else 1.0
        ax.scatter(xs[~stable], np.full((~stable).sum(), top), marker="x", color="r",
                   label=f"unstable ({(~stable).sum()})")  # fmt: skip
    if logx if logx is not None else _looks_logarithmic(xs):
        ax.set_xscale("log")
    ax.set_xlabel(x)
    ax.set_ylabel(metric)
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title(f"{metric} vs {x} ({table.height} runs)")
    return fig


def sweep_hist(table: pl.DataFrame, metric: str, bins: int = 50) -> Figure:
    """Histogram of a metric over the stable runs; the unstable count in the title."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.subplots()
    stable = _stable_mask(table)
    values = table[metric].to_numpy()[stable]
    values = values[np.isfinite(values)]
    ax.hist(values, bins=bins)
    ax.set_xlabel(metric)
    ax.set_ylabel("runs")
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{metric}: {stable.sum()} stable, {(~stable).sum()} unstable runs")
    return fig


def sweep_heatmap(
    table: pl.DataFrame,
    x: str,
    y: str,
    metric: str,
    *,
    bins: int = 12,
    agg: str = "mean",
    logx: bool = False,
    logy: bool = False,
) -> Figure:
    """A metric over two parameters: the grid values as they are, or ``bins`` bins per
    axis for random draws; each cell aggregates its stable runs (``mean``, ``max``,
    ``min`` or ``median``) and cells with any unstable run are hatched and annotated.
    ``logx``/``logy`` bin and draw an axis logarithmically (for log-uniform draws)."""
    from matplotlib.figure import Figure

    if agg not in ("mean", "max", "min", "median"):
        raise ValueError(f"agg = {agg!r} is invalid: must be mean, max, min or median")
    xs, ys = table[x].to_numpy().astype(float), table[y].to_numpy().astype(float)
    xe, xi = _axis(xs, bins, logx)
    ye, yi = _axis(ys, bins, logy)
    values = table[metric].to_numpy().astype(float)
    stable = _stable_mask(table)
    grid = np.full((len(ye) - 1, len(xe) - 1), np.nan)
    unstable = np.zeros_like(grid, dtype=int)
    reducers: dict[str, Callable[[npt.NDArray[np.float64]], Any]] = {
        "mean": np.mean, "max": np.max, "min": np.min, "median": np.median,
    }  # fmt: skip
    reducer = reducers[agg]
    for r in range(grid.shape[0]):
        for c in range(grid.shape[1]):
            cell = (yi == r) & (xi == c)
            good = values[cell & stable]
            good = good[np.isfinite(good)]
            if good.size:
                grid[r, c] = reducer(good)
            unstable[r, c] = int((cell & ~stable).sum())
    fig = Figure(figsize=(8, 6), layout="constrained")
    ax = fig.subplots()
    mesh = ax.pcolormesh(xe, ye, grid, shading="flat")
    fig.colorbar(mesh, ax=ax, label=f"{agg} {metric} (stable runs)")
    for r, c in zip(*np.nonzero(unstable), strict=True):
        ax.add_patch(Rectangle((xe[c], ye[r]), xe[c + 1] - xe[c], ye[r + 1] - ye[r],
                               fill=False, hatch="xx", edgecolor="r", lw=0))  # fmt: skip
        ax.text((xe[c] + xe[c + 1]) / 2, (ye[r] + ye[r + 1]) / 2, f"{unstable[r, c]} ✗",
                color="r", ha="center", va="center", fontsize=8)  # fmt: skip
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(f"{metric} over {x} × {y} ({table.height} runs)")
    return fig


def _looks_logarithmic(xs: npt.NDArray[Any]) -> bool:
    xs = np.asarray(xs, dtype=float)
    xs = xs[np.isfinite(xs)]
    return bool(xs.size and xs.min() > 0 and xs.max() / xs.min() > 50)


def _axis(
    values: npt.NDArray[np.float64], bins: int, log: bool = False
) -> tuple[npt.NDArray[np.float64], Any]:
    """Cell edges and each value's cell: distinct values if few, else equal-width bins
    (equal in log10 when ``log``)."""
    if log:
        edges, index = _axis(np.log10(values), bins)
        return 10.0**edges, index
    distinct = np.unique(values[np.isfinite(values)])
    if distinct.size == 0:
        raise ValueError("no finite values to place on the axis")
    if distinct.size <= bins:
        if distinct.size == 1:
            edges = np.array([distinct[0] - 0.5, distinct[0] + 0.5])
        else:
            mids = (distinct[1:] + distinct[:-1]) / 2
            edges = np.concatenate(
                [[distinct[0] - (mids[0] - distinct[0])], mids,
                 [distinct[-1] + (distinct[-1] - mids[-1])]]
            )  # fmt: skip
        return edges, np.searchsorted(distinct, values)
    edges = np.linspace(distinct[0], distinct[-1], bins + 1)
    return edges, np.clip(np.searchsorted(edges, values, side="right") - 1, 0, bins - 1)
