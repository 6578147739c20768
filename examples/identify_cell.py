"""Your cell from your recording (issue #58, docs/identify.md): a recording made, read
and fitted back.

    python examples/identify_cell.py [--out DIR]

1. A recording as a robot would give it: the Panda approaches a wall through 5 mm, presses
   10 N and slides ±5 cm along it (fig. 14's task and TDC, 4 s at 1 kHz), and its flange F/T
   sensor reads the force on the part and a 0.5 kg tool's weight in the tool frame with a
   bias, white noise, a 60 Hz first-order low-pass and 3 samples of latency. The arm's joints
   come from an admit_rs run; the sensor is applied here, sample by sample, from its
   definition (SPEC §15), so the fit cannot lean on the simulator's own sensor code.
2. The recording is written as a ROS 2 bag in MCAP storage (``/joint_states`` and
   ``/ft_sensor/wrench``, with rosbags' writer; a CSV table without the ``logs`` extra), read
   back with ``ar.read_log`` and fitted with ``ar.identify``; the fitted cell is printed
   beside the truth.
3. The fitted cell, as a scenario, is simulated beside the true cell under the same
   controller.

Writes identify_cell.png and identify_cell.md (the table docs/identify.md shows) into
DIR (default: here; ``docs/identify`` refreshes the figure of the docs).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import admit_rs as ar
import matplotlib
import numpy as np
import polars as pl

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

DATA = Path(__file__).resolve().parent / "data"
ARM = ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp",
                 q0=(0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785))  # fmt: skip
PERIOD = 1e-3
WALL = ar.Wall(stiffness=3e4, damping=30.0, friction=0.3, gap=0.005)
SPHERE = ar.Sphere(radius=0.2, stiffness=3e4, damping=30.0, friction=0.3, gap=0.005)
"""A ball the same tool slides over (``identify(surface="sphere")``): the force turns ±12°."""
SENSOR = {"bias": (0.5, -0.3, 1.2), "noise": 0.2, "cutoff": 60.0, "latency": 3, "mass": 0.5}
"""The true flange sensor and tool: bias [N] per tool axis, noise σ [N], cut-off [Hz],
latency [samples], tool mass [kg]."""


def base_scenario() -> ar.Scenario:
    """fig. 14's task and loop on the Panda (TDC tuned for it), 4 s."""
    return ar.paper.scenario("fig14").replace(
        robot=ARM, controller=ar.TimeDelayControl.for_arm(ARM), duration=4.0)


def true_cell() -> ar.Scenario:
    """The cell the recording is made in: the wall and the flange sensor with the tool's weight
    in the reading, not compensated by the controller."""
    return base_scenario().replace(wall=WALL, sensor=ar.ForceSensor(
        frame="tip", bias=SENSOR["bias"], noise_std=SENSOR["noise"], cutoff=SENSOR["cutoff"],
        latency=SENSOR["latency"], tool_mass=SENSOR["mass"], tool_mass_estimate=0.0))  # fmt: skip


def sensor_reading(rotation: np.ndarray, force: np.ndarray, seed: int) -> np.ndarray:
    """The flange sensor of SPEC §15 sample by sample: u = Rᵀ (F + w) + β + σ n, y_0 = u_0,
    y_k = y_{k−1} + α (u_k − y_{k−1}), output delayed by the latency (holding y_0)."""
    weight = np.array([0.0, 0.0, SENSOR["mass"] * ARM.gravity])
    u = np.einsum("kji,kj->ki", rotation, force + weight) + np.asarray(SENSOR["bias"])
    u = u + SENSOR["noise"] * np.random.default_rng(seed).standard_normal(u.shape)
    alpha = 1 - math.exp(-2 * math.pi * SENSOR["cutoff"] * PERIOD)
    y = np.empty_like(u)
    y[0] = u[0]
    for k in range(1, len(u)):
        y[k] = y[k - 1] + alpha * (u[k] - y[k - 1])
    lat = int(SENSOR["latency"])
    return np.concatenate([np.repeat(y[:1], lat, axis=0), y[:-lat]]) if lat else y


def recording(wall: ar.Wall = WALL, seed: int = 1,
              slide: bool = True) -> tuple[pl.DataFrame, ar.Result]:  # fmt: skip
    """The log table (t, q.<joint>, qd.<joint>, fx … tz) of the Panda pressing on ``wall``
    (and sliding along it, unless ``slide`` is false), and the run it was made from (the
    truth: contact force, penetration)."""
    sensor = ar.ForceSensor(tool_mass=SENSOR["mass"])
    scenario = base_scenario().replace(wall=wall, sensor=sensor)
    if not slide:
        scenario = scenario.replace(z_reference=ar.Sine(amplitude=0.0))
    run = ar.simulate(scenario)
    tr = run.trace
    q = tr.select([f"q{i + 1}" for i in range(ARM.dof)]).to_numpy()
    qd = tr.select([f"qd{i + 1}" for i in range(ARM.dof)]).to_numpy()
    rotation = np.array([ARM.dynamics(qk)["rotation"] for qk in q])
    reading = sensor_reading(rotation, tr.select("fx", "fy", "fz").to_numpy(), seed)
    cols: dict[str, Any] = {"t": tr["t"].to_numpy()}
    for i, j in enumerate(ARM.joint_names):
        cols[f"q.{j}"] = q[:, i]
        cols[f"qd.{j}"] = qd[:, i]
    for i, c in enumerate(("fx", "fy", "fz")):
        cols[c] = reading[:, i]
    for c in ("tx", "ty", "tz"):
        cols[c] = np.zeros(len(q))
    return pl.DataFrame(cols), run


def write_mcap(table: pl.DataFrame, path: Path, start_ns: int = 1_700_000_000 * 10**9) -> Path:
    """The table as a ROS 2 bag in MCAP storage, as the robot would have recorded it with
    ``ros2 bag record``: ``/joint_states`` (sensor_msgs/msg/JointState: names, positions,
    velocities) and ``/ft_sensor/wrench`` (geometry_msgs/msg/WrenchStamped in the tool's
    frame), every message stamped (header.stamp) on the driver's clock. Needs ``rosbags``
    (the ``logs`` extra)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    types = ts.types
    names = ARM.joint_names
    q = np.ascontiguousarray(table.select([f"q.{j}" for j in names]).to_numpy())
    qd = np.ascontiguousarray(table.select([f"qd.{j}" for j in names]).to_numpy())
    force = table.select("fx", "fy", "fz").to_numpy()
    vec = types["geometry_msgs/msg/Vector3"]
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as bag:
        joints = bag.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        wrench = bag.add_connection("/ft_sensor/wrench", "geometry_msgs/msg/WrenchStamped",
                                    typestore=ts)  # fmt: skip
        for k, t in enumerate(table["t"].to_numpy()):
            ns = start_ns + int(round(t * 1e9))
            stamp = types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            state = types["sensor_msgs/msg/JointState"](
                header=types["std_msgs/msg/Header"](stamp=stamp, frame_id=""), name=names,
                position=np.ascontiguousarray(q[k]), velocity=np.ascontiguousarray(qd[k]),
                effort=np.array([], dtype=float))  # fmt: skip
            measured = types["geometry_msgs/msg/WrenchStamped"](
                header=types["std_msgs/msg/Header"](stamp=stamp, frame_id=ARM.tip_link),
                wrench=types["geometry_msgs/msg/Wrench"](
                    force=vec(x=force[k, 0], y=force[k, 1], z=force[k, 2]),
                    torque=vec(x=0.0, y=0.0, z=0.0)))  # fmt: skip
            bag.write(joints, ns, ts.serialize_cdr(state, "sensor_msgs/msg/JointState"))
            bag.write(wrench, ns, ts.serialize_cdr(measured, "geometry_msgs/msg/WrenchStamped"))
    return path


def truths(run: ar.Result) -> dict[str, Any]:
    """The true values by path (the bias with the tool's weight at q0 in it: the tool keeps
    that orientation, so the log shows them together)."""
    tr = run.trace
    touching = tr["f"].to_numpy() > 0
    x = tr["x"].to_numpy()[touching] - tr["penetration"].to_numpy()[touching]
    weight = ARM.dynamics(ARM.q0)["rotation"].T @ [0.0, 0.0, SENSOR["mass"] * ARM.gravity]
    return {"sensor.bias": tuple(float(b) for b in np.asarray(SENSOR["bias"]) + weight),
            "wall.normal": (1.0, 0.0, 0.0),
            "wall.stiffness": WALL.stiffness, "wall.damping": WALL.damping,
            "wall.friction": WALL.friction, "wall.position": float(np.mean(x)),
            "sensor.latency": SENSOR["latency"], "sensor.cutoff": SENSOR["cutoff"],
            "sensor.noise_std": SENSOR["noise"]}  # fmt: skip


def sphere_truths() -> dict[str, Any]:
    """The true values of :data:`SPHERE`'s cell by path: its centre is X0 + (gap + R) n."""
    start = ARM.tip_position(ARM.initial_position)
    centre = start + (SPHERE.gap + SPHERE.radius) * np.asarray(SPHERE.normal, dtype=float)
    return {"wall.centre": tuple(float(c) for c in centre), "wall.radius": SPHERE.radius,
            "wall.stiffness": SPHERE.stiffness, "wall.damping": SPHERE.damping,
            "wall.friction": SPHERE.friction, "sensor.latency": SENSOR["latency"],
            "sensor.cutoff": SENSOR["cutoff"], "sensor.noise_std": SENSOR["noise"]}  # fmt: skip


def markdown(fit: ar.CellFit, truth: dict[str, Any]) -> str:
    lines = ["| path | fitted | 95 % interval | true |", "|---|---|---|---|"]
    for row in fit.table().iter_rows(named=True):
        true = truth.get(row["path"], "")
        shown = true if isinstance(true, str) else (
            "(" + ", ".join(f"{v:.6g}" for v in true) + ")" if isinstance(true, tuple)
            else f"{true:.6g}")  # fmt: skip
        lines.append(f"| `{row['path']}` | {row['value']} | {row['interval']} | {shown} |")
    return "\n".join(lines) + "\n"


def figure(fit: ar.CellFit, log: pl.DataFrame, run: ar.Result, truth: dict[str, Any],
           fitted_run: ar.Result, true_run: ar.Result) -> Any:  # fmt: skip
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5))
    t = log["t"].to_numpy()
    q = log.select([f"q.{j}" for j in ARM.joint_names]).to_numpy()
    rotation = np.array([ARM.dynamics(qk)["rotation"] for qk in q])
    reading = log.select("fx", "fy", "fz").to_numpy()
    n = np.asarray(fit.values["wall.normal"])
    static = np.asarray(fit.values["sensor.bias"])
    read_n = np.einsum("kij,kj->ki", rotation, reading - static) @ n
    ax = axes[0, 0]
    phases = fit.segments["phase"].to_numpy()
    for phase, colour in (("impact", "#f4d03f"), ("free", "#d6eaf8")):  # contact: unshaded
        mask = phases == phase
        ax.fill_between(t, 0, 1, where=mask, color=colour, alpha=0.6, step="mid",
                        transform=ax.get_xaxis_transform(), label=f"segment: {phase}")  # fmt: skip
    ax.plot(t, read_n, lw=0.6, color="C0", label="read along the fitted n (bias removed)")
    ax.plot(t, run.trace["f"].to_numpy(), lw=0.8, color="k", ls="--", label="true contact force")
    ax.set(xlabel="t [s]", ylabel="force [N]",
           title="The recording, segmented (contact unshaded)")  # fmt: skip
    ax.legend(fontsize=8, loc="lower right")
    ax = axes[0, 1]
    zoom = t < 0.35
    ax.plot(t[zoom], read_n[zoom], lw=0.9, color="C0", label="read (low-pass, latency, noise)")
    ax.plot(t[zoom], run.trace["f"].to_numpy()[zoom], color="k", ls="--", label="true")
    ax.set(xlabel="t [s]", ylabel="force [N]", title="First contact: what the sensor lags by")
    ax.legend(fontsize=8)
    ax = axes[1, 0]
    names = [p for p in truth if p in fit.intervals and isinstance(truth[p], float | int)
             and p != "wall.position"]  # fmt: skip
    for i, path in enumerate(names):
        lo, hi = fit.intervals[path]
        value, true = fit.values[path], truth[path]
        ax.plot([lo / true, hi / true], [i, i], color="C0", lw=3, solid_capstyle="butt")
        ax.plot(value / true, i, "o", color="C0")
    ax.axvline(1.0, color="k", ls="--", lw=1, label="truth")
    ax.axvline(0.0, color="grey", lw=0.6)
    ax.set_yticks(range(len(names)), names)
    ax.set(xlabel="fitted / true (dot) and the 95 % interval (bar); a bar through 0 "
           "admits a value of 0", title="Each number against the truth")  # fmt: skip
    ax.legend(fontsize=8)
    ax = axes[1, 1]
    for res, label, style in ((true_run, "true cell", "k--"), (fitted_run, "fitted cell", "C1")):
        ax.plot(res.trace["t"].to_numpy(), res.trace["f"].to_numpy(), style, lw=0.9, label=label)
    ax.set(xlabel="t [s]", ylabel="contact force f [N]",
           title="Simulated: the fitted cell beside the true one (same controller)")  # fmt: skip
    ax.legend(fontsize=8)
    fig.suptitle("ar.identify on a 4-s recording of the Panda pressing and sliding on a wall")
    fig.tight_layout()
    return fig


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=Path("."))
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    table, run = recording()
    try:
        import shutil

        shutil.rmtree(out / "cell_bag", ignore_errors=True)
        log = ar.read_log(write_mcap(table, out / "cell_bag"), robot=ARM)  # a ROS 2 bag
        shutil.rmtree(out / "cell_bag")
    except ImportError:  # no rosbags (the ``logs`` extra): the same table as CSV
        table.write_csv(out / "cell.csv")
        log = ar.read_log(out / "cell.csv", robot=ARM)
        (out / "cell.csv").unlink()
    fit = ar.identify(log, ARM)
    print(fit)
    truth = truths(run)
    fitted_run = ar.simulate(fit.scenario(base_scenario()))
    true_run = ar.simulate(true_cell())
    (out / "identify_cell.md").write_text(markdown(fit, truth))
    figure(fit, log, run, truth, fitted_run, true_run).savefig(out / "identify_cell.png", dpi=110)
    print(f"wrote {out / 'identify_cell.png'} and {out / 'identify_cell.md'}")


if __name__ == "__main__":
    main()
