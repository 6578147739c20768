"""The loop as stages (SPEC §10): walls of any orientation and damping, force sensors,
actuators, stepping and the explicit state, each against an independent answer."""

import math

import admit_rs as ar
import numpy as np
import polars as pl
import pytest
from scipy import signal

# An ideal inner loop: computed torque with the true model, contact compensation and fast
# gains (SPEC §9's tests), so the force loop behaves like its closed form.
IDEAL = ar.ComputedTorque(command_divisor=1.0, kp=1e4, kd=200.0, contact_compensation=True)


def ideal_scenario(**changes):
    sc = ar.Scenario(controller=IDEAL, z_reference=ar.Step(value=0.0), duration=3.0)
    return sc.replace(**changes)


# -- one source of truth for defaults: tests/test_schema.py -------------------------------


# -- environment -------------------------------------------------------------------------


def tilted_wall(**kw):
    a = math.radians(30)
    # e_x rotated 30° about y.
    return ar.Wall(normal=(math.cos(a), 0.0, -math.sin(a)), **kw)


def test_tilted_wall_force_settles_on_fd_along_n():
    sc = ideal_scenario(
        wall=tilted_wall(), admittance=ar.AdmittanceFilter.scheme2(b=800, ka=0.1), duration=10.0
    )
    r = ar.simulate(sc)
    assert r.stable
    assert abs(r.trace["f"][-1] - 10.0) < 1e-6
    # The force is along n: the penetration times k_e is the force.
    last = r.trace.row(-1, named=True)
    assert last["f"] == pytest.approx(30_000.0 * last["penetration"], rel=1e-12)


def test_tilted_wall_motion_follows_the_tangent():
    a = math.radians(30)
    n = np.array([math.cos(a), 0.0, -math.sin(a)])
    t_hat = np.array([math.sin(a), 0.0, math.cos(a)])  # normalise(e_z − (e_z·n) n)
    sc = ideal_scenario(
        wall=tilted_wall(),
        admittance=ar.AdmittanceFilter.scheme2(b=800, ka=0.1),
        z_reference=ar.Sine(amplitude=0.05),
        duration=5.0,
    )
    r = ar.simulate(sc)
    tr = r.trace
    xyz = tr.select("x", "y", "z").to_numpy()
    ref = tr.select("x_ref", "y_ref", "z_ref").to_numpy()
    s = 0.05 * np.sin(tr["t"].to_numpy())
    along_t = (xyz - xyz[0]) @ t_hat
    # The reference moves along t̂ by s(t) and along n by x̂_e + x_a only.
    np.testing.assert_allclose((ref - xyz[0]) @ t_hat, s, atol=1e-12)
    np.testing.assert_allclose(ref[:, 1], xyz[0, 1], atol=1e-15)
    # The tip follows: within 0.1 mm along t̂ once the start-up lag is gone (the sine starts
    # at 0.05 m/s with the arm at rest), nothing out of the plane (y).
    settled = tr["t"].to_numpy() > 0.5
    assert np.max(np.abs(along_t - s)[settled]) < 1e-4
    assert np.max(np.abs(xyz[:, 1])) < 1e-9
    # Through the motion the force stays near f_d (after the first contact transient).
    late = tr["t"].to_numpy() > 2.0
    assert np.max(np.abs(tr["f"].to_numpy()[late] - 10.0)) < 0.5
    assert np.all(np.abs((xyz - xyz[0]) @ n - tr["penetration"].to_numpy()) < 1e-12)


@pytest.mark.parametrize("c", [0.0, 20.0, 100.0])
def test_damped_wall_step_response_matches_the_closed_form(c):
    """F/F_d = k_a (k_e + c s) / (m s² + (b + k_a c) s + k_a k_e) with x = x_d."""
    m, b, ka, ke = 10.0, 200.0, 0.1, 30_000.0
    sc = ideal_scenario(
        wall=ar.Wall(stiffness=ke, damping=c), admittance=ar.AdmittanceFilter(m=m, b=b, k=0, ka=ka)
    )
    tr = ar.simulate(sc).trace
    t, f = tr["t"].to_numpy(), tr["f"].to_numpy()
    fine = np.linspace(0.0, 3.0, 300_001)
    num = [ka * c, ka * ke] if c else [ka * ke]
    _, y = signal.step(signal.lti(num, [m, b + ka * c, ka * ke]), T=fine)
    y = 10.0 * y
    rise_sim, rise_cf = t[np.argmax(f >= 6.32)], fine[np.argmax(y >= 6.32)]
    assert rise_sim == pytest.approx(rise_cf, rel=0.05)
    assert f.max() == pytest.approx(y.max(), rel=0.05)
    # The closed form's overshoot changes with c; so does the simulated one.
    assert y.max() > 10.5


def test_hunt_crossley_force_is_continuous_and_settles():
    sc = ideal_scenario(
        wall=ar.Wall(stiffness=3e6, damping=5e4, model="hunt_crossley", exponent=1.5),
        admittance=ar.AdmittanceFilter.scheme2(b=800, ka=0.1),
        duration=10.0,
    )
    r = ar.simulate(sc)
    tr = r.trace.row(-1, named=True)
    assert r.stable and abs(tr["f"] - 10.0) < 1e-4
    assert tr["f"] == pytest.approx(3e6 * tr["penetration"] ** 1.5, rel=1e-3)


def test_zero_normal_is_a_parameter_error():
    with pytest.raises(ar.ParameterError, match=r"normal = \[0.0, 0.0, 0.0\]"):
        ar.Wall(normal=(0, 0, 0))


# -- force sensor ------------------------------------------------------------------------


def test_bias_shifts_the_true_steady_force():
    sc = ideal_scenario(
        admittance=ar.AdmittanceFilter.scheme2(b=800, ka=0.1),
        sensor=ar.ForceSensor(bias=1.5),
        duration=10.0,
    )
    tr = ar.simulate(sc).trace
    assert abs(tr["f"][-1] - (10.0 - 1.5)) < 1e-6
    assert abs(tr["f_measured"][-1] - 10.0) < 1e-6


def expected_reading(f, *, bias, resolution, alpha, latency):
    u = f + bias
    if resolution:
        u = np.round(u / resolution) * resolution
    y = np.empty_like(u)
    y[0] = u[0]
    for k in range(1, len(u)):
        y[k] = y[k - 1] + alpha * (u[k] - y[k - 1])
    out = np.empty_like(y)
    out[:latency] = y[0]
    out[latency:] = y[: len(y) - latency]
    return out


def test_measured_force_is_the_processed_force_delayed():
    sensor = ar.ForceSensor(bias=0.2, resolution=0.01, cutoff=30.0, latency=3)
    tr = ar.simulate(ar.paper.scenario("fig14").replace(sensor=sensor, duration=2.0)).trace
    alpha = 1 - math.exp(-2 * math.pi * 30.0 * 1e-3)
    want = expected_reading(
        tr["f"].to_numpy(), bias=0.2, resolution=0.01, alpha=alpha, latency=3
    )
    np.testing.assert_allclose(tr["f_measured"].to_numpy(), want, rtol=0, atol=1e-12)


def test_low_pass_follows_its_recursion_in_a_run():
    """y_k = y_{k−1} + α (f_k − y_{k−1}); its unit-step response 1 − (1 − α)^k is checked
    sample by sample in the core's unit tests (sensor.rs)."""
    sensor = ar.ForceSensor(cutoff=30.0)
    tr = ar.simulate(ar.paper.scenario("fig14").replace(sensor=sensor, duration=0.5)).trace
    f, y = tr["f"].to_numpy(), tr["f_measured"].to_numpy()
    alpha = 1 - math.exp(-2 * math.pi * 30.0 * 1e-3)
    assert y[0] == f[0]
    np.testing.assert_allclose(y[1:] - y[:-1], alpha * (f[1:] - y[:-1]), rtol=0, atol=1e-12)
    assert np.max(np.abs(y - f)) > 0.1  # the filter did something


def test_noise_statistics_and_seeds():
    sc = ar.paper.scenario("fig14").replace(sensor=ar.ForceSensor(noise_std=0.5), seed=7)
    a = ar.simulate(sc).trace
    noise = (a["f_measured"] - a["f"]).to_numpy()
    assert len(noise) == 10_001
    assert np.std(noise) == pytest.approx(0.5, rel=0.05)
    assert abs(np.mean(noise)) < 0.02
    again = ar.simulate(sc).trace
    assert a.equals(again)
    other = ar.simulate(sc.replace(seed=8)).trace
    assert not np.array_equal(other["f_measured"].to_numpy(), a["f_measured"].to_numpy())


def test_sweep_with_noise_is_bit_identical_on_any_threads_and_resumed(tmp_path):
    base = ar.paper.scenario("fig19").replace(
        sensor=ar.ForceSensor(noise_std=0.3, cutoff=50.0, latency=1), duration=1.2
    )
    kw = {"vary": {"wall.stiffness": ar.LogUniform(1e4, 1e5)}, "samples": 12, "seed": 3,
          "progress": False}
    one = ar.sweep(base, threads=1, **kw)
    two = ar.sweep(base, threads=2, **kw)
    assert one.equals(two)
    ck = tmp_path / "ck"
    first = ar.sweep(base, threads=2, chunk_size=5, checkpoint=ck, **kw)
    (ck / "chunk-000001.parquet").unlink()  # lose a chunk: it is recomputed on resume
    resumed = ar.sweep(base, threads=1, chunk_size=5, checkpoint=ck, **kw)
    assert first.equals(one) and resumed.equals(one)
    # Each run's noise seed reproduces the run alone: to SPEC §13's 1e-9, as lanes and a
    # single run differ in e^x's last bits (another seed's noise moves it by 1e-2).
    row = one.row(4, named=True)
    alone = ar.simulate(
        base.replace(seed=row["noise_seed"], **{"wall.stiffness": row["wall.stiffness"]})
    )
    assert alone.metrics["force_rms_error"] == pytest.approx(row["force_rms_error"], rel=1e-9)
    other = ar.simulate(
        base.replace(seed=row["noise_seed"] + 1, **{"wall.stiffness": row["wall.stiffness"]})
    )
    assert other.metrics["force_rms_error"] != pytest.approx(row["force_rms_error"], rel=1e-4)
    assert one["noise_seed"].n_unique() == 12


# -- actuator ----------------------------------------------------------------------------


def test_actuator_limits_hold_at_every_sample():
    limits = np.array([60.0, 40.0, 20.0])
    rate = 2_000.0
    act = ar.Actuator(torque_limit=tuple(limits), rate_limit=rate, delay=2)
    r = ar.simulate(ar.paper.scenario("fig19").replace(actuator=act, duration=3.0))
    tau = r.trace.select("tau1", "tau2", "tau3").to_numpy()
    cmd = r.trace.select("tau_cmd1", "tau_cmd2", "tau_cmd3").to_numpy()
    assert np.all(np.abs(tau) <= limits)
    assert np.all(np.abs(np.diff(tau, axis=0)) <= rate * 1e-3 * (1 + 1e-12))
    assert np.any(np.abs(cmd) > limits)  # the limits were reached
    assert r.metrics["torque_saturation"] > 0


def test_tdc_memory_holds_the_applied_torque():
    act = ar.Actuator(torque_limit=(60.0, 40.0, 20.0))
    sim = ar.Simulation(ar.paper.scenario("fig19").replace(actuator=act, duration=1.0))
    saw_limit = False
    for _ in range(200):
        sim.step(1)
        st = sim.state
        last = sim.trace.row(-1, named=True)
        applied = [last[f"tau{j}"] for j in (1, 2, 3)]
        assert [st[f"controller.tau_prev{j}"] for j in (1, 2, 3)] == applied
        assert [st[f"actuator.applied{j}"] for j in (1, 2, 3)] == applied
        saw_limit |= any(last[f"tau_cmd{j}"] != last[f"tau{j}"] for j in (1, 2, 3))
    assert saw_limit


def test_bad_actuator_and_sensor_values_name_the_field():
    with pytest.raises(ar.ParameterError, match=r"torque_limit\[1\] = -1"):
        ar.Actuator(torque_limit=(5, -1, 5))
    with pytest.raises(ar.ParameterError, match="latency = 2.5"):
        ar.ForceSensor(latency=2.5)
    # Two limits fit a two-joint arm, not the three-link one: the scenario says so.
    with pytest.raises(ar.ParameterError, match=r"torque_limit = \[1.0, 2.0\] .* one per joint"):
        ar.Scenario(actuator=ar.Actuator(torque_limit=(1.0, 2.0)))
    with pytest.raises(ar.ParameterError, match=r"torque_limit = .* one per joint"):
        ar.Actuator(torque_limit=tuple(range(1, 11)))


# -- stepping and state ------------------------------------------------------------------


def noisy_limited():
    return ar.paper.scenario("fig14").replace(
        sensor=ar.ForceSensor(noise_std=0.5, cutoff=30.0, latency=2),
        actuator=ar.Actuator(torque_limit=(60, 40, 20), rate_limit=2e4, delay=1),
        wall=ar.Wall(damping=50.0),
        duration=1.0,
    )


def test_stepping_equals_simulate_bit_for_bit():
    sc = noisy_limited()
    whole = ar.simulate(sc)
    sim = ar.Simulation(sc)
    taken = [sim.step(n) for n in (1, 7, 300, 5000)]
    assert taken == [1, 7, 300, 693] and sim.done
    assert sim.trace.equals(whole.trace)
    res = sim.result()
    assert res.stable == whole.stable and res.metrics.keys() == whole.metrics.keys()
    for name, value in whole.metrics.items():
        assert res.metrics[name] == value or (math.isnan(value) and math.isnan(res.metrics[name]))


def test_set_state_round_trips_and_resumes():
    sc = noisy_limited()
    whole = ar.simulate(sc).trace
    sim = ar.Simulation(sc)
    sim.step(400)
    saved = sim.state
    assert saved["sample"] == 400 and list(saved) == sim.state_labels
    assert {"plant.q1", "filter.x_a", "controller.tau_prev1", "sensor.in_flight2",
            "actuator.in_flight1_3"} <= set(saved)
    sim.step(600)
    sim.set_state(saved)
    assert sim.state == saved and sim.trace.height == 400
    sim.step(10_000)
    assert sim.trace.equals(whole)
    # Perturb and resume: a kick changes what follows, and only that.
    sim.set_state(saved)
    sim.set_state({"plant.qd2": saved["plant.qd2"] + 0.05})
    sim.step(10_000)
    kicked = sim.trace
    assert kicked[:400].equals(whole[:400])
    assert not kicked["q2"].equals(whole["q2"])


def test_state_errors():
    sim = ar.Simulation(ar.paper.scenario("fig14"))
    with pytest.raises(KeyError, match="plant.qd2"):
        sim.set_state({"plant.qdd2": 1.0})
    with pytest.raises(ar.ParameterError, match="state = 3 values"):
        sim.set_state([1.0, 2.0, 3.0])
    with pytest.raises(ar.AdmitError, match="not over"):
        sim.result()


def test_new_fields_by_dotted_path_and_toml():
    sc = ar.Scenario().replace(
        **{"sensor.noise_std": 0.2, "actuator.delay": 2, "wall.damping": 10.0, "seed": 5}
    )
    assert sc.sensor.noise_std == 0.2 and sc.actuator.delay == 2 and sc.seed == 5
    back = ar.Scenario.from_dict(sc.to_dict())
    assert back == sc
    table = ar.sweep(
        sc.replace(duration=0.2),
        grid={"sensor.latency": [0, 3], "actuator.torque_limit": [None, 30.0]},
        progress=False,
    )
    assert table.height == 4 and table["stable"].all()
    assert pl.Series(table["sensor.latency"]).to_list() == [0, 0, 3, 3]


def test_set_state_refuses_a_bool():
    """Issue #53, item 17: set_state({"sample": True}) was sample 1."""
    sim = ar.Simulation(ar.paper.scenario("fig14").replace(duration=0.1))
    sim.step(10)
    with pytest.raises(ar.ParameterError) as info:
        sim.set_state({"sample": True})
    assert info.value.field == "sample"
    with pytest.raises(ar.ParameterError):
        sim.set_state([True] + [0.0] * (len(sim.state_labels) - 1))
    assert sim.sample == 10
