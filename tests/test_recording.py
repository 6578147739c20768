"""``ar.read_log`` (SPEC §21, issue #58 part 1): ROS 2 bags (sqlite3, MCAP) and ROS 1 bags
written here with ``rosbags``' own writers, and CSV / Parquet tables, read into one table on
one clock; the values are the signals written (exact for a linear signal, within linear
interpolation's h²/8·max|q̈| for a sine); every refusal names the topic and the place."""

from __future__ import annotations

import math
from pathlib import Path

import admit_rs as ar
import numpy as np
import polars as pl
import pytest

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Ros1Writer  # noqa: E402
from rosbags.rosbag2 import StoragePlugin  # noqa: E402
from rosbags.rosbag2 import Writer as Ros2Writer  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "examples" / "data"
UR5 = ar.UrdfArm(DATA / "ur5.urdf", "tool0")
JOINT_RATE, WRENCH_RATE, SECONDS = 250.0, 1000.0, 2.0


def _joint(t: float) -> float:
    return math.sin(2.0 * t)


def _fx(t: float) -> float:
    return 10.0 + 3.0 * t


def _ns(t: float) -> int:
    """A stamp t [s] after 1.7e9 s of the epoch, in whole nanoseconds (as a driver stamps)."""
    return 1_700_000_000 * 10**9 + int(round(t * 1e9))


def _messages(ros1: bool, joints: list[str], frame: str, *, stamps=None, reference=False):
    """(topic, msgtype, [(stamp [s], message)]) of a synthetic cell: joint states at 250 Hz,
    the wrench at 1 kHz from 0.1 s (so the common clock starts there), stamps absolute."""
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    types = ts.types
    def header(t: float) -> object:
        ns = _ns(t)
        stamp = types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        if ros1:
            return types["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
        return types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    vec = types["geometry_msgs/msg/Vector3"]
    joint_times = stamps if stamps is not None else np.arange(0, SECONDS, 1 / JOINT_RATE)
    # Received in order (the bag's own timestamps), stamped as given (a driver's clock).
    joint_msgs = [(received, types["sensor_msgs/msg/JointState"](
        header=header(t), name=joints,
        position=np.array([_joint(t) * (i + 1) for i in range(len(joints))]),
        velocity=np.array([2.0 * math.cos(2.0 * t) * (i + 1) for i in range(len(joints))]),
        effort=np.array([], dtype=float)))
        for received, t in zip(np.sort(joint_times), joint_times, strict=True)]  # fmt: skip

    def wrench_msg(t: float, fx: float) -> object:
        w = types["geometry_msgs/msg/Wrench"](force=vec(x=fx, y=1.0, z=-2.0),
                                              torque=vec(x=0.5, y=0.0, z=0.25))  # fmt: skip
        return types["geometry_msgs/msg/WrenchStamped"](header=header(t), wrench=w)

    wrench_times = np.arange(0.1, SECONDS, 1 / WRENCH_RATE)
    out = [("/joint_states", "sensor_msgs/msg/JointState", joint_msgs),
           ("/ft_sensor/wrench", "geometry_msgs/msg/WrenchStamped",
            [(t, wrench_msg(t, _fx(t))) for t in wrench_times])]  # fmt: skip
    if reference:
        out.append(("/wrench_reference", "geometry_msgs/msg/WrenchStamped",
                    [(t, wrench_msg(t, 10.0)) for t in wrench_times]))  # fmt: skip
    return ts, out


def _write(path: Path, kind: str, joints=None, frame="tool0", **kw) -> Path:
    joints = joints or UR5.joint_names
    ts, topics = _messages(kind == "ros1", joints, frame, **kw)
    if kind == "ros1":
        path = path / "cell.bag"
        writer: object = Ros1Writer(path)
    else:
        path = path / f"cell_{kind}"
        plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
        writer = Ros2Writer(path, version=9, storage_plugin=plugin)
    with writer as w:  # type: ignore[attr-defined]
        connections = [w.add_connection(topic, msgtype, typestore=ts)
                       for topic, msgtype, _ in topics]  # fmt: skip
        serialize = ts.serialize_ros1 if kind == "ros1" else ts.serialize_cdr
        for c, (_, msgtype, msgs) in zip(connections, topics, strict=True):
            for stamp, msg in msgs:
                w.write(c, _ns(stamp), serialize(msg, msgtype))
    return path


@pytest.mark.parametrize("kind", ["sqlite3", "mcap", "ros1"])
def test_a_bag_becomes_one_table_on_one_clock(tmp_path, kind):
    table = ar.read_log(_write(tmp_path, kind), robot=UR5)
    t = table["t"].to_numpy()
    # The clock: the wrench's 1 kHz from where every topic has started (0.1 s), to where
    # the first one stops.
    assert t[0] == 0.0 and np.allclose(np.diff(t), 1e-3, atol=1e-9)
    assert table.height == pytest.approx((SECONDS - 1 / JOINT_RATE - 0.1) * 1e3, abs=2)
    absolute = t + 0.1
    for i, name in enumerate(UR5.joint_names):
        q = table[f"q.{name}"].to_numpy()
        # Linear interpolation of (i + 1) sin 2t at 4 ms: error ≤ h²/8 · 4 (i + 1).
        bound = (1 / JOINT_RATE) ** 2 / 8 * 4 * (i + 1) + 1e-9
        assert np.max(np.abs(q - (i + 1) * np.sin(2 * absolute))) <= bound
        assert f"qd.{name}" in table.columns
    assert np.allclose(table["fx"].to_numpy(), _fx(absolute), atol=1e-6)
    assert table["fz"].to_list() == [-2.0] * table.height
    assert table["wrench_frame"].unique().to_list() == ["tool0"]


def test_topics_by_name_and_a_wrench_reference(tmp_path):
    path = _write(tmp_path, "sqlite3", reference=True)
    with pytest.raises(ar.LogError, match=r"2 topics \(/ft_sensor/wrench, /wrench_reference\)"):
        ar.read_log(path)
    table = ar.read_log(path, {"wrench": "/ft_sensor/wrench",
                               "wrench_reference": "/wrench_reference"})  # fmt: skip
    assert table["ref.fx"].to_list() == [10.0] * table.height
    with pytest.raises(ar.LogError, match=r"the wrench topic '/ft' is not in the bag; topics "
                                          r"present: /ft_sensor/wrench \(geometry_msgs"):
        ar.read_log(path, {"wrench": "/ft"})
    with pytest.raises(ar.LogError, match="is sensor_msgs/msg/JointState, not geometry_msgs"):
        ar.read_log(path, {"wrench": "/joint_states", "wrench_reference": "/wrench_reference"})
    with pytest.raises(ar.ArgumentError, match="no role 'force'"):
        ar.read_log(path, {"force": "/ft"})


def test_stamps_out_of_order_repeated_or_with_a_gap_are_refused(tmp_path):
    base = np.arange(0, SECONDS, 1 / JOINT_RATE)
    swapped = base.copy()
    swapped[[100, 101]] = swapped[[101, 100]]
    cases = {
        "swapped": (swapped, r"'/joint_states' has stamps out of order: sample 101 at"),
        "repeated": (np.sort(np.r_[base, base[50]]), r"'/joint_states' has a repeated stamp: "
                                                     r"samples 50 and 51"),
        "gap": (np.r_[base[:100], base[150:]], r"topic '/joint_states' has a gap of 0\.204 s "
                                               r"after 0\.396 s \(max_gap 0\.1 s\)"),
    }  # fmt: skip
    for name, (stamps, message) in cases.items():
        folder = tmp_path / name
        folder.mkdir()
        with pytest.raises(ar.LogError, match=message):
            ar.read_log(_write(folder, "sqlite3", stamps=stamps))
    # A longer max_gap reads the gap (and interpolates over it).
    folder = tmp_path / "gap"
    assert ar.read_log(next(folder.iterdir()), max_gap=0.25).height > 1500


def test_joints_and_frames_must_be_the_urdf_s(tmp_path):
    names = list(UR5.joint_names)
    names[1] = "shoulder_lift"
    with pytest.raises(ar.LogError, match=r"no joint shoulder_lift_joint of the URDF chain "
                                          r"\(shoulder_lift_joint: closest logged shoulder_lift"):
        ar.read_log(_write(tmp_path, "mcap", joints=names), robot=UR5)
    folder = tmp_path / "frame"
    folder.mkdir()
    with pytest.raises(ar.LogError, match=r"the wrench's frame 'ft_link' is not a link of "
                                          r"ur5\.urdf; links: "):
        ar.read_log(_write(folder, "ros1", frame="ft_link"), robot=UR5)


def test_csv_and_parquet_tables(tmp_path):
    t = np.arange(0, 1.0, 1e-3)
    frame = pl.DataFrame({"t": t + 5.0, "q.j1": np.sin(t), "fx": 2 * t, "fy": 0.0, "fz": 0.0,
                          "tx": 0.0, "ty": 0.0, "tz": 0.0})  # fmt: skip
    frame.write_csv(tmp_path / "cell.csv")
    frame.write_parquet(tmp_path / "cell.parquet")
    for name in ("cell.csv", "cell.parquet"):
        table = ar.read_log(tmp_path / name)
        assert table["t"][0] == 0.0 and np.allclose(table["fx"].to_numpy(), 2 * t)
    frame.drop("tz").write_csv(tmp_path / "short.csv")
    with pytest.raises(ar.LogError, match="short.csv has no column tz; it has t, q.j1, fx"):
        ar.read_log(tmp_path / "short.csv")
    frame.with_columns(pl.col("t").reverse()).write_csv(tmp_path / "reversed.csv")
    with pytest.raises(ar.LogError, match="'reversed.csv' has stamps out of order"):
        ar.read_log(tmp_path / "reversed.csv")


@pytest.mark.parametrize(
    ("kw", "error", "message"),
    [({"rate": 0.0}, ar.LogError, r"rate = 0\.0 is invalid: must be a rate in Hz above 0"),
     ({"rate": math.nan}, ar.LogError, "rate = nan is invalid"),
     ({"rate": 1e300}, ar.LogError, "at most 1e6"),
     ({"max_gap": -1.0}, ar.LogError, r"max_gap = -1\.0 is invalid: must be a time in s"),
     ({"max_gap": math.inf}, ar.LogError, "max_gap = inf is invalid"),
     ({"rate": True}, ar.ParameterTypeError, "rate must be a number"),
     ({"topics": ["/joint_states"]}, ar.ParameterTypeError, "topics must be a mapping")],
)
def test_bad_arguments_name_the_field(tmp_path, kw, error, message):
    with pytest.raises(error, match=message):
        ar.read_log(tmp_path, **kw)


def test_a_clock_too_fine_for_memory_is_refused_at_once(tmp_path):
    """The count of the common clock's samples is checked before anything is allocated:
    a long recording at a fine rate is refused, not read into memory it does not fit."""
    from admit_rs import recording

    path = _write(tmp_path, "sqlite3")
    assert ar.read_log(path, rate=1e5).height == 189_601  # 1.896 s at 100 kHz
    limit = recording.MAX_ROWS
    try:
        recording.MAX_ROWS = 100_000
        with pytest.raises(ar.LogError, match=r"at 100000 Hz over 1\.896 s would have "
                                              r"1\.896e\+05 samples, more than 100,000"):
            ar.read_log(path, rate=1e5)
    finally:
        recording.MAX_ROWS = limit


def test_what_is_not_a_log(tmp_path):
    with pytest.raises(ar.LogError, match="does not exist"):
        ar.read_log(tmp_path / "nothing.bag")
    (tmp_path / "junk.bag").write_bytes(b"not a bag")
    with pytest.raises(ar.LogError, match="is not a bag rosbags can read"):
        ar.read_log(tmp_path / "junk.bag")
