"""Plots people expect: one run, a paper figure, and sweep tables."""

from __future__ import annotations

import ast
import functools
import inspect
import re
import textwrap
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Protocol

import matplotlib
import numpy as np
import numpy.typing as npt
import polars as pl
from matplotlib.patches import Rectangle
from matplotlib.ticker import NullLocator

from admit_rs.config import Scenario
from admit_rs.errors import ArgumentError

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


class Run(Protocol):
    """What the run plots read from a run: an :class:`admit_rs.Result` is one.

    Declared here so that plotting depends on no simulation code (and
    :meth:`admit_rs.Result.plot` can call :func:`plot_result` without an import cycle).
    """

    @property
    def scenario(self) -> Scenario:
        """The scenario that was run (its label and whether it has a force loop)."""

    @property
    def trace(self) -> pl.DataFrame:
        """The trace, with the columns of :data:`admit_rs.TRACE_COLUMNS`."""

    @property
    def diverged_at(self) -> float | None:
        """When the run stopped as unstable [s], ``None`` if it completed."""

    @property
    def divergence_cause(self) -> str | None:
        """Why it stopped, ``None`` if it completed."""


def plot_result(result: Run, title: str | None = None) -> Figure:
    """Four panels: force and f_d; the position along the wall normal n and along the motion
    direction t̂ against their references (the directions of the ``x_*`` and ``z_*``
    metrics: world x and z for the paper's wall, n·X and t̂·X for a tilted one), with the
    wall drawn; x_a.

    With a real sensor the true force is a wide band under the thin measured force, so
    both stay visible. Position-only runs show joint torques in place of the force panels.
    The title is ``title``, else the scenario's label, else :func:`admit_rs.describe` of
    the scenario (derived now, so it cannot be stale).
    """
    from matplotlib.figure import Figure

    from admit_rs.config import describe

    matplotlib.rcParams.setdefault("figure.dpi", 100)
    tr = result.trace
    t = tr["t"].to_numpy()
    sc = result.scenario
    force_control = sc.admittance is not None
    n, tangent, tilted = _directions(sc)
    xyz = np.column_stack([tr[c].to_numpy() for c in ("x", "y", "z")])
    ref = np.column_stack([tr[c].to_numpy() for c in ("x_ref", "y_ref", "z_ref")])
    along_n, along_n_ref = xyz @ n, ref @ n
    along_t, along_t_ref = xyz @ tangent, ref @ tangent
    n_name, t_name = ("n·X", "t̂·X") if tilted else ("x", "z")
    fig = Figure(figsize=(11, 7.5), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True)
    (ax_f, ax_x), (ax_z, ax_a) = axes
    if force_control:
        f = tr["f"].to_numpy()
        measured = tr["f_measured"].to_numpy() if "f_measured" in tr.columns else f
        if not np.array_equal(measured, f):
            # A real sensor: the true force as a wide band underneath, what the controller
            # saw as a thin line on top; where they coincide the band shows on both sides.
            ax_f.plot(t, f, color="C0", lw=3.0, alpha=0.45, label="f (true)", zorder=2,
                      solid_capstyle="butt")  # fmt: skip
            ax_f.plot(t, measured, color="C1", lw=0.8, label="f measured", zorder=3)
        else:
            ax_f.plot(t, f, color="C0", label="f", zorder=2)
        ax_f.plot(t, tr["f_d"].to_numpy(), "--", color="k", lw=1, label="f_d", zorder=4)
        if "f_t" in tr.columns and np.any(tr["f_t"].to_numpy() > 0):
            # Friction along the surface (SPEC §15), beside the normal force.
            ax_f.plot(t, tr["f_t"].to_numpy(), color="C4", lw=1, label="f_t (friction)",
                      zorder=3)  # fmt: skip
        ax_f.set_ylabel("force along n [N]" if tilted else "force [N]")
        ax_f.set_title("contact force")
        ax_a.plot(t, 1e3 * tr["x_a"].to_numpy(), color="C2")
        ax_a.set_ylabel("x_a [mm]")
        ax_a.set_title("admittance output x_a")
    else:
        taus = [c for c in tr.columns if re.fullmatch(r"tau\d+", c)]
        for c in taus:
            ax_f.plot(t, tr[c].to_numpy(), label=f"τ{c[3:]}")
        ax_f.set_ylabel("torque [N·m]")
        ax_f.set_title("joint torques")
        ax_a.plot(t, 1e3 * (along_t_ref - along_t), color="C3")
        ax_a.set_ylabel(f"{'t̂·(X_d − X)' if tilted else 'z_d − z'} [mm]")
        ax_a.set_title("motion tracking error along t̂" if tilted else "z tracking error")
    ax_x.plot(t, along_n, label=n_name, zorder=3)
    ax_x.plot(t, along_n_ref, "--", color="k", lw=1, label=f"{n_name} reference", zorder=3)
    ax_x.set_ylabel(f"{n_name} [m]")
    ax_x.set_title(f"position along the wall normal n = {_vector(n)}" if tilted
                   else "x position" + (" (along the wall normal)" if sc.wall else ""))  # fmt: skip
    if sc.wall is not None:
        _draw_wall(ax_x, sc, t, along_n, tr["penetration"].to_numpy())
    ax_z.plot(t, along_t, label=t_name)
    ax_z.plot(t, along_t_ref, "--", color="k", lw=1, label=f"{t_name} reference")
    ax_z.set_ylabel(f"{t_name} [m]")
    ax_z.set_title(f"position along the motion direction t̂ = {_vector(tangent)}" if tilted
                   else "z position")  # fmt: skip
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
        # Plain tick labels: no "1e-5+7.34e-1" offset text on nearly constant positions.
        ax.ticklabel_format(axis="y", useOffset=False)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=8)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    if result.diverged_at is not None:
        for ax in axes.flat:
            ax.axvline(result.diverged_at, color="r", lw=1)
    heading = title or sc.label or describe(sc)
    if result.diverged_at is not None:
        heading += f" — diverged at {result.diverged_at:.3g} s: {result.divergence_cause}"
    fig.suptitle(textwrap.fill(heading, 120))
    return fig


def _directions(
    scenario: Scenario,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], bool]:
    """n̂, t̂ of the scenario's wall (the paper's +x, +z without one) and whether tilted."""
    if scenario.wall is None:
        return np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), False
    n, t = scenario.wall.directions()
    return n, t, scenario.wall.tilted


def _vector(v: npt.NDArray[np.float64]) -> str:
    return "(" + ", ".join(f"{x + 0.0:.3g}" for x in v) + ")"


def _draw_wall(
    ax: Axes,
    scenario: Scenario,
    t: npt.NDArray[np.float64],
    along_n: npt.NDArray[np.float64],
    penetration: Any,
) -> None:
    """The wall as a shaded band beyond its surface n·X = x_e (from the trace: x_e =
    n·X − δ), and the controller's estimate x̂_e when it differs."""
    finite = np.isfinite(penetration) & np.isfinite(along_n)
    if not finite.any():
        return
    wall = scenario.wall
    if wall is not None and not wall.planar:
        _draw_curved_surface(ax, t, along_n, penetration)
        return
    k = int(np.argmax(finite))
    x_e = float(along_n[k] - penetration[k])
    lo, hi = ax.get_ylim()
    estimate = x_e + (scenario.wall.position_error if scenario.wall is not None else 0.0)
    lo, hi = min(lo, x_e, estimate), max(hi, x_e, estimate)
    pad = 0.08 * (hi - lo if hi > lo else max(abs(x_e), 1e-3))
    lo, hi = lo - pad, hi + pad
    ax.axhspan(x_e, hi, facecolor="0.55", alpha=0.25, hatch="///", edgecolor="0.4", lw=0,
               zorder=1, label="wall (penetration > 0)")  # fmt: skip
    ax.axhline(x_e, color="0.25", lw=1.2, zorder=2)
    if estimate != x_e:
        ax.axhline(estimate, color="0.25", lw=1, ls=":", zorder=2, label="estimated wall x̂_e")
    ax.set_ylim(lo, hi)


def _draw_curved_surface(
    ax: Axes, t: npt.NDArray[np.float64], along_n: npt.NDArray[np.float64], penetration: Any
) -> None:
    """A curved surface's section under the tip: n·X − δ at each sample, where the surface
    lies along n at the tip's place (to first order in the normal's tilt), shaded beyond."""
    surface = along_n - np.asarray(penetration, dtype=float)
    lo, hi = ax.get_ylim()
    finite = surface[np.isfinite(surface)]
    lo, hi = min(lo, float(finite.min())), max(hi, float(finite.max()))
    pad = 0.08 * (hi - lo if hi > lo else 1e-3)
    lo, hi = lo - pad, hi + pad
    ax.fill_between(t, surface, hi, facecolor="0.55", alpha=0.25, hatch="///", edgecolor="0.4",
                    lw=0, zorder=1, label="surface under the tip (n·X − δ)")  # fmt: skip
    ax.plot(t, surface, color="0.25", lw=1.2, zorder=2)
    ax.set_ylim(lo, hi)


def plot_paper_figure(
    results: Sequence[Run], title: str, size: tuple[float, float] = (15.0, 8.0)
) -> Figure:
    """A paper figure: every curve overlaid, panels like the paper's (a), (b), ...

    Force runs: force and f_d, force error, x and x_ref, z and z_ref, x_a, joint torques
    (of the first curve). Position-only runs: x, z, their errors and the joint torques.
    With a tilted wall, x and z are the positions along n and t̂ (n·X, t̂·X), as the
    metrics measure them. Curves without a label are named by :func:`admit_rs.describe`.
    """
    from matplotlib.figure import Figure

    from admit_rs.config import describe

    fig = Figure(figsize=size, layout="constrained")
    axes = list(fig.subplots(2, 3, sharex=True).flat)
    force_control = results[0].scenario.admittance is not None
    many = len(results) > 1
    for i, r in enumerate(results):
        tr = r.trace
        t = tr["t"].to_numpy()
        # A curve without a label is named by its scenario (a single one only in the title,
        # so that long descriptions stay out of the panel legends).
        label = r.scenario.label or (describe(r.scenario) if many else "run")
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
        # Along n and t̂, as the metrics are (world x and z for the paper's wall).
        n, tangent, _ = _directions(r.scenario)
        xyz = np.column_stack([tr[c].to_numpy() for c in ("x", "y", "z")])
        ref = np.column_stack([tr[c].to_numpy() for c in ("x_ref", "y_ref", "z_ref")])
        pos_n, ref_n, pos_t, ref_t = xyz @ n, ref @ n, xyz @ tangent, ref @ tangent
        if not force_control:
            axes[0].plot(t, 1e3 * (ref_n - pos_n), color=color, label=label)
            axes[1].plot(t, 1e3 * (ref_t - pos_t), color=color, label=label)
        axes[2].plot(t, pos_n, color=color, label=label)
        axes[2].plot(t, ref_n, label=ref_label, **ref_style)
        axes[3].plot(t, pos_t, color=color, label=label)
        if i == 0 or many:
            axes[3].plot(t, ref_t, label=ref_label if i == 0 else None, **ref_style)
        if i == 0:
            for c in (c for c in tr.columns if re.fullmatch(r"tau\d+", c)):
                axes[5].plot(t, tr[c].to_numpy(), label=f"τ{c[3:]}")
        if r.diverged_at is not None:
            for ax in axes:
                ax.axvline(r.diverged_at, color="r", lw=1)
    if any(_directions(r.scenario)[2] for r in results):  # a tilted wall
        pos = ["(c) position along the wall normal n·X [m]", "(d) position along t̂, t̂·X [m]"]
        err = ["(a) error along n, n·(X_d − X) [mm]", "(b) error along t̂, t̂·(X_d − X) [mm]"]
    else:
        pos = ["(c) x position [m]", "(d) z position [m]"]
        err = ["(a) x error x_d − x [mm]", "(b) z error z_d − z [mm]"]
    if force_control:
        names = ["(a) contact force [N]", "(b) force error f_d − f [N]", *pos,
                 "(e) admittance output x_a [mm]"]  # fmt: skip
    else:
        names = [*err, *pos, ""]
        axes[4].set_visible(False)
    first = results[0].scenario.label or describe(results[0].scenario)
    tau_title = "joint torques [N·m]" + (f" ({first})" if many else "")
    clip_note = _clip_torques(axes[5], results[0].trace)
    names.append(("(f) " if force_control else "(e) ") + tau_title + clip_note)
    for ax, name in zip(axes, names, strict=True):
        # Long curve labels wrap instead of running past the figure's edge.
        lines = name.split("\n")
        ax.set_title("\n".join(textwrap.fill(line, 62) for line in lines), fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=9)
        # Plain tick labels: no "1e-5+7.34e-1" offset text on nearly constant traces.
        ax.ticklabel_format(axis="y", useOffset=False, style="plain")
        if ax.get_legend_handles_labels()[0] and (not many or ax is axes[5]):
            ax.legend(fontsize=7, loc="best")
    if many:
        # One legend for every panel, below them: curve colours, f_d, dashed references.
        from matplotlib.lines import Line2D

        handles = [Line2D([], [], color=f"C{i}", label=r.scenario.label or describe(r.scenario))
                   for i, r in enumerate(results)]  # fmt: skip
        if force_control:
            handles.append(Line2D([], [], color="k", ls="--", lw=1, label="f_d"))
        handles.append(Line2D([], [], color="0.4", ls="--", lw=1,
                              label="reference (dashed, in the curve's colour)"))  # fmt: skip
        longest = max(len(str(h.get_label())) for h in handles)
        fig.legend(handles=handles, loc="outside lower center",
                   ncols=min(len(handles), 4 if longest <= 80 else 2 if longest <= 160 else 1),
                   fontsize=8, frameon=False)  # fmt: skip
    for ax in axes[3:]:
        ax.set_xlabel("t [s]")
    if not many and not results[0].scenario.label:
        title = f"{title}\n{describe(results[0].scenario)}"
    fig.suptitle(title, fontsize=12)
    return fig


def _clip_torques(ax: Any, trace: pl.DataFrame) -> str:
    """Limits a torque panel to a robust range when a start-up spike would flatten the
    other traces; returns the note for the panel title ("" if nothing was clipped)."""
    tau = np.concatenate([trace[c].to_numpy() for c in trace.columns if c.startswith("tau")])
    tau = tau[np.isfinite(tau)]
    if tau.size == 0:
        return ""
    lo, hi = np.percentile(tau, [0.5, 99.5])
    pad = 0.15 * max(hi - lo, 1.0)
    lo, hi = lo - pad, hi + pad
    full_lo, full_hi = float(tau.min()), float(tau.max())
    if (full_hi - full_lo) < 2.0 * (hi - lo):
        return ""
    ax.set_ylim(lo, hi)
    extreme = full_lo if abs(full_lo) > abs(full_hi) else full_hi
    t = trace["t"].to_numpy()
    cols = [c for c in trace.columns if c.startswith("tau")]
    at = next(float(t[np.nonzero(trace[c].to_numpy() == extreme)[0][0]])
              for c in cols if (trace[c].to_numpy() == extreme).any())  # fmt: skip
    return f"\nclipped: spike to {extreme:.0f} N·m at t = {at:.3g} s off scale"


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



def _finish_grid_axes(
    ax: Axes,
    xe: npt.NDArray[np.float64],
    ye: npt.NDArray[np.float64],
    logx: bool,
    logy: bool,
    xlabel: str,
    ylabel: str,
    handles: list[Any],
) -> None:
    """Scales, limits (the cell edges), labels and the legend below a grid plot."""
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if handles:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.0, -0.12), ncols=2,
                  fontsize=8, frameon=False)  # fmt: skip

def parameter_unit(path: str) -> str:
    """The unit of a dotted parameter path, from its block's attribute docstring ("" if none).

    Example:
        >>> parameter_unit("wall.stiffness"), parameter_unit("admittance.b")
        ('N/m', 'N·s/m')
    """
    from admit_rs import config

    leaf = path.rsplit(".", 1)[-1]
    owner: Any = config.Scenario()
    for part in path.split(".")[:-1]:
        owner = getattr(owner, part, None)
    classes = [type(owner)] if owner is not None else []
    classes += [c for c in vars(config).values()
                if isinstance(c, type) and issubclass(c, config._Block)]  # fmt: skip
    for cls in classes:
        for klass in cls.__mro__:
            doc = _attribute_docs(klass).get(leaf)
            if doc is not None:
                found = re.search(r"\[([^\]]+)\]", doc)
                return found.group(1) if found else ""
    return ""


@functools.cache
def _attribute_docs(cls: type) -> dict[str, str]:
    """``{field: docstring}`` from the string literal under each annotated field."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError, SyntaxError):
        return {}
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    docs = {}
    for a, b in zip(body, body[1:], strict=False):
        if (isinstance(a, ast.AnnAssign) and isinstance(a.target, ast.Name)
                and isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant)
                and isinstance(b.value.value, str)):  # fmt: skip
            docs[a.target.id] = b.value.value
    return docs


def _metric_label(name: str, units: dict[str, str] | None = None) -> str:
    from admit_rs.metrics import METRICS

    if units and name in units:
        return f"{name} [{units[name]}]"
    return METRICS[name].label if name in METRICS else _with_unit(name, units)


def _with_unit(name: str, units: dict[str, str] | None = None) -> str:
    unit = (units or {}).get(name)
    if unit is None:
        unit = parameter_unit(name) if "." in name else ""
    return f"{name} [{unit}]" if unit else name


def _log_axis(values: npt.NDArray[np.float64], bins: int = 12) -> bool:
    """Whether values look log-uniform (random draws) or log-spaced (a grid)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0 or v.min() <= 0:
        return False
    distinct = np.unique(v)
    if distinct.size < 3:
        return bool(distinct[-1] / distinct[0] > 50)
    if distinct.size <= bins:  # a grid: geometric rather than arithmetic spacing
        lin, geo = np.diff(distinct), np.diff(np.log(distinct))
        return bool(np.std(geo) / np.mean(geo) < np.std(lin) / np.mean(lin))
    lo, hi = distinct[0], distinct[-1]
    if hi / lo < 5:
        return False
    # Draws: the median sits at the geometric middle for log-uniform, the arithmetic one
    # for uniform.
    med = np.log(np.median(v))
    return bool(abs(med - np.log(np.sqrt(lo * hi))) < abs(med - np.log((lo + hi) / 2)))


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
        raise ArgumentError("no finite values to place on the axis")
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


def _crosses_zero(distinct: npt.NDArray[np.float64]) -> bool:
    """Positive values whose cells on a linear axis (edges halfway between values) would
    start below zero."""
    if distinct.size < 2 or distinct.min() <= 0:
        return False
    return bool(distinct[0] - (distinct[1] - distinct[0]) / 2 < 0)


def _categories(values: npt.NDArray[np.float64], bins: int) -> npt.NDArray[np.float64] | None:
    """The distinct values of a grid axis (at most ``bins`` of them, each repeated: a
    factorial grid lists every value once per value of the other axis), else ``None``."""
    v = values[np.isfinite(values)]
    distinct = np.unique(v)
    if 0 < distinct.size <= bins and (distinct.size < v.size or distinct.size == 1):
        return distinct
    return None


def _cell_axis(
    values: npt.NDArray[np.float64],
    bins: int,
    log: bool,
    categories: npt.NDArray[np.float64] | None,
) -> tuple[npt.NDArray[np.float64], Any, npt.NDArray[np.float64]]:
    """Cell edges, each value's cell and each value's plot coordinate: category index
    ``i`` spans [i - 0.5, i + 0.5]; otherwise the values themselves (see :func:`_axis`)."""
    if categories is not None:
        index = np.searchsorted(categories, values)
        edges = np.asarray(np.arange(categories.size + 1) - 0.5, dtype=np.float64)
        return edges, index, np.asarray(index, dtype=np.float64)
    edges, index = _axis(values, bins, log)
    return edges, index, values


def _tick_texts(values: npt.NDArray[np.float64]) -> list[str]:
    """Labels for category ticks, one style for the axis: plain (0.1, 800, 30000) or, when
    any value needs it, powers of ten ($3\\times10^{4}$)."""
    finite = np.abs(values[np.isfinite(values) & (values != 0)])
    if finite.size == 0 or (finite.min() >= 1e-3 and finite.max() < 1e5):
        return [f"{v:g}" for v in values]
    out = []
    for v in values:
        if v == 0 or not np.isfinite(v):
            out.append(f"{v:g}")
            continue
        mantissa, exponent = f"{v:.3e}".split("e")
        m = mantissa.rstrip("0").rstrip(".")
        power = f"10^{{{int(exponent)}}}"
        out.append(f"${power}$" if m == "1" else f"${m}\\times{power}$")
    return out


def _declutter(fig: Figure, ax: Axes) -> None:
    """Tick labels that do not overlap (nor touch: "3×10⁴4×10⁴" reads as one number).

    Measured on a drawn canvas. When the labels on an axis collide, its ticks are frozen
    (major and minor labels together, in order) and every 2nd, 3rd, ... label is kept
    until none collides."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)

    def colliding(axis: Any) -> bool:
        canvas.draw()
        renderer = canvas.get_renderer()
        # Padded by 1 px: labels less than 2 px apart collide.
        boxes = [label.get_window_extent(renderer).padded(1.0) for _, label in _shown(axis)]
        return any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1 :])

    for axis in (ax.xaxis, ax.yaxis):
        if not colliding(axis):
            continue
        ticks = sorted((float(loc), label.get_text()) for loc, label in _shown(axis))
        axis.set_minor_locator(NullLocator())
        for step in range(2, len(ticks) + 1):
            kept = ticks[::step]
            axis.set_ticks([loc for loc, _ in kept], labels=[text for _, text in kept])
            if not colliding(axis):
                break


def _shown(axis: Any) -> list[tuple[float, Any]]:
    """(location, label) of the tick labels that are drawn: visible, non-empty and inside
    the axis limits."""
    lo, hi = sorted(axis.get_view_interval())
    ticks = list(zip(axis.get_majorticklocs(), axis.get_ticklabels(), strict=False))
    ticks += list(zip(axis.get_minorticklocs(), axis.get_ticklabels(minor=True), strict=False))
    span = hi - lo
    return [(loc, label) for loc, label in ticks
            if label.get_visible() and label.get_text()
            and lo - 1e-9 * span <= loc <= hi + 1e-9 * span]  # fmt: skip


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
    motion drives fails them while the loop stays stable). An axis
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
        joined = table.select(x, y, pl.col("stable").alias("_predicted")).join(
            overlay.select(pl.col(x).cast(table[x].dtype), pl.col(y).cast(table[y].dtype),
                           pl.col(by).alias("_simulated")),
            on=[x, y],
        )  # fmt: skip
        if joined.height:
            agree = float((joined["_predicted"] == joined["_simulated"]).mean())  # type: ignore[arg-type]
            subtitle = (f"\nsimulated `{by}` agrees with predicted `stable` in {agree:.0%} of "
                        f"{joined.height} cells")  # fmt: skip
    xlabel, ylabel = _with_unit(x, {x: parameter_unit(x)}), _with_unit(y, {y: parameter_unit(y)})
    _finish_grid_axes(ax, xe, ye, logx, logy, xlabel, ylabel, handles)
    for axis, values in ((ax.xaxis, xv), (ax.yaxis, yv)):
        if values.size <= 12:  # a short grid: a tick at each value, labelled with it
            axis.set_ticks(values, labels=_tick_texts(values))
            axis.set_minor_locator(NullLocator())
    _declutter(fig, ax)
    ax.set_title(title or f"predicted stability over {x} × {y}{subtitle}", fontsize=11)
    return fig
