"""Export to ros2_controllers' admittance_controller: numbers read back with a YAML parser."""

from __future__ import annotations

import math
import re
import warnings

import admit_rs as ar
import numpy as np
import pytest
import yaml


def _params(path):
    data = yaml.safe_load(path.read_text())
    assert list(data) == ["admittance_controller"]
    return data["admittance_controller"]["ros__parameters"]


def test_scheme1_maps_mass_damping_ratio_stiffness_axes_and_filter(tmp_path):
    sc = ar.paper.scenario("fig8")  # CT + Scheme 1: m = 1, b = 800, k = 400, k_a = 0.1
    adm = sc.admittance
    assert (adm.m, adm.b, adm.k, adm.ka) == (1.0, 800.0, 400.0, 0.1)
    path = tmp_path / "admittance.yaml"
    text = ar.export.ros2_admittance(sc, path)
    assert path.read_text() == text
    p = _params(path)
    a = p["admittance"]
    assert a["selected_axes"] == [True, False, False, False, False, False]
    assert a["mass"] == [pytest.approx(10.0)] * 6  # m / k_a
    # k / k_a on x; the unselected axes have no spring (and so no damping: D = ζ 2 √(M K)).
    assert a["stiffness"] == [pytest.approx(4000.0)] + [0.0] * 5
    assert a["damping_ratio"] == [pytest.approx(20.0)] + [0.0] * 5  # b / (2 sqrt(m k))
    assert p["ft_sensor"]["filter_coefficient"] == 1.0
    # Every double is written as a float (the controller rejects integers there).
    assert all(isinstance(v, float) for v in a["mass"] + a["stiffness"] + a["damping_ratio"])
    # The controller's own damping, D = zeta * 2 sqrt(M K), is the filter's b / k_a.
    damping = a["damping_ratio"][0] * 2 * math.sqrt(a["mass"][0] * a["stiffness"][0])
    assert damping == pytest.approx(adm.b / adm.ka)


def test_other_gains_and_options(tmp_path):
    sc = ar.Scenario(admittance=ar.AdmittanceFilter.scheme1(m=2.0, b=100.0, k=50.0, ka=2.0))
    text = ar.export.ros2_admittance(sc, tmp_path / "a.yaml", controller_name="force_ctl",
                                     filter_coefficient=None)  # fmt: skip
    data = yaml.safe_load(text)
    p = data["force_ctl"]["ros__parameters"]
    assert "ft_sensor" not in p
    assert p["admittance"]["mass"][0] == pytest.approx(1.0)
    assert p["admittance"]["stiffness"][0] == pytest.approx(25.0)
    assert p["admittance"]["damping_ratio"][0] == pytest.approx(100.0 / (2 * math.sqrt(100.0)))
    tiny = ar.Scenario(admittance=ar.AdmittanceFilter.scheme1(m=1.0, b=1e-5, k=1.0, ka=1.0))
    # 5e-06 must stay a float for a YAML 1.1 reader too: a dot in the mantissa.
    assert "damping_ratio: [5.0e-06," in ar.export.ros2_admittance(tiny, None)


def test_scheme2_is_refused_with_the_nearest_faithful_alternative(tmp_path):
    sc = ar.paper.scenario("fig14")  # TDC + Scheme 2: k = 0, k_a = 1, k_e = 30 000
    path = tmp_path / "a.yaml"
    with pytest.raises(ar.ExportError) as info:
        ar.export.ros2_admittance(sc, path)
    msg = str(info.value)
    assert "Scheme 2 (admittance.k = 0) cannot be written" in msg
    assert "damping_ratio * 2 * sqrt(M * K), which is 0" in msg
    assert "admittance.k = 303 N/m keeps the steady-state force error at 1 % of f_d" in msg
    assert isinstance(info.value, ar.AdmitError) and isinstance(info.value, ValueError)
    assert not path.exists()  # nothing written, not even a different controller
    # The suggested alternative exports, and in simulation it costs less than the 1 % of
    # f_d (0.1 N) of extra steady-state force error that the message promises.
    alt = sc.replace(**{"admittance.k": 303.0303})
    assert _params_text(ar.export.ros2_admittance(alt, None))["stiffness"][0] == (
        pytest.approx(303.0303)
    )
    extra = ar.simulate(alt).metrics["force_ss_error"] - ar.simulate(sc).metrics["force_ss_error"]
    assert 0.0 < extra < 0.1


def _params_text(text):
    return yaml.safe_load(text)["admittance_controller"]["ros__parameters"]["admittance"]


def test_force_loops_without_an_equivalent_are_refused():
    with pytest.raises(ar.ExportError, match="eq. \\(20\\) impedance reference"):
        ar.export.ros2_admittance(ar.Scenario(admittance=ar.ImpedanceReference()), None)
    with pytest.raises(ar.ExportError, match="no force loop"):
        ar.export.ros2_admittance(ar.paper.scenario("fig5"), None)
    with pytest.raises(ar.ExportError, match="admittance.ka = 0"):
        ar.export.ros2_admittance(
            ar.Scenario(admittance=ar.AdmittanceFilter.scheme1(ka=0.0)), None
        )
    with pytest.raises(ar.ExportError, match="outside admittance_controller's bounds"):
        ar.export.ros2_admittance(
            ar.Scenario(admittance=ar.AdmittanceFilter.scheme1(k=1e9, ka=1.0)), None
        )


# Issue 21 item 8: what the export used to drop, invent or let through.


def test_sensor_low_pass_maps_to_the_controllers_exponential_filter():
    import scipy.signal

    sc = ar.paper.scenario("fig8").replace(sensor=ar.ForceSensor(cutoff=30.0), duration=1.0)
    text = ar.export.ros2_admittance(sc, None)
    alpha = yaml.safe_load(text)["admittance_controller"]["ros__parameters"]["ft_sensor"][
        "filter_coefficient"
    ]
    assert alpha == pytest.approx(1 - math.exp(-2 * math.pi * 30 * 1e-3), rel=1e-15)
    assert alpha == pytest.approx(0.171796, abs=1e-6)
    assert "the sensor's 30 Hz low-pass" in _comments(text)
    # The controller's filters::exponentialSmoothing(x, y_prev, a) = a x + (1 - a) y_prev
    # with that coefficient is the sensor admit_rs simulated, sample for sample.
    tr = ar.simulate(sc).trace
    f, measured = tr["f"].to_numpy(), tr["f_measured"].to_numpy()
    smoothed, _ = scipy.signal.lfilter([alpha], [1.0, alpha - 1.0], f[1:],
                                       zi=[(1 - alpha) * measured[0]])  # fmt: skip
    np.testing.assert_allclose(measured[1:], smoothed, rtol=1e-12, atol=1e-12)
    # No low-pass: the raw measurement; an explicit number still wins; None leaves it out.
    raw = _params_text_full(ar.export.ros2_admittance(ar.paper.scenario("fig8"), None))
    assert raw["ft_sensor"]["filter_coefficient"] == 1.0
    forced = ar.export.ros2_admittance(sc, None, filter_coefficient=0.5)
    assert _params_text_full(forced)["ft_sensor"]["filter_coefficient"] == 0.5


def _comments(text):
    """The file's comment lines as one paragraph."""
    return " ".join(line[2:] for line in text.splitlines() if line.startswith("# "))


def _params_text_full(text):
    return yaml.safe_load(text)["admittance_controller"]["ros__parameters"]


def test_tilted_wall_warns_and_gives_the_control_frame_rotation():
    from scipy.spatial.transform import Rotation

    sc = ar.paper.scenario("fig8").replace(**{"wall.normal": (1.0, 0.0, -1.0)})
    with pytest.warns(ar.export.ExportWarning, match=r"wall normal n = \(0.707107, 0, -0.707107\)"
                      r" is not the x axis: control.frame.id must be a link of the chain"
                      ) as record:  # fmt: skip
        text = ar.export.ros2_admittance(sc, None)
    assert len(record) == 1 and record[0].filename == __file__
    notes = _comments(text)
    assert "REQUIRED: The wall normal n = (0.707107, 0, -0.707107) is not the x axis" in notes
    assert "A TF frame published elsewhere is not seen (no admittance)" in notes
    quat = [float(v) for v in notes.split("[x, y, z, w] = [")[1].split("]")[0].split(",")]
    rot = Rotation.from_quat(quat).as_matrix()
    n, t = sc.wall.directions()
    np.testing.assert_allclose(rot @ [1, 0, 0], n, atol=1e-6)  # control x along n
    np.testing.assert_allclose(rot @ [0, 0, 1], t, atol=1e-6)  # control z along t
    np.testing.assert_allclose(n, [2**-0.5, 0, -(2**-0.5)], atol=1e-15)
    # The URDF joint from the new root link to the base: the base's pose in it is Rᵀ, in
    # URDF's rpy (R = Rz(yaw) Ry(pitch) Rx(roll), scipy's extrinsic "xyz").
    rpy = [float(v) for v in notes.split("origin rpy = '")[1].split("'")[0].split(",")]
    np.testing.assert_allclose(Rotation.from_euler("xyz", rpy).as_matrix(), rot.T, atol=1e-6)
    # The paper's wall needs no rotation: no warning, no frame to add.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "is not the x axis" not in ar.export.ros2_admittance(ar.paper.scenario("fig8"),
                                                                    None)


def test_header_describes_the_scenario_as_it_is():
    sc = ar.paper.scenario("fig8").replace(**{"admittance.ka": 1.0})  # label said k_a=0.1
    text = ar.export.ros2_admittance(sc, None)
    assert "k_a=0.1" not in text and "k_a = 0.1" not in text
    assert "Scheme 1 (k=400, b=800, k_a=1)" in _comments(text)
    # A label with a newline cannot break out of the comment.
    odd = sc.replace(label="mine\nadmittance_controller: {}\nevil: 1")
    assert list(yaml.safe_load(ar.export.ros2_admittance(odd, None))) == ["admittance_controller"]


def test_joint_damping_is_written():
    sc = ar.paper.scenario("fig8")
    assert _params_text(ar.export.ros2_admittance(sc, None))["joint_damping"] == 0.0
    two = ar.export.ros2_admittance(sc, None, joint_damping=2.5)
    assert _params_text(two)["joint_damping"] == 2.5
    assert "is 2.5, which eq. (30) does not have" in _comments(two)
    assert "is 0.0: eq. (30) has none" in _comments(ar.export.ros2_admittance(sc, None))
    with pytest.raises(ar.ParameterError, match=r"joint_damping = -1.0 is invalid: must be a"
                       r" finite number >= 0") as info:  # fmt: skip
        ar.export.ros2_admittance(sc, None, joint_damping=-1.0)
    assert info.value.field == "joint_damping"


@pytest.mark.parametrize(
    "name", ["evil\nmalicious_key: 1", "a b", "ctl: {x: 1}", "9lives", "", "a/b", "ns.ctl"]
)
def test_controller_name_must_be_a_ros_node_name(tmp_path, name):
    path = tmp_path / "a.yaml"
    with pytest.raises(ar.ParameterError, match="controller_name = .* is invalid: must be a ROS"
                       " 2 node name") as info:  # fmt: skip
        ar.export.ros2_admittance(ar.paper.scenario("fig8"), path, controller_name=name)
    assert info.value.field == "controller_name" and info.value.value == repr(name)
    assert not path.exists()


def test_vanishing_stiffness_is_refused_not_an_absurd_damping_ratio():
    sc = ar.Scenario(admittance=ar.AdmittanceFilter.scheme1(m=1.0, b=800.0, k=1e-300, ka=1.0))
    with pytest.raises(ar.ExportError) as info:
        ar.export.ros2_admittance(sc, None)
    msg = str(info.value)
    assert msg.startswith("admittance.k = 1e-300 N/m gives damping_ratio = b / (2 sqrt(m k)) ="
                          " 4e+152, above 1e+06")  # fmt: skip
    assert "admittance.k >= 1.6e-07 N/m" in msg
    # Just above the limit it exports, and the controller's D = zeta 2 sqrt(M K) is b / k_a.
    ok = sc.replace(**{"admittance.k": 1.7e-7})
    a = _params_text(ar.export.ros2_admittance(ok, None))
    assert a["damping_ratio"][0] <= ar.export.MAX_DAMPING_RATIO
    assert a["damping_ratio"][0] * 2 * math.sqrt(a["mass"][0] * a["stiffness"][0]) == (
        pytest.approx(800.0, rel=1e-12)
    )


@pytest.mark.parametrize(
    "normal", [(1, 0, -1), (-1, 0, 0), (0, 1, 0), (1, 1, 1), (0, 0, 1), (0.2, -3, 0.5)]
)
def test_control_frame_rotation_for_any_normal(normal):
    from scipy.spatial.transform import Rotation

    sc = ar.paper.scenario("fig8").replace(**{"wall.normal": normal})
    with pytest.warns(ar.export.ExportWarning):
        notes = _comments(ar.export.ros2_admittance(sc, None))
    quat = [float(v) for v in notes.split("[x, y, z, w] = [")[1].split("]")[0].split(",")]
    rows = re.search(r"in the base frame\): (.*?)\.(?: |$)", notes).group(1)
    matrix = np.array([[float(v) for v in row.split(",")] for row in rows.split(";")])
    n, t = sc.wall.directions()
    rot = Rotation.from_quat(quat).as_matrix()
    for r in (rot, matrix):
        np.testing.assert_allclose(r @ [1, 0, 0], n, atol=2e-6)
        np.testing.assert_allclose(r @ [0, 0, 1], t, atol=2e-6)
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=2e-6)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-5)


def test_a_tool_is_exported_as_gravity_compensation(tmp_path):
    """The tool the controller believes (SPEC §15) is the controller's gravity compensation:
    CoG.force = m̂_t g at the tip origin; none is written without a tool."""
    sc = ar.paper.scenario("fig8")
    assert "gravity_compensation" not in _params_text_full(ar.export.ros2_admittance(sc, None))
    tooled = sc.replace(sensor=ar.ForceSensor(tool_mass=1.5, tool_mass_estimate=1.2))
    text = ar.export.ros2_admittance(tooled, tmp_path / "a.yaml")
    p = yaml.safe_load(text)["admittance_controller"]["ros__parameters"]
    cog = p["gravity_compensation"]["CoG"]
    assert cog["force"] == pytest.approx(1.2 * 9.81)
    assert cog["pos"] == [0.0, 0.0, 0.0]
    assert "1.2 kg" in text


def test_numpy_scalars_are_written_as_plain_toml_numbers():
    """A block holds NumPy scalars as the Python numbers they are (issue #53, item 4): the
    TOML export wrote ``stiffness = np.float64(50000.0)`` and refused ``np.int64``."""
    import tomllib

    sc = ar.paper.scenario("fig14").replace(**{
        "wall.stiffness": np.float64(5e4), "sensor.latency": np.int64(2),
        "actuator.torque_limit": (np.float64(60.0), 40, np.float32(20.0)), "seed": np.int64(3),
    })  # fmt: skip
    assert type(sc.wall.stiffness) is float and type(sc.sensor.latency) is int
    assert type(sc.seed) is int and [type(t) for t in sc.actuator.torque_limit] == [float] * 3
    text = ar.export.toml(sc)
    assert "stiffness = 50000.0" in text and "latency = 2" in text and "np." not in text
    assert ar.Scenario.from_dict(tomllib.loads(text)) == sc


# -- issue #57 part 1: nothing false (the controller's source on humble ad559d9, jazzy
# ed360c9, kilted 0f8eb14, rolling 94e74de) -------------------------------------------------


def test_the_force_set_point_goes_to_the_wrench_reference_and_humble_is_refused():
    sc = ar.paper.scenario("fig8")
    notes = _comments(ar.export.ros2_admittance(sc, None))
    assert ("REQUIRED: the force set-point f_d (step, 10 N at the end of the run) is not a"
            " parameter: publish it on the controller's ~/wrench_reference topic") in notes
    assert "send force = 10 N along the wall normal n (into the surface)" in notes
    assert "one message holds a constant f_d" in notes
    assert "ros2_controllers jazzy, ed360c9" in notes
    for version in ("kilted", "rolling"):
        assert f"ros2_controllers {version}" in ar.export.ros2_admittance(sc, None,
                                                                          version=version)
    sine = _comments(ar.export.ros2_admittance(
        sc.replace(force_reference=ar.Sine(offset=10.0, amplitude=2.0, omega=1.0)), None))
    assert "publish f_d(t) at the update rate" in sine
    with pytest.raises(ar.ExportError, match=r"humble \(ad559d9\): its admittance_controller has"
                       r" no force set-point input \(the ~/wrench_reference topic exists from"
                       r" jazzy on\)"):  # fmt: skip
        ar.export.ros2_admittance(sc, None, version="humble")
    with pytest.raises(ar.ParameterError, match=r"version = 'jazy' is invalid: must be one of"
                       r" humble, jazzy, kilted, rolling \(did you mean 'jazzy'\?\)"):  # fmt: skip
        ar.export.ros2_admittance(sc, None, version="jazy")


def test_the_pose_shift_recipe_overshoots_and_the_wrench_reference_does_not():
    """The advice this page used to give (shift the pose reference by f_d / K) against f_d
    as a force set-point, on fig. 14's cell with the export's own Scheme 1 suggestion
    (k = k_a k_e / 99 = 303 N/m), simulated with admit_rs's filter and TDC inner loop."""
    sc = ar.paper.scenario("fig14")
    k = sc.admittance.ka * sc.wall.stiffness / 99.0
    scheme1 = sc.replace(admittance=ar.AdmittanceFilter.scheme1(m=1.0, b=800.0, k=k, ka=1.0))
    wrench = ar.simulate(scheme1)
    shift = 10.0 / (k / 1.0)  # f_d / K into the wall, f_d = 0 in the filter
    shifted = ar.simulate(scheme1.replace(force_reference=ar.Step(value=0.0),
                                          **{"wall.position_error": shift}))  # fmt: skip
    assert wrench.metrics["force_peak"] == pytest.approx(12.6, abs=0.05)
    assert shifted.metrics["force_peak"] == pytest.approx(86.3, abs=0.05)
    # Both settle near 10 N: the recipe is exact once settled, and wrong on the way.
    assert shifted.trace["f"][-1] == pytest.approx(9.91, abs=0.01)
    # With an ideal inner loop the shifted reference would press k_e f_d / K.
    assert sc.wall.stiffness * 10.0 / k == pytest.approx(990.0)


def test_the_file_names_every_required_key_it_does_not_write():
    required = ["joints", "command_interfaces", "state_interfaces", "kinematics.plugin_name",
                "kinematics.plugin_package", "kinematics.base", "kinematics.tip",
                "ft_sensor.name", "ft_sensor.frame.id", "control.frame.id",
                "fixed_world_frame.frame.id", "gravity_compensation.frame.id",
                "gravity_compensation.CoG.pos"]  # fmt: skip
    notes = _comments(ar.export.ros2_admittance(ar.paper.scenario("fig8"), None))
    listed = notes.split("merge them in): ")[1].split(". Every frame")[0]
    assert listed.split(", ") == required
    assert "a frame outside the chain fails every update" in notes
    # A URDF arm: the file names its joints, base and tip, and lists the other ten.
    from pathlib import Path

    panda = ar.UrdfArm(Path(__file__).parent.parent / "examples" / "data" / "panda.urdf",
                       "panda_hand_tcp", q0=(0, -0.785, 0, -2.356, 0, 1.571, 0.785))
    sc = ar.paper.scenario("fig8").replace(robot=panda,
                                           controller=ar.TimeDelayControl.for_arm(panda))
    text = ar.export.ros2_admittance(sc, None)
    p = yaml.safe_load(text)["admittance_controller"]["ros__parameters"]
    assert p["joints"] == panda.joint_names and len(p["joints"]) == 7
    assert p["kinematics"] == {"base": "panda_link0", "tip": "panda_hand_tcp"}
    listed = _comments(text).split("merge them in): ")[1].split(". Every frame")[0]
    assert listed.split(", ") == [r for r in required
                                  if r not in ("joints", "kinematics.base", "kinematics.tip")]


@pytest.mark.parametrize(("change", "what"), [
    ({"admittance.sigma": 0.005}, "the adaptive term sigma = 0.005: the controller has no"
                                  " integral action on the force error"),
    ({"approach": ar.GuardedApproach()}, "the guarded approach: the controller is in force"
                                         " control from its activation"),
    ({"wall.position_error": 0.002}, "the wall estimate (position_error = 0.002 m): the"
                                     " controller has no surface model"),
    ({"sensor.bias": 0.3}, "the sensor bias 0.3: a property of your sensor"),
    ({"sensor.noise_std": 0.5}, "the sensor noise (std 0.5 N): your sensor's own"),
    ({"sensor.resolution": 0.01}, "the sensor resolution (0.01 N): your sensor's own"),
    ({"sensor.latency": 2}, "the sensor latency (2 periods): your sensor's and driver's own"),
])  # fmt: skip
def test_every_dropped_part_is_a_warning_and_a_header_line(change, what):
    sc = ar.paper.scenario("fig8").replace(**change)
    with pytest.warns(ar.export.ExportWarning) as record:
        text = ar.export.ros2_admittance(sc, None)
    messages = [str(r.message) for r in record]
    assert [m for m in messages if "not exported" in m] == [
        m for m in messages if m.startswith(f"ros2_admittance: not exported: {what}")]
    assert any(m.startswith(f"ros2_admittance: not exported: {what}") for m in messages)
    assert f"NOT EXPORTED: {what}" in _comments(text)
    # The paper's fig. 8 drops nothing.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "NOT EXPORTED" not in ar.export.ros2_admittance(ar.paper.scenario("fig8"), None)


def test_the_adaptive_filter_is_refused_naming_sigma():
    sc = ar.paper.scenario("fig14").replace(admittance=ar.AdmittanceFilter.adaptive())
    with pytest.raises(ar.ExportError, match=r"the adaptive filter \(admittance.sigma = 0.005,"
                       r" k = 0\) cannot be written for admittance_controller: the controller"
                       r" has no integral term on the force error"):  # fmt: skip
        ar.export.ros2_admittance(sc, None)
