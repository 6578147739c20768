"""Sweep tables drawn (:func:`sweep_scatter`, :func:`sweep_hist`, :func:`sweep_heatmap`) and
the predicted stability map with the simulated runs over it (:func:`stability_map`), each
splitting the runs by ``stable`` or ``passed`` (SPEC §23)."""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import polars as pl
from matplotlib.patches import Rectangle
from matplotlib.ticker import NullLocator

from admit_rs.errors import ArgumentError
from admit_rs.plot.axes import (
    _axis,
    _categories,
    _cell_axis,
    _crosses_zero,
    _declutter,
    _finish_grid_axes,
    _log_axis,
    _metric_label,
    _tick_texts,
    _with_unit,
    parameter_unit,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure



_JUDGED_BY: dict[str, tuple[str, str, str]] = {
    "stable": ("stable", "unstable", "not stable"),
    "passed": ("passed", "failed", "not passed"),
}
"""A judgement a sweep plot can split runs by (SPEC §23): the word for a run that has it,
one that has it not, and the group when some were not assessed."""


def _judged(table: pl.DataFrame, by: str) -> npt.NDArray[np.bool_]:
    """Runs judged ``by`` (``stable``: the loop's dynamics; ``passed``: the criteria met);
    a run not assessed (null: too short) is not among them."""
    if by not in _JUDGED_BY:
        raise ArgumentError(f"by = {by!r} is invalid: must be one of {', '.join(_JUDGED_BY)}")
    from admit_rs._names import check_column

    check_column(table.columns, by, "column")
    return (table[by] == True).fill_null(False).to_numpy().astype(bool)  # noqa: E712


def _good(by: str) -> str:
    return _JUDGED_BY[by][0]


def _bad(table: pl.DataFrame, by: str = "stable") -> str:
    """What the runs outside :func:`_judged` are: "unstable" / "failed", or "not stable" /
    "not passed" when some were not assessed (null)."""
    _, bad, unassessed = _JUDGED_BY[by]
    return unassessed if table[by].null_count() else bad


def sweep_scatter(
    table: pl.DataFrame, x: str, metric: str, *, logx: bool | None = None, by: str = "stable"
) -> Figure:
    """A metric against one parameter, one dot per run; unstable runs as red crosses (at
    their value, or at the top of the axis when it is NaN because the run diverged).
    ``by="passed"`` splits the runs by their criteria instead (a stable run out of
    tolerance is a cross then, SPEC §23)."""
    from matplotlib.figure import Figure

    from admit_rs._names import check_column

    for name in (x, metric):
        check_column(table.columns, name, "column")
    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.subplots()
    stable = _judged(table, by)
    xs, ys = table[x].to_numpy(), table[metric].to_numpy().astype(float)
    ax.scatter(xs[stable], ys[stable], s=8, alpha=0.6, label=f"{_good(by)} ({stable.sum()})")
    if (~stable).any():
        finite = ys[np.isfinite(ys)]
        top = finite.max() if finite.size else 1.0
        bad = np.where(np.isfinite(ys[~stable]), ys[~stable], top)
        ax.scatter(xs[~stable], bad, marker="x", color="r",
                   label=f"{_bad(table, by)} ({(~stable).sum()})")  # fmt: skip
    if logx if logx is not None else _log_axis(xs):
        ax.set_xscale("log")
    ax.set_xlabel(_with_unit(x))
    ax.set_ylabel(_metric_label(metric))
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title(f"{metric} vs {x} ({table.height} runs)")
    return fig


def sweep_hist(table: pl.DataFrame, metric: str, bins: int = 50, *, by: str = "stable") -> Figure:
    """Histogram of a metric over the stable runs (``by="passed"``: the runs that passed
    their criteria); the count of the others in the title."""
    from matplotlib.figure import Figure

    from admit_rs._names import check_column

    check_column(table.columns, metric, "column")
    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.subplots()
    stable = _judged(table, by)
    values = table[metric].to_numpy()[stable]
    values = values[np.isfinite(values)]
    ax.hist(values, bins=bins)
    ax.set_xlabel(_metric_label(metric))
    ax.set_ylabel("runs")
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{metric}: {stable.sum()} {_good(by)}, {(~stable).sum()} {_bad(table, by)} "
                 "runs")
    return fig


WORST_CASE: dict[str, str] = {
    "force_ss_error": "absmax",
    "force_rms_error": "max",
    "force_peak": "max",
    "overshoot_pct": "max",
    "settling_time": "max",
    "rise_time_63": "max",
    "rise_time_10_90": "max",
    "peak_time": "max",
    "z_rms_error": "max",
    "x_rms_error": "max",
    "contact_loss": "max",
    "force_oscillation": "max",
}
"""The default ``agg`` of :func:`sweep_heatmap` per metric: the worst run of each cell
(largest peak, overshoot, oscillation, contact loss, error or time; the signed
``force_ss_error`` of largest magnitude). Other columns default to the mean."""

_REDUCERS: dict[str, Callable[[npt.NDArray[np.float64]], Any]] = {
    "mean": np.mean,
    "max": np.max,
    "min": np.min,
    "median": np.median,
    "absmax": lambda v: v[np.argmax(np.abs(v))],
}


def sweep_heatmap(
    table: pl.DataFrame,
    x: str,
    y: str,
    metric: str,
    *,
    bins: int = 12,
    agg: str | None = None,
    logx: bool | None = None,
    logy: bool | None = None,
    units: dict[str, str] | None = None,
    overlay_unstable: bool = False,
    by: str = "stable",
) -> Figure:
    """A metric over two parameters, to answer "which gains are safe".

    A grid axis (at most ``bins`` distinct values, each repeated) is drawn as categories:
    one equal cell per listed value, its tick labelled with the value (a grid over k_a =
    0.1, 1, 2 is three cells, not a linear axis from −0.4); random draws are binned,
    ``bins`` bins per axis, on a linear or log axis. Tick labels that would collide are
    thinned (every 2nd, 3rd, ... kept). Each cell
    aggregates its stable runs with ``agg`` (``max``, ``min``, ``mean``, ``median`` or
    ``absmax``); the default is the worst case for the metric (:data:`WORST_CASE`: ``max``
    of force_peak, overshoot_pct, force_oscillation, contact_loss and the errors, the
    largest-magnitude force_ss_error), the mean for other columns. Cells whose runs are all
    unstable are filled as the "unstable" category, cells with some unstable runs are
    hatched with their count, cells without runs are grey; a legend explains the three.
    For draws, ``logx``/``logy`` default to a log axis (and log bins) when the parameter
    looks log-uniform; ``True``/``False`` force a continuous log/linear axis (also for a
    grid, whose cells then span halfway to the next value). Axes and colour bar show
    units (metrics from :data:`admit_rs.METRICS`, parameters from the blocks' docs;
    ``units={"path": "unit"}`` adds or overrides). ``overlay_unstable`` marks every unstable
    run with a red ×. ``by="passed"`` splits the runs by their criteria instead of their
    stability (SPEC §23: a ripple the motion drives is stable and fails its criteria): cells
    then aggregate the runs that passed and mark the ones that failed. Unknown
    ``x``/``y``/``metric`` raise :class:`admit_rs.UnknownNameError`.

    Example:
        >>> import admit_rs as ar
        >>> t = ar.sweep(ar.paper.scenario("fig14").replace(duration=1.5),
        ...              grid={"wall.stiffness": [1e4, 1e5], "admittance.b": [200.0, 800.0]},
        ...              progress=False)
        >>> ax = ar.plot.sweep_heatmap(t, "wall.stiffness", "admittance.b", "force_peak").axes[0]
        >>> ax.get_xlabel(), ax.get_xscale()
        ('wall.stiffness [N/m]', 'linear')
    """
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    from admit_rs._names import check_column

    for name in (x, y, metric):
        check_column(table.columns, name, "column")
    agg = agg if agg is not None else WORST_CASE.get(metric, "mean")
    if agg not in _REDUCERS:
        raise ArgumentError(f"agg = {agg!r} is invalid: must be one of {', '.join(_REDUCERS)}")
    xs, ys = table[x].to_numpy().astype(float), table[y].to_numpy().astype(float)
    # A grid is drawn as categories: one equal cell per listed value, labelled with it
    # (k_a = 0.1, 1, 2 are three cells, not a linear axis from -0.4); random draws are
    # binned on a linear or log axis. logx/logy force a continuous axis.
    xcat = _categories(xs, bins) if logx is None else None
    ycat = _categories(ys, bins) if logy is None else None
    logx = False if xcat is not None else _log_axis(xs, bins) if logx is None else logx
    logy = False if ycat is not None else _log_axis(ys, bins) if logy is None else logy
    xe, xi, xp = _cell_axis(xs, bins, logx, xcat)
    ye, yi, yp = _cell_axis(ys, bins, logy, ycat)
    values = table[metric].to_numpy().astype(float)
    stable = _judged(table, by)
    grid = np.full((len(ye) - 1, len(xe) - 1), np.nan)
    unstable = np.zeros_like(grid, dtype=int)
    runs = np.zeros_like(grid, dtype=int)
    reducer = _REDUCERS[agg]
    for r in range(grid.shape[0]):
        for c in range(grid.shape[1]):
            cell = (yi == r) & (xi == c)
            good = values[cell & stable]
            good = good[np.isfinite(good)]
            if good.size:
                grid[r, c] = reducer(good)
            unstable[r, c] = int((cell & ~stable).sum())
            runs[r, c] = int(cell.sum())
    fig = Figure(figsize=(8.5, 6), layout="constrained")
    ax = fig.subplots()
    ax.set_facecolor("0.85")  # cells without a value show the background
    mesh = ax.pcolormesh(xe, ye, grid, shading="flat")
    label = _metric_label(metric, units)
    fig.colorbar(mesh, ax=ax, label=f"{agg} {label} ({_good(by)} runs)")
    handles: list[Any] = []
    if (runs == 0).any():
        handles.append(Patch(facecolor="0.85", edgecolor="0.5", label="no runs in cell"))
    all_bad = (runs > 0) & (unstable == runs)
    some_bad = (unstable > 0) & ~all_bad
    for r, c in zip(*np.nonzero(unstable), strict=True):
        w, h = xe[c + 1] - xe[c], ye[r + 1] - ye[r]
        if all_bad[r, c]:
            ax.add_patch(Rectangle((xe[c], ye[r]), w, h, facecolor="#8b0000", lw=0))
        else:
            ax.add_patch(Rectangle((xe[c], ye[r]), w, h, fill=False, hatch="xx",
                                   edgecolor="r", lw=0))  # fmt: skip
        cx = np.sqrt(xe[c] * xe[c + 1]) if logx else (xe[c] + xe[c + 1]) / 2
        cy = np.sqrt(ye[r] * ye[r + 1]) if logy else (ye[r] + ye[r + 1]) / 2
        box = None if all_bad[r, c] else {"facecolor": "w", "alpha": 0.7, "lw": 0}
        ax.text(cx, cy, f"{unstable[r, c]} ✗", color="w" if all_bad[r, c] else "k",
                ha="center", va="center", fontsize=8, bbox=box)  # fmt: skip
    if all_bad.any():
        handles.append(Patch(facecolor="#8b0000",
                             label=f"{_bad(table, by)}: every run in the cell"))  # fmt: skip
    if some_bad.any():
        handles.append(Patch(fill=False, hatch="xx", edgecolor="r",
                             label=f"some runs {_bad(table, by)} (count ✗)"))  # fmt: skip
    if overlay_unstable and (~stable).any():
        bad = f"{_bad(table, by)} run ({(~stable).sum()})"
        handles.append(ax.scatter(xp[~stable], yp[~stable], marker="x", color="r", s=12,
                                  lw=0.8, label=bad))  # fmt: skip
    _finish_grid_axes(ax, xe, ye, logx, logy, _with_unit(x, units), _with_unit(y, units), handles)
    for axis, cats in ((ax.xaxis, xcat), (ax.yaxis, ycat)):
        if cats is not None:
            axis.set_ticks(np.arange(cats.size), labels=_tick_texts(cats))
            axis.set_minor_locator(NullLocator())
    _declutter(fig, ax)
    ax.set_title(textwrap.fill(f"{agg} {metric} over {x} × {y} ({table.height} runs,"
                               f" {int((~stable).sum())} {_bad(table, by)})", 70))  # fmt: skip
    return fig




def stability_map(
    table: pl.DataFrame,
    overlay: pl.DataFrame | None = None,
    *,
    logx: bool | None = None,
    logy: bool | None = None,
    title: str | None = None,
    by: str = "stable",
) -> Figure:
    """A predicted stability map (:func:`admit_rs.analysis.stability_map`): the spectral
    radius ρ per cell (blue below 1, red above), the predicted boundary ρ = 1 as a black
    line, cells without an equilibrium in grey; with ``overlay`` (a sweep table with the
    same two parameter columns) each simulated run as a green ○ (``stable``, SPEC §23) or a
    red × (not), and the share of cells where prediction and simulation agree.
    ``by="passed"`` marks and compares the runs by their criteria instead (a ripple the
    motion drives fails them while the loop stays stable); on a map made with
    ``motion=True`` it also hatches the cells predicted out of tolerance and compares the
    runs with the predicted ``passed``. An axis
    is logarithmic when its values are log-spaced, or positive with linear cells that
    would start below zero; tick labels that would collide are thinned.

    Example:
        >>> import admit_rs as ar
        >>> t = ar.analysis.stability_map(ar.paper.scenario("fig14"),
        ...     x={"wall.stiffness": [1e4, 1e5, 1e6]}, y={"admittance.b": [200.0, 800.0]})
        >>> ar.plot.stability_map(t).axes[0].get_xscale()
        'log'
    """
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    x, y = table.columns[0], table.columns[1]
    xv = np.unique(table[x].to_numpy().astype(float))
    yv = np.unique(table[y].to_numpy().astype(float))
    # A positive grid whose linear cells would reach below zero (k_a = 0.1, 1, 2: from
    # -0.35) is drawn on a log axis instead.
    logx = _log_axis(xv) or _crosses_zero(xv) if logx is None else logx
    logy = _log_axis(yv) or _crosses_zero(yv) if logy is None else logy
    rho = np.full((yv.size, xv.size), np.nan)
    xi = np.searchsorted(xv, table[x].to_numpy().astype(float))
    yi = np.searchsorted(yv, table[y].to_numpy().astype(float))
    rho[yi, xi] = table["spectral_radius"].to_numpy().astype(float)
    xe, _ = _axis(np.log10(xv) if logx else xv, xv.size)
    ye, _ = _axis(np.log10(yv) if logy else yv, yv.size)
    xe, ye = (10.0**xe if logx else xe), (10.0**ye if logy else ye)
    fig = Figure(figsize=(8.5, 6), layout="constrained")
    ax = fig.subplots()
    ax.set_facecolor("0.85")
    finite = rho[np.isfinite(rho)]
    lo = float(min(finite.min(), 0.99)) if finite.size else 0.99
    hi = float(max(finite.max(), 1.01)) if finite.size else 1.01
    mesh = ax.pcolormesh(xe, ye, rho, shading="flat", cmap="coolwarm",
                         norm=TwoSlopeNorm(vcenter=1.0, vmin=lo, vmax=hi))  # fmt: skip
    fig.colorbar(mesh, ax=ax, label="predicted spectral radius ρ")
    handles: list[Any] = []
    if finite.size and (finite < 1).any() and (finite > 1).any() and min(rho.shape) > 1:
        ax.contour(xv, yv, np.nan_to_num(rho, nan=2.0), levels=[1.0], colors="k",
                   linewidths=2)  # fmt: skip
        handles.append(Line2D([], [], color="k", lw=2, label="predicted boundary ρ = 1"))
    subtitle = ""
    # Predicted with the motion running (stability_map(..., motion=True)): hatch the cells
    # stable by ρ that the forced response predicts out of tolerance.
    motion = by == "passed" and "passed" in table.columns
    if motion:
        from matplotlib.patches import Rectangle

        out = table.filter((pl.col("passed") == False) & (pl.col("spectral_radius") < 1))  # noqa: E712
        for cx, cy in zip(out[x].to_numpy().astype(float), out[y].to_numpy().astype(float),
                          strict=True):  # fmt: skip
            i, j = int(np.searchsorted(xv, cx)), int(np.searchsorted(yv, cy))
            ax.add_patch(Rectangle((xe[i], ye[j]), xe[i + 1] - xe[i], ye[j + 1] - ye[j],
                                   fill=False, hatch="///", edgecolor="0.25", lw=0))  # fmt: skip
        if out.height:
            label = f"predicted out of tolerance ({out.height})"
            handles.append(Rectangle((0, 0), 1, 1, fill=False, hatch="///", edgecolor="0.25",
                                     label=label))  # fmt: skip
    predicted_by = "passed" if motion else "stable"
    if overlay is not None:
        from admit_rs._names import check_column

        for name in (x, y):
            check_column(overlay.columns, name, "column")
        ox = overlay[x].to_numpy().astype(float)
        oy = overlay[y].to_numpy().astype(float)
        ok = _judged(overlay, by)
        handles.append(ax.scatter(ox[ok], oy[ok], marker="o", facecolors="none",
                                  edgecolors="g", s=28, lw=1.2,
                                  label=f"simulated {_good(by)} ({ok.sum()})"))  # fmt: skip
        bad = f"simulated {_bad(overlay, by)} ({(~ok).sum()})"
        handles.append(ax.scatter(ox[~ok], oy[~ok], marker="x", color="darkred", s=28,
                                  lw=1.2, label=bad))  # fmt: skip
        joined = table.select(x, y, pl.col(predicted_by).alias("_predicted")).join(
            overlay.select(pl.col(x).cast(table[x].dtype), pl.col(y).cast(table[y].dtype),
                           pl.col(by).alias("_simulated")),
            on=[x, y],
        )  # fmt: skip
        if joined.height:
            same = (joined["_predicted"] == joined["_simulated"]).fill_null(False)
            agree = float(same.mean())  # type: ignore[arg-type]
            subtitle = (f"\nsimulated `{by}` agrees with predicted `{predicted_by}` in "
                        f"{agree:.0%} of {joined.height} cells")  # fmt: skip
    xlabel, ylabel = _with_unit(x, {x: parameter_unit(x)}), _with_unit(y, {y: parameter_unit(y)})
    _finish_grid_axes(ax, xe, ye, logx, logy, xlabel, ylabel, handles)
    for axis, values in ((ax.xaxis, xv), (ax.yaxis, yv)):
        if values.size <= 12:  # a short grid: a tick at each value, labelled with it
            axis.set_ticks(values, labels=_tick_texts(values))
            axis.set_minor_locator(NullLocator())
    _declutter(fig, ax)
    ax.set_title(title or f"predicted stability over {x} × {y}{subtitle}", fontsize=11)
    return fig
