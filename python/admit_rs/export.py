"""Export a scenario's force loop to other control stacks, and a whole scenario as TOML.

:func:`ros2_admittance` writes the admittance part of the parameter file of
ros2_controllers' ``admittance_controller`` for the force axis (jazzy, kilted, rolling;
humble has no force set-point and is refused); docs/export.md gives the mapping, what the
file does not hold and what does not map. :func:`toml` writes a scenario in the layout
``admit-rs run`` and :meth:`Scenario.from_dict <admit_rs.Scenario.from_dict>` read.

Example:
    >>> import admit_rs as ar
    >>> sc = ar.paper.scenario("fig8")  # CT + Scheme 1: m = 1, b = 800, k = 400, k_a = 0.1
    >>> # A path instead of None also writes the file.
    >>> print(ar.export.ros2_admittance(sc, None))  # doctest: +ELLIPSIS
    # admittance_controller parameters (ros2_controllers jazzy, ed360c9) for the force axis ...
    # REQUIRED: the force set-point f_d (step, 10 N at the end of the run) is not a parameter:
    # publish it on the controller's ~/wrench_reference topic ...
    admittance_controller:
      ros__parameters:
        admittance:
          selected_axes: [true, false, false, false, false, false]
          mass: [10.0, 10.0, 10.0, 10.0, 10.0, 10.0]
          damping_ratio: [20.0, 0.0, 0.0, 0.0, 0.0, 0.0]
          stiffness: [4000.0, 0.0, 0.0, 0.0, 0.0, 0.0]
          joint_damping: 0.0
        ft_sensor:
          filter_coefficient: 1.0
    <BLANKLINE>
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import textwrap
import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import Any, Literal

import numpy as np

from admit_rs.config import AdmittanceFilter, Scenario, UrdfArm, _Block, describe
from admit_rs.errors import ExportError, ParameterError, ParameterTypeError, closest

__all__ = ["ExportWarning", "ros2_admittance", "sensor_filter_coefficient", "toml"]

_MASS_BOUNDS = (1e-4, 1e6)
_STIFFNESS_BOUNDS = (0.0, 1e8)
"""``element_bounds`` of admittance.mass and admittance.stiffness in
admittance_controller_parameters.yaml."""

MAX_DAMPING_RATIO = 1e6
"""The largest damping ratio written. The controller derives its damping from the ratio,
D = ζ · 2 √(M K); ζ = b / (2 √(m k)) above 1e6 means k is below b² / (4 m · 1e12) (1.6e-7
N/m for b = 800, m = 1): Scheme 2 in all but name, with a number in the file that no one
can read as a damping ratio. Such a k is refused (use a Scheme 1 k that means something)."""

ROS2_VERSIONS: dict[str, str] = {
    "humble": "ad559d9",
    "jazzy": "ed360c9",
    "kilted": "0f8eb14",
    "rolling": "94e74de",
}
"""The ros2_controllers branches this export follows, with the commit of each whose
``admittance_controller`` (its ``src/admittance_controller_parameters.yaml``,
``src/admittance_controller.cpp`` and ``include/admittance_controller/admittance_rule_impl.hpp``)
was read (rolling: master)."""

_REQUIRED = (
    "joints", "command_interfaces", "state_interfaces", "kinematics.plugin_name",
    "kinematics.plugin_package", "kinematics.base", "kinematics.tip", "ft_sensor.name",
    "ft_sensor.frame.id", "control.frame.id", "fixed_world_frame.frame.id",
    "gravity_compensation.frame.id", "gravity_compensation.CoG.pos",
)  # fmt: skip
"""The controller's parameters without a default (it refuses to load without them) that are
not the admittance's own (``admittance.selected_axes``, ``mass``, ``damping_ratio`` and
``stiffness``, always written); humble also requires ``robot_description``."""

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
"""A ROS 2 node name (rcl's rule: letters, digits and underscores, not starting with a
digit): the controller manager loads each controller as a node of that name."""


class ExportWarning(UserWarning):
    """A scenario exported with a requirement the file alone cannot meet (a tilted wall
    needs a rotated control frame in the chain), or with a part of it the controller has no
    equivalent of (the adaptive term σ, a guarded approach, the wall estimate's offset, the
    sensor's bias, noise, resolution and latency); the message and a line of the file say
    what it changes."""


def _yaml_float(x: float) -> str:
    """A float as YAML 1.1 and 1.2 both read it as a float (always a dot: ``1.0``,
    ``1.0e-05``); admittance_controller refuses integers in its double arrays."""
    text = repr(float(x))
    mantissa, e, exponent = text.partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    return mantissa + (e + exponent if e else "")


def _yaml_list(values: list[float] | list[bool]) -> str:
    items = [("true" if v else "false") if isinstance(v, bool) else _yaml_float(v) for v in values]
    return "[" + ", ".join(items) + "]"


def _comment(text: str) -> str:
    """Text safe inside a YAML comment: one line (control characters escaped)."""
    return text.encode("unicode_escape").decode("ascii")


def _wrap(text: str) -> list[str]:
    """A comment paragraph as ``# ``-lines of at most 92 characters."""
    return ["# " + line for line in textwrap.wrap(_comment(text), 90, break_on_hyphens=False)]


def sensor_filter_coefficient(scenario: Scenario) -> float:
    """``ft_sensor.filter_coefficient`` equivalent to the scenario's force-sensor low-pass:
    α = 1 − exp(−2π f_c T) (the sensor's y_k = y_{k−1} + α (u_k − y_{k−1}) is the
    controller's exponential smoothing with that coefficient); 1.0 without a low-pass.

    Example:
        >>> import admit_rs as ar
        >>> sc = ar.paper.scenario("fig8").replace(sensor=ar.ForceSensor(cutoff=30.0))
        >>> round(ar.export.sensor_filter_coefficient(sc), 4)
        0.1718
    """
    cutoff = scenario.sensor.cutoff
    if cutoff is None:
        return 1.0
    return float(-math.expm1(-2.0 * math.pi * cutoff * scenario.period))


def _control_frame(scenario: Scenario) -> tuple[np.ndarray, list[float]] | None:
    """For a wall whose normal is not +x: the rotation R (columns: the control frame's x =
    n̂, y = t̂ × n̂, z = t̂ in the base frame) and its quaternion [x, y, z, w]."""
    wall = scenario.wall
    if wall is None or not wall.tilted:
        return None
    n, t = wall.directions()
    rot = np.column_stack([n, np.cross(t, n), t])
    # Shepperd's method on a proper rotation (det = +1 by construction).
    m = rot
    tr = float(np.trace(m))
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0, 0.0, 0.0, (m[k, j] - m[j, k]) / s]
        q[i] = s / 4
        q[j] = (m[j, i] + m[i, j]) / s
        q[k] = (m[k, i] + m[i, k]) / s
    return rot, [float(v) for v in q]


def ros2_admittance(
    scenario: Scenario,
    path: str | os.PathLike[str] | None,
    *,
    controller_name: str = "admittance_controller",
    filter_coefficient: float | Literal["sensor"] | None = "sensor",
    joint_damping: float = 0.0,
    version: str = "jazzy",
) -> str:
    """Writes the admittance part of a ros2_controllers ``admittance_controller`` parameter
    file for ``scenario``'s force axis; returns the YAML text (``path=None``: only returns).

    The filter m ẍ_a + b ẋ_a + k x_a = k_a e_f of eq. (30) becomes the controller's
    M ẍ + D ẋ + K x = F with M = m/k_a, K = k/k_a and damping_ratio ζ = b / (2 √(m k))
    (the controller computes D = ζ · 2 √(M K) = b/k_a). Only x, the wall normal, is selected;
    the other five axes get the same mass and K = 0, ζ = 0 (the controller zeroes only their
    force: a stiffness there would pull them along the robot's tracking error). The force
    set-point f_d is the controller's ``~/wrench_reference`` topic (jazzy on), which the
    file's header says how to publish; humble has no such input and is refused. For a URDF
    arm the file also names ``joints``, ``kinematics.base`` and ``kinematics.tip``; every
    other parameter the controller requires is listed in the header (docs/export.md).

    Args:
        scenario: a scenario whose ``admittance`` is an :class:`~admit_rs.AdmittanceFilter`
            with k > 0 (Scheme 1).
        path: the YAML file to write, or ``None``.
        controller_name: the controller's name in the controller manager (top-level key):
            a ROS 2 node name (letters, digits, underscores; not starting with a digit).
        filter_coefficient: ``ft_sensor.filter_coefficient`` of the controller's exponential
            F/T filter. ``"sensor"`` (default): the scenario's sensor low-pass,
            1 − exp(−2π f_c T) (:func:`sensor_filter_coefficient`; 1.0, the raw
            measurement, without one); a number in (0, 1]; ``None`` leaves the key out (the
            controller then uses its default, 0.05; the key exists on every branch read).
        joint_damping: ``admittance.joint_damping`` [1/s]. The controller subtracts
            joint_damping · q̇ from the admittance's joint accelerations (default 5 when the
            key is absent); eq. (30) has no such term, so 0.0 is written unless you ask.
        version: the ros2_controllers release the file is for: ``"humble"``, ``"jazzy"``
            (default), ``"kilted"`` or ``"rolling"`` (:data:`ROS2_VERSIONS`).

    Raises:
        ExportError: the force loop has no faithful admittance_controller equivalent:
            Scheme 2 (k = 0: D = ζ · 2 √(M · 0) = 0, no damping whatever ζ), k so small
            that ζ > :data:`MAX_DAMPING_RATIO`, the adaptive term σ without a stiffness,
            k_a = 0, the eq. (20) impedance baseline, no force loop, values outside the
            controller's bounds, or ``version="humble"`` (no force set-point input). The
            message names the nearest faithful alternative.
        ParameterError: ``controller_name``, ``filter_coefficient``, ``joint_damping`` or
            ``version`` out of range (a name that is no ROS 2 node name would also inject
            YAML; a misspelt version names the closest).

    Warns:
        ExportWarning: the wall normal is not +x (the control frame must be a rotated link
            of the chain: the file's header gives it); the surface is not a plane (the
            file's fixed frame is the surface's normal at the start only); and one warning
            for each part of the scenario the controller has no equivalent of (the adaptive
            term σ, a guarded approach, the wall estimate's offset, the sensor's bias,
            noise, resolution, latency), each also a ``NOT EXPORTED`` line of the header
            saying what it changes.
    """
    if not isinstance(scenario, Scenario):
        kind = type(scenario).__name__
        raise ParameterTypeError(f"ros2_admittance takes an admit_rs.Scenario, got {kind}")
    if not isinstance(controller_name, str) or not _NAME.fullmatch(controller_name):
        raise _bad("controller_name", repr(controller_name),
                   "a ROS 2 node name: letters, digits and underscores, not starting with a"
                   " digit (e.g. 'admittance_controller')")  # fmt: skip
    if isinstance(joint_damping, bool) or not isinstance(joint_damping, int | float) or not (
        math.isfinite(joint_damping) and joint_damping >= 0.0
    ):
        raise _bad("joint_damping", repr(joint_damping), "a finite number >= 0 [1/s]")
    if not isinstance(version, str) or version not in ROS2_VERSIONS:
        near = closest(version, ROS2_VERSIONS) if isinstance(version, str) else []
        raise _bad("version", repr(version), "one of " + ", ".join(ROS2_VERSIONS)
                   + (f" (did you mean {near[0]!r}?)" if near else ""))  # fmt: skip
    adm = scenario.admittance
    if not isinstance(adm, AdmittanceFilter):
        what = "no force loop" if adm is None else "the eq. (20) impedance reference"
        raise ExportError(
            f"admittance is {what}: admittance_controller is an admittance filter driven by the"
            " measured force; nearest faithful alternative: an AdmittanceFilter.scheme1(...)"
        )
    if adm.ka == 0.0:
        raise ExportError(
            "admittance.ka = 0 disconnects the force feedback; admittance_controller has no"
            " such setting (its mass would be m / k_a = inf)"
        )
    hint = ""
    if scenario.wall is not None:
        k_hint = adm.ka * scenario.wall.stiffness / 99.0
        hint = (
            f" For example admittance.k = {k_hint:.4g} N/m keeps the steady-state force"
            f" error at 1 % of f_d against this wall (k_e = {scenario.wall.stiffness:g} N/m,"
            " r = k_a k_e / k = 99, with an ideal inner loop)."
        )
    if adm.k == 0.0 and adm.sigma != 0.0:
        raise ExportError(
            f"the adaptive filter (admittance.sigma = {adm.sigma:g}, k = 0) cannot be written"
            " for admittance_controller: the controller has no integral term on the force"
            " error (sigma), and without a stiffness it has no damping either (it computes"
            " D = damping_ratio * 2 * sqrt(M * K), 0 when K = 0). Nearest faithful"
            " alternative: Scheme 1 with a small stiffness k > 0 and sigma = 0, which keeps a"
            " steady-state force offset f_d / (1 + r), r = k_a k_e / k; simulate that scenario"
            " before exporting it." + hint
        )
    if adm.k == 0.0:
        raise ExportError(
            "Scheme 2 (admittance.k = 0) cannot be written for admittance_controller: it"
            " computes its damping as D = damping_ratio * 2 * sqrt(M * K), which is 0 when"
            " K = 0 whatever the ratio, so the exported filter would have no damping"
            f" instead of b = {adm.b:g} N*s/m. Nearest faithful alternative: Scheme 1 with a"
            " small stiffness k > 0 (it keeps a steady-state force offset f_d / (1 + r),"
            " r = k_a k_e / k); simulate that scenario before exporting it." + hint
        )
    mass = adm.m / adm.ka
    stiffness = adm.k / adm.ka
    zeta = adm.b / (2.0 * math.sqrt(adm.m * adm.k))
    if not zeta <= MAX_DAMPING_RATIO:
        k_min = adm.b**2 / (4.0 * adm.m * MAX_DAMPING_RATIO**2)
        raise ExportError(
            f"admittance.k = {adm.k:.4g} N/m gives damping_ratio = b / (2 sqrt(m k)) ="
            f" {zeta:.3g}, above {MAX_DAMPING_RATIO:g}: admittance_controller derives its"
            " damping from that ratio and K = k / k_a, and a k this small is Scheme 2 in all"
            f" but name. Nearest faithful alternative: admittance.k >= {k_min:.3g} N/m, or a"
            " Scheme 1 stiffness chosen for its force offset." + hint
        )
    if not _MASS_BOUNDS[0] <= mass <= _MASS_BOUNDS[1]:
        raise ExportError(f"mass m / k_a = {mass:g} kg is outside admittance_controller's"
                          f" bounds {list(_MASS_BOUNDS)}")  # fmt: skip
    if not _STIFFNESS_BOUNDS[0] <= stiffness <= _STIFFNESS_BOUNDS[1]:
        raise ExportError(f"stiffness k / k_a = {stiffness:g} N/m is outside"
                          f" admittance_controller's bounds {list(_STIFFNESS_BOUNDS)}")  # fmt: skip
    if isinstance(filter_coefficient, str):
        if filter_coefficient != "sensor":
            raise _bad("filter_coefficient", repr(filter_coefficient),
                       "'sensor', a number in (0, 1] or None")  # fmt: skip
        alpha: float | None = sensor_filter_coefficient(scenario)
    else:
        alpha = filter_coefficient
    if alpha is not None and (isinstance(alpha, bool) or not 0.0 < alpha <= 1.0):
        raise _bad("filter_coefficient", repr(alpha), "a number in (0, 1], 'sensor' or None")
    if version == "humble":
        raise ExportError(
            f"ros2_controllers humble ({ROS2_VERSIONS['humble']}): its admittance_controller has"
            " no force set-point input (the ~/wrench_reference topic exists from jazzy on), so"
            f" f_d = {_final_force(scenario):g} N cannot reach it. Shifting the pose reference"
            " by f_d / K into the surface instead is a step of the position reference into"
            " the wall: with a stiff inner loop the force peaks near k_e f_d / K before the"
            " admittance yields (docs/export.md). Nearest faithful alternative: export for"
            " version='jazzy' (or later) and publish f_d on ~/wrench_reference."
        )

    cutoff = scenario.sensor.cutoff
    f_d = _final_force(scenario)
    notes = [
        f"admittance_controller parameters (ros2_controllers {version},"
        f" {ROS2_VERSIONS[version]}) for the force axis of the admit_rs scenario:"
        f" {describe(scenario)}.",
        f"m = {adm.m:g} kg, b = {adm.b:g} N*s/m, k = {adm.k:g} N/m, k_a = {adm.ka:g}: M = m/k_a,"
        " K = k/k_a, damping_ratio = b/(2 sqrt(m k)). Only x (the wall normal of the control"
        " frame) is selected; the other axes have K = 0 and damping_ratio = 0 (the controller"
        " zeroes only their force, so a stiffness there would pull them along the robot's"
        " tracking error).",
        "joint_damping (the controller's extra joint-space damping q'' -= joint_damping q',"
        f" 5 if absent) is {_yaml_float(joint_damping)}"
        + (": eq. (30) has none." if joint_damping == 0.0 else
           ", which eq. (30) does not have: the controller is damped more than the"
           " simulated filter."),
        f"REQUIRED: the force set-point f_d ({_force_words(scenario)}) is not a parameter:"
        " publish it on the controller's ~/wrench_reference topic (geometry_msgs/WrenchStamped,"
        " header.frame_id = ft_sensor.frame.id). The controller adds that wrench to the"
        f" measured one, so send force = {f_d:g} N along the wall normal n (into the surface)"
        " expressed in the sensor frame, torque 0"
        + ("; one message holds a constant f_d." if _constant_force(scenario) else
           "; publish f_d(t) at the update rate.")
        + " Do not shift the pose reference by f_d / K instead: that steps the reference into"
        " the wall (docs/export.md).",
    ]
    if filter_coefficient is None:
        notes.append("ft_sensor.filter_coefficient is left out: the controller then smooths"
                     " the wrench with its default 0.05.")  # fmt: skip
    elif cutoff is not None and filter_coefficient == "sensor":
        notes.append(f"ft_sensor.filter_coefficient = 1 - exp(-2 pi f_c T): the sensor's"
                     f" {cutoff:g} Hz low-pass at T = {scenario.period:g} s.")  # fmt: skip
    known, base = _chain(scenario)
    missing = [k for k in _REQUIRED if k not in known]
    notes.append(
        "REQUIRED, not in this file (the controller refuses to load without them; they"
        f" describe your cell, merge them in): {', '.join(missing)}."
        + (" Every frame (control.frame.id, ft_sensor.frame.id, fixed_world_frame.frame.id,"
           " gravity_compensation.frame.id) must be a link of the chain from kinematics.base"
           " to kinematics.tip: the controller resolves them only through its kinematics"
           " plugin, and a frame outside the chain fails every update, which then passes the"
           " reference through: no admittance.")
    )
    frame = _control_frame(scenario)
    if frame is not None:
        rot, quat = frame

        def fmt(values: Iterable[float]) -> str:
            return ", ".join(f"{v + 0.0:.6g}" for v in values)  # + 0.0: no "-0"

        roll, pitch, yaw = _rpy(rot.T)
        message = (
            f"the wall normal n = ({fmt(rot[:, 0])}) is not the x axis: control.frame.id must"
            " be a link of the chain whose x axis is n (its z along the motion direction t);"
            f" relative to the base frame its rotation is the quaternion [x, y, z, w] ="
            f" [{fmt(quat)}]. A TF frame published elsewhere is not seen (no admittance). Add"
            " it to the URDF as the chain's root: a link 'admittance_control_frame' with a"
            f" fixed joint to {base} (parent admittance_control_frame, child {base}, origin"
            f" rpy = '{fmt((roll, pitch, yaw))}'), and set kinematics.base and"
            " control.frame.id to admittance_control_frame"
        )
        warnings.warn(f"ros2_admittance: {message}", ExportWarning, stacklevel=2)
        notes += [
            "REQUIRED: " + message[0].upper() + message[1:] + ".",
            "Rotation matrix (rows; columns are the control frame's x, y, z in the base"
            f" frame): {'; '.join(fmt(row) for row in rot)}.",
        ]
    wall = scenario.wall
    if wall is not None and not wall.planar:
        message = (
            f"the surface is a {type(wall).__name__}, not a plane: admittance_controller"
            " keeps one fixed control frame, so the force axis above is the surface's normal"
            " at the start only; on a curved part the normal turns under the tool and this"
            " file does not follow it"
        )
        warnings.warn(f"ros2_admittance: {message}", ExportWarning, stacklevel=2)
        notes.append("WARNING: " + message[0].upper() + message[1:] + ".")
    for what, changes in _not_exported(scenario):
        warnings.warn(f"ros2_admittance: not exported: {what}: {changes}", ExportWarning,
                      stacklevel=2)  # fmt: skip
        notes.append(f"NOT EXPORTED: {what}: {changes}.")
    if wall is not None and wall.friction:
        notes.append(f"Not exported: the surface's friction (mu = {wall.friction:g}) is part of"
                     " the simulated world, not of the controller.")  # fmt: skip
    sensor = scenario.sensor
    tool = sensor.tool_mass if sensor.tool_mass_estimate is None else sensor.tool_mass_estimate
    weight = tool * _gravity(scenario)
    if weight > 0.0:
        notes.append(f"gravity_compensation: the tool the controller believes, {tool:g} kg at"
                     f" the tip origin (CoG.force = m g = {weight:g} N); set"
                     " gravity_compensation.frame.id to the tool (tip) frame.")  # fmt: skip
    notes.append(
        "Not exported (see docs/export.md): the inner loop, the period"
        f" T = {scenario.period:g} s (the controller manager's update_rate). The controller's"
        " own law (semi-implicit Euler in joint space through a damped pseudo-inverse, its"
        " stiffness on the measured pose, the current force sample) is not admit_rs's filter:"
        " the responses differ, most with a slow inner loop."
    )
    lines = [line for note in notes for line in _wrap(note)]
    lines += [f"{controller_name}:", "  ros__parameters:"]
    if known:
        lines += [f"    joints: [{', '.join(known['joints'])}]",
                  "    kinematics:",
                  f"      base: {known['kinematics.base']}",
                  f"      tip: {known['kinematics.tip']}"]  # fmt: skip
    lines += [
        "    admittance:",
        f"      selected_axes: {_yaml_list([True] + [False] * 5)}",
        f"      mass: {_yaml_list([mass] * 6)}",
        f"      damping_ratio: {_yaml_list([zeta] + [0.0] * 5)}",
        f"      stiffness: {_yaml_list([stiffness] + [0.0] * 5)}",
        f"      joint_damping: {_yaml_float(joint_damping)}",
    ]
    if alpha is not None:
        lines += ["    ft_sensor:", f"      filter_coefficient: {_yaml_float(alpha)}"]
    if weight > 0.0:
        lines += [
            "    gravity_compensation:",
            "      CoG:",
            f"        pos: {_yaml_list([0.0, 0.0, 0.0])}",
            f"        force: {_yaml_float(weight)}",
        ]
    text = "\n".join(lines) + "\n"
    if path is not None:
        Path(path).write_text(text, encoding="utf-8")
    return text


def _final_force(scenario: Scenario) -> float:
    """f_d at the end of the run [N]."""
    return float(np.asarray(scenario.force_reference(scenario.duration)))


def _constant_force(scenario: Scenario) -> bool:
    """f_d is one value from t = 0 (a step at t = 0, or a constant)."""
    ref = scenario.force_reference
    times = np.linspace(0.0, scenario.duration, 64)
    values = np.asarray([float(np.asarray(ref(t))) for t in times])
    return bool(np.all(values == values[-1]))


def _force_words(scenario: Scenario) -> str:
    ref = scenario.force_reference
    return f"{type(ref).__name__.lower()}, {_final_force(scenario):g} N at the end of the run"


def _chain(scenario: Scenario) -> tuple[dict[str, Any], str]:
    """What admit_rs knows of the controller's required keys for a URDF arm (``joints``,
    ``kinematics.base``, ``kinematics.tip``), and the base link's name (a placeholder for
    the three-link arm, which has no URDF)."""
    robot = scenario.robot
    if not isinstance(robot, UrdfArm):
        return {}, "your base link"
    base = robot.base_link or _urdf_root(robot.urdf)
    known = {"joints": robot.joint_names, "kinematics.base": base,
             "kinematics.tip": robot.tip_link}  # fmt: skip
    return known, base


def _urdf_root(document: str) -> str:
    """The URDF's root link: the link that is no joint's child."""
    import xml.etree.ElementTree as ET

    tree = ET.fromstring(document)
    children = {c.get("link") for c in tree.iter("child")}
    roots = [link.get("name", "") for link in tree.iter("link") if link.get("name") not in children]
    return roots[0] if roots else "your base link"


def _rpy(rot: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw of a rotation R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = math.asin(max(-1.0, min(1.0, -float(rot[2, 0]))))
    if abs(math.cos(pitch)) > 1e-9:
        roll = math.atan2(float(rot[2, 1]), float(rot[2, 2]))
        yaw = math.atan2(float(rot[1, 0]), float(rot[0, 0]))
    else:  # gimbal lock: put it all in yaw
        roll = 0.0
        yaw = math.atan2(-float(rot[0, 1]), float(rot[1, 1]))
    return roll, pitch, yaw


def _not_exported(scenario: Scenario) -> list[tuple[str, str]]:
    """The scenario's parts the controller has no equivalent of, each with what leaving it
    out changes (SPEC §22: every dropped concept is said)."""
    out: list[tuple[str, str]] = []
    adm = scenario.admittance
    if isinstance(adm, AdmittanceFilter) and adm.sigma != 0.0:
        out.append((f"the adaptive term sigma = {adm.sigma:g}", "the controller has no"
                    " integral action on the force error; with this file the steady force"
                    " is Scheme 1's f_d / (1 + r), r = k_a k_e / k, not the simulated one"))
    if scenario.approach is not None:
        out.append(("the guarded approach", "the controller is in force control from its"
                    " activation; bring the tool to the surface yourself (slowly) first, or"
                    " the first contact is the impact of the unguarded run"))
    wall = scenario.wall
    offset = wall.position_error if wall is not None else 0.0
    if offset != 0.0 or scenario.wall_estimate is not None:
        out.append((f"the wall estimate (position_error = {offset:g} m"
                    + (", a wall_estimate surface" if scenario.wall_estimate is not None else "")
                    + ")", "the controller has no surface model: the pose reference you send"
                    " plays x_e's role; send the pose the simulated controller believed"))
    sensor = scenario.sensor
    bias = np.atleast_1d(np.asarray(sensor.bias, dtype=float))
    if np.any(bias != 0.0):
        out.append((f"the sensor bias {sensor.bias}", "a property of your sensor, not of the"
                    " controller: zero (tare) it, or the true force settles at f_d minus it"))
    if sensor.noise_std:
        out.append((f"the sensor noise (std {sensor.noise_std:g} N)", "your sensor's own;"
                    " the simulated ripple assumed this much"))
    if sensor.resolution:
        out.append((f"the sensor resolution ({sensor.resolution:g} N)", "your sensor's own;"
                    " the simulated loop assumed it"))
    if sensor.latency:
        out.append((f"the sensor latency ({sensor.latency} periods)", "your sensor's and"
                    " driver's own; the simulated loop's margins assumed it"))
    return out


def _gravity(scenario: Scenario) -> float:
    """The arm's gravity [m/s²] (both arm blocks have the field)."""
    return float(getattr(scenario.robot, "gravity", 9.81))


def _bad(name: str, value: str, allowed: str) -> ParameterError:
    err = ParameterError(f"{name} = {value} is invalid: must be {allowed}")
    err.field, err.value, err.allowed = name, value, allowed
    return err


def _toml_value(value: Any, where: str) -> str:
    """One TOML value: a bool, number, string or (nested) array."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
        return repr(value)
    if isinstance(value, str | Path):
        # A JSON string is a TOML basic string (the same escapes, \\uXXXX included).
        return json.dumps(str(value), ensure_ascii=False)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml_value(v, where) for v in value) + "]"
    raise ExportError(f"{where}: cannot write a {type(value).__name__} as TOML")


def _toml_table(block: _Block, name: str, out: list[str]) -> None:
    """``[name]`` with the block's scalar fields, then its sub-blocks as ``[name.sub]``;
    ``None`` fields are left out where ``None`` is the default (what leaving a key out gives
    back), else written ``false``."""
    lines: list[str] = []
    if block._kind is not None:
        lines.append(f"kind = {_toml_value(block._kind, name)}")
    subs: list[tuple[str, _Block]] = []
    for f in dataclasses.fields(block):  # type: ignore[arg-type]
        value = getattr(block, f.name)
        where = f"{name}.{f.name}" if name else f.name
        if isinstance(block, UrdfArm) and f.name in ("path", "urdf"):
            value = _urdf_source(block, f.name)
            if value is None:
                continue  # the arm is written by its file or by its document, not both
        if value is None or (f.name == "label" and value == ""):
            # A None that is not the default (the scenario's wall, an approach's
            # acceleration): leaving the key out would give the default back.
            not_default = name == "" or f.default is not dataclasses.MISSING
            if value is None and f.default is not None and not_default:
                lines.append(f"{f.name} = false  # None (TOML has no null)")
            continue
        if isinstance(value, _Block):
            subs.append((where, value))
        else:
            lines.append(f"{f.name} = {_toml_value(value, where)}")
    if name:
        out.append(f"\n[{name}]")
    out.extend(lines)
    for where, sub in subs:
        _toml_table(sub, where, out)


def _urdf_source(arm: UrdfArm, field: str) -> str | None:
    """A URDF arm is written by its file's absolute path when that file still holds the
    arm's document, else by the document itself."""
    path = Path(arm.path) if arm.path else None
    try:
        same = path is not None and path.read_text(encoding="utf-8") == arm.urdf
    except OSError:
        same = False
    if field == "path":
        return str(path.resolve()) if same and path is not None else None
    return None if same else arm.urdf


def toml(scenario: Scenario, path: str | os.PathLike[str] | None = None) -> str:
    """The scenario as a TOML document in the layout of :meth:`Scenario.to_dict` (what
    ``admit-rs run`` reads); returns the text and, given ``path``, writes it there.

    Every field is written, so the file does not depend on later changes of the defaults;
    ``None`` fields are left out, except where ``None`` is not the default (``wall`` and
    ``admittance``, whose defaults are blocks; ``approach.acceleration``), written ``false``.
    A URDF arm is written by its file's absolute path, or by its document when the file no
    longer holds it. :meth:`Scenario.from_dict` of the parsed
    text gives the scenario back.

    Example:
        >>> import admit_rs as ar, tomllib
        >>> sc = ar.paper.scenario("fig5")           # position only: no wall, no filter
        >>> text = ar.export.toml(sc)
        >>> ar.Scenario.from_dict(tomllib.loads(text)) == sc
        True
        >>> print(text.splitlines()[0])
        wall = false  # None (TOML has no null)
    """
    if not isinstance(scenario, Scenario):
        raise ParameterTypeError(
            f"toml() takes an admit_rs.Scenario, got {type(scenario).__name__}"
        )
    out: list[str] = []
    _toml_table(scenario, "", out)
    text = "\n".join(out) + "\n"
    if path is not None:
        Path(path).write_text(text, encoding="utf-8")
    return text
