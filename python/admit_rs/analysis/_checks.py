"""What every analysis checks first, and the describing-function gain of smoothed Coulomb
friction (shared by :mod:`admit_rs.analysis.linear` and :mod:`admit_rs.analysis.forced`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from admit_rs.config import Scenario
from admit_rs.errors import AnalysisError, ParameterError, ParameterTypeError

__all__ = ["friction_gain"]


def _check_scenario(scenario: Any, what: str) -> Scenario:
    if not isinstance(scenario, Scenario):
        raise ParameterTypeError(
            f"{what}() takes an admit_rs.Scenario, got {type(scenario).__name__}"
        )
    if scenario.substeps == "auto":
        # Said once, here, not as an error per cell (issue #53 item 10: tune() reported
        # "no gains keep every point predicted stable" instead).
        allowed = ("a count for the analysis (\"auto\" chooses one by comparing whole runs:"
                   " scenario.replace(substeps=ar.simulate(scenario).substeps) is its choice)")
        err = ParameterError(f'{what}(): substeps = "auto" is invalid: must be {allowed}')
        err.field, err.value, err.allowed = "substeps", '"auto"', allowed
        raise err
    return scenario


def friction_gain(amplitude: float, smoothing: float) -> float:
    """Describing-function gain of c·tanh(q̇/ε) for q̇ = A sin(ωt), relative to its slope
    c/ε at rest: (ε/(πA)) ∫₀^{2π} tanh(A sin θ / ε) sin θ dθ. 1 for A → 0, ≈ 4ε/(πA) for
    A ≫ ε.

    Example:
        >>> from admit_rs.analysis import friction_gain
        >>> friction_gain(0.0, 0.01), round(friction_gain(1.0, 0.01), 5)  # 4ε/(πA) = 0.01273
        (1.0, 0.01273)
    """
    if amplitude <= 0:
        return 1.0
    theta = np.linspace(0.0, 2 * np.pi, 2049)[:-1]
    ratio = amplitude / smoothing
    integral = float(np.mean(np.tanh(ratio * np.sin(theta)) * np.sin(theta))) * 2 * np.pi
    return integral / (np.pi * ratio)


def _check_friction(scenario: Scenario) -> None:
    robot = scenario.robot
    eps = getattr(robot, "friction_smoothing", 1.0)
    coulomb = getattr(robot, "coulomb_friction", 0.0)
    if eps is not None and eps <= 0 and np.any(np.asarray(coulomb) != 0):
        raise AnalysisError(
            "cannot linearise: exact Coulomb friction (robot.friction_smoothing <= 0) is not "
            "differentiable at rest; use a smoothing > 0 (the default is 0.01 rad/s)"
        )
