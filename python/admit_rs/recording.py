"""Your cell's recording as one table (SPEC §21, issue #58 part 1): :func:`read_log` reads
ROS 2 bags (sqlite3 and MCAP storage) and ROS 1 bags with the pure-Python ``rosbags`` library
(no ROS install), and CSV or Parquet files with Polars, into one Polars table on one clock.

Columns of the table:

- ``t`` [s], from the first common sample, evenly spaced at the recording's fastest rate
  (or ``rate``);
- ``q.<joint>`` [rad or m] for every joint of the ``sensor_msgs/msg/JointState`` topic (by
  its name in the message, checked against the URDF's when a ``robot`` is given) and
  ``qd.<joint>`` [rad/s or m/s] where velocities were recorded;
- ``fx``, ``fy``, ``fz`` [N] and ``tx``, ``ty``, ``tz`` [N·m]: the measured wrench
  (``geometry_msgs/msg/WrenchStamped``) in its own frame, the ``wrench_frame`` column (the
  message's ``header.frame_id``, checked to be a link of the URDF when a ``robot`` is given);
- ``ref.fx`` … ``ref.tz``: a wrench reference, when its topic is named.

Each topic's samples are placed at their ``header.stamp`` (the sensor's time, not the bag's
receive time) and interpolated linearly onto the common clock. A recording the table would
misrepresent is refused with a :class:`LogError` naming the topic and the place: stamps out of
order or repeated, a gap longer than ``max_gap``, no overlap between the topics, a topic
missing (the error lists the topics and types present), joint names the URDF does not have,
a wrench frame that is not one of its links.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import polars as pl

from admit_rs.blocks.robot import UrdfArm
from admit_rs.errors import AdmitError, ArgumentError, ParameterTypeError

__all__ = ["LogError", "read_log"]

JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
WRENCH_AXES = ("fx", "fy", "fz", "tx", "ty", "tz")
MAX_ROWS = 20_000_000
"""Most samples of the common clock (5.6 h at 1 kHz; about 2.4 GB for a six-joint arm's
table): a ``rate`` that would make more is refused before anything is allocated."""
ROLES = ("joints", "wrench", "wrench_reference")
"""The topics a log table is made of: ``topics={"joints": ..., "wrench": ...,
"wrench_reference": ...}`` (the first two are found by type when not named)."""


class LogError(AdmitError, ValueError):
    """A recording :func:`read_log` cannot turn into a faithful table; the message names the
    topic (or column) and the place."""


@dataclass(frozen=True)
class _Series:
    """One topic's samples: stamps [ns] (absolute, as recorded) and named columns."""

    topic: str
    stamps: npt.NDArray[np.int64]
    columns: dict[str, npt.NDArray[np.float64]]
    frame: str | None = None


def read_log(
    path: str | Path,
    topics: Mapping[str, str] | None = None,
    *,
    robot: UrdfArm | None = None,
    rate: float | None = None,
    max_gap: float = 0.1,
) -> pl.DataFrame:
    """Reads a recording into one table on one clock (the columns are in this module's
    docstring).

    ``path``: a ROS 2 bag (its folder, or its ``.db3`` / ``.mcap`` file), a ROS 1 ``.bag``,
    or a ``.csv`` / ``.parquet`` table with a ``t`` column [s], ``q.<joint>`` (and
    ``qd.<joint>``) and ``fx`` … ``tz`` columns (and optionally ``wrench_frame``). ``topics``
    names a bag's topics by role (``"joints"``, ``"wrench"``, ``"wrench_reference"``); an
    unnamed joints or wrench topic is found by its type (``sensor_msgs/msg/JointState``,
    ``geometry_msgs/msg/WrenchStamped``), and must then be the only one of its type.
    ``robot``: a :class:`admit_rs.UrdfArm` whose joints and links the log must use. ``rate``
    [Hz]: the common clock (default: the fastest topic's median rate). ``max_gap`` [s]: the
    longest interval between two samples of one topic that is interpolated over.

    Example:
        >>> import admit_rs as ar, polars as pl
        >>> import tempfile, pathlib
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> pl.DataFrame({"t": [0.0, 0.001, 0.002], "q.j1": [0.0, 0.1, 0.2],
        ...               "fx": [0.0, 1.0, 2.0], "fy": 0.0, "fz": 0.0, "tx": 0.0,
        ...               "ty": 0.0, "tz": 0.0}).write_csv(folder / "cell.csv")
        >>> ar.read_log(folder / "cell.csv")["fx"].to_list()
        [0.0, 1.0, 2.0]
    """
    path = Path(path)
    roles = _check_arguments(topics, rate, max_gap)
    if not path.exists():
        raise LogError(f"read_log: {str(path)!r} does not exist")
    if path.is_file() and path.suffix.lower() in (".csv", ".parquet"):
        table = _read_table(path)
    else:
        series = _read_bag(path, roles)
        table = _one_clock(series, rate, max_gap)
    if robot is not None:
        _check_robot(table, robot)
    return table


def _check_arguments(
    topics: Mapping[str, str] | None, rate: float | None, max_gap: float
) -> dict[str, str]:
    if topics is not None and not isinstance(topics, Mapping):
        raise ParameterTypeError(
            f"read_log: topics must be a mapping of role to topic name, got "
            f"{type(topics).__name__}"
        )
    roles = dict(topics or {})
    for role, name in roles.items():
        if role not in ROLES:
            raise ArgumentError(f"read_log: topics has no role {role!r}; roles: "
                                f"{', '.join(ROLES)}")  # fmt: skip
        if not isinstance(name, str) or not name:
            raise ParameterTypeError(f"read_log: topics[{role!r}] must be a topic name, got "
                                     f"{name!r}")  # fmt: skip
    for name, value, allowed in (("rate", rate, "a rate in Hz above 0 and at most 1e6"),
                                 ("max_gap", max_gap, "a time in s above 0")):  # fmt: skip
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ParameterTypeError(f"read_log: {name} must be a number, got {value!r}")
        if not (math.isfinite(value) and value > 0 and (name != "rate" or value <= 1e6)):
            raise LogError(f"read_log: {name} = {value!r} is invalid: must be {allowed}")
    return roles


def _read_table(path: Path) -> pl.DataFrame:
    """A CSV or Parquet recording: already one clock, checked as a bag's topics are."""
    try:
        table = pl.read_csv(path) if path.suffix.lower() == ".csv" else pl.read_parquet(path)
    except (pl.exceptions.PolarsError, OSError) as e:
        raise LogError(f"read_log: cannot read {path.name}: {e}") from None
    missing = [c for c in ("t", *WRENCH_AXES) if c not in table.columns]
    if missing:
        raise LogError(f"read_log: {path.name} has no column {', '.join(missing)}; it has "
                       f"{', '.join(table.columns)}")  # fmt: skip
    t = table["t"].cast(pl.Float64).to_numpy()
    _check_stamps(path.name, t)
    return table.with_columns(pl.col("t") - float(t[0]))


def _reader(path: Path) -> Any:
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise ImportError("reading a bag needs rosbags: from the clone pip install "
                          "'.[logs]', or pip install rosbags") from None  # fmt: skip
    return AnyReader([path])


def _read_bag(path: Path, roles: dict[str, str]) -> dict[str, _Series]:
    from rosbags.highlevel import AnyReaderError  # type: ignore[attr-defined]

    try:
        reader = _reader(path)
        reader.open()
    except AnyReaderError as e:
        raise LogError(f"read_log: {path} is not a bag rosbags can read: {e}") from None
    try:
        present = {c.topic: c.msgtype for c in reader.connections}
        chosen = _choose_topics(present, roles)
        out: dict[str, _Series] = {}
        for role, topic in chosen.items():
            connections = [c for c in reader.connections if c.topic == topic]
            stamps: list[int] = []
            rows: list[dict[str, float]] = []
            frames: set[str] = set()
            for connection, _, raw in reader.messages(connections=connections):
                msg = reader.deserialize(raw, connection.msgtype)
                stamp = msg.header.stamp
                stamps.append(int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec))
                if role == "joints":
                    rows.append(_joint_row(topic, msg, len(stamps) - 1))
                else:
                    w = msg.wrench
                    rows.append(dict(zip(WRENCH_AXES, (w.force.x, w.force.y, w.force.z,
                                                       w.torque.x, w.torque.y, w.torque.z),
                                         strict=True)))  # fmt: skip
                    frames.add(str(msg.header.frame_id))
            if not stamps:
                raise LogError(f"read_log: topic {topic!r} ({role}) has no messages")
            names = list(rows[0])
            for i, row in enumerate(rows):
                if list(row) != names:
                    raise LogError(f"read_log: topic {topic!r} changes its joints at message "
                                   f"{i}: {list(row)} after {names}")  # fmt: skip
            columns = {n: np.array([r[n] for r in rows], dtype=float) for n in names}
            if len(frames) > 1:
                raise LogError(f"read_log: topic {topic!r} changes its frame: "
                               f"{', '.join(sorted(frames))}")  # fmt: skip
            out[role] = _Series(topic, np.array(stamps, dtype=np.int64), columns,
                                frames.pop() if frames else None)  # fmt: skip
        return out
    finally:
        reader.close()


def _joint_row(topic: str, msg: Any, index: int) -> dict[str, float]:
    names = [str(n) for n in msg.name]
    position = list(msg.position)
    velocity = list(msg.velocity)
    if len(position) != len(names) or (velocity and len(velocity) != len(names)):
        raise LogError(f"read_log: topic {topic!r} message {index} has {len(names)} joint "
                       f"names, {len(position)} positions and {len(velocity)} "
                       "velocities")  # fmt: skip
    row = {f"q.{n}": float(p) for n, p in zip(names, position, strict=True)}
    row.update({f"qd.{n}": float(v) for n, v in zip(names, velocity, strict=False)})
    return row


def _choose_topics(present: dict[str, str], roles: dict[str, str]) -> dict[str, str]:
    listing = ", ".join(f"{t} ({m})" for t, m in sorted(present.items())) or "none"
    chosen: dict[str, str] = {}
    expected = {"joints": JOINT_STATE, "wrench": WRENCH_STAMPED,
                "wrench_reference": WRENCH_STAMPED}  # fmt: skip
    for role, topic in roles.items():
        msgtype = expected[role]
        if topic not in present:
            raise LogError(f"read_log: the {role} topic {topic!r} is not in the bag; "
                           f"topics present: {listing}")  # fmt: skip
        if present[topic] != msgtype:
            raise LogError(f"read_log: the {role} topic {topic!r} is {present[topic]}, "
                           f"not {msgtype}")  # fmt: skip
        chosen[role] = topic
    for role in ROLES:
        msgtype = expected[role]
        if role not in roles and role != "wrench_reference":
            found = sorted(t for t, m in present.items() if m == msgtype
                           and t not in roles.values())  # fmt: skip
            if len(found) != 1:
                what = "no topic" if not found else f"{len(found)} topics ({', '.join(found)})"
                raise LogError(f"read_log: {what} of type {msgtype} for the {role}; name it "
                               f"with topics={{{role!r}: ...}}; topics present: "
                               f"{listing}")  # fmt: skip
            chosen[role] = found[0]
    return chosen


def _check_stamps(
    topic: str, stamps: npt.NDArray[np.float64], exact: npt.NDArray[np.int64] | None = None
) -> None:
    """Sorted, distinct, finite stamps (compared as recorded: ``exact`` ns where given)."""
    steps = np.diff(stamps if exact is None else exact)
    if not np.all(np.isfinite(stamps)):
        raise LogError(f"read_log: {topic!r} has a stamp that is not finite")
    if np.any(steps < 0):
        i = int(np.argmax(steps < 0)) + 1
        raise LogError(f"read_log: {topic!r} has stamps out of order: sample {i} at "
                       f"{stamps[i]:.9f} s after {stamps[i - 1]:.9f} s")  # fmt: skip
    if np.any(steps == 0):
        i = int(np.argmax(steps == 0)) + 1
        raise LogError(f"read_log: {topic!r} has a repeated stamp: samples {i - 1} and {i} "
                       f"both at {stamps[i]:.9f} s")  # fmt: skip


def _one_clock(series: dict[str, _Series], rate: float | None, max_gap: float) -> pl.DataFrame:
    # Stamps in s from the earliest one: absolute epoch seconds as floats would be rounded
    # to 0.24 µs, and a 1 kHz clock found from them would be 999.93 Hz.
    origin = min(int(s.stamps[0]) for s in series.values())
    seconds = {role: ((s.stamps - origin) * 1e-9).astype(np.float64)
               for role, s in series.items()}  # fmt: skip
    for role, s in series.items():
        stamps = seconds[role]
        _check_stamps(s.topic, stamps, s.stamps)
        if len(stamps) < 2:
            raise LogError(f"read_log: topic {s.topic!r} has {len(stamps)} message; at least "
                           "2 are needed")  # fmt: skip
        steps = np.diff(stamps)
        if np.any(steps > max_gap):
            i = int(np.argmax(steps > max_gap))
            raise LogError(f"read_log: topic {s.topic!r} has a gap of {steps[i]:.6g} s after "
                           f"{stamps[i] - stamps[0]:.6g} s (max_gap {max_gap:g} s)")  # fmt: skip
    start = max(float(t[0]) for t in seconds.values())
    stop = min(float(t[-1]) for t in seconds.values())
    if not stop > start:
        spans = "; ".join(f"{series[r].topic} {t[0]:.6f}–{t[-1]:.6f} s"
                          for r, t in seconds.items())  # fmt: skip
        raise LogError(f"read_log: the topics do not overlap in time: {spans}")
    if rate is None:
        rate = max(1e9 / float(np.median(np.diff(s.stamps))) for s in series.values())
    rows = math.floor((stop - start) * rate + 1e-9) + 1
    if rows > MAX_ROWS:
        raise LogError(f"read_log: the common clock at {rate:.6g} Hz over {stop - start:.6g} s "
                       f"would have {rows:.4g} samples, more than {MAX_ROWS:,}; lower the rate "
                       "or read a shorter part of the recording")  # fmt: skip
    count = int(rows)
    clock = start + np.arange(count) / rate
    columns: dict[str, Any] = {"t": clock - start}
    for role in ROLES:
        if role not in series:
            continue
        s = series[role]
        prefix = "ref." if role == "wrench_reference" else ""
        for name, values in s.columns.items():
            columns[prefix + name] = np.interp(clock, seconds[role], values)
        if role == "wrench":
            columns["wrench_frame"] = [s.frame or ""] * count
    return pl.DataFrame(columns)


def _check_robot(table: pl.DataFrame, robot: UrdfArm) -> None:
    if not isinstance(robot, UrdfArm):
        raise ParameterTypeError(f"read_log: robot must be an admit_rs.UrdfArm, got "
                                 f"{type(robot).__name__}")  # fmt: skip
    known = robot.joint_names
    logged = [c[2:] for c in table.columns if c.startswith("q.")]
    missing = [n for n in known if n not in logged]
    if missing:
        from admit_rs.errors import closest

        hints = "; ".join(f"{n}: closest logged {', '.join(closest(n, logged)) or 'none'}"
                          for n in missing)  # fmt: skip
        raise LogError(f"read_log: the log has no joint {', '.join(missing)} of the URDF "
                       f"chain ({hints}); logged joints: "
                       f"{', '.join(logged) or 'none'}")  # fmt: skip
    if "wrench_frame" in table.columns and table.height:
        frame = str(table["wrench_frame"][0])
        links = [link.get("name", "") for link in ET.fromstring(robot.urdf).iter("link")]
        if frame not in links:
            raise LogError(f"read_log: the wrench's frame {frame!r} is not a link of "
                           f"{Path(str(robot.path)).name}; links: {', '.join(links)}")  # fmt: skip
