"""The forced response with the motion running (SPEC §23, docs/analysis.md §3b): predicted
force oscillation against the simulated one, predicted ``passed`` against the simulated."""

from __future__ import annotations

import math

import admit_rs as ar
import numpy as np
import pytest

CLOSE = 0.3
"""The issue's bound: predicted force oscillation within 30 % of the simulated one."""


def _cell(figure: str, **changes: object) -> ar.Scenario:
    return ar.paper.scenario(figure).replace(**changes)


@pytest.mark.parametrize(
    ("figure", "stiffness", "damping", "passed"),
    [
        ("fig14", 1e5, 2500.0, False),  # the cell: a stable loop out of tolerance
        ("fig14", 3.2e4, 1000.0, True),
        ("fig8", 1e5, 1000.0, True),
        ("fig8", 3.2e5, 2500.0, True),
    ],
)
def test_predicted_ripple_matches_the_simulated_one(
    figure: str, stiffness: float, damping: float, passed: bool
) -> None:
    cell = _cell(figure, **{"wall.stiffness": stiffness, "admittance.b": damping})
    simulated = ar.simulate(cell)
    predicted = ar.analysis.predict(cell)
    assert simulated.stable is True
    assert simulated.passed is passed
    assert predicted["passed"] is passed
    ratio = float(predicted["force_oscillation"]) / simulated.metrics["force_oscillation"]
    assert abs(ratio - 1) <= CLOSE, ratio
    assert predicted["contact_loss"] == 0.0
    if not passed:
        assert str(predicted["tolerance_verdict"]).startswith(
            "out of tolerance: predicted force oscillation"
        )


def test_the_second_order_terms_carry_the_path_geometry() -> None:
    # Without Coulomb friction the ripple is the arm's own geometry and dynamics along the
    # path; the linear response alone gives about half of it (0.52), the second order 0.8.
    cell = _cell("fig14", **{"wall.stiffness": 1e5, "admittance.b": 2500.0,
                             "robot.coulomb_friction": (0.0, 0.0, 0.0)})  # fmt: skip
    simulated = ar.simulate(cell).metrics["force_oscillation"]
    response = ar.analysis.forced_response(cell)
    assert response.second_order
    assert response.friction_gains == (1.0, 1.0, 1.0)
    assert abs(response.force_oscillation / simulated - 1) <= CLOSE
    # The predicted trace follows the simulated one over the last 2 s, not only its spread.
    trace = ar.simulate(cell).trace
    window = trace["t"].to_numpy()[:-1] >= 8.0
    f_sim = trace["f"].to_numpy()[:-1][window]
    f_pred = response.force[: len(trace) - 1][window]
    assert np.sqrt(np.mean((f_pred - f_sim) ** 2)) < 0.15  # N, against a 0.27 N spread


def test_no_motion_no_ripple() -> None:
    cell = _cell("fig14", **{"z_reference.amplitude": 0.0})
    response = ar.analysis.forced_response(cell)
    assert response.stable and response.passed
    assert response.force_oscillation < 1e-9
    # The run starts touching at rest (f = 0): the response starts there, its first
    # transient included, and holds f_d over the last 2 s.
    assert abs(response.force[0]) < 1e-5
    assert np.allclose(response.force[-2000:], 10.0, atol=1e-6)
    simulated = ar.simulate(cell).trace["f"].to_numpy()
    assert response.force.max() == pytest.approx(simulated.max(), rel=0.05)  # 11.94, 11.66
    assert np.max(np.abs(response.force[:1000] - simulated[:1000])) < 1.0  # 0.76 N
    assert response.verdict.startswith("passed: predicted force oscillation")


def test_a_loop_unstable_with_the_motion_fails() -> None:
    cell = _cell("fig14", **{"wall.stiffness": 3.2e4, "admittance.b": 100.0})
    assert ar.simulate(cell).stable is False
    predicted = ar.analysis.predict(cell)
    assert predicted["passed"] is False
    assert str(predicted["tolerance_verdict"]).startswith("unstable with the motion running: ")
    assert math.isnan(float(predicted["force_oscillation"]))


def test_no_contact_equilibrium_predicts_failure() -> None:
    far = _cell("fig14", **{"force_reference.value": -10.0})
    predicted = ar.analysis.predict(far)
    assert predicted["stable"] is False and predicted["passed"] is False
    assert str(predicted["tolerance_verdict"]).startswith("unstable: no contact equilibrium")


def test_motion_false_keeps_the_held_answer() -> None:
    cell = _cell("fig14", **{"admittance.b": 2500.0})
    predicted = ar.analysis.predict(cell, motion=False)
    assert predicted["passed"] is predicted["stable"] is True
    assert math.isnan(float(predicted["force_oscillation"]))


def test_unjudged_criteria_are_listed() -> None:
    cell = _cell("fig14", **{"criteria.force_limit": 50.0, "criteria.max_bounces": 2})
    response = ar.analysis.forced_response(cell)
    assert response.unjudged == ("force_limit", "max_bounces")


def test_forced_response_takes_a_scenario() -> None:
    with pytest.raises(ar.errors.ParameterTypeError, match="forced_response"):
        ar.analysis.forced_response({"wall": None})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("path", "value"),
    [("duration", 1e6), ("duration", 200.0), ("period", 1e-7), ("z_reference.amplitude", 1e3),
     ("z_reference.omega", 1e4), ("admittance.b", 1e9), ("wall.stiffness", 1e300)],
)
def test_hostile_values_give_an_answer_or_an_error(path: str, value: float) -> None:
    try:
        cell = _cell("fig14", **{path: value})
    except ar.AdmitError:
        return
    try:
        response = ar.analysis.forced_response(cell)
    except ar.AdmitError as e:
        assert str(e)
        return
    assert response.passed in (True, False, None)
    if response.passed is None:
        assert response.verdict.startswith("not predicted: ")
    elif response.stable:
        assert math.isfinite(response.force_oscillation)


def test_a_long_run_is_not_predicted() -> None:
    response = ar.analysis.forced_response(_cell("fig14", duration=200.0))
    assert response.passed is None and response.stable is None
    assert response.verdict == ("not predicted: the run has 200001 samples, the forced response"
                                " is computed for up to 100000")


def test_stability_map_with_the_motion_running() -> None:
    sc = ar.paper.scenario("fig14")
    grid = {"x": {"wall.stiffness": [1e5]}, "y": {"admittance.b": [1000.0, 2500.0]}}
    table = ar.analysis.stability_map(sc, **grid, motion=True)
    assert table["stable"].to_list() == [True, True]
    assert table["passed"].to_list() == [True, False]
    assert table["force_oscillation"][1] > 0.1 > table["force_oscillation"][0]
    sweep = ar.sweep(sc, grid={"wall.stiffness": [1e5], "admittance.b": [1000.0, 2500.0]},
                     progress=False)  # fmt: skip
    fig = ar.plot.stability_map(table, overlay=sweep, by="passed")
    labels = [t.get_text() for t in fig.legends[0].get_texts()] if fig.legends else [
        t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert "predicted out of tolerance (1)" in labels
    assert "simulated `passed` agrees with predicted `passed` in 100% of 2 cells" in (
        fig.axes[0].get_title())
    # Without motion columns, by="passed" compares with the predicted `stable`.
    plain = ar.analysis.stability_map(sc, **grid)
    assert "passed" not in plain.columns
    title = ar.plot.stability_map(plain, overlay=sweep, by="passed").axes[0].get_title()
    assert "agrees with predicted `stable` in 50% of 2 cells" in title


@pytest.mark.parametrize("figure", ["fig14", "fig8"])
def test_predicted_passed_agrees_on_a_grid_with_motion(figure: str) -> None:
    """The issue's acceptance grid (examples/stable_or_out_of_tolerance.py): k_e 1e4–1e6 ×
    b 100–2500 × latency 0, 3 samples, the sine motion running; ≥ 95 % agreement on
    `passed` (39/40 and 40/40 measured), every miss conservative (never predicted to pass
    where the run fails), the ripple within 30 % on every cell stable in both."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).parents[1] / "examples" / "stable_or_out_of_tolerance.py"
    spec = importlib.util.spec_from_file_location("stable_or_out_of_tolerance", path)
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    table = example.grid(figure)
    assert table.height == 40
    same = (table["predicted_passed"] == table["passed"]).fill_null(False)
    assert int(same.sum()) >= 39
    optimistic = table.filter(table["predicted_passed"].fill_null(False) & ~table["passed"])
    assert optimistic.height == 0, optimistic
    both = table.filter(table["stable"] & table["predicted_oscillation"].is_finite())
    ratio = (both["predicted_oscillation"] / both["force_oscillation"]).to_numpy()
    assert both.height >= 20 and np.all(np.abs(ratio - 1) <= CLOSE), ratio


def test_a_first_transient_that_can_sustain_itself_is_predicted_unstable() -> None:
    """Fig. 8 at k_e = 1e6 N/m, b = 400 N·s/m: stable at the motion's joint speeds
    (ρ < 1), but the first contact's transient moves the joints faster, where Coulomb
    friction's describing-function gain is lower and ρ ≥ 1; the run bounces for 4 s."""
    cell = _cell("fig8", **{"wall.stiffness": 1e6, "admittance.b": 400.0})
    simulated = ar.simulate(cell)
    assert simulated.stable is False and simulated.metrics["bounces"] > 100
    response = ar.analysis.forced_response(cell)
    assert response.stable is False and response.passed is False
    assert response.spectral_radius >= 1.0
    assert response.verdict.startswith("unstable at the first transient: its joint speeds")
    assert min(response.friction_gains) < 1.0


def test_nothing_to_judge_is_not_predicted() -> None:
    for cell in (_cell("fig14", duration=0.5), _cell("fig14", **{"force_reference.value": 0.0,
                                                                 "force_reference.initial": 0.0})):
        try:
            response = ar.analysis.forced_response(cell)
        except ar.errors.AnalysisError as e:  # f_d = 0: no contact equilibrium to expand about
            assert "no contact equilibrium" in str(e)
            continue
        assert response.passed is None
        assert response.verdict.startswith("not predicted: the run has no window to judge")
