"""A log table as the arrays identify fits: time, the tip's position, velocity and rotation
from the arm's kinematics, and the force reading."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from admit_rs.blocks.robot import UrdfArm
from admit_rs.identification.least_squares import Array
from admit_rs.recording import LogError

MAX_FORCE = 1e6
"""The largest force reading [N] a log may hold (beyond it, a unit or a corrupt value)."""
MAX_JOINT = 1e3
"""The largest joint position [rad or m] a log may hold."""


@dataclass
class LogArrays:
    """The log as arrays: time, tip position X, velocity V, rotation R, reading y (tip frame)."""

    t: Array
    period: float
    x: Array
    v: Array
    rotation: Array
    reading: Array
    tip_frame: bool
    gravity: float

    @classmethod
    def of(cls, log: pl.DataFrame, robot: UrdfArm) -> LogArrays:
        missing = [c for c in ("t", "fx", "fy", "fz") if c not in log.columns]
        missing += [f"q.{j}" for j in robot.joint_names if f"q.{j}" not in log.columns]
        if missing:
            raise LogError(f"the log has no column {', '.join(missing)}; columns present: "
                           f"{', '.join(log.columns)}")  # fmt: skip
        if log.height < 200:
            raise LogError(f"the log has {log.height} samples: at least 200 are needed")
        t = log["t"].cast(pl.Float64).to_numpy()
        dt = np.diff(t)
        period = float(np.median(dt))
        if not (period > 0 and np.all(dt > 0) and np.allclose(dt, period, rtol=1e-3)):
            raise LogError("the log's clock t must be evenly spaced and increasing "
                           "(ar.read_log's table is)")  # fmt: skip
        q = log.select([f"q.{j}" for j in robot.joint_names]).cast(pl.Float64).to_numpy()
        qd_cols = [f"qd.{j}" for j in robot.joint_names]
        has_qd = all(c in log.columns for c in qd_cols)
        qd = log.select(qd_cols).cast(pl.Float64).to_numpy() if has_qd else None
        reading = log.select("fx", "fy", "fz").cast(pl.Float64).to_numpy()
        checks = (("q", q, MAX_JOINT, "rad"), ("fx/fy/fz", reading, MAX_FORCE, "N"))
        for name, arr, most, unit in checks:
            if not np.all(np.isfinite(arr)):
                raise LogError(f"the log's {name} columns hold NaN or infinite values")
            if np.max(np.abs(arr)) > most:
                raise LogError(f"the log's {name} columns reach {np.max(np.abs(arr)):.3g} {unit}: "
                               f"more than {most:g} {unit} is not a recording identify() "
                               "can fit")  # fmt: skip
        tip_frame = True
        if "wrench_frame" in log.columns:
            frames = {f for f in log["wrench_frame"].unique().to_list() if f}
            base = {robot.base_link} if robot.base_link else set()
            allowed = {robot.tip_link} | base | {"world", "base", "base_link"}
            bad = frames - allowed
            if bad or len(frames) > 1:
                raise LogError(
                    f"wrench_frame {sorted(frames)} is not usable: identify() reads the wrench "
                    f"in the tip link's frame ({robot.tip_link!r}) or the base's"
                )
            tip_frame = not frames or frames == {robot.tip_link}
        n = len(t)
        x = np.empty((n, 3))
        rot = np.empty((n, 3, 3))
        v = np.empty((n, 3))
        for k in range(n):
            terms = robot.dynamics(q[k], None if qd is None else qd[k])
            x[k] = terms["position"]
            rot[k] = terms["rotation"]
            if qd is not None:
                v[k] = terms["jacobian"][:3] @ qd[k]
        if qd is None:
            v = np.asarray(np.gradient(x, t, axis=0), dtype=float)
        return cls(t - t[0], period, x, v, rot, reading, tip_frame, float(robot.gravity))

    def to_world(self, vectors: Array) -> Array:
        """Tip-frame vectors (one per sample) in the world frame."""
        if not self.tip_frame:
            return vectors
        return np.einsum("kij,kj->ki", self.rotation, vectors)

    def up_in_sensor(self) -> Array:
        """(0, 0, g) in the sensor frame, per sample: the regressor of the tool's mass."""
        up = np.array([0.0, 0.0, self.gravity])
        if not self.tip_frame:
            return np.tile(up, (len(self.t), 1))
        return np.einsum("kji,j->ki", self.rotation, up)
