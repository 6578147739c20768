"""The loop with its motion running (SPEC §23): the forced response of the linearised loop
to the scenario's references and to the Coulomb friction the motion drives, and what it
predicts for the criteria (force oscillation, loss of contact) that a run with motion is
judged by. Reached as :func:`admit_rs.analysis.forced_response` and through
:func:`admit_rs.analysis.predict` (``passed``, ``force_oscillation``, ``contact_loss``).

The model, in three steps (docs/analysis.md §3b):

1. **Friction as what it is with the motion running.** Coulomb friction c·tanh(q̇/ε) is
   split into a linear part, its describing-function gain g_i at joint i's speed amplitude
   A_i (:func:`~admit_rs.analysis.friction_gain`), which goes into the linearised loop, and
   the rest, d_i(t) = −c_i·tanh(q̇_i/ε) + (c_i g_i/ε)·q̇_i along the predicted joint speeds,
   which enters as a joint torque disturbance (the periodic disturbance the reversals
   are). A computed-torque law that compensates friction with its model cancels the share
   ``model.friction_scale`` of it. A_i, g_i and d are iterated to a fixed point (a few
   passes).
2. **First order.** δx_{k+1} = A δx_k + B δf_d,k + B_u u_k with u = (s − s(0), ṡ, s̈, d):
   the linear response to the references and the friction disturbance.
3. **Second order.** The quadratic terms of the one-period map (its curvature in state and
   inputs: the arm's geometry along a path of centimetres, centripetal terms, torque ×
   pose) driven by the first-order response, x₂ = Σ A^j ½ H(z₁, z₁) (a Volterra series
   to second order; the torque × torque terms, which the plant does not have, are left
   out).

4. **The first transient's amplitude.** Step 1's amplitudes are those after the first
   second (the oscillation that goes on). The first transient moves the joints faster;
   where the loop at friction's describing-function gains for those speeds has ρ ≥ 1, an
   oscillation the start sets off can sustain itself (bouncing): predicted unstable.

A response that chatters from sample to sample at the reversals (a fast mode that the
describing function leaves undamped, where the true friction's steep slope near q̇ = 0
damps it) is not a prediction: ``passed`` is None and the verdict says to simulate.

The predicted force trace is f* + C(x₁ + x₂) + D u + ½ H_f(z₁, z₁), from the run's initial
state when it starts touching at rest (its first transient included), else from the contact
equilibrium (a free-space start is outside the linear contact model).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from admit_rs import _core
from admit_rs.analysis._checks import _check_friction, _check_scenario, friction_gain
from admit_rs.blocks.controller import ComputedTorque
from admit_rs.config import Scenario

__all__ = ["ForcedResponse", "forced_response"]

ITERATIONS = 6
"""Most passes of the friction fixed point (step 1); it stops once every gain moves < 1e-3."""

TRANSIENT_END = 1.0
"""As the simulated metrics: the criteria's windows start 1 s in (SPEC §7)."""

STEADY_WINDOW = 2.0
"""``force_oscillation``'s window: the last 2 s (SPEC §7)."""

MAX_SAMPLES = 100_000
"""Longest run the forced response is computed for (100 s at 1 kHz: a few seconds); a
longer one is not predicted (``passed`` None, the verdict says why)."""

ROUGHNESS = 0.1
"""Above this rms increment per sample, relative to its spread, the predicted force is
chatter, not a response to the motion (:func:`_chatters`)."""


@dataclass(frozen=True)
class ForcedResponse:
    """What the linearised loop predicts with the scenario's references running.

    ``time`` [s] and ``force`` [N]: the predicted true contact force f(t_k) (the linear
    model keeps contact: f ≤ 0 there means the arm would leave the surface);
    ``force_oscillation``: std(f − f_d) / mean|f_d| over the last 2 s, as the simulated
    metric; ``contact_loss``: the fraction of samples t ≥ 1 s with f ≤ 0;
    ``spectral_radius``: ρ of the loop with friction at its gains for the motion's joint
    speeds (``friction_gains``, relative to the slope at rest, per joint, at
    ``joint_speed_amplitudes`` [rad/s]; for a loop unstable at its first transient's speeds,
    those speeds, gains and ρ); ``stable``: ρ < 1 at the motion's speeds and at the first
    transient's (None for a run too long to predict); ``passed``: stable and within
    the scenario's ``max_force_oscillation`` and ``max_contact_loss`` (the criteria the
    forced response can judge: the others are listed in ``unjudged``), None where the
    response chatters at the reversals (not predicted, ``verdict`` says so); ``verdict`` in
    words; ``second_order``: whether the quadratic terms were kept; ``caveats``.
    """

    time: npt.NDArray[np.float64]
    force: npt.NDArray[np.float64]
    force_oscillation: float
    contact_loss: float
    spectral_radius: float
    friction_gains: tuple[float, ...]
    joint_speed_amplitudes: tuple[float, ...]
    stable: bool | None
    passed: bool | None
    verdict: str
    second_order: bool
    iterations: int
    unjudged: tuple[str, ...] = ()
    caveats: tuple[str, ...] = field(default_factory=tuple)


_CHATTER = ("not predicted: the forced response chatters from sample to sample at the friction"
            " reversals (a fast mode that friction's describing function leaves undamped);"
            " simulate this one")

_UNJUDGED = ("force_limit", "max_bounces", "max_path_error", "max_torque_saturation")


def forced_response(scenario: Scenario) -> ForcedResponse:
    """The loop's predicted force with its motion running (SPEC §23; the model is in this
    module's docstring and docs/analysis.md §3b).

    Raises :class:`admit_rs.errors.AnalysisError` where :func:`linearize` does (no contact
    equilibrium, no force loop, exact Coulomb friction) and :class:`admit_rs.ParameterError`
    for ``substeps="auto"``.

    Example:
        >>> import admit_rs as ar
        >>> cell = ar.paper.scenario("fig14").replace(**{"admittance.b": 2500.0})
        >>> r = ar.analysis.forced_response(cell)
        >>> r.stable, r.passed, round(r.force_oscillation, 2)  # simulated: 0.19
        (True, False, 0.16)
        >>> r.verdict
        'out of tolerance: predicted force oscillation 15.6 % > 10 % (driven by the motion)'
    """
    scenario = _check_scenario(scenario, "forced_response")
    _check_friction(scenario)
    samples = int(round(scenario.duration / scenario.period)) + 1
    if samples > MAX_SAMPLES:
        verdict = (f"not predicted: the run has {samples} samples, the forced response is"
                   f" computed for up to {MAX_SAMPLES}")  # fmt: skip
        empty = np.zeros(0)
        return _without_ripple(scenario, empty, empty, (math.nan, empty, empty, 0),
                               (None, None, verdict))  # fmt: skip
    refs = _core.reference_samples(scenario._to_core())
    time = np.arange(len(refs["force"]), dtype=np.float64) * float(scenario.period)
    motion = np.stack(
        [refs["motion"] - refs["motion"][0], refs["motion_rate"], refs["motion_accel"]], axis=1
    )
    robot = scenario.robot
    eps = float(getattr(robot, "friction_smoothing", 0.0) or 0.0)
    coulomb_spec = np.atleast_1d(np.asarray(getattr(robot, "coulomb_friction", 0.0), float))
    # The law's own model cancels this share of the plant's friction (computed torque).
    law = scenario.controller
    compensated = float(law.model.friction_scale) if isinstance(law, ComputedTorque) else 0.0
    gains: npt.NDArray[np.float64] | None = None
    speeds: npt.NDArray[np.float64] | None = None
    amplitudes = np.zeros(0)
    used = np.ones(0)
    caveats: list[str] = []
    iterations = 0
    late = time >= TRANSIENT_END
    start: npt.NDArray[np.float64] | None = None
    for iterations in range(1, ITERATIONS + 1):
        raw = _linearize(scenario, coulomb_spec, gains)
        if iterations == 1:
            start = _start_deviation(scenario, raw)
        joints = sum(1 for label in raw["drive_labels"] if label.startswith("torque"))
        coulomb = np.broadcast_to(coulomb_spec, (joints,)) if coulomb_spec.size else np.zeros(
            joints
        )
        g = np.ones(joints) if gains is None else gains
        rho = float(np.max(np.abs(np.linalg.eigvals(np.asarray(raw["a"])))))
        if not rho < 1.0:
            return _unstable(scenario, time, (rho, g, amplitudes, iterations))
        if speeds is None or eps <= 0:
            disturbance = np.zeros((len(time), joints))
        else:
            slope = coulomb * g / eps
            disturbance = (1.0 - compensated) * (
                -coulomb * np.tanh(speeds / eps) + slope * speeds
            )
        force, speeds, kept = _respond(raw, motion, refs["force"], disturbance, start)
        # The motion's amplitude, after the first transient (whose speeds are checked apart,
        # below): the describing function is of the oscillation that goes on.
        amplitudes = np.max(np.abs(speeds[late] if np.any(late) else speeds), axis=0)
        new_gains = np.array([friction_gain(float(a), eps) if eps > 0 else 1.0
                              for a in amplitudes])  # fmt: skip
        settled = gains is not None and np.all(np.abs(new_gains - gains) <= 1e-3)
        gains, used = new_gains, g
        if settled or not np.any(coulomb):
            break
    gains = used
    coulomb = (np.broadcast_to(coulomb_spec, gains.shape) if coulomb_spec.size
               else np.zeros(gains.shape))  # fmt: skip
    transient = (None if speeds is None else
                 _transient_check(scenario, coulomb, speeds, ~late, amplitudes))  # fmt: skip
    if transient is not None and not transient[0] < 1.0:
        rho_t, gains_t, peak = transient
        verdict = (f"unstable at the first transient: its joint speeds (up to "
                   f"{float(np.max(peak)):.3g} rad/s) lower Coulomb friction's describing-"
                   f"function gain to {float(np.min(gains_t)):.3g} of its slope at rest, where "
                   f"ρ = {rho_t:.6g} ≥ 1: an oscillation the start sets off can sustain itself "
                   f"(bouncing), although the loop is stable at the motion's own speeds "
                   f"(ρ = {rho:.6g})")  # fmt: skip
        return _without_ripple(scenario, time, force, (rho_t, gains_t, peak, iterations),
                               (False, False, verdict))  # fmt: skip
    if not kept:
        caveats.append("the second-order terms were dropped (not finite): the force is first"
                       " order")  # fmt: skip
    if _chatters(force, scenario.period):
        return _without_ripple(scenario, time, force, (rho, gains, amplitudes, iterations),
                               (True, None, _CHATTER))  # fmt: skip
    f_d = refs["force"]
    window = (time >= scenario.duration - STEADY_WINDOW) & (time >= TRANSIENT_END)
    denominator = float(np.mean(np.abs(f_d[window]))) if np.any(window) else math.nan
    oscillation = (
        float(np.std(force[window] - f_d[window]) / denominator)
        if np.any(window) and denominator > 0
        else math.nan
    )
    late = time >= TRANSIENT_END
    loss = float(np.mean(force[late] <= 0.0)) if np.any(late) else math.nan
    passed, verdict = _judge(scenario, oscillation, loss)
    return ForcedResponse(
        time=time,
        force=force,
        force_oscillation=oscillation,
        contact_loss=loss,
        spectral_radius=rho,
        friction_gains=tuple(map(float, gains)),
        joint_speed_amplitudes=tuple(map(float, amplitudes)),
        stable=True,
        passed=passed,
        verdict=verdict,
        second_order=kept,
        iterations=iterations,
        unjudged=_unjudged(scenario),
        caveats=tuple(caveats) + _CAVEATS,
    )


_CAVEATS = (
    "a run that starts touching at rest starts from its initial state (the first transient "
    "is in the response); one that starts apart or with a guarded approach starts at the "
    "contact equilibrium (its first contact is not in it)",
    "the contact is linear: f ≤ 0 in the response counts as contact lost, the bounce after "
    "it is not modelled",
    "sensor noise and resolution are off; actuator limits are not modelled",
)


def _linearize(
    scenario: Scenario, coulomb: npt.NDArray[np.float64], gains: npt.NDArray[np.float64] | None
) -> dict[str, Any]:
    if gains is not None and coulomb.size:
        scaled = tuple(float(c) * float(g) for c, g in
                       zip(np.broadcast_to(coulomb, gains.shape), gains, strict=True))  # fmt: skip
        scenario = scenario.replace(**{"robot.coulomb_friction": scaled})
    return dict(_core.linearize(scenario._to_core(), None, True))


def _simulate(
    a: npt.NDArray[np.float64],
    forcing: npt.NDArray[np.float64],
    start: npt.NDArray[np.float64] | None = None,
) -> Any:
    """x_{k+1} = A x_k + forcing_k from x_0 = ``start`` (0 if None): the states at every
    sample."""
    states = np.empty_like(forcing)
    x = np.zeros(a.shape[0]) if start is None else start.copy()
    for k in range(forcing.shape[0]):
        states[k] = x
        x = a @ x + forcing[k]
    return states


def _respond(
    raw: dict[str, Any],
    motion: npt.NDArray[np.float64],
    force_reference: npt.NDArray[np.float64],
    disturbance: npt.NDArray[np.float64],
    start: npt.NDArray[np.float64] | None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], bool]:
    """The predicted force and joint speeds, first order (from the deviation ``start``, or
    from the equilibrium) plus second order where it converges; and whether the second
    order was kept."""
    a = np.asarray(raw["a"], dtype=float)
    b = np.asarray(raw["b"], dtype=float)[:, 0]
    c_f = np.asarray(raw["c"], dtype=float)[0]
    d_f = float(np.asarray(raw["d"], dtype=float)[0, 0])
    b_u = np.asarray(raw["b_drive"], dtype=float)
    d_u = np.asarray(raw["d_drive"], dtype=float)[0]
    n = a.shape[0]
    inputs = np.concatenate([motion, disturbance], axis=1)
    held = force_reference - float(raw["force_desired"])
    first = _simulate(a, inputs @ b_u.T + np.outer(held, b), start)
    force = float(raw["outputs"][0]) + first @ c_f + inputs @ d_u + d_f * held
    labels = list(raw["labels"])
    speed_rows = [i for i, label in enumerate(labels) if label.startswith("plant.qd")]
    # Second order over z = (δx, u); the plant is affine in torque: no torque × torque.
    curvature = np.stack([np.asarray(h, dtype=float) for h in raw["curvature"]])
    torques = n + motion.shape[1]
    curvature[:, torques:, torques:] = 0.0
    z = np.concatenate([first, inputs], axis=1)
    quadratic = 0.5 * np.einsum("rij,ki,kj->kr", curvature[: n + 1], z, z, optimize=True)
    second = _simulate(a, quadratic[:, :n])
    force_second = second @ c_f + quadratic[:, n]
    if np.all(np.isfinite(force_second)):
        return force + force_second, (first + second)[:, speed_rows], True
    return force, first[:, speed_rows], False


def _start_deviation(scenario: Scenario, raw: dict[str, Any]) -> npt.NDArray[np.float64] | None:
    """The run's initial state less the contact equilibrium, in the linearisation's state
    order, for a run that starts touching the surface at rest (no gap, no guarded
    approach); None otherwise (a free-space start is outside the linear contact model, and
    the response then starts at the equilibrium)."""
    if scenario.approach is not None or float(getattr(scenario.wall, "gap", 0.0)) > 0.0:
        return None
    from admit_rs.simulation import Simulation  # the stepped run: its state at sample 0

    initial = Simulation(scenario).state
    labels = list(raw["labels"])
    if not all(label in initial for label in labels):
        return None
    return np.array([initial[label] for label in labels]) - np.asarray(raw["state"], float)


def _transient_check(
    scenario: Scenario,
    coulomb: npt.NDArray[np.float64],
    speeds: npt.NDArray[np.float64],
    early: npt.NDArray[np.bool_],
    steady_amplitudes: npt.NDArray[np.float64],
) -> tuple[float, npt.NDArray[np.float64], npt.NDArray[np.float64]] | None:
    """The loop at the first transient's joint speeds: (ρ, gains, amplitudes) when those
    speeds exceed the motion's at some joint with Coulomb friction (its describing-function
    gain falls with amplitude, so the loop is less damped there); None otherwise."""
    eps = float(getattr(scenario.robot, "friction_smoothing", 0.0) or 0.0)
    if eps <= 0 or not np.any(early) or not np.any(coulomb):
        return None
    peak = np.max(np.abs(speeds[early]), axis=0)
    if not np.any((peak > steady_amplitudes) & (coulomb > 0)):
        return None
    gains = np.array([friction_gain(float(a), eps) for a in np.maximum(peak, steady_amplitudes)])
    raw = _linearize(scenario, coulomb, gains)
    rho = float(np.max(np.abs(np.linalg.eigvals(np.asarray(raw["a"])))))
    return rho, gains, np.maximum(peak, steady_amplitudes)


def _chatters(force: npt.NDArray[np.float64], period: float) -> bool:
    """Whether the predicted force over the last 2 s is mostly sample-to-sample chatter:
    the rms of its increments above ROUGHNESS × its spread (a smooth response at the
    motion's frequencies and the reversals' transients stays below 0.02; fig. 14 at
    k_e = 1e6 N/m, b = 2500 N·s/m, where the describing function leaves a fast mode
    undamped that the true friction's slope damps at each reversal, reads 0.36)."""
    tail = force[-min(len(force), int(round(STEADY_WINDOW / period))):]
    spread = float(np.std(tail))
    return spread > 0 and float(np.std(np.diff(tail))) > ROUGHNESS * spread


def _judge(scenario: Scenario, oscillation: float, loss: float) -> tuple[bool | None, str]:
    if not (math.isfinite(oscillation) and math.isfinite(loss)):
        # As the simulated metrics: nothing to assess after t = 1 s, or f_d = 0 there.
        return None, ("not predicted: the run has no window to judge (shorter than 1 s, or"
                      " f_d = 0 in its last 2 s)")  # fmt: skip
    criteria = scenario.criteria
    failures = []
    limit = criteria.max_force_oscillation
    if limit is not None and not oscillation <= limit:
        failures.append(f"predicted force oscillation {100 * oscillation:.3g} % > "
                        f"{100 * limit:.3g} %")  # fmt: skip
    limit = criteria.max_contact_loss
    if limit is not None and not loss <= limit:
        failures.append(f"predicted loss of contact in {100 * loss:.3g} % of samples > "
                        f"{100 * limit:.3g} %")  # fmt: skip
    if failures:
        return False, "out of tolerance: " + "; ".join(failures) + " (driven by the motion)"
    return True, (f"passed: predicted force oscillation {100 * oscillation:.3g} %, "
                  f"loss of contact {100 * loss:.3g} %")  # fmt: skip


def _unjudged(scenario: Scenario) -> tuple[str, ...]:
    criteria = scenario.criteria
    return tuple(name for name in _UNJUDGED if getattr(criteria, name, None) is not None)


def _without_ripple(
    scenario: Scenario,
    time: npt.NDArray[np.float64],
    force: npt.NDArray[np.float64],
    loop: tuple[float, npt.NDArray[np.float64], npt.NDArray[np.float64], int],
    answer: tuple[bool | None, bool | None, str],
) -> ForcedResponse:
    """A response without a ripple to judge: ``loop`` = (ρ, gains, amplitudes, passes),
    ``answer`` = (stable, passed, verdict)."""
    rho, gains, amplitudes, iterations = loop
    stable, passed, verdict = answer
    return ForcedResponse(
        time=time,
        force=force,
        force_oscillation=math.nan,
        contact_loss=math.nan,
        spectral_radius=rho,
        friction_gains=tuple(map(float, gains)),
        joint_speed_amplitudes=tuple(map(float, amplitudes)),
        stable=stable,
        passed=passed,
        verdict=verdict,
        second_order=False,
        iterations=iterations,
        unjudged=_unjudged(scenario),
        caveats=_CAVEATS,
    )


def _unstable(
    scenario: Scenario,
    time: npt.NDArray[np.float64],
    loop: tuple[float, npt.NDArray[np.float64], npt.NDArray[np.float64], int],
) -> ForcedResponse:
    rho, iterations = loop[0], loop[3]
    where = ("with Coulomb friction at its slope at rest" if iterations == 1 else
             "with Coulomb friction at its describing-function gain for the motion's joint "
             "speeds")  # fmt: skip
    verdict = f"unstable with the motion running: spectral radius ρ = {rho:.6g} ≥ 1 {where}"
    return _without_ripple(scenario, time, np.full(len(time), math.nan), loop,
                           (False, False, verdict))  # fmt: skip
