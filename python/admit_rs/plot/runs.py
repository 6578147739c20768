"""One run and a paper figure: force against f_d, the tip against its references, x_a and the
torques (:func:`plot_result`, :func:`plot_paper_figure`)."""

from __future__ import annotations

import re
import textwrap
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

import matplotlib
import numpy as np
import numpy.typing as npt
import polars as pl

from admit_rs.config import Scenario

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
