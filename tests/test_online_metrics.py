"""Metrics are accumulated while a run advances (issue 12, part 3): a sweep without traces
keeps no trace at all, and every number equals the definitions of docs/metrics.md applied to
the recorded trace."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap

import admit_rs as ar
import numpy as np
import pytest

WINDOW, TRANSIENT, BAND, IMPACT = 2.0, 1.0, 0.02, 0.5


def _frame(scenario: ar.Scenario) -> tuple[np.ndarray, np.ndarray]:
    """The wall normal n and the motion tangent t̂ of SPEC §10."""
    n = np.array(scenario.wall.normal, dtype=float)
    n /= np.linalg.norm(n)
    ez = np.array([0.0, 0.0, 1.0])
    t = ez - (ez @ n) * n
    if np.linalg.norm(t) < 1e-12:
        t = np.array([1.0, 0.0, 0.0])
    return n, t / np.linalg.norm(t)


def reference_metrics(scenario: ar.Scenario, res: ar.Result) -> dict[str, float]:
    """docs/metrics.md, written again from the trace with NumPy (two-pass statistics)."""
    tr = res.trace
    t, f, fd = (tr[c].to_numpy() for c in ("t", "f", "f_d"))
    n, tangent = _frame(scenario)
    error = np.stack([tr[f"{c}_ref"].to_numpy() - tr[c].to_numpy() for c in "xyz"], axis=1)
    in_plane = error - np.outer(error @ n, n)
    out = {
        "x_rms_error": float(np.sqrt(np.mean((error @ n) ** 2))),
        "z_rms_error": float(np.sqrt(np.mean((error @ tangent) ** 2))),
        "path_rms_error": float(np.sqrt(np.mean(np.sum(in_plane**2, axis=1)))),
        "force_peak": float(f.max()),
    }
    touching = f > 0
    first = int(np.argmax(touching)) if touching.any() else len(f)
    out["bounces"] = float(np.sum(touching[first:-1] & ~touching[first + 1 :]))
    end, period = t[-1], scenario.period
    index = np.arange(len(t))
    steady = t >= end - WINDOW - 1e-9 * period
    late = t >= TRANSIENT - 1e-9 * period
    # SPEC §16: a run that starts apart (δ < 0 at sample 0) is judged from first contact + 1 s.
    starts_touching = tr["penetration"][0] >= 0
    if first < len(f):
        out["first_contact_time"] = float(t[first])
        out["impact_peak"] = float(f[first : first + round(IMPACT / period) + 1].max())
        if not starts_touching:
            late = index >= first + round(TRANSIENT / period)
            steady &= late
    else:
        out["first_contact_time"] = out["impact_peak"] = math.nan
    out["force_ss_error"] = float(np.mean(fd[steady] - f[steady]))
    out["force_rms_error"] = float(np.sqrt(np.mean((fd[late] - f[late]) ** 2)))
    out["contact_loss"] = float(np.mean(f[late] == 0.0))
    out["assessed_time"] = float((late.sum() - 1) * period)
    window = steady & late
    out["force_oscillation"] = float(
        np.std(f[window] - fd[window]) / np.mean(np.abs(fd[window]))
    )
    limit = scenario.actuator.torque_limit
    if limit is None:
        out["torque_saturation"] = 0.0
    else:
        tau = np.stack([tr[f"tau{j}"].to_numpy() for j in (1, 2, 3)], axis=1)
        out["torque_saturation"] = float(np.mean(np.any(np.abs(tau) >= limit, axis=1)))
    step = scenario.force_reference
    if isinstance(step, ar.Step):
        value = step.value
        outside = np.nonzero(np.abs(f - value) > BAND * abs(value))[0]
        if not len(outside):
            out["settling_time"] = 0.0
        elif outside[-1] + 1 < len(t):
            out["settling_time"] = float(t[outside[-1] + 1])
        else:
            out["settling_time"] = math.nan  # outside the band at the end
        out["rise_time_63"] = float(t[np.argmax(f >= 0.632 * value)])
        first = {level: t[np.argmax(f >= level * value)] for level in (0.1, 0.9)}
        out["rise_time_10_90"] = float(first[0.9] - first[0.1])
        out["peak_time"] = float(t[np.argmax(np.abs(f))])
        out["overshoot_pct"] = 100.0 * (out["force_peak"] - value) / value
        # The step's first peak: the first local maximum once f has reached f_d.
        above = f >= value
        if above.any():
            start = int(np.argmax(above))
            falls = np.nonzero(np.diff(f[start:]) < 0)[0]
            peak = start + (int(falls[0]) if len(falls) else int(np.argmax(f[start:])))
            out["step_overshoot_pct"] = 100.0 * (f[peak] - value) / value
            out["step_peak_time"] = float(t[peak])
        else:
            out["step_overshoot_pct"], out["step_peak_time"] = 0.0, math.nan
    return out


def _scenarios() -> dict[str, ar.Scenario]:
    fig14 = ar.paper.scenario("fig14").replace(duration=4.0)
    return {
        "fig14": fig14,
        "scheme1_ct": ar.paper.scenario("fig10").replace(duration=3.0),
        "sine_tdc": ar.paper.scenario("fig20").replace(duration=3.0),
        "realistic_tilted": fig14.replace(
            wall=ar.Wall(damping=50.0, normal=(1, 0, -0.5)),
            sensor=ar.ForceSensor(noise_std=0.5, cutoff=30.0, latency=2),
            actuator=ar.Actuator(torque_limit=(60.0, 60.0, 20.0)),
            seed=3,
        ),
        "saturating": fig14.replace(actuator=ar.Actuator(torque_limit=(60.0, 40.0, 20.0))),
        # Free space first (SPEC §16): 2 cm with a correct estimate, and 2 cm that the
        # controller believes touching (contact after about 1.6 s).
        "gap": fig14.replace(wall=ar.Wall(gap=0.02)),
        "believed_touching": fig14.replace(
            wall=ar.Wall(gap=0.02, position_error=-0.02), duration=5.0
        ),
    }


@pytest.mark.parametrize("name", list(_scenarios()))
def test_online_metrics_equal_the_definitions_on_the_trace(name):
    scenario = _scenarios()[name]
    res = ar.simulate(scenario)
    assert not res.metrics["diverged"]
    expected = reference_metrics(scenario, res)
    for metric, value in expected.items():
        got = res.metrics[metric]
        assert got == pytest.approx(value, rel=1e-12, abs=1e-12, nan_ok=True), (metric, got)
    # The saturating case is really there: its fraction is neither 0 nor 1.
    if name == "saturating":
        assert 0.5 < res.metrics["torque_saturation"] < 1.0


def _same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == b


def test_a_sweep_without_traces_gives_the_simulated_metrics_bit_for_bit():
    # The scalar path: the lanes' exp differs in the last bits (tests/test_lanes.py).
    base = ar.paper.scenario("fig19").replace(duration=2.5)
    grid = {"wall.stiffness": [1e4, 3e4, 3e5], "controller.inertia": [0.1, 0.5]}
    table = ar.sweep(base, grid=grid, progress=False, lanes=False)
    assert table["diverged"].any() and not table["diverged"].all()
    for row in table.iter_rows(named=True):
        res = ar.simulate(
            base.replace(**{p: row[p] for p in grid})
        )
        for name in ar.METRIC_NAMES:
            assert _same(row[name], res.metrics[name]), (name, row[name], res.metrics[name])
        assert row["stable"] == res.metrics["stable"]


def test_stepping_back_recomputes_the_metrics_from_the_trace():
    scenario = ar.paper.scenario("fig14").replace(duration=3.0)
    whole = ar.simulate(scenario).metrics
    sim = ar.Simulation(scenario)
    sim.step(1500)
    state = sim.state
    sim.step(10_000)
    first = sim.result().metrics
    assert all(_same(first[name], whole[name]) for name in ar.METRIC_NAMES)
    sim.set_state(state)  # back to sample 1500: samples 1500.. are taken again
    sim.step(10_000)
    again = sim.result().metrics
    for name in ar.METRIC_NAMES:
        assert _same(again[name], whole[name]), name


def test_a_fresh_run_given_a_later_state_starts_there():
    """Issue #53, item 3: a fresh run given another run's state at sample 2000 had a trace
    starting at 2 s and metrics that took its first row as t = 0 (first contact at 0 s,
    "not assessed: only 0 s"). Now it starts at sample 2000; a run that took samples cannot
    jump forward past them."""
    scenario = ar.paper.scenario("fig14").replace(duration=5.0)
    whole = ar.simulate(scenario)
    donor = ar.Simulation(scenario)
    donor.step(2000)
    late = ar.Simulation(scenario)
    late.set_state(donor.state_vector())
    late.step(10_000)
    res = late.result()
    assert res.trace["t"][0] == 2.0 and res.trace.height == whole.trace.height - 2000
    assert res.trace["f"].to_list() == whole.trace["f"].to_list()[2000:]
    m = res.metrics
    assert m["first_contact_time"] == 2.0 and m["assessed_time"] == pytest.approx(3.0)
    assert m["force_ss_error"] == whole.metrics["force_ss_error"]
    assert "not assessed" not in res.verdict, res.verdict
    ahead = ar.Simulation(scenario)
    ahead.step(500)
    with pytest.raises(ar.ParameterError, match=r"an integer from 0 to 500 .*never took"):
        ahead.set_state({"sample": 2000.0})


def test_a_20000_run_sweep_without_traces_stays_under_50_mb():
    # In a fresh process, so that ru_maxrss measures this sweep and nothing else.
    script = textwrap.dedent(
        """
        import resource
        import admit_rs as ar
        sc = ar.paper.scenario("fig19").replace(duration=0.2)
        vary = {"wall.stiffness": ar.LogUniform(1e4, 1e5)}
        ar.sweep(sc, vary=vary, samples=64, seed=0, progress=False)
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        table = ar.sweep(sc, vary=vary, samples=20_000, seed=0, progress=False)
        after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        assert table.height == 20_000 and table["stable"].all()
        print((after - before) / 1024)
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=True
    )
    growth_mb = float(out.stdout.strip().splitlines()[-1])
    assert growth_mb < 50.0, growth_mb
