"""Export a scenario's force loop to other control stacks.

:func:`ros2_admittance` writes the parameter file of ros2_controllers'
``admittance_controller`` for the force axis; docs/export.md gives the mapping and what
does not map.

Example:
    >>> import admit_rs as ar
    >>> sc = ar.paper.scenario("fig8")  # CT + Scheme 1: m = 1, b = 800, k = 400, k_a = 0.1
    >>> # A path instead of None also writes the file.
    >>> print(ar.export.ros2_admittance(sc, None))  # doctest: +ELLIPSIS
    # admittance_controller parameters for the force axis of admit_rs scenario ...
    admittance_controller:
      ros__parameters:
        admittance:
          selected_axes: [true, false, false, false, false, false]
          mass: [10.0, 10.0, 10.0, 10.0, 10.0, 10.0]
          damping_ratio: [20.0, 20.0, 20.0, 20.0, 20.0, 20.0]
          stiffness: [4000.0, 4000.0, 4000.0, 4000.0, 4000.0, 4000.0]
        ft_sensor:
          filter_coefficient: 1.0
    <BLANKLINE>
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from admit_rs.config import AdmittanceFilter, Scenario
from admit_rs.errors import ExportError

__all__ = ["ros2_admittance"]

_MASS_BOUNDS = (1e-4, 1e6)
_STIFFNESS_BOUNDS = (0.0, 1e8)
"""``element_bounds`` of admittance.mass and admittance.stiffness in
admittance_controller_parameters.yaml."""


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


def ros2_admittance(
    scenario: Scenario,
    path: str | os.PathLike[str] | None,
    *,
    controller_name: str = "admittance_controller",
    filter_coefficient: float | None = 1.0,
) -> str:
    """Writes the admittance part of a ros2_controllers ``admittance_controller`` parameter
    file for ``scenario``'s force axis; returns the YAML text (``path=None``: only returns).

    The filter m ẍ_a + b ẋ_a + k x_a = k_a e_f of eq. (30) becomes the controller's
    M ẍ + D ẋ + K x = F with M = m/k_a, K = k/k_a and damping_ratio ζ = b / (2 √(m k))
    (the controller computes D = ζ · 2 √(M K) = b/k_a). Only x, the wall normal, is selected;
    the other five axes repeat x's values so that the file passes the controller's bounds.

    Args:
        scenario: a scenario whose ``admittance`` is an :class:`~admit_rs.AdmittanceFilter`
            with k > 0 (Scheme 1).
        path: the YAML file to write, or ``None``.
        controller_name: the controller's name in the controller manager (top-level key).
        filter_coefficient: ``ft_sensor.filter_coefficient`` of the controller's exponential
            F/T filter (1.0: the raw measurement, as admit_rs simulates it); ``None`` leaves
            the key out (releases that replaced it by a ``sensor_filter_chain``).

    Raises:
        ExportError: the force loop has no faithful admittance_controller equivalent:
            Scheme 2 (k = 0: D = ζ · 2 √(M · 0) = 0, no damping whatever ζ), k_a = 0, the
            eq. (20) impedance baseline, no force loop, or values outside the controller's
            bounds. The message names the nearest faithful alternative.
    """
    if not isinstance(scenario, Scenario):
        kind = type(scenario).__name__
        raise TypeError(f"ros2_admittance takes an admit_rs.Scenario, got {kind}")
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
    if adm.k == 0.0:
        hint = ""
        if scenario.wall is not None:
            k_hint = adm.ka * scenario.wall.stiffness / 99.0
            hint = (
                f" For example admittance.k = {k_hint:.4g} N/m keeps the steady-state force"
                f" error at 1 % of f_d against this wall (k_e = {scenario.wall.stiffness:g} N/m,"
                " r = k_a k_e / k = 99, with an ideal inner loop)."
            )
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
    if not _MASS_BOUNDS[0] <= mass <= _MASS_BOUNDS[1]:
        raise ExportError(f"mass m / k_a = {mass:g} kg is outside admittance_controller's"
                          f" bounds {list(_MASS_BOUNDS)}")  # fmt: skip
    if not _STIFFNESS_BOUNDS[0] <= stiffness <= _STIFFNESS_BOUNDS[1]:
        raise ExportError(f"stiffness k / k_a = {stiffness:g} N/m is outside"
                          f" admittance_controller's bounds {list(_STIFFNESS_BOUNDS)}")  # fmt: skip
    if filter_coefficient is not None and not 0.0 < filter_coefficient <= 1.0:
        raise ExportError(f"filter_coefficient = {filter_coefficient} must be in (0, 1]")

    label = scenario.label or "(no label)"
    lines = [
        f"# admittance_controller parameters for the force axis of admit_rs scenario {label!r}.",
        f"# m = {adm.m:g} kg, b = {adm.b:g} N*s/m, k = {adm.k:g} N/m, k_a = {adm.ka:g}:",
        "# M = m/k_a, K = k/k_a, damping_ratio = b/(2 sqrt(m k)). Only x (the wall normal of",
        "# the control frame) is selected. Not exported (see docs/export.md): f_d, the inner",
        f"# loop, the period T = {scenario.period:g} s (the controller manager's update_rate).",
        f"{controller_name}:",
        "  ros__parameters:",
        "    admittance:",
        f"      selected_axes: {_yaml_list([True] + [False] * 5)}",
        f"      mass: {_yaml_list([mass] * 6)}",
        f"      damping_ratio: {_yaml_list([zeta] * 6)}",
        f"      stiffness: {_yaml_list([stiffness] * 6)}",
    ]
    if filter_coefficient is not None:
        lines += ["    ft_sensor:", f"      filter_coefficient: {_yaml_float(filter_coefficient)}"]
    text = "\n".join(lines) + "\n"
    if path is not None:
        Path(path).write_text(text, encoding="utf-8")
    return text
