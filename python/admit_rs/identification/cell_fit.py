"""A fitted cell: values and intervals by scenario path, and what becomes of them."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from admit_rs.blocks.robot import UrdfArm
from admit_rs.blocks.scenario import Scenario
from admit_rs.blocks.sensor import ForceSensor
from admit_rs.blocks.surface import Sphere, Wall
from admit_rs.distributions import LogUniform, Uniform
from admit_rs.errors import AnalysisError, ParameterTypeError
from admit_rs.identification.check import CellCheck, check, write_report
from admit_rs.identification.log_arrays import LogArrays
from admit_rs.identification.model import STICTION_VELOCITY


@dataclass(frozen=True)
class CellFit:
    """A cell fitted from a recording (:func:`identify`).

    ``values`` and ``intervals`` are keyed by the scenario's dotted paths (``wall.stiffness``,
    ``sensor.latency``, ...); an interval is ``(low, high)`` at ``confidence`` (vectors: per
    component). ``unidentified`` maps a path to why the log cannot tell it; ``how`` maps
    every path to how it was obtained. ``segments`` is the log's clock with each sample's
    phase (``"free"``, ``"impact"``, ``"contact"``)."""

    values: Mapping[str, Any]
    intervals: Mapping[str, Any]
    unidentified: Mapping[str, str]
    how: Mapping[str, str]
    segments: pl.DataFrame
    confidence: float
    stiction_velocity: float = STICTION_VELOCITY
    """v_s [m/s] the friction was fitted with: :meth:`scenario`'s wall and :meth:`check`'s
    replay use it too (μ means nothing without it)."""
    residual_std: Mapping[str, float] = field(default_factory=dict)
    doubts: tuple[str, ...] = ()
    """Why the fit should not be trusted (empty: nothing found): a step hidden in what was
    taken for free space, a contact force within the noise, a stiffness known to no better
    than ±50 %."""

    @property
    def trustworthy(self) -> bool:
        """No doubt found (:attr:`doubts` is empty)."""
        return not self.doubts

    def scenario(self, base: Scenario) -> Scenario:
        """``base`` with the fitted wall and sensor: its other blocks (the arm, the
        controller, the references) stay. A path the log did not identify keeps ``base``'s
        value (a bias with the weight in it and ``tool_mass`` 0 when the mass is unknown); a
        damping fitted below 0 becomes 0. A fitted sphere is placed from ``base``'s tip at its
        q0 (:class:`~admit_rs.Sphere` is), so that its centre is the fitted one."""
        if not isinstance(base, Scenario):
            raise ParameterTypeError(
                f"CellFit.scenario() takes an admit_rs.Scenario, got {type(base).__name__}"
            )
        v = self.values
        if "wall.centre" in v:
            return base.replace(wall=self.sphere(base), sensor=self.sensor(base))
        wall_kw = {
            name: v[f"wall.{name}"]
            for name in ("normal", "position", "stiffness", "damping", "model", "exponent",
                         "friction")
            if f"wall.{name}" in v
        }  # fmt: skip
        old = base.wall if isinstance(base.wall, Wall) else Wall()
        if "damping" in wall_kw:
            wall_kw["damping"] = _physical_damping(wall_kw["damping"])
        if "position" in wall_kw:
            wall_kw["gap"] = 0.0  # the fitted plane is where the surface is
        if "friction" in wall_kw:
            wall_kw["stiction_velocity"] = self.stiction_velocity
        wall = dataclasses.replace(old, **wall_kw)
        return base.replace(wall=wall, sensor=self.sensor(base))

    def sensor(self, base: Scenario) -> ForceSensor:
        """``base``'s sensor with the fitted values, reading in the tip frame."""
        v = self.values
        sensor_kw = {
            name: v[f"sensor.{name}"]
            for name in ("bias", "noise_std", "cutoff", "latency", "tool_mass")
            if f"sensor.{name}" in v
        }
        return dataclasses.replace(base.sensor, frame="tip", **sensor_kw)

    def sphere(self, base: Scenario) -> Sphere:
        """The fitted sphere as ``base``'s surface: a sphere is placed from the tip's start X0
        (``Sphere``'s centre is X0 + (gap + R) n), so n and the gap follow from the fitted
        centre and ``base``'s arm at its q0."""
        v = self.values
        start = np.asarray(base.robot.tip_position(_initial_q(base.robot)), dtype=float)
        towards = np.asarray(v["wall.centre"], dtype=float) - start
        distance = float(np.linalg.norm(towards))
        gap = distance - float(v["wall.radius"])
        if not gap >= 0.0:
            raise AnalysisError(
                f"the base scenario's tip starts {-gap:.3g} m inside the fitted sphere (its "
                f"centre is {distance:.4g} m from the tip at q0, its radius "
                f"{v['wall.radius']:.4g} m): choose a q0 outside it"
            )
        kw = {name: v[f"wall.{name}"]
              for name in ("stiffness", "damping", "model", "exponent", "friction", "radius")
              if f"wall.{name}" in v}  # fmt: skip
        if "friction" in kw:
            kw["stiction_velocity"] = self.stiction_velocity
        if "damping" in kw:
            kw["damping"] = _physical_damping(kw["damping"])
        old = base.wall if isinstance(base.wall, Sphere) else Sphere()
        n = towards / distance
        return dataclasses.replace(old, normal=(float(n[0]), float(n[1]), float(n[2])), gap=gap,
                                   inside=False, **kw)  # fmt: skip

    def box(self) -> dict[str, Uniform | LogUniform]:
        """The identified scalar parameters as distributions over their intervals: what
        ``sweep(vary=...)`` draws from and ``analysis.tune(over=...)`` takes as its box
        ("gains stable over every cell this log admits"). Stiffness and cut-off are
        log-uniform; vectors (normal, bias) and the latency stay at their values in
        :meth:`scenario`."""
        out: dict[str, Uniform | LogUniform] = {}
        for path, iv in self.intervals.items():
            if not isinstance(iv, tuple) or len(iv) != 2 or isinstance(iv[0], tuple):
                continue
            if path == "sensor.latency":
                continue
            lo, hi = float(iv[0]), float(iv[1])
            if path in ("wall.stiffness", "sensor.cutoff") and lo > 0:
                out[path] = LogUniform(lo, hi)
            else:
                out[path] = Uniform(max(lo, 0.0), max(hi, 0.0))
        return out

    def table(self) -> pl.DataFrame:
        """One row per path: value, interval, how (or why it is unidentified)."""
        rows = []
        for path in sorted(set(self.values) | set(self.unidentified)):
            if path in self.values:
                iv = self.intervals.get(path)
                rows.append({"path": path, "value": _shown(self.values[path]),
                             "interval": "" if iv is None else _shown(iv),
                             "how": self.how.get(path, "")})  # fmt: skip
            else:
                rows.append({"path": path, "value": "unidentified", "interval": "",
                             "how": self.unidentified[path]})  # fmt: skip
        return pl.DataFrame(rows)

    def check(self, log: pl.DataFrame, robot: UrdfArm) -> CellCheck:
        """This cell's prediction of another recording (``log``, an ``ar.read_log`` table of
        the same ``robot``): its motion replayed through the fitted plane, contact law,
        friction (with :attr:`stiction_velocity`) and sensor, the force read compared with
        the recorded one (RMS and peak error, the trace)."""
        if not isinstance(robot, UrdfArm):
            raise ParameterTypeError(
                f"check() needs an admit_rs.UrdfArm, got {type(robot).__name__}")
        sphere = "wall.centre" in self.values or "wall.centre" in self.unidentified
        needed = (("wall.centre", "wall.radius") if sphere
                  else ("wall.normal", "wall.position")) + ("wall.stiffness",)  # fmt: skip
        missing = [p for p in needed if p not in self.values]
        if missing:
            why = self.unidentified.get(missing[0], "its log had no contact")
            raise AnalysisError(f"the fit has no {', '.join(missing)} to predict another log "
                                f"from: {why}")  # fmt: skip
        return check(self.values, LogArrays.of(log, robot), self.stiction_velocity)

    def report(self, out: str | Path, log: pl.DataFrame, robot: UrdfArm,
               title: str = "Your cell") -> Path:  # fmt: skip
        """Writes ``report.md`` and ``check.png`` into ``out``: this cell's table and its
        :meth:`check` against ``log`` (a part of the recording it was not fitted on); returns
        the report's path."""
        result = self.check(log, robot)
        return write_report(self.table(), self.confidence, result, Path(out), title,
                            self.doubts)  # fmt: skip

    def __str__(self) -> str:
        lines = [f"Cell fitted from the log ({100 * self.confidence:.0f} % intervals):"]
        lines += [f"  NOT TRUSTWORTHY: {d}" for d in self.doubts]
        for row in self.table().iter_rows(named=True):
            iv = f"  [{row['interval']}]" if row["interval"] else ""
            lines.append(f"  {row['path']:20s} {row['value']}{iv}")
        return "\n".join(lines)


def _shown(v: Any) -> str:
    if isinstance(v, tuple):
        return "(" + ", ".join(_shown(x) for x in v) + ")"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def _initial_q(robot: Any) -> Any:
    """The arm's q0 as used (a URDF arm's default is zero clipped into its limits)."""
    return robot.initial_position if isinstance(robot, UrdfArm) else robot.q0


def _physical_damping(value: float) -> float:
    """A damping fitted below 0 (the log leaves it loose: its interval reaches past 0) as the
    nearest one a surface can have, 0."""
    return max(float(value), 0.0)
