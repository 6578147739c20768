"""ar.identify (issue #58 part 2, SPEC §21): a recorded cell fitted back from its log.

The logs are made by examples/identify_cell.py, independently of identify's code: the Panda
pressing and sliding on a wall simulated by admit_rs (the true contact force, its joints), and
the flange sensor applied in numpy from its definition (SPEC §10, §15: the force and the
tool's weight in the tip frame, bias, white noise, a first-order low-pass started at u_0, a
latency holding y_0). Every true value must lie in its interval and near the value fitted."""

from __future__ import annotations

import dataclasses
import importlib.util
import math
from pathlib import Path
from typing import Any

import admit_rs as ar
import numpy as np
import polars as pl
import pytest
from admit_rs.errors import ArgumentError, ParameterTypeError
from admit_rs.identification.check import check
from admit_rs.identification.fitter import Fitter
from admit_rs.identification.least_squares import ar1_inflation, low_pass_delay
from admit_rs.identification.log_arrays import LogArrays
from admit_rs.identification.model import STICTION_VELOCITY

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("identify_cell",
                                               ROOT / "examples" / "identify_cell.py")  # fmt: skip
assert _spec is not None and _spec.loader is not None
cell = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cell)
ARM, SENSOR, PERIOD = cell.ARM, cell.SENSOR, cell.PERIOD


def table(t: np.ndarray, q: np.ndarray, reading: np.ndarray) -> pl.DataFrame:
    cols: dict[str, Any] = {"t": t}
    for i, j in enumerate(ARM.joint_names):
        cols[f"q.{j}"] = q[:, i]
    for i, c in enumerate(("fx", "fy", "fz")):
        cols[c] = reading[:, i]
    return pl.DataFrame(cols)


def pressing(wall: ar.Wall, seed: int = 1) -> tuple[pl.DataFrame, ar.Result]:
    """4 s of the Panda: a 5 mm approach, 10 N on the wall, sliding ±5 cm along it."""
    return cell.recording(wall, seed)  # type: ignore[no-any-return]


KV_WALL = cell.WALL


@pytest.fixture(scope="module")
def kv() -> tuple[ar.CellFit, ar.Result, pl.DataFrame]:
    log, run = pressing(KV_WALL)
    return ar.identify(log, ARM), run, log


def within(fit: ar.CellFit, path: str, truth: float) -> None:
    lo, hi = fit.intervals[path]
    assert lo <= truth <= hi, f"{path}: {truth} not in [{lo}, {hi}] ({fit.how[path]})"


def test_a_pressed_wall_and_its_sensor_come_back_within_their_intervals(kv: Any) -> None:
    fit, run, _ = kv
    tr = run.trace
    touching = tr["f"].to_numpy() > 0
    x = tr.select("x", "y", "z").to_numpy()
    # The true plane: n = e_x, x_e where the penetration is zero.
    position = float(np.mean(x[touching, 0] - tr["penetration"].to_numpy()[touching]))
    for path, truth in (("wall.stiffness", 3e4), ("wall.damping", 30.0), ("wall.friction", 0.3),
                        ("sensor.latency", 3), ("sensor.cutoff", 60.0),
                        ("sensor.noise_std", 0.2)):  # fmt: skip
        within(fit, path, truth)
    v = fit.values
    # The fitted plane n·X = x_e (n tilted by a milliradian or so) where the tool touched:
    # its x there, and its interval's, hold the true plane's.
    n = np.asarray(v["wall.normal"])
    centre = x[touching].mean(axis=0)

    def x_at(xe: float) -> float:
        return float((xe - n[1] * centre[1] - n[2] * centre[2]) / n[0])

    lo, hi = fit.intervals["wall.position"]
    assert x_at(lo) <= position <= x_at(hi), (x_at(lo), position, x_at(hi))
    assert v["wall.model"] == "kelvin_voigt"
    assert abs(v["wall.stiffness"] / 3e4 - 1) < 0.05
    assert abs(v["wall.friction"] - 0.3) < 0.003
    assert abs(x_at(v["wall.position"]) - position) < 2e-6
    assert math.degrees(math.acos(v["wall.normal"][0])) < 0.1
    for a in (1, 2):  # the tilts towards y and z; n_x = cos(tilt) moves at second order
        lo, hi = fit.intervals["wall.normal"][a]
        assert lo <= 0.0 <= hi, (a, lo, hi)
    # One orientation in free space: the bias holds the weight, the mass is not guessed.
    weight_in_tip = np.asarray(ARM.dynamics(ARM.q0)["rotation"]).T @ [0, 0, 0.5 * ARM.gravity]
    for a in range(3):
        lo, hi = fit.intervals["sensor.bias"][a]
        assert lo <= SENSOR["bias"][a] + weight_in_tip[a] <= hi
    assert "one orientation" in fit.unidentified["sensor.tool_mass"]
    assert "six-axis" in fit.unidentified["tool.com"]
    assert fit.trustworthy and fit.doubts == ()


def test_the_log_is_segmented_where_the_tool_touches(kv: Any) -> None:
    fit, run, _ = kv
    phases = fit.segments["phase"].to_numpy()
    touching = run.trace["f"].to_numpy() > 0
    first = int(np.argmax(touching))
    # Free until the first touch (within the sensor's lag and the 50-ms guard band).
    assert np.all(phases[: first - 60] == "free")
    assert phases[first + 20] == "impact"
    assert np.all(phases[first + 100 :] == "contact")


def test_the_tool_turned_in_free_space_gives_its_mass_and_the_bias() -> None:
    t = np.arange(0.0, 4.0, PERIOD)
    q = np.tile(np.asarray(ARM.q0, dtype=float), (len(t), 1))
    q[:, 4] += 0.8 * np.sin(2 * np.pi * t / 4)
    q[:, 5] += 0.6 * np.sin(4 * np.pi * t / 4)
    q[:, 6] += 1.0 * np.sin(2 * np.pi * t / 4 + 1)
    rotation = np.array([ARM.dynamics(qk)["rotation"] for qk in q])
    reading = cell.sensor_reading(rotation, np.zeros((len(t), 3)), 2)
    fit = ar.identify(table(t, q, reading), ARM)
    within(fit, "sensor.tool_mass", 0.5)
    assert abs(fit.values["sensor.tool_mass"] - 0.5) < 0.005
    for a in range(3):
        lo, hi = fit.intervals["sensor.bias"][a]
        assert lo <= SENSOR["bias"][a] <= hi
    # No cut-off identified: the noise as read, σ √(α/(2 − α)).
    alpha = 1 - math.exp(-2 * math.pi * 60.0 * PERIOD)
    within(fit, "sensor.noise_std", 0.2 * math.sqrt(alpha / (2 - alpha)))
    for path in ("wall.stiffness", "wall.friction", "sensor.latency"):
        assert "no contact" in fit.unidentified[path]
    assert set(fit.segments["phase"].unique()) == {"free"}
    assert fit.trustworthy, fit.doubts


def test_pressing_without_sliding_leaves_friction_unidentified() -> None:
    log, _ = cell.recording(slide=False, seed=4)
    fit = ar.identify(log, ARM)
    assert "did not slide" in fit.unidentified["wall.friction"]
    within(fit, "wall.stiffness", 3e4)


def test_noise_ten_times_the_force_is_not_trusted(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(cell.SENSOR, "noise", 100.0)  # σ = 100 N against a 10 N contact
    log, _ = cell.recording(seed=5)
    fit = ar.identify(log, ARM)
    assert not fit.trustworthy
    assert "not trustworthy" in fit.doubts[0] and "NOT TRUSTWORTHY" in str(fit)


def test_a_hunt_crossley_wall_is_told_from_kelvin_voigt() -> None:
    wall = ar.Wall(stiffness=3e6, damping=2000.0, model="hunt_crossley", exponent=1.5,
                   friction=0.3, gap=0.005)  # fmt: skip
    log, _ = pressing(wall, seed=3)
    fit = ar.identify(log, ARM)
    assert fit.values["wall.model"] == "hunt_crossley", fit.how["wall.model"]
    within(fit, "wall.exponent", 1.5)
    within(fit, "wall.stiffness", 3e6)
    within(fit, "wall.friction", 0.3)
    within(fit, "sensor.latency", 3)


def test_a_fit_becomes_a_scenario_and_a_box(kv: Any) -> None:
    fit, run, log = kv
    sc = fit.scenario(cell.base_scenario())
    assert isinstance(sc.wall, ar.Wall)
    assert sc.wall.stiffness == fit.values["wall.stiffness"]
    assert sc.wall.position == fit.values["wall.position"] and sc.wall.gap == 0.0
    assert sc.sensor.frame == "tip" and sc.sensor.latency == fit.values["sensor.latency"]
    # The fitted cell behaves as the true one: the same controller fed the same kind of
    # reading (bias, weight, noise, low-pass, latency; neither compensates the weight)
    # holds the same force, and peaks alike.
    fitted, truth = ar.simulate(sc).trace, ar.simulate(cell.true_cell()).trace
    last = truth["t"].to_numpy() >= 3.0
    held = float(truth["f"].to_numpy()[last].mean())
    assert abs(float(fitted["f"].to_numpy()[last].mean()) - held) < 0.01 * held
    assert abs(float(fitted["f"].max()) - float(truth["f"].max())) < 0.05 * float(truth["f"].max())
    box = fit.box()
    assert isinstance(box["wall.stiffness"], ar.LogUniform)
    assert (box["wall.stiffness"].low, box["wall.stiffness"].high) == fit.intervals[
        "wall.stiffness"]  # fmt: skip
    assert "sensor.latency" not in box and "wall.normal" not in box
    swept = ar.sweep(sc, vary={"wall.stiffness": box["wall.stiffness"]}, samples=2, seed=0,
                     progress=False)  # fmt: skip
    lo, hi = fit.intervals["wall.stiffness"]
    assert swept["wall.stiffness"].is_between(lo, hi).all()
    text = str(fit)
    assert "wall.stiffness" in text and "unidentified" in text


def test_a_long_log_mostly_in_contact_finds_its_free_space(kv: Any) -> None:
    # 36 s of steady contact appended to the 4-s log (its last second, repeated): a fiftieth
    # of the log is then 0.8 s, ten times the 73 free samples at its start. The start's
    # reading is taken from its first 50 ms, not from that fiftieth (whose median was the
    # contact's: the bias absorbed a 10 N force, and a 60-s log fitted nothing).
    fit, _, log = kv
    arrays = LogArrays.of(log, ARM)
    n = len(arrays.t)
    index = np.concatenate([np.arange(n), np.tile(np.arange(n - 1000, n), 36)])
    long = dataclasses.replace(
        arrays, t=np.arange(len(index)) * arrays.period, x=arrays.x[index], v=arrays.v[index],
        rotation=arrays.rotation[index], reading=arrays.reading[index])  # fmt: skip
    fitter = Fitter(long, 0.95, STICTION_VELOCITY)
    free, _ = fitter.free_space()
    assert free[:70].all() and not free[100:].any()  # the 4-s log's own free space
    bias = np.asarray(fitter.found.values["sensor.bias"])
    assert np.abs(bias - np.asarray(fit.values["sensor.bias"])).max() < 1e-9


def test_the_low_pass_and_latency_model() -> None:
    u = np.random.default_rng(0).standard_normal((50, 2))
    alpha, lat = 0.3, 4
    y = np.empty_like(u)
    y[0] = u[0]
    for k in range(1, 50):
        y[k] = y[k - 1] + alpha * (u[k] - y[k - 1])
    expected = np.vstack([np.repeat(y[:1], lat, axis=0), y[:-lat]])
    np.testing.assert_allclose(low_pass_delay(u, alpha, lat), expected, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(low_pass_delay(u, 1.0, 0), u)
    # An AR(1) series of ρ = 0.8: inflation (1 + ρ)/(1 − ρ) = 9, within sampling error.
    rng = np.random.default_rng(1)
    e = np.zeros(200_000)
    for k in range(1, len(e)):
        e[k] = 0.8 * e[k - 1] + rng.standard_normal()
    inflation, rho = ar1_inflation(e)
    assert abs(rho - 0.8) < 0.01 and abs(inflation - 9.0) < 0.5
    # Two series raveled sample by sample are taken apart first.
    _, rho2 = ar1_inflation(np.column_stack([e, -e]).ravel(), columns=2)
    assert abs(rho2 - rho) < 1e-9


@pytest.fixture(scope="module")
def short_log(kv: Any) -> pl.DataFrame:
    return kv[2].head(600)


def test_refusals_name_what_is_wrong(short_log: pl.DataFrame) -> None:
    with pytest.raises(ar.LogError, match="no column q.panda_joint3"):
        ar.identify(short_log.drop("q.panda_joint3"), ARM)
    with pytest.raises(ar.LogError, match="NaN"):
        ar.identify(short_log.with_columns(pl.lit(float("nan")).alias("fx")), ARM)
    with pytest.raises(ar.LogError, match="wrench_frame.*'camera'"):
        ar.identify(short_log.with_columns(pl.lit("camera").alias("wrench_frame")), ARM)
    with pytest.raises(ar.LogError, match="at least 200"):
        ar.identify(short_log.head(50), ARM)
    with pytest.raises(ar.LogError, match="evenly spaced"):
        ar.identify(short_log.with_columns(pl.col("t") ** 2), ARM)
    with pytest.raises(ParameterTypeError, match="UrdfArm"):
        ar.identify(short_log, ar.Robot())  # type: ignore[arg-type]
    with pytest.raises(ParameterTypeError, match="DataFrame"):
        ar.identify(short_log.to_dict(as_series=False), ARM)  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match="must be 'plane' or 'sphere'"):
        ar.identify(short_log, ARM, surface="cylinder")
    for bad in (0, -1, 1, 1e300, -1e300, math.nan, math.inf, -math.inf, "0.9"):
        with pytest.raises(ArgumentError, match="confidence"):
            ar.identify(short_log, ARM, confidence=bad)  # type: ignore[arg-type]
        with pytest.raises(ArgumentError, match="stiction_velocity"):
            ar.identify(short_log, ARM, stiction_velocity=bad)  # type: ignore[arg-type]


def test_a_log_of_hostile_readings_gives_a_result_or_a_named_error(short_log: Any) -> None:
    for value in (0.0, -1.0, 1e100, -1e300, 1e300):
        log = short_log.with_columns(pl.lit(value).alias("fz"))
        try:
            fit = ar.identify(log, ARM)
        except ar.LogError as err:
            assert "log" in str(err)
            continue
        for path, v in fit.values.items():
            if isinstance(v, float):
                assert not math.isnan(v), path


def test_a_fit_checked_on_the_part_of_the_log_it_did_not_see(kv: Any, tmp_path: Path) -> None:
    _, _, log = kv
    split = 3000
    fit = ar.identify(log.head(split), ARM)
    held = log.slice(split).with_columns(pl.col("t") - pl.col("t").first())
    result = fit.check(held, ARM)
    # What is left is the sensor's noise as read: σ √(α/(2 − α)) = 0.0863 N.
    alpha = 1 - math.exp(-2 * math.pi * SENSOR["cutoff"] * PERIOD)
    noise = SENSOR["noise"] * math.sqrt(alpha / (2 - alpha))
    assert abs(result.rms_error / noise - 1) < 0.15, result
    assert result.peak_error < 5 * noise
    assert result.trace.height == held.height
    # A plane 0.1 mm off predicts k·0.1 mm = 3 N off.
    moved = dataclasses.replace(fit, values={**fit.values,
                                             "wall.position": fit.values["wall.position"] + 1e-4})
    off = moved.check(held, ARM)
    assert abs(off.rms_error - 3e4 * 1e-4) < 0.3, off
    report = fit.report(tmp_path / "r", held, ARM, title="Held out")
    text = report.read_text()
    assert "RMS error" in text and "wall.stiffness" in text
    assert (tmp_path / "r" / "check.png").exists()
    no_contact = dataclasses.replace(fit, values={k: v for k, v in fit.values.items()
                                                  if not k.startswith("wall.")})  # fmt: skip
    with pytest.raises(ar.AnalysisError, match="no wall.normal"):
        no_contact.check(held, ARM)


def test_the_stiction_velocity_fitted_with_is_kept_for_the_scenario_and_the_check(
    kv: Any,
) -> None:
    assert kv[0].stiction_velocity == ar.Wall().stiction_velocity == STICTION_VELOCITY
    # A wall whose friction saturates at v_s = 3 mm/s, fitted with that v_s.
    log, _ = pressing(dataclasses.replace(KV_WALL, stiction_velocity=0.003))
    fit = ar.identify(log, ARM, stiction_velocity=0.003)
    assert fit.stiction_velocity == 0.003
    within(fit, "wall.friction", 0.3)
    assert fit.scenario(cell.base_scenario()).wall.stiction_velocity == 0.003
    # The check replays with the fit's v_s: the tangential error is the noise's (0.124 N),
    # not the 0.231 N the default v_s left.
    cells = LogArrays.of(log, ARM)
    own = fit.check(log, ARM).tangential_rms_error
    assert own == check(fit.values, cells, 0.003).tangential_rms_error
    assert own < 0.6 * check(fit.values, cells, STICTION_VELOCITY).tangential_rms_error


def test_a_sphere_comes_back_within_its_intervals() -> None:
    # The Panda presses 10 N on a ball of 0.2 m and slides ±5 cm over it (the force turns
    # by ±12°): its centre, radius, law, friction and sensor, fitted with surface="sphere".
    log, _ = pressing(cell.SPHERE)
    fit = ar.identify(log, ARM, surface="sphere")
    truths = cell.sphere_truths()
    centre = np.asarray(truths.pop("wall.centre"))
    for path, truth in truths.items():
        within(fit, path, truth)
    for axis, ((lo, hi), truth) in enumerate(zip(fit.intervals["wall.centre"], centre,
                                                 strict=True)):  # fmt: skip
        assert lo <= truth <= hi, (axis, lo, truth, hi)
    # In the plane the tip slid in (x, z) the law places the centre to micrometres; across
    # it (y) the force's sideways part does, to a millimetre.
    found = np.asarray(fit.values["wall.centre"])
    assert np.abs(found[[0, 2]] - centre[[0, 2]]).max() < 3e-5
    assert abs(found[1] - centre[1]) < 1e-3
    assert abs(fit.values["wall.radius"] - 0.2) < 3e-5
    # What is left of the force read is the noise as read.
    alpha = 1 - math.exp(-2 * math.pi * SENSOR["cutoff"] * PERIOD)
    assert fit.check(log, ARM).rms_error < 1.2 * SENSOR["noise"] * math.sqrt(alpha / (2 - alpha))
    # As a scenario: the sphere placed from the tip's start holds the true cell's force.
    sc = fit.scenario(cell.base_scenario())
    assert isinstance(sc.wall, ar.Sphere) and abs(sc.wall.gap - 0.005) < 5e-5
    fitted = ar.simulate(sc).trace
    truth = ar.simulate(cell.true_cell().replace(wall=cell.SPHERE)).trace
    last = truth["t"].to_numpy() >= 3.0
    held = float(truth["f"].to_numpy()[last].mean())
    assert abs(float(fitted["f"].to_numpy()[last].mean()) - held) < 0.01 * held
    assert abs(float(fitted["f"].max()) - float(truth["f"].max())) < 0.05 * float(truth["f"].max())


def test_a_flat_wall_fitted_as_a_sphere_says_it_is_a_plane(kv: Any) -> None:
    fit = ar.identify(kv[2], ARM, surface="sphere")
    assert "the log shows a plane; fit surface='plane'" in fit.unidentified["wall.centre"]
    assert "wall.radius" not in fit.values and "wall.stiffness" in fit.unidentified
    with pytest.raises(ar.AnalysisError, match="no wall.centre"):
        fit.check(kv[2], ARM)


def test_the_identify_command_writes_the_report_and_the_cell(kv: Any, tmp_path: Path) -> None:
    from admit_rs import cli

    _, _, log = kv
    log.write_csv(tmp_path / "cell.csv")
    out = tmp_path / "out"
    code = cli.main(["identify", str(tmp_path / "cell.csv"), "--urdf", str(ARM.path),
                     "--tip", ARM.tip_link, "--q0", *map(str, ARM.q0), "--out", str(out),
                     "--no-progress"])  # fmt: skip
    assert code == 0
    assert {p.name for p in out.iterdir()} == {"report.md", "check.png", "cell.toml"}
    sc = cli._scenario_argument(str(out / "cell.toml"))
    assert isinstance(sc.wall, ar.Wall) and abs(sc.wall.stiffness / 3e4 - 1) < 0.05
    assert sc.sensor.frame == "tip"
    assert cli.main(["identify", str(tmp_path / "cell.csv"), "--urdf", str(ARM.path), "--tip",
                     ARM.tip_link, "--out", str(out), "--holdout", "0.95",
                     "--no-progress"]) == 2  # fmt: skip
    # --surface sphere: the ball's cell, as a sphere placed from the arm's start.
    pressing(cell.SPHERE)[0].write_csv(tmp_path / "ball.csv")
    args = ["identify", str(tmp_path / "ball.csv"), "--urdf", str(ARM.path), "--tip",
            ARM.tip_link, "--q0", *map(str, ARM.q0), "--out", str(tmp_path / "ball"),
            "--surface", "sphere", "--no-progress"]  # fmt: skip
    assert cli.main(args) == 0
    ball = cli._scenario_argument(str(tmp_path / "ball" / "cell.toml"))
    assert isinstance(ball.wall, ar.Sphere) and abs(ball.wall.radius - 0.2) < 1e-4
    assert abs(ball.wall.gap - 0.005) < 1e-4


def test_a_recording_written_as_an_mcap_bag_fits_as_its_table(kv: Any, tmp_path: Path) -> None:
    pytest.importorskip("rosbags")
    fit, _, log = kv
    bag = cell.write_mcap(log, tmp_path / "cell_bag")
    read = ar.read_log(bag, robot=ARM)
    assert read.height == log.height and set(read["wrench_frame"].unique()) == {ARM.tip_link}
    np.testing.assert_allclose(read["fx"].to_numpy(), log["fx"].to_numpy(), rtol=0, atol=1e-9)
    again = ar.identify(read, ARM)
    for path in ("wall.stiffness", "wall.friction", "sensor.latency"):
        assert again.values[path] == pytest.approx(fit.values[path], rel=1e-6), path
