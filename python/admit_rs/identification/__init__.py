"""Your cell, fitted from your recording (SPEC §21, issue #58 parts 2–5): :func:`identify` turns
a table of :func:`~admit_rs.read_log` (joint states and the flange force) into a
:class:`CellFit`: the sensor's bias, noise, low-pass and latency, the tool's weight, and a
plane surface's position, normal, contact law and friction, each with a confidence interval
and how it was obtained, or unidentified with the reason.

The model is the simulator's own (SPEC §10, §15; ``ForceSensor(frame="tip")``): the sensor
reads u_k = R_kᵀ (F_k + w) + β + noise in the tip frame, F_k the force on the surface, w =
(0, 0, m g) the tool's weight held up by the arm, β the bias; then a first-order low-pass
y_k = y_{k−1} + α (u_k − y_{k−1}), α = 1 − exp(−2π f_c T), and a latency of L samples. The
surface is a plane {X : n·X = x_e}; the tip presses on it with f = k δ + c δ̇ (Kelvin–Voigt)
or f = k δ^p + c δ^p δ̇ (Hunt–Crossley), δ = n·X − x_e, and slides with Coulomb friction
μ f v_t / √(|v_t|² + v_s²).

How each number is obtained (the :attr:`CellFit.how` of each path says it again):

1. **Free space** (the samples whose reading the static model explains): β and m by linear
   least squares on y_k = β + R_kᵀ (0, 0, g) m. The mass needs the tool's orientation to
   change in free space; with one orientation the bias absorbs the weight in that pose and
   the mass is unidentified. The noise level from the residuals.
2. **Contact** (the rest): the normal force the sensor reports, n·R_k (y_k − β) − n·w, is
   the contact law passed through the same low-pass and latency. For each latency L and
   cut-off f_c the law is linear in (k, c, k x_e), so each pair costs one least-squares
   solve on regressors filtered like the reading; L is searched over whole samples, f_c by
   a bounded scalar search, and the pair of least residual kept. The normal is the mean
   force direction where friction is known: sliding (its part along the velocity taken
   out) or still; the law tilts it where the tip moved along the surface. Hunt–Crossley is fitted
   from there by nonlinear least squares and chosen only if an F-test at the confidence
   level prefers it.
3. **Friction**, where the tip slid steadily one way (faster than 10 v_s for the filter's
   settling time): μ by least squares of the tangential force read on the normal force read
   times v_t / √(|v_t|² + v_s²) (both pass through the same filter), with v_s the surface's
   default (it is not identifiable at recorded speeds).

Intervals are (1 − confidence) two-sided, from the least-squares covariance with the
residuals' lag-one autocorrelation taken into account (an AR(1) effective sample count: the
low-pass makes neighbouring residuals alike, and ordinary least squares would claim too much),
united over every latency and cut-off the residual's profile admits (an F-test). The fit's
:attr:`CellFit.doubts` say when not to trust it; :meth:`CellFit.check` and
:meth:`CellFit.report` replay another recording through the fitted cell. Not built yet (issue
#58 stays open): the centre of mass (it needs the torques and the six-axis tool of SPEC §19),
curved surfaces other than a sphere touched from outside (``surface="sphere"``:
``identification/sphere.py``), the speed for long logs. docs/identify.md has the rest.
"""

from __future__ import annotations

import polars as pl

from admit_rs.blocks.robot import UrdfArm
from admit_rs.errors import ArgumentError, ParameterTypeError
from admit_rs.identification.cell_fit import CellFit
from admit_rs.identification.fitter import Fitter
from admit_rs.identification.log_arrays import LogArrays
from admit_rs.identification.model import STICTION_VELOCITY

__all__ = ["STICTION_VELOCITY", "CellFit", "identify"]


def identify(
    log: pl.DataFrame,
    robot: UrdfArm,
    *,
    surface: str = "plane",
    confidence: float = 0.95,
    stiction_velocity: float = STICTION_VELOCITY,
) -> CellFit:
    """Fits the cell a recording shows (the module's docstring has the model and each step).

    ``log``: a table of :func:`~admit_rs.read_log` (``t``, ``q.<joint>`` for every joint of
    ``robot``, optionally ``qd.<joint>``, ``fx``, ``fy``, ``fz``, optionally
    ``wrench_frame``: the wrench is read in the tip link's frame unless that column names
    the base link). ``surface``: ``"plane"``, or ``"sphere"`` (a ball touched from outside:
    ``wall.centre`` in the base frame and ``wall.radius`` instead of ``wall.normal`` and
    ``wall.position``).

    Raises :class:`~admit_rs.LogError` for a log it cannot use (a missing joint, a wrench
    frame that is neither the tip nor the base link, no free space to fit the sensor from)
    and :class:`~admit_rs.errors.ArgumentError` for a bad argument.
    """
    if not isinstance(robot, UrdfArm):
        raise ParameterTypeError(
            f"identify() needs the recorded arm as an admit_rs.UrdfArm, got "
            f"{type(robot).__name__}"
        )
    if not isinstance(log, pl.DataFrame):
        raise ParameterTypeError(
            f"identify() takes a polars DataFrame (ar.read_log's table), got {type(log).__name__}"
        )
    if surface not in ("plane", "sphere"):
        raise ArgumentError(f"surface = {surface!r} is invalid: must be 'plane' or 'sphere'")
    if not (isinstance(confidence, float | int) and 0.5 <= confidence < 1):
        raise ArgumentError(f"confidence = {confidence!r} is invalid: must be in [0.5, 1)")
    if not (isinstance(stiction_velocity, float | int) and 0 < stiction_velocity < 1):
        raise ArgumentError(
            f"stiction_velocity = {stiction_velocity!r} is invalid: must be in (0, 1) m/s"
        )
    cell = LogArrays.of(log, robot)
    return Fitter(cell, float(confidence), float(stiction_velocity), surface).fit()
