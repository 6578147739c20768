"""Verdicts a user can set and trust (SPEC §17, issue #21 items 4-7): ``ar.Criteria``
judges ``stable`` and the verdict in one place (the Rust core), so ``Result``, sweep
tables and the command line agree; short runs are "not assessed"; ripple and loss of
contact read differently; the step's own first peak beside python-control's whole-run
maximum."""

from __future__ import annotations

import json
import math

import admit_rs as ar
import control
import numpy as np
import polars as pl
import pytest
from admit_rs import cli

FIG14 = ar.paper.scenario("fig14")


def test_criteria_is_a_scenario_block_with_the_spec_defaults():
    c = FIG14.criteria
    assert c == ar.Criteria()
    assert (c.max_force_oscillation, c.max_contact_loss, c.min_assessed) == (0.1, 0.05, 1.0)
    assert (c.force_limit, c.max_bounces, c.max_path_error, c.max_torque_saturation) == (
        None, None, None, None)  # fmt: skip
    with pytest.raises(ar.ParameterError, match=r"criteria.max_contact_loss = -0.1 is invalid"):
        FIG14.replace(**{"criteria.max_contact_loss": -0.1})
    with pytest.raises(ar.ParameterError, match=r"max_bounces = 1.5 is invalid"):
        ar.Criteria(max_bounces=1.5)
    with pytest.raises(ar.UnknownParameterError, match="force_limit"):
        ar.Criteria(force_limt=20.0)


def test_a_force_limit_names_the_peak_and_the_limit():
    # fig. 14's first-contact peak is 12.57 N for f_d = 10 N: "stable" by default, not
    # with an 11 N limit.
    assert ar.simulate(FIG14).verdict == "stable"
    res = ar.simulate(FIG14.replace(**{"criteria.force_limit": 11.0}))
    # A peak is the user's tolerance, not the loop's dynamics (SPEC §23).
    assert res.passed is False and res.stable is True
    # The first-contact peak is the impact (within 0.5 s of first contact, SPEC §16); the
    # whole run's 12.58 N at 1.716 s comes later.
    m = res.metrics
    assert res.verdict == (f"out of tolerance: impact peak {m['impact_peak']:.4g} N (within "
                           "0.5 s of "
                           "first contact at t = 0.001 s) above force_limit 11 N (force peak "
                           f"{m['force_peak']:.4g} N later)")  # fmt: skip


def test_ripple_in_contact_and_loss_of_contact_read_differently():
    # b = 2000 with the z motion: the force ripples at friction reversals, contact kept.
    ripple = ar.simulate(FIG14.replace(**{"admittance.b": 2000.0}))
    # (one touch-and-go during the first contact, before the assessed window)
    assert ripple.metrics["contact_loss"] == 0.0 and ripple.metrics["bounces"] <= 1
    assert ripple.metrics["force_oscillation"] > 0.1
    assert ripple.verdict.startswith("out of tolerance: force oscillation, contact kept: "
                                     "std(f − f_d)")
    assert ripple.stable is True and ripple.passed is False
    # The limit is the user's: at 20 % the same run passes.
    loose = ar.simulate(FIG14.replace(**{"admittance.b": 2000.0,
                                         "criteria.max_force_oscillation": 0.2}))
    assert loose.stable is True and loose.passed is True and loose.verdict == "stable"
    # A stiff wall and little damping: the tool bounces.
    bounce = ar.simulate(FIG14.replace(**{"wall.stiffness": 7e5, "admittance.b": 200.0}))
    assert bounce.metrics["bounces"] > 10
    assert bounce.verdict.startswith("unstable: loss of contact: f = 0 in ")
    assert "force oscillation with loss of contact" in bounce.verdict
    limited = ar.simulate(FIG14.replace(**{"wall.stiffness": 7e5, "admittance.b": 200.0,
                                           "criteria.max_contact_loss": 1.0,
                                           "criteria.max_force_oscillation": 100.0,
                                           "criteria.max_bounces": 3}))
    assert limited.verdict.startswith(f"unstable: {limited.metrics['bounces']:.0f} bounces "
                                      "above max_bounces 3 — self-sustained: with the motion "
                                      "held, std(f − f_d) is ")
    assert limited.verdict.endswith(" bounces")


@pytest.mark.parametrize("duration", [0.5, 1.0, 1.5])
def test_a_run_too_short_to_assess_is_not_stable_but_not_assessed(duration):
    res = ar.simulate(FIG14.replace(duration=duration))
    assert res.stable is None and res.metrics["stable"] is None
    assessed = max(duration - 1.0, 0.0)
    assert res.metrics["assessed_time"] == pytest.approx(assessed, abs=1e-12)
    assert res.verdict == (f"not assessed: only {assessed:g} s of the run after t = 1 s, "
                           "min_assessed is 1 s")
    assert "not assessed" in repr(res)
    # The user may accept a shorter window.
    short = ar.simulate(FIG14.replace(duration=duration, **{"criteria.min_assessed": 0.25}))
    assert short.stable is (True if duration == 1.5 else None)
    # A failed criterion is a failure even in a short run; its stability is not assessed.
    peak = ar.simulate(FIG14.replace(duration=duration, **{"criteria.force_limit": 5.0}))
    assert peak.passed is False and peak.stable is None
    assert peak.verdict.startswith("out of tolerance: impact peak")
    assert peak.verdict.endswith(f"; stability not assessed: only {assessed:g} s of the run "
                                 "after t = 1 s, min_assessed is 1 s")


def test_a_position_only_run_is_judged_on_its_path_and_torque_when_asked():
    weak = FIG14.replace(admittance=None, actuator=ar.Actuator(torque_limit=(20.0, 5.0, 2.0)))
    res = ar.simulate(weak)
    m = res.metrics
    assert not m["diverged"] and m["torque_saturation"] > 0.9 and m["path_rms_error"] > 0.05
    # Default criteria: judged on divergence only, and the verdict says so and what it saw.
    assert res.stable is True
    assert res.verdict.startswith("stable (position-only run: judged on divergence only")
    assert "torque saturated in" in res.verdict
    judged = ar.simulate(weak.replace(**{"criteria.max_path_error": 0.01,
                                         "criteria.max_torque_saturation": 0.1}))
    assert judged.stable is True and judged.passed is False
    assert judged.verdict == (
        f"out of tolerance: path error {m['path_rms_error']:.4g} m RMS above max_path_error "
        "0.01 m; "
        f"torque saturated in {100 * m['torque_saturation']:.0f} % of samples "
        "(max_torque_saturation 10 %)")
    # path_rms_error of a position-only run is the whole error |X_d − X| (x and z here).
    assert m["path_rms_error"] == pytest.approx(math.hypot(m["x_rms_error"],
                                                           m["z_rms_error"]), rel=1e-9)


def test_sweep_tables_carry_the_same_judgement_null_when_not_assessed():
    base = FIG14.replace(duration=3.0)
    grid = {"admittance.b": [200.0, 2000.0], "criteria.max_force_oscillation": [0.1, 0.5],
            "duration": [1.0, 3.0]}
    one = ar.sweep(base, grid=grid, threads=1, progress=False)
    assert one["stable"].dtype == pl.Boolean and one["verdict"].dtype == pl.String
    assert one["stable"].null_count() == 4  # the 1-s runs
    for row in one.iter_rows(named=True):
        res = ar.simulate(base.replace(**{p: row[p] for p in grid}))
        assert row["stable"] == res.stable and row["verdict"] == res.verdict
    # Deterministic with criteria on any thread count and chunking.
    for threads, chunk in [(2, 256), (1, 3)]:
        other = ar.sweep(base, grid=grid, threads=threads, chunk_size=chunk, progress=False)
        assert other.equals(one)


def test_step_first_peak_and_whole_run_maximum_have_their_own_names():
    res = ar.simulate(FIG14)
    m, tr = res.metrics, res.trace
    # Whole run (python-control's PeakTime): a bump from the z motion.
    assert m["peak_time"] == pytest.approx(1.716)
    # The step's own first peak, after first contact.
    assert m["step_peak_time"] == pytest.approx(0.321)
    f = tr["f"].to_numpy()
    assert m["step_overshoot_pct"] == pytest.approx(100 * (f[321] - 10) / 10, rel=1e-12)
    info = control.step_info(f, T=tr["t"].to_numpy(), yfinal=10.0)
    assert res.step_info()["PeakTime"] == pytest.approx(info["PeakTime"])
    assert ar.METRICS["peak_time"].description.startswith("time of the whole run's maximum")
    assert "first local maximum" in ar.METRICS["step_overshoot_pct"].description


BOUNCING = FIG14.replace(**{"wall.stiffness": 1e6},
                         sensor=ar.ForceSensor(noise_std=0.5, latency=1), seed=2)


BOUNCING_TOML = "seed = 2\n[wall]\nstiffness = 1e6\n[sensor]\nnoise_std = 0.5\nlatency = 1\n"


def test_an_unstable_run_does_not_look_good_in_the_cli_table(tmp_path, capsys):
    path = tmp_path / "bounce.toml"
    path.write_text(BOUNCING_TOML)
    code = cli.main(["run", str(path), "--format", "table"])
    out = capsys.readouterr().out
    assert code == 3
    first = out.splitlines()[0]
    assert first.startswith("NOT STABLE: unstable: loss of contact")
    row = next(line for line in out.splitlines() if line.startswith("force_ss_error"))
    assert row.split()[-2] == "*" or row.rstrip().endswith("* N")
    assert "these numbers describe no settled response" in out
    # JSON keeps the numbers and says stable false.
    cli.main(["run", str(path)])
    report = json.loads(capsys.readouterr().out)
    assert report["stable"] is False and report["verdict"].startswith("unstable:")


def test_a_stable_run_is_not_marked(tmp_path, capsys):
    path = tmp_path / "ok.toml"
    path.write_text("duration = 3.0\n")
    assert cli.main(["run", str(path), "--format", "table"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith("verdict") and " *" not in out


def test_the_verdict_names_the_numbers_it_judged():
    res = ar.simulate(BOUNCING)
    m = res.metrics
    assert res.stable is False
    assert f"f = 0 in {100 * m['contact_loss']:.0f} % of samples" in res.verdict
    assert f"{m['bounces']:.0f} bounces" in res.verdict
    assert repr(res).endswith(f"{res.verdict}>")


def test_numpy_agrees_with_bounces_on_a_bouncing_run():
    res = ar.simulate(BOUNCING)
    f = res.trace["f"].to_numpy()
    touching = f > 0
    first = int(np.argmax(touching))
    assert res.metrics["bounces"] == np.sum(touching[first:-1] & ~touching[first + 1:])


def test_a_value_just_over_its_limit_reads_apart_from_it():
    """Issue #53, item 18: "12.58 N above force_limit 12.58 N", "4 % of f_d
    (max_force_oscillation 4 %)" and "1 bounces"."""
    sc = ar.paper.scenario("fig14")
    m = ar.simulate(sc).metrics
    peak = m["force_peak"]  # 12.5799 N, after the impact peak 12.5749 N
    verdict = ar.simulate(sc.replace(**{"criteria.force_limit": peak - 1e-6})).verdict
    value, limit = verdict.split("force peak ")[1].split(" N above force_limit ")
    assert value != limit.rstrip(" N") and float(value) > float(limit.rstrip(" N"))
    osc = m["force_oscillation"]  # 0.0704
    verdict = ar.simulate(sc.replace(**{"criteria.max_force_oscillation": osc - 1e-5})).verdict
    shown = verdict.split("over the last 2 s is ")[1]
    value, limit = shown.split(" of f_d (max_force_oscillation ")
    assert value != limit.rstrip(")") and value.endswith(" %")
    assert "1 bounce (max_contact_loss" in ar.simulate(ar.paper.scenario("fig12")).verdict


# -- issue #54, part 1: unstable or out of tolerance (SPEC §23) ------------------------------

# fig. 14 at k_e = 1e4 N/m, b = 2500 N·s/m: a well-damped slow loop (predicted ρ = 0.998,
# ζ = 0.38) whose force ripples at the motion's friction reversals.
SLOW = FIG14.replace(**{"wall.stiffness": 1e4, "admittance.b": 2500.0})
HELD = ar.Step(value=0.0, time=0.0, initial=0.0)


def test_a_ripple_the_motion_drives_is_stable_and_out_of_tolerance():
    r = ar.simulate(SLOW)
    assert r.metrics["force_oscillation"] > 0.1 and r.metrics["contact_loss"] == 0.0
    assert r.stable is True and r.passed is False
    assert r.metrics["stable"] is True and r.metrics["passed"] is False
    assert r.verdict.startswith("out of tolerance: force oscillation, contact kept: std(f − f_d)")
    # The held run is the same scenario with the motion at s(0) = 0: simulated on its own, it
    # meets the criterion, and the verdict quotes its figure.
    held = ar.simulate(SLOW.replace(z_reference=HELD))
    assert held.stable is True and held.passed is True and held.verdict == "stable"
    osc = held.metrics["force_oscillation"]
    assert osc < 0.1
    shown = f"{100 * osc:.0f} %" if osc >= 0.01 else f"{float(f'{100 * osc:.2g}'):g} %"
    assert r.verdict.endswith(
        f"— driven: with the motion held, std(f − f_d) is {shown} of f_d and f = 0 in 0 % of "
        "samples"), r.verdict


def test_bouncing_and_diverging_are_unstable_whatever_drives_them():
    bounce = ar.simulate(FIG14.replace(**{"wall.stiffness": 7e5, "admittance.b": 200.0}))
    assert bounce.stable is False and bounce.passed is False
    assert bounce.verdict.startswith("unstable: loss of contact: f = 0 in ")
    assert "— self-sustained: with the motion held, " in bounce.verdict
    # Held, it bounces too: the run the verdict quotes.
    held = ar.simulate(FIG14.replace(z_reference=HELD,
                                     **{"wall.stiffness": 7e5, "admittance.b": 200.0}))
    assert held.stable is False and held.metrics["contact_loss"] > 0.05
    diverged = ar.simulate(ar.paper.scenario("fig12").replace(
        **{"controller.command_divisor": 0.1}))  # fmt: skip
    assert diverged.diverged and diverged.stable is False and diverged.passed is False
    assert diverged.verdict.startswith("unstable: diverged at t = ")


def test_a_ripple_nothing_drives_is_the_loops_own():
    # No motion, a constant f_d, no noise: the same bouncing cell needs no held run.
    still = ar.simulate(FIG14.replace(z_reference=HELD,
                                      **{"wall.stiffness": 7e5, "admittance.b": 200.0}))
    assert still.verdict.endswith("— self-sustained: nothing drives the run (no motion, f_d "
                                  "constant in the last 2 s, no sensor noise)")


def test_noise_is_a_drive_the_held_run_turns_off():
    noisy = ar.simulate(FIG14.replace(z_reference=HELD, **{"sensor.noise_std": 40.0}))
    assert noisy.metrics["force_oscillation"] > 0.1
    assert noisy.stable is True and noisy.passed is False
    assert "— driven: with the sensor noise off, std(f − f_d) is " in noisy.verdict


def sim_samples(sc: ar.Scenario) -> int:
    return round(sc.duration / sc.period) + 1


def test_sweeps_simulate_and_the_stepped_loop_agree_on_both_answers():
    grid = {"admittance.b": [200.0, 2500.0], "wall.stiffness": [1e4, 7e5]}
    base = FIG14.replace(duration=4.0)
    # The scalar path: each run bit-identical to `simulate` (a bouncing run is chaotic, so
    # the lanes' last-bit differences show in its figures, not in its answers).
    table = ar.sweep(base, grid=grid, threads=2, progress=False, lanes=False)
    assert table["passed"].dtype == pl.Boolean
    for row in table.iter_rows(named=True):
        sc = base.replace(**{p: row[p] for p in grid})
        res = ar.simulate(sc)
        assert (row["stable"], row["passed"], row["verdict"]) == (
            res.stable, res.passed, res.verdict), row
        sim = ar.Simulation(sc)
        sim.step(sim_samples(sc))
        stepped = sim.result()
        assert (stepped.stable, stepped.passed) == (res.stable, res.passed)
    # Out of tolerance is a separate count from unstable.
    assert set(zip(table["stable"], table["passed"], strict=True)) >= {(True, False)}
    # The same table on one thread, scalar path and in other chunks.
    for kwargs in ({"threads": 1, "chunk_size": 1}, {"threads": 2, "chunk_size": 3}):
        other = ar.sweep(base, grid=grid, progress=False, lanes=False, **kwargs)
        assert other.select("stable", "passed", "verdict").equals(
            table.select("stable", "passed", "verdict"))
    lanes = ar.sweep(base, grid=grid, progress=False)
    assert lanes.select("stable", "passed").equals(table.select("stable", "passed"))


def test_the_held_run_can_be_turned_off_and_stability_is_then_not_told():
    """``criteria.held_run=False``: no second run (a sweep over mostly failing cells pays up to
    one more run each otherwise); `passed` and the verdict's figures stay."""
    off = ar.simulate(SLOW.replace(**{"criteria.held_run": False}))
    on = ar.simulate(SLOW)
    assert off.passed is False and off.stable is None
    assert off.metrics["force_oscillation"] == on.metrics["force_oscillation"]
    assert off.verdict == on.verdict.split(" — ")[0] + (
        " — driven or self-sustained: not told (criteria.held_run is false); stability not "
        "assessed")
    table = ar.sweep(SLOW, grid={"criteria.held_run": [True, False]}, progress=False)
    assert table["stable"].to_list() == [True, None]
    assert table["passed"].to_list() == [False, False]
