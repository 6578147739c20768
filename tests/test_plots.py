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
    assert "agrees with predicted `stable` in" in ax.get_title()
    labels = [h.get_label() for h in ax.get_legend().legend_handles]
    assert any("boundary" in s for s in labels) and any("simulated" in s for s in labels)
    assert np.isfinite(t["spectral_radius"].to_numpy()).all()
    # Coloured and compared by either simulated answer (SPEC §23).
    both = t.select("wall.stiffness", "admittance.b", "stable").join(
        sw.select("wall.stiffness", "admittance.b", "stable", "passed"),
        on=["wall.stiffness", "admittance.b"], suffix="_sim")  # fmt: skip
    for by, column in (("stable", "stable_sim"), ("passed", "passed")):
        ax = ar.plot.stability_map(t, overlay=sw, by=by).axes[0]
        agree = float((both["stable"] == both[column]).mean())  # type: ignore[arg-type]
        assert (f"simulated `{by}` agrees with predicted `stable` in {agree:.0%} of 6 cells"
                in ax.get_title())
        ok = int(sw[by].fill_null(False).sum())
        labels = [h.get_label() for h in ax.get_legend().legend_handles]
        assert f"simulated {by} ({ok})" in labels, labels


# Issue 21 items 9 and 10: labels derived from the scenario, axes a reader can trust.


def _collisions(fig, ax):
    """Pairs of drawn tick labels (major and minor, inside the limits) less than 2 px apart."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).draw()
    renderer = fig.canvas.get_renderer()
    out = []
    for axis in (ax.xaxis, ax.yaxis):
        lo, hi = sorted(axis.get_view_interval())
        ticks = list(zip(axis.get_majorticklocs(), axis.get_ticklabels(), strict=False))
        ticks += list(zip(axis.get_minorticklocs(), axis.get_ticklabels(minor=True),
                          strict=False))  # fmt: skip
        shown = [t for loc, t in ticks if t.get_visible() and t.get_text() and lo <= loc <= hi]
        boxes = [t.get_window_extent(renderer).padded(1.0) for t in shown]
        out += [(shown[i].get_text(), shown[j].get_text()) for i in range(len(boxes))
                for j in range(i + 1, len(boxes)) if boxes[i].overlaps(boxes[j])]  # fmt: skip
    return out, shown


@pytest.fixture(scope="module")
def ka_grid() -> pl.DataFrame:
    # 3 s: the windows after t = 1 s must hold min_assessed = 1 s to be judged at all.
    sc = ar.paper.scenario("fig14").replace(duration=3.0)
    return ar.sweep(sc, grid={"admittance.b": [200, 400, 800], "admittance.ka": [0.1, 1, 2]},
                    progress=False)  # fmt: skip


def test_a_grid_is_drawn_as_categories(ka_grid):
    fig = ar.plot.sweep_heatmap(ka_grid, "admittance.b", "admittance.ka", "force_peak",
                                by="passed")  # fmt: skip
    ax = fig.axes[0]
    assert ax.get_yscale() == "linear" and ax.get_ylim() == (-0.5, 2.5)  # not from -0.4
    assert [t.get_text() for t in ax.get_yticklabels()] == ["0.1", "1", "2"]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["200", "400", "800"]
    np.testing.assert_array_equal(ax.get_yticks(), [0, 1, 2])
    # Row r, column c holds the run with k_a = [0.1, 1, 2][r] and b = [200, 400, 800][c].
    grid = cell_values(fig).reshape(3, 3)
    for row in ka_grid.iter_rows(named=True):
        r = [0.1, 1.0, 2.0].index(row["admittance.ka"])
        c = [200.0, 400.0, 800.0].index(row["admittance.b"])
        if row["passed"]:
            assert grid[r, c] == row["force_peak"]
        else:
            assert np.isnan(grid[r, c])  # drawn as the "failed" category
    # Both kinds of cell were drawn and checked: k_a = 1 passes at every b (fig. 14's
    # gains), k_a = 0.1 fails at every b.
    assert 0 < ka_grid["passed"].sum() < ka_grid.height
    assert ka_grid.filter(pl.col("admittance.ka") == 1.0)["passed"].all()
    assert not ka_grid.filter(pl.col("admittance.ka") == 0.1)["passed"].any()
    assert "failed: every run in the cell" in [t.get_text() for t in ax.get_legend().texts]
    # k_a = 0.1 is slow, not unstable: its ripple is the motion's (SPEC §23), so split by
    # `stable` (the default) its cells hold their runs' values.
    assert ka_grid.filter(pl.col("admittance.ka") == 0.1)["stable"].all()
    by_stable = cell_values(ar.plot.sweep_heatmap(ka_grid, "admittance.b", "admittance.ka",
                                                  "force_peak")).reshape(3, 3)  # fmt: skip
    for row in ka_grid.iter_rows(named=True):
        r = [0.1, 1.0, 2.0].index(row["admittance.ka"])
        c = [200.0, 400.0, 800.0].index(row["admittance.b"])
        assert np.isfinite(by_stable[r, c]) == bool(row["stable"])
    with pytest.raises(ar.ArgumentError, match="by = 'stabel' is invalid: must be one of "
                                               "stable, passed"):
        ar.plot.sweep_heatmap(ka_grid, "admittance.b", "admittance.ka", "force_peak",
                              by="stabel")  # fmt: skip
    # The predicted map of the same grid: a log axis from above 0, a tick at each value.
    t = ar.analysis.stability_map(ar.paper.scenario("fig14"), x={"admittance.b": [200.0, 800.0]},
                                  y={"admittance.ka": [0.1, 1.0, 2.0]})  # fmt: skip
    ax = ar.plot.stability_map(t).axes[0]
    assert ax.get_yscale() == "log" and ax.get_ylim()[0] > 0
    np.testing.assert_allclose(ax.get_yticks(), [0.1, 1.0, 2.0])
    assert [t.get_text() for t in ax.get_yticklabels()] == ["0.1", "1", "2"]


def test_tick_labels_never_collide():
    import matplotlib

    rng = np.random.default_rng(0)
    k = np.exp(rng.uniform(np.log(1.2e4), np.log(2.4e5), 200))
    draws = pl.DataFrame({"wall.stiffness": k, "admittance.b": rng.uniform(100, 800, 200),
                          "force_peak": rng.uniform(10, 20, 200),
                          "stable": np.ones(200, bool)})  # fmt: skip
    grid12 = [1e4, 1.5e4, 2e4, 3e4, 4e4, 5e4, 6e4, 8e4, 1e5, 1.2e5, 1.5e5, 2e5]
    cells = pl.DataFrame({"wall.stiffness": grid12 * 2, "admittance.b": [200.0] * 12 + [800.0] * 12,
                          "force_peak": rng.uniform(10, 20, 24),
                          "stable": np.ones(24, bool)})  # fmt: skip
    # Larger fonts (slides) made "3×10⁴4×10⁴" of the log axis' minor labels.
    for size in (10, 16):
        with matplotlib.rc_context({"font.size": size}):
            fig = ar.plot.sweep_heatmap(draws, "wall.stiffness", "admittance.b", "force_peak")
            ax = fig.axes[0]
            assert ax.get_xscale() == "log"
            collisions, _ = _collisions(fig, ax)
            assert collisions == []
            shown = [t for t in ax.get_xticklabels() + ax.get_xticklabels(minor=True)
                     if t.get_visible() and t.get_text()]  # fmt: skip
            assert len(shown) >= 2
            fig = ar.plot.sweep_heatmap(cells, "wall.stiffness", "admittance.b", "force_peak")
            assert _collisions(fig, fig.axes[0])[0] == []
            labels = [t.get_text() for t in fig.axes[0].get_xticklabels()]
            assert labels[0] == "$10^{4}$" and len(labels) >= 4  # thinned, not emptied


def test_result_plot_shows_the_true_force_under_the_measured_one():
    sc = ar.paper.scenario("fig14").replace(duration=1.0, sensor=ar.ForceSensor(
        noise_std=0.5, cutoff=30.0, latency=2))  # fmt: skip
    r = ar.simulate(sc)
    ax = r.plot().axes[0]
    lines = {line.get_label(): line for line in ax.get_lines()}
    true, measured = lines["f (true)"], lines["f measured"]
    np.testing.assert_array_equal(true.get_ydata(), r.trace["f"].to_numpy())
    np.testing.assert_array_equal(measured.get_ydata(), r.trace["f_measured"].to_numpy())
    # The measured line is drawn on top, thin; the true force a wide band beneath it.
    assert measured.get_zorder() > true.get_zorder()
    assert true.get_linewidth() >= 3 * measured.get_linewidth()
    assert true.get_alpha() < 1


def test_tilted_wall_is_drawn_along_n_and_t_like_the_metrics():
    sc = ar.paper.scenario("fig8").replace(**{"wall.normal": (1.0, 0.0, -1.0)}, duration=2.0)
    r = ar.simulate(sc)
    fig = r.plot()
    ax_n, ax_t = fig.axes[1], fig.axes[2]
    n, t = sc.wall.directions()
    tr = r.trace
    xyz = np.column_stack([tr[c].to_numpy() for c in ("x", "y", "z")])
    ref = np.column_stack([tr[c].to_numpy() for c in ("x_ref", "y_ref", "z_ref")])
    (pos_n, ref_n), (pos_t, ref_t) = ([ln.get_ydata() for ln in a.get_lines()[:2]]
                                      for a in (ax_n, ax_t))  # fmt: skip
    np.testing.assert_allclose(pos_n, xyz @ n, rtol=0, atol=1e-15)
    np.testing.assert_allclose(pos_t, xyz @ t, rtol=0, atol=1e-15)
    np.testing.assert_allclose(ref_n, ref @ n, rtol=0, atol=1e-15)
    # What is drawn is what the metrics measure: x_rms_error along n, z_rms_error along t.
    assert np.sqrt(np.mean((ref_n - pos_n) ** 2)) == pytest.approx(r.metrics["x_rms_error"],
                                                                    rel=1e-9)  # fmt: skip
    assert np.sqrt(np.mean((ref_t - pos_t) ** 2)) == pytest.approx(r.metrics["z_rms_error"],
                                                                    rel=1e-9)  # fmt: skip
    assert ax_n.get_ylabel() == "n·X [m]" and ax_t.get_ylabel() == "t̂·X [m]"
    assert ax_n.get_title() == "position along the wall normal n = (0.707, 0, -0.707)"
    # The wall: a band from its surface x_e = n·X − penetration upwards, in the legend.
    x_e = (xyz @ n - tr["penetration"].to_numpy())[0]
    (wall,) = [p for p in ax_n.patches if p.get_label().startswith("wall")]
    assert wall.get_extents().y0 == pytest.approx(
        ax_n.transData.transform((0, x_e))[1], abs=0.5
    )
    assert "wall (penetration > 0)" in [t.get_text() for t in ax_n.get_legend().get_texts()]
    # The paper's wall: world x and z, the wall drawn too.
    fig = ar.simulate(ar.paper.scenario("fig19").replace(duration=1.0)).plot()
    assert fig.axes[1].get_ylabel() == "x [m]" and fig.axes[2].get_ylabel() == "z [m]"
    labels = [t.get_text() for t in fig.axes[1].get_legend().get_texts()]
    assert "wall (penetration > 0)" in labels and "estimated wall x̂_e" in labels


def test_plot_titles_describe_the_scenario_as_it_is():
    from pathlib import Path

    urdf = Path(__file__).parent.parent / "examples" / "data" / "panda.urdf"
    panda = ar.UrdfArm(urdf, "panda_hand_tcp", q0=(0, -0.785, 0, -2.356, 0, 1.571, 0.785))
    sc = ar.paper.scenario("fig14").replace(
        robot=panda, controller=ar.ComputedTorque(kp=600.0, kd=50.0, command_divisor=1.0),
        duration=0.3,
    )  # fmt: skip
    title = ar.simulate(sc).plot()._suptitle.get_text()
    assert "TDC" not in title and "k_a=1'" not in title
    assert title.startswith("panda arm (panda_hand_tcp), CT, Scheme 2 (b=800, k_a=1)")
    # A paper figure of replaced scenarios: each legend entry describes its curve.
    curves = [ar.paper.scenario("fig14").replace(**{"admittance.b": b}, duration=0.3)
              for b in (200.0, 800.0)]  # fmt: skip
    fig = ar.plot.plot_paper_figure([ar.simulate(c) for c in curves], "b")
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels[:2] == [ar.describe(c) for c in curves]
    assert "Scheme 2 (b=200, k_a=1)" in labels[0]


def test_paper_figure_of_a_tilted_wall_is_along_n_and_t():
    sc = ar.paper.scenario("fig8").replace(**{"wall.normal": (1.0, 0.0, -1.0)}, duration=0.5)
    r = ar.simulate(sc)
    fig = ar.plot.plot_paper_figure([r], "tilted")
    n, t = sc.wall.directions()
    xyz = np.column_stack([r.trace[c].to_numpy() for c in ("x", "y", "z")])
    np.testing.assert_allclose(fig.axes[2].get_lines()[0].get_ydata(), xyz @ n, atol=1e-15)
    np.testing.assert_allclose(fig.axes[3].get_lines()[0].get_ydata(), xyz @ t, atol=1e-15)
    assert fig.axes[2].get_title() == "(c) position along the wall normal n·X [m]"
    # The paper's wall: world x, exactly.
    p = ar.simulate(ar.paper.scenario("fig14").replace(duration=0.5))
    fig = ar.plot.plot_paper_figure([p], "paper")
    np.testing.assert_array_equal(fig.axes[2].get_lines()[0].get_ydata(), p.trace["x"].to_numpy())
    assert fig.axes[2].get_title() == "(c) x position [m]"
