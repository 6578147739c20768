"""Plots that answer the user's question and can be read (issue 13)."""

from __future__ import annotations

import admit_rs as ar
import numpy as np
import polars as pl
import pytest


@pytest.fixture(scope="module")
def draws() -> pl.DataFrame:
    """k_e log-uniform over three decades, b uniform: the sweep of issue 13, shortened."""
    sc = ar.paper.scenario("fig14").replace(duration=3.0)
    return ar.sweep(sc, vary={"wall.stiffness": ar.LogUniform(1e3, 1e6),
                              "admittance.b": ar.Uniform(100.0, 1600.0)},
                    samples=120, seed=0, progress=False)  # fmt: skip


def cell_values(fig) -> np.ndarray:
    ax = fig.axes[0]
    return np.ma.filled(ax.collections[0].get_array(), np.nan)


def test_log_uniform_parameter_gets_a_log_axis(draws):
    fig = ar.plot.sweep_heatmap(draws, "wall.stiffness", "admittance.b", "force_peak", bins=6)
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "linear"
    assert ax.get_xlabel() == "wall.stiffness [N/m]"
    assert ax.get_ylabel() == "admittance.b [N·s/m]"
    assert fig.axes[1].get_ylabel() == "max force_peak [N] (stable runs)"
    forced = ar.plot.sweep_heatmap(draws, "wall.stiffness", "admittance.b", "force_peak",
                                   bins=6, logx=False)  # fmt: skip
    assert forced.axes[0].get_xscale() == "linear"


def test_worst_case_aggregation_by_default(draws):
    bins = 6
    fig = ar.plot.sweep_heatmap(draws, "wall.stiffness", "admittance.b", "force_peak",
                                bins=bins)  # fmt: skip
    grid = cell_values(fig).reshape(bins, bins)
    k, b = draws["wall.stiffness"].to_numpy(), draws["admittance.b"].to_numpy()
    xe = np.logspace(np.log10(k.min()), np.log10(k.max()), bins + 1)
    ye = np.linspace(b.min(), b.max(), bins + 1)
    xi = np.clip(np.searchsorted(xe, k, side="right") - 1, 0, bins - 1)
    yi = np.clip(np.searchsorted(ye, b, side="right") - 1, 0, bins - 1)
    stable = draws["stable"].to_numpy()
    peak = draws["force_peak"].to_numpy()
    checked = 0
    for r in range(bins):
        for c in range(bins):
            cell = (xi == c) & (yi == r) & stable
            if cell.sum() >= 2:
                assert grid[r, c] == pytest.approx(peak[cell].max(), rel=1e-6)
                assert grid[r, c] > peak[cell].mean()
                checked += 1
    assert checked >= 5
    mean = ar.plot.sweep_heatmap(draws, "wall.stiffness", "admittance.b", "force_peak",
                                 bins=bins, agg="mean")  # fmt: skip
    assert np.nanmax(cell_values(mean)) < np.nanmax(grid)


def test_unstable_and_empty_cells_have_a_legend(draws):
    assert (~draws["stable"]).sum() > 0
    fig = ar.plot.sweep_heatmap(draws, "wall.stiffness", "admittance.b", "contact_loss",
                                bins=12, overlay_unstable=True)  # fmt: skip
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert "no runs in cell" in labels
    assert any(label.startswith("unstable") for label in labels)
    n_bad = int((~draws["stable"]).sum())
    assert f"unstable run ({n_bad})" in labels
    assert fig.axes[1].get_ylabel() == "max contact_loss [fraction] (stable runs)"


def test_unknown_column_suggests(draws):
    with pytest.raises(ar.UnknownNameError, match="did you mean 'force_peak'") as info:
        ar.plot.sweep_heatmap(draws, "wall.stiffness", "admittance.b", "force_peek")
    assert isinstance(info.value, KeyError) and isinstance(info.value, ar.AdmitError)
    with pytest.raises(ar.UnknownNameError, match="wall.stiffness"):
        ar.plot.sweep_heatmap(draws, "wall.stifness", "admittance.b", "force_peak")


def test_parameter_units_come_from_the_blocks():
    assert ar.plot.parameter_unit("wall.position_error") == "m"
    assert ar.plot.parameter_unit("admittance.m") == "kg"
    assert ar.plot.parameter_unit("duration") == "s"
    assert ar.plot.parameter_unit("no.such") == ""


def test_paper_panels_have_no_offset_label():
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = ar.paper.figure(5)
    FigureCanvasAgg(fig).draw()
    for ax in fig.axes:
        assert ax.yaxis.get_offset_text().get_text() == "", ax.get_title()
    assert fig.axes[2].get_title() == "(c) x position [m]"


def test_many_curves_share_one_legend_outside_the_panels():
    fig = ar.paper.figure(20)
    assert all(ax.get_legend() is None for ax in fig.axes[:5])
    assert len(fig.legends) == 1
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert len(labels) == 6 and labels[-2:] == ["f_d", "reference (dashed, in the curve's colour)"]


def test_torque_spike_is_clipped_and_said():
    fig = ar.paper.figure(10)
    ax = fig.axes[5]
    lo, hi = ax.get_ylim()
    assert -20 < lo < 0 and 50 < hi < 80  # the −541 N·m spike at t = 0 is off scale
    assert "clipped: spike to -541 N·m at t = 0 s off scale" in ax.get_title()
    assert "clipped" not in ar.paper.figure(20).axes[5].get_title()


def test_stability_map_plot_with_overlay():
    sc = ar.paper.scenario("fig14").replace(duration=3.0)
    ke, b = [1e4, 1e5, 1e6], [100.0, 800.0]
    t = ar.analysis.stability_map(sc, x={"wall.stiffness": ke}, y={"admittance.b": b})
    sw = ar.sweep(sc, grid={"wall.stiffness": ke, "admittance.b": b}, progress=False)
    fig = ar.plot.stability_map(t, overlay=sw)
    ax = fig.axes[0]
    assert ax.get_xscale() == "log"
    assert "agrees in" in ax.get_title()
    labels = [h.get_label() for h in ax.get_legend().legend_handles]
    assert any("boundary" in s for s in labels) and any("simulated" in s for s in labels)
    assert np.isfinite(t["spectral_radius"].to_numpy()).all()
