"""ar.analysis (SPEC §12): the linearised closed loop against the simulator, the paper's
analysis (eqs. 25-28, 34-37), classic delay bounds, stability maps and tune."""

import itertools
import math
from pathlib import Path

import admit_rs as ar
import control
import numpy as np
import polars as pl
import pytest
import scipy.linalg as sla
from admit_rs.config import Step

HOLD = Step(value=0.0, time=0.0, initial=0.0)  # the motion frozen at s(0), as linearised


def fig14(**changes):
    return ar.paper.scenario("fig14").replace(z_reference=HOLD, **changes)


def ideal_loop(**changes):
    """Computed torque with K_A = 1, stiff PD and contact compensation: the paper's ideal
    inner loop as closely as a sampled controller gets."""
    return ar.paper.scenario("fig8").replace(
        z_reference=HOLD,
        **{"controller.command_divisor": 1.0, "controller.kd": 200.0, "controller.kp": 1e4,
           "controller.contact_compensation": True},
        **changes,
    )  # fmt: skip


def test_linearize_returns_a_named_discrete_state_space():
    sys = ar.analysis.linearize(ar.paper.scenario("fig14"))
    assert isinstance(sys, control.StateSpace)
    assert sys.dt == 1e-3
    assert sys.input_labels == ["f_d"] and sys.output_labels == ["f", "x", "z"]
    sim = ar.Simulation(ar.paper.scenario("fig14"))
    assert sys.state_labels == list(sim.state)[1:]  # the flat state without `sample`
    assert sys.equilibrium and sys.newton_iterations >= 1
    assert sys.operating_outputs["f"] == pytest.approx(10.0, abs=1e-8)
    assert any("contact is assumed kept" in c for c in sys.caveats)
    assert any("slope" in c for c in sys.caveats)
    # Latency adds states.
    lat = ar.analysis.linearize(ar.paper.scenario("fig14").replace(**{"sensor.latency": 3}))
    assert lat.nstates == sys.nstates + 3
    assert "sensor.in_flight3" in lat.state_labels


def sc_period(scenario):
    return scenario.period


def _step_from_equilibrium(scenario, samples, rel=0.01):
    """Simulated and linear response of f, x, z to a step of rel·f_d from the equilibrium."""
    sys = ar.analysis.linearize(scenario)
    fd = sys.force_desired
    stepped = scenario.replace(force_reference=Step(value=fd * (1 + rel), time=0.0,
                                                    initial=fd * (1 + rel)))  # fmt: skip
    sim = ar.Simulation(stepped)
    sim.set_state({"sample": 1.0, **sys.operating_point})
    sim.step(samples)
    tr = sim.trace.filter(pl.col("t") >= 0.5 * sc_period(scenario)).head(samples)
    lin = control.forced_response(sys, U=np.full(samples, fd * rel))
    y0 = sys.operating_outputs
    n = np.array([1.0, 0.0, 0.0])  # fig14's wall normal; t̂ = e_z
    sim_y = {
        "f": tr["f"].to_numpy() - y0["f"],
        "x": tr["x"].to_numpy() * n[0] - y0["x"],
        "z": tr["z"].to_numpy() - y0["z"],
    }
    return {k: (sim_y[k], lin.outputs[i]) for i, k in enumerate(["f", "x", "z"])}, fd * rel


def ur5_scenario() -> ar.Scenario:
    """fig14's task on the UR5 from its URDF (TDC tuned for the arm, SPEC §11)."""
    data = Path(__file__).resolve().parent.parent / "examples" / "data"
    q0 = (0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0)
    arm = ar.UrdfArm(data / "ur5.urdf", "tool0", q0=q0)
    return fig14().replace(robot=arm, controller=ar.TimeDelayControl.for_arm(arm))


@pytest.mark.parametrize("label", ["fig14", "fig8 scheme 1", "ur5 urdf"])
def test_small_step_linear_matches_simulation(label):
    sc = {
        "fig14": fig14,
        "fig8 scheme 1": lambda: ar.paper.scenarios("fig8")[0].replace(z_reference=HOLD),
        "ur5 urdf": ur5_scenario,
    }[label]()
    out, step = _step_from_equilibrium(sc, 1500)
    sim_f, lin_f = out["f"]
    rms = np.sqrt(np.mean((sim_f - lin_f) ** 2))
    assert rms <= 0.01 * step, f"RMS {rms / step:.2%} of the step"
    assert np.max(np.abs(sim_f)) > 0.5 * step  # it did respond
    sim_x, lin_x = out["x"]
    dx = np.max(np.abs(lin_x))
    assert np.sqrt(np.mean((sim_x - lin_x) ** 2)) <= 0.01 * dx


CASES = [
    ("fig14", 400.0, 1e4), ("fig14", 400.0, 3e4), ("fig14", 200.0, 1e5),
    ("fig14", 0.0, 1e4), ("fig14", 0.0, 1e5),
    ("fig8", 400.0, 1e4), ("fig8", 400.0, 3e4), ("fig8", 800.0, 1e5), ("fig8", 0.0, 3e4),
]  # fmt: skip


def test_steady_state_errors_match_simulation():
    """Scheme 1 (k > 0) and Scheme 2 (k = 0), TDC (fig14) and computed torque (fig8): the
    predicted f_d − f and n·X_d − n·X match the last 2 s of a 10-s run to 1 % (or 1e-3 N /
    1e-7 m where they vanish)."""
    scenarios = [
        ar.paper.scenario(fig).replace(
            z_reference=HOLD, **{"admittance.k": k, "wall.stiffness": ke}
        )
        for fig, k, ke in CASES
    ]
    for sc in scenarios:
        p = ar.analysis.predict(sc)
        r = ar.simulate(sc)
        tail = r.trace.filter(pl.col("t") >= sc.duration - 2.0)
        f_err = float((tail["f_d"] - tail["f"]).mean())
        x_err = float((tail["x_ref"] - tail["x"]).mean())
        assert abs(p["force_ss_error"] - f_err) <= max(0.01 * abs(f_err), 1e-3), (sc, p, f_err)
        assert abs(p["x_ss_error"] - x_err) <= max(0.01 * abs(x_err), 1e-7), (sc, p, x_err)


def test_scheme1_offset_of_the_real_inner_loop():
    """Fig. 8's Scheme 1 (computed torque, K_A = 0.1): the offset the real inner loop leaves
    (f = 7.35 N, where the ideal eq. 26 gives 8.82 N) is predicted."""
    sc = ar.paper.scenarios("fig8")[0]
    sys = ar.analysis.linearize(sc)
    assert sys.operating_outputs["f"] == pytest.approx(7.35, abs=0.01)
    sim = ar.simulate(sc.replace(z_reference=HOLD))
    assert float(sim.trace["f"][-1]) == pytest.approx(sys.operating_outputs["f"], rel=1e-4)


@pytest.mark.parametrize("k,ka", [(400.0, 0.1), (200.0, 1.0), (0.0, 0.1), (0.0, 1.0)])
def test_paper_analysis_with_an_ideal_inner_loop(k, ka):
    """Eqs. 25/34 (with k_a): f/f_d = k_a k_e / (m s² + b s + k + k_a k_e) at low
    frequency; eqs. 26/35: f(∞) = f_d k_a k_e / (k + k_a k_e); eqs. 28/37: the wall
    penetration (−ε) = f(∞)/k_e."""
    ke, b, fd = 3e4, 800.0, 10.0
    sys = ar.analysis.linearize(ideal_loop(**{"admittance.k": k, "admittance.ka": ka}))
    f_inf = fd * ka * ke / (k + ka * ke)
    assert sys.operating_outputs["f"] == pytest.approx(f_inf, rel=1e-8)
    assert sys.penetration == pytest.approx(f_inf / ke, rel=1e-8)
    dc = control.dcgain(sys)[0]
    assert dc == pytest.approx(ka * ke / (k + ka * ke), rel=1e-6)
    for hz in (0.1, 0.3, 1.0):
        s = 2j * np.pi * hz
        paper = ka * ke / (s * s + b * s + k + ka * ke)
        model = sys(np.exp(s * sys.dt))[0, 0]
        assert abs(model / paper - 1) < 0.01, (hz, model, paper)


def _jury_stable(coeffs):
    """Jury's (Schur-Cohn) test: are all roots of a_0 z^n + … + a_n strictly inside the
    unit circle? With c the ascending coefficients, each step needs |c_0| < |c_n| and
    reduces to q_i = c_n c_{i+1} − c_0 c_{n−1−i}."""
    c = np.array(coeffs, dtype=float)[::-1]
    while len(c) > 1:
        if abs(c[0]) >= abs(c[-1]):
            return False
        n = len(c) - 1
        c = np.array([c[-1] * c[i + 1] - c[0] * c[n - 1 - i] for i in range(n)])
    return True


def _sampled_loop(ke, b, ka, latency, kp=1e4, kd=200.0, period=1e-3):
    """Scheme 2 with an ideal (exactly modelled) inner loop, written from scratch: the
    ZOH filter, a task-space double integrator under computed torque with feed-forward
    (X_{k+1} = X_k + T Ẋ_k + T²/2 V_k), f_k = k_e X_k, measured L samples late."""
    E = sla.expm(np.array([[0, 1, 0], [0, -b, ka], [0, 0, 0]]) * period)
    ad, bd = E[:2, :2], E[:2, 2]
    n = 4 + latency
    eye = np.eye(n)
    e = -ke * eye[2] if latency == 0 else -eye[3 + latency]
    xa, va, x, v = eye[0], eye[1], eye[2], eye[3]
    acc = (ka * e - b * va) + kd * (va - v) + kp * (xa - x)
    rows = [ad[0, 0] * xa + ad[0, 1] * va + bd[0] * e, ad[1, 0] * xa + ad[1, 1] * va + bd[1] * e,
            x + period * v + period**2 / 2 * acc, v + period * acc]  # fmt: skip
    if latency:
        rows += [ke * x] + [eye[i - 1] for i in range(5, n)]
    return np.array(rows)


def _critical(stable, lo, hi):
    assert stable(lo) and not stable(hi)
    for _ in range(40):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return math.sqrt(lo * hi)


@pytest.mark.parametrize("b,ka,latency", [(50, 10, 1), (50, 10, 3), (100, 10, 2), (50, 5, 5),
                                          (800, 100, 2)])  # fmt: skip
def test_critical_stiffness_matches_jury(b, ka, latency):
    """With an ideal inner loop, Scheme 2's critical stiffness under an L-sample
    measurement delay: from the predicted spectral radius and from Jury's test on the
    characteristic polynomial of the hand-written sampled loop, within 2 %."""
    jury = _critical(lambda ke: _jury_stable(np.poly(_sampled_loop(ke, b, ka, latency))),
                     10.0, 1e8)  # fmt: skip
    sc = ideal_loop(**{"admittance.b": float(b), "admittance.ka": float(ka),
                       "admittance.k": 0.0, "sensor.latency": latency,
                       "robot.coulomb_friction": (0.0, 0.0, 0.0),
                       "robot.viscous_friction": (0.0, 0.0, 0.0)})  # fmt: skip
    rho = lambda ke: ar.analysis.predict(sc.replace(**{"wall.stiffness": ke}))["spectral_radius"]  # noqa: E731
    predicted = _critical(lambda ke: rho(ke) < 1, jury / 3, jury * 3)
    assert predicted == pytest.approx(jury, rel=0.02)
    # The textbook bound that takes X ≡ x_a (no inner loop at all) is 2-6 % lower:
    # the sampled inner loop is not transparent at the loop's crossover.


def _agreement(scenario, x, y, duration=6.0):
    sc = scenario.replace(duration=duration)
    (xp, xs), (yp, ys) = next(iter(x.items())), next(iter(y.items()))
    pred = ar.analysis.stability_map(sc, x=x, y=y, friction="step")
    sims = ar.sweep(sc, grid={yp: ys, xp: xs}, progress=False)
    joined = pred.join(sims.select(xp, yp, pl.col("stable").alias("simulated")), on=[xp, yp])
    joined = joined.sort([yp, xp])
    p = joined["stable"].to_numpy().reshape(len(ys), len(xs))
    s = joined["simulated"].to_numpy().reshape(len(ys), len(xs))
    return p, s


def _check_map(p, s):
    agree = float(np.mean(p == s))
    assert agree >= 0.95, f"{agree:.1%} of cells agree"
    rows, cols = p.shape
    for i, j in zip(*np.nonzero(p != s), strict=True):
        near = {p[a, c] for a, c in itertools.product(range(max(i - 1, 0), min(i + 2, rows)),
                                                      range(max(j - 1, 0), min(j + 2, cols)))}
        assert near == {True, False}, f"cell ({i}, {j}) disagrees away from the boundary"
    return agree


KE = [float(v) for v in np.geomspace(1e4, 1e6, 12)]


def test_stability_map_agrees_with_simulation_ke_b():
    b = [float(v) for v in np.geomspace(50, 2000, 12)]
    p, s = _agreement(fig14(), {"wall.stiffness": KE}, {"admittance.b": b})
    _check_map(p, s)
    assert p.any() and not p.all()  # the grid crosses the boundary


def test_stability_map_agrees_with_simulation_ke_latency():
    p, s = _agreement(fig14(), {"wall.stiffness": KE}, {"sensor.latency": list(range(12))})
    _check_map(p, s)
    assert p.any() and not p.all()


def test_stability_map_table():
    t = ar.analysis.stability_map(ar.paper.scenario("fig14"), x={"wall.stiffness": [1e4, 2e6]},
                                  y={"sensor.latency": [0, 2, 4]})  # fmt: skip
    assert t.height == 6
    assert t.columns[:2] == ["wall.stiffness", "sensor.latency"]
    assert t["sensor.latency"].dtype == pl.Int64
    assert set(ar.analysis.PREDICTION_NAMES) <= set(t.columns)
    assert t["stable"].dtype == pl.Boolean
    assert t.filter(pl.col("wall.stiffness") == 2e6)["stable"].sum() == 0
    # A cell with no equilibrium is a row with its error, not an exception.
    far = ar.analysis.stability_map(ar.paper.scenario("fig14"),
                                    x={"wall.position": [0.7340560, 3.0]},
                                    y={"admittance.b": [800.0]})  # fmt: skip
    assert far["error"][0] is None and "no contact equilibrium" in far["error"][1]
    assert not far["stable"][1] and math.isnan(far["spectral_radius"][1])


def test_tune_is_verified_by_simulation():
    res = ar.analysis.tune(
        ar.paper.scenario("fig14"),
        vary={"admittance.b": (100.0, 3000.0), "admittance.ka": (0.2, 5.0)},
        over={"wall.stiffness": (1e4, 1e5)},
        max_overshoot_pct=15.0, grid=7, refine=1, verify_duration=6.0,
    )  # fmt: skip
    assert set(res.gains) == {"admittance.b", "admittance.ka"}
    assert 100 <= res.gains["admittance.b"] <= 3000 and 0.2 <= res.gains["admittance.ka"] <= 5
    assert res.predicted["stable"].all()
    assert (res.predicted["spectral_radius"] <= 1 - res.stability_margin).all()
    assert (res.predicted["overshoot_pct"] <= 15.0).all()
    v = res.verification
    assert v["point"].to_list() == ["corner", "corner", "centre"]
    assert v["stable"].all() and (v["overshoot_pct"] <= 15.0).all()
    assert v["stable_with_motion"].all()
    assert res.verified and "-> verified" in res.summary()
    # Checked independently of tune: the gains at both corners, simulated here.
    for ke in (1e4, 1e5):
        r = ar.simulate(ar.paper.scenario("fig14").replace(
            z_reference=HOLD, duration=6.0, **res.gains, **{"wall.stiffness": ke}))  # fmt: skip
        assert r.stable and r.metrics["overshoot_pct"] <= 15.0


def test_bad_input_gives_clear_errors():
    out_of_reach = ar.paper.scenario("fig14").replace(**{"wall.position": 3.0})
    with pytest.raises(ar.AnalysisError, match="no contact equilibrium"):
        ar.analysis.linearize(out_of_reach)
    # predict answers it (SPEC §23): a loop that cannot hold contact is predicted unstable.
    p = ar.analysis.predict(out_of_reach)
    assert p["stable"] is False and math.isnan(p["spectral_radius"])
    assert p["verdict"].startswith("unstable: no contact equilibrium: ")
    with pytest.raises(ar.AnalysisError, match="singular"):
        ar.analysis.linearize(ideal_loop(**{"admittance.ka": 0.0, "admittance.k": 0.0,
                                            "wall.position_error": 1e-3}))  # fmt: skip
    with pytest.raises(ar.AnalysisError, match="no wall"):
        ar.analysis.linearize(ar.paper.scenario("fig5"))
    with pytest.raises(ar.AnalysisError, match="Coulomb"):
        ar.analysis.linearize(ar.paper.scenario("fig14").replace(
            **{"robot.friction_smoothing": 0.0}))  # fmt: skip
    with pytest.raises(ar.ParameterError, match="numeric parameter"):
        ar.analysis.stability_map(ar.paper.scenario("fig14"), x={"wall.model": [1, 2]},
                                  y={"admittance.b": [800.0]})  # fmt: skip
    with pytest.raises(ar.ParameterError, match="sequence of numbers"):
        ar.analysis.stability_map(ar.paper.scenario("fig14"), x={"wall.stiffness": ["a"]},
                                  y={"admittance.b": [800.0]})  # fmt: skip
    with pytest.raises(TypeError, match="no such parameter"):
        ar.analysis.stability_map(ar.paper.scenario("fig14"), x={"wall.stifness": [1e4]},
                                  y={"admittance.b": [800.0]})  # fmt: skip
    with pytest.raises(ar.ParameterError, match="lo <= hi"):
        ar.analysis.tune(ar.paper.scenario("fig14"), vary={"admittance.b": (900.0, 100.0)},
                         over={"wall.stiffness": (1e4, 1e5)})  # fmt: skip
    with pytest.raises(TypeError):
        ar.analysis.predict("fig14")


def test_predict_fields_and_friction_options():
    sc = ar.paper.scenario("fig14")
    rest = ar.analysis.predict(sc, friction="rest")
    assert list(rest) == [*ar.analysis.PREDICTION_NAMES, "friction_amplitude", "verdict",
                          "passed", "force_oscillation", "contact_loss", "tolerance_verdict"]
    assert rest["stable"] and rest["spectral_radius"] < 1 and rest["friction_amplitude"] == 0
    assert rest["rise_time_63"] > 0 and rest["settling_time"] > rest["rise_time_63"]
    step = ar.analysis.predict(sc)
    assert step == ar.analysis.predict(sc, friction="step")  # the default
    # The peak joint speed of the step transient, well above ε = 0.01 rad/s.
    assert 0.02 < step["friction_amplitude"] < 0.2
    assert step["stable"] and step["overshoot_pct"] != rest["overshoot_pct"]
    assert ar.analysis.friction_gain(1e-9, 0.01) == pytest.approx(1.0)
    assert ar.analysis.friction_gain(1.0, 0.01) == pytest.approx(4 * 0.01 / math.pi, rel=0.02)
    with pytest.raises(ValueError, match="friction"):
        ar.analysis.predict(sc, friction="sliding")


def test_caveats_say_what_the_model_leaves_out():
    sc = ar.paper.scenario("fig14").replace(
        sensor=ar.ForceSensor(noise_std=0.5, resolution=0.01, cutoff=30.0, latency=2),
        actuator=ar.Actuator(torque_limit=(200.0, 200.0, 200.0), rate_limit=1e4, delay=1),
    )
    sys = ar.analysis.linearize(sc)
    text = " | ".join(sys.caveats)
    assert "noise is off" in text and "resolution is not modelled" in text
    assert "saturation is inactive" in text and "rate limit is inactive" in text
    # Latency, the low-pass and the actuator delay are states of the model.
    assert {"sensor.filtered", "sensor.in_flight2", "actuator.in_flight1_3"} <= set(
        sys.state_labels)  # fmt: skip
    assert ar.analysis.predict(sc)["stable"]
    # About a running state (not a fixed point): references held at t.
    at = ar.analysis.linearize(ar.paper.scenario("fig14"), at=0.05)
    assert not at.equilibrium and at.nstates == 18
    with pytest.raises(ar.ParameterError, match="at = 20"):
        ar.analysis.linearize(ar.paper.scenario("fig14"), at=20.0)


def _held_grid() -> tuple[ar.Scenario, dict, dict]:
    """Issue #21's grid: fig. 14 with the motion held, k_e 1e4-1e6 × b 100-800 (6 × 4)."""
    ke = [float(v) for v in np.geomspace(1e4, 1e6, 6)]
    return fig14(), {"wall.stiffness": ke}, {"admittance.b": [100.0, 200.0, 400.0, 800.0]}


def test_the_default_prediction_is_the_validated_linearisation():
    sc, x, y = _held_grid()
    p, s = _agreement(sc, x, y, duration=10.0)
    # ar.analysis.predict's default (friction="step", Margins()) agrees on every cell ...
    default = ar.analysis.stability_map(sc.replace(duration=10.0), x=x, y=y)
    assert default["stable"].to_list() == ar.analysis.stability_map(
        sc.replace(duration=10.0), x=x, y=y, friction="step")["stable"].to_list()
    assert (p == s).all(), (p, s)
    assert p.any() and not p.all()
    # ... where friction at rest (SPEC §12's small-signal slope) calls bouncing cells
    # stable: 6 by ρ < 1 alone (the count), 4 even with the margins.
    rest = ar.analysis.stability_map(sc.replace(duration=10.0), x=x, y=y, friction="rest")
    optimistic = rest["stable"].to_numpy() & ~s.ravel()
    assert optimistic.sum() == 4 and (rest["stable"].to_numpy() == s.ravel()).sum() == 20
    rho = (rest["spectral_radius"].to_numpy() < 1) & ~s.ravel()
    assert rho.sum() == 6


ITEM2 = fig14().replace(**{"wall.stiffness": 1e6, "admittance.b": 3000.0, "sensor.latency": 1})


def test_stable_requires_margins_not_only_a_spectral_radius_below_1():
    p = ar.analysis.predict(ITEM2)
    assert p["spectral_radius"] == pytest.approx(0.99865, abs=1e-5)
    assert p["dominant_frequency"] == pytest.approx(63.7, abs=0.1)
    assert p["dominant_damping"] == pytest.approx(0.0034, abs=1e-4)
    assert p["stable"] is False
    assert p["verdict"].startswith("insufficient margin (ρ = 0.998653 < 1): damping ratio ζ "
                                   "0.00337 < 0.05; gain margin 1.02 < 1.1; phase margin 0.6")
    # ... and the simulator agrees that it is not a stable run: it loses contact.
    res = ar.simulate(ITEM2)
    assert res.stable is False and res.metrics["contact_loss"] > 0.6
    # The margins are the user's: ρ < 1 alone calls it stable.
    loose = ar.analysis.Margins(min_damping=0.0, min_gain_margin=1.0, min_phase_margin=0.0,
                                min_delay_margin=0.0)
    assert ar.analysis.predict(ITEM2, margins=loose)["stable"] is True
    with pytest.raises(ar.ParameterError, match="min_gain_margin"):
        ar.analysis.Margins(min_gain_margin=0.5)


@pytest.mark.parametrize("sc", [ar.paper.scenario("fig14"), ITEM2], ids=["fig14", "item2"])
def test_margins_equal_python_control_on_the_force_loop(sc):
    """Gain, phase and delay margins of the loop cut at the filter input, against
    python-control's stability_margins on a dense frequency response of sys.force_loop."""
    import control

    p = ar.analysis.predict(sc)
    sys = ar.analysis.linearize(sc, friction="step")
    loop = sys.force_loop
    # The loop closes to the linearisation: A = A0 − B c̃.
    assert np.allclose(loop.A - loop.B @ loop.C, sys.A, rtol=0, atol=1e-12 * abs(sys.A).max())
    w = np.geomspace(1e-3, np.pi / sc.period, 20_000)
    gm, pm, _, _, wgc, _ = control.stability_margins(control.frd(loop, w))
    assert p["gain_margin"] == pytest.approx(gm, rel=1e-4)
    assert p["phase_margin"] == pytest.approx(pm, rel=1e-4, abs=1e-3)
    delay = math.radians(pm) / wgc / sc.period
    assert p["delay_margin"] == pytest.approx(delay, rel=1e-3)


def test_tune_reports_the_true_worst_case_over_every_verified_point(capsys):
    """Issue #21 item 3: the box's centre is predicted at 10.34 % and simulated at 16.75 %;
    the summary's worst case is over every point, predicted and simulated, and says why
    the answer is not verified."""
    from admit_rs import cli

    argv = ["tune", "fig14", "--vary", "admittance.b=100:3000",
            "--over", "wall.stiffness=1e4:1e5"]  # fmt: skip
    assert cli.main(argv) == 3
    out = " ".join(capsys.readouterr().out.split())  # as read, whatever the terminal's width
    res = ar.analysis.tune(ar.paper.scenario("fig14"), vary={"admittance.b": (100, 3000)},
                           over={"wall.stiffness": (1e4, 1e5)})  # fmt: skip
    v = res.verification
    centre = v.filter(pl.col("point") == "centre").row(0, named=True)
    predicted = max(res.predicted["overshoot_pct"].max(), v["predicted_overshoot_pct"].max())
    assert res.worst("overshoot_pct") == (predicted, v["overshoot_pct"].max())
    assert predicted == pytest.approx(centre["predicted_overshoot_pct"]) == pytest.approx(
        10.34, abs=0.01)
    assert centre["overshoot_pct"] == pytest.approx(16.75, abs=0.01)
    assert "worst overshoot 10.34 %" in out and "worst overshoot 16.75 % (limit 10 %)" in out
    assert "NOT verified" in out and not res.verified
    assert "wall.stiffness = 3.162e+04 (centre), motion held: overshoot 16.75 % > 10 %" in (
        res.summary())
    assert ("centre: wall.stiffness = 3.162e+04 motion held: stable, passed; overshoot "
            "16.75 % (10.34 %) > 10 %") in out  # fmt: skip
    # The ripple with the motion is driven: out of tolerance, stable (SPEC §23).
    assert ("with motion: stable, not passed: out of tolerance: force oscillation, contact "
            "kept") in out  # fmt: skip
    assert v.filter(pl.col("point") == "centre")["stable_with_motion"].item() is True


@pytest.mark.parametrize(
    ("name", "value", "allowed"),
    [("grid", 0, "from 2 to 100"), ("grid", 1, "from 2 to 100"), ("grid", 2.5, "from 2 to 100"),
     ("grid", True, "from 2 to 100"), ("over_points", 0, "from 1 to 100"),
     ("refine", -1, "from 0 to 20"), ("corrections", -1, "from 0 to 20"),
     ("grid", 10**9, "from 2 to 100")],
)
def test_tune_refuses_counts_out_of_range_naming_them(name, value, allowed):
    """Issue #53, item 15: grid=0 gave "attempt to get argmin of an empty sequence",
    refine=-1 an empty AssertionError."""
    sc = ar.paper.scenario("fig14").replace(duration=2.0)
    with pytest.raises(ar.ParameterError) as info:
        ar.analysis.tune(sc, {"admittance.b": (100, 1000)}, {"wall.stiffness": (1e4, 1e5)},
                         verify=False, **{name: value})  # fmt: skip
    assert info.value.field == name and allowed in info.value.allowed


def test_linearize_at_a_time_names_what_it_cannot_do():
    """Issue #53 item 9: at=NaN blamed z_reference.value; with a guarded approach the run's
    state did not fit the linear model ("state = 23 values ... must be 19")."""
    sc = ar.paper.scenario("fig14")
    for at in (math.nan, -1.0, 11.0, math.inf):
        with pytest.raises(ar.ParameterError, match=r"at = .* is invalid: must be a time of the"
                           r" run, from 0 to its duration 10 s, or None") as info:  # fmt: skip
            ar.analysis.linearize(sc, at=at)
        assert info.value.field == "at"
    guarded = sc.replace(approach=ar.GuardedApproach(), **{"wall.gap": 0.01})
    with pytest.raises(ar.AnalysisError, match=r"linearize\(at=\.\.\.\) with a guarded approach"
                       r" is not supported"):  # fmt: skip
        ar.analysis.linearize(guarded, at=1.0)
    assert ar.analysis.linearize(sc, at=1.0).nstates == 18
