"""Predict before you simulate (SPEC §12): the closed loop over one controller period,
linearised about its steady contact equilibrium, and what it predicts.

- :func:`linearize` → a python-control ``StateSpace(A, B, C, D, dt=T)`` on the full state
  (plant, filter, controller memory, sensor, actuator), input δf_d, outputs δf, δx (along
  the wall normal n) and δz (along the motion direction t̂).
- :func:`predict` → the steady-state errors, step metrics, poles and a stable verdict.
- :func:`stability_map` → :func:`predict` over a grid of two parameters, in Rust on all
  cores, as a Polars table (draw it with :func:`admit_rs.plot.stability_map`).
- :func:`tune` → the gains that minimise the worst-case predicted settling time over a box
  of uncertain parameters, checked by simulating the box's corners and centre.

How the linearisation is built and what it assumes: docs/analysis.md.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import polars as pl

from admit_rs import _core
from admit_rs.blocks._base import _parameter_error
from admit_rs.config import Scenario, Step, _check_path, _core_dict_with, _core_value
from admit_rs.errors import AnalysisError, ArgumentError, ParameterError, ParameterTypeError

__all__ = [
    "PREDICTION_NAMES",
    "AnalysisError",
    "Margins",
    "TuneResult",
    "friction_gain",
    "linearize",
    "predict",
    "stability_map",
    "tune",
]

PREDICTION_NAMES: tuple[str, ...] = tuple(_core.PREDICTION_NAMES)
"""Numeric fields of :func:`predict`, in order (it adds ``verdict``)."""


@dataclass(frozen=True, kw_only=True)
class Margins:
    """What a prediction needs, beyond ρ < 1, to be called stable (SPEC §17).

    A loop with ρ = 0.9987 and ζ = 0.003 is stable on paper and rings for seconds in
    simulation (docs/analysis.md). The margins are of the force loop, cut where the
    measured force enters the admittance filter (e_f = f_d − f̃): the loop gain
    L(z) = c̃ (zI − A − B c̃)⁻¹ B of the linearisation, in python-control's
    ``stability_margins`` conventions.

    Example:
        >>> import admit_rs as ar
        >>> ar.analysis.Margins(min_damping=0.1).min_damping
        0.1
    """

    min_damping: float = 0.05
    """Smallest damping ratio ζ of the dominant pole (the pole of largest modulus)."""
    min_gain_margin: float = 1.1
    """Smallest gain margin (factor; 1.1 ≈ 0.8 dB)."""
    min_phase_margin: float = 5.0
    """Smallest phase margin [deg]."""
    min_delay_margin: float = 0.1
    """Smallest delay margin: extra loop delay the loop tolerates [samples of T]."""

    def __post_init__(self) -> None:
        for name in ("min_damping", "min_gain_margin", "min_phase_margin", "min_delay_margin"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ParameterError(f"Margins.{name} = {v!r} is invalid: must be a finite "
                                     "number")  # fmt: skip
        if self.min_gain_margin < 1 or self.min_delay_margin < 0 or self.min_damping < -1:
            raise ParameterError(
                f"Margins: min_gain_margin = {self.min_gain_margin} must be >= 1, "
                f"min_delay_margin = {self.min_delay_margin} >= 0, min_damping >= -1"
            )

    def judge(self, p: Mapping[str, Any]) -> tuple[bool, str]:
        """(stable, verdict) of one prediction (a row of :func:`stability_map`)."""
        rho = float(p["spectral_radius"])
        if not rho < 1:
            return False, f"unstable: spectral radius ρ = {rho:.6g} ≥ 1"
        failed = []
        checks = [
            ("dominant_damping", "damping ratio ζ", self.min_damping, ""),
            ("gain_margin", "gain margin", self.min_gain_margin, ""),
            ("phase_margin", "phase margin", self.min_phase_margin, "°"),
            ("delay_margin", "delay margin", self.min_delay_margin, " samples"),
        ]
        for key, words, limit, unit in checks:
            v = float(p[key])
            if not v >= limit:  # NaN fails too
                failed.append(f"{words} {v:.3g}{unit} < {limit:g}{unit}")
        if failed:
            return False, f"insufficient margin (ρ = {rho:.6g} < 1): " + "; ".join(failed)
        return True, "stable"

    def apply(self, table: pl.DataFrame) -> pl.DataFrame:
        """``table`` with ``stable`` and ``verdict`` judged by these margins."""
        judged = [self.judge(r) if r["error"] is None else (False, f"no prediction: {r['error']}")
                  for r in table.iter_rows(named=True)]  # fmt: skip
        return table.with_columns(
            pl.Series("stable", [j[0] for j in judged], dtype=pl.Boolean),
            pl.Series("verdict", [j[1] for j in judged], dtype=pl.String),
        )


STEP_ITERATIONS = 4
"""Updates of the friction amplitude under ``friction="step"``."""


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


def linearize(scenario: Scenario, at: float | None = None, friction: Any = "rest") -> Any:
    """The one-period closed-loop map x_{k+1} = Φ(x_k, f_d) linearised (SPEC §12).

    About the steady contact equilibrium (f_d held at its final value — a sine's offset —,
    the motion reference frozen at s(0), velocities zero; found by Newton on Φ(x) = x from a
    short settling run), or about the state of the run at time ``at`` [s] (references held
    at their values there; not a fixed point).

    Returns a ``control.StateSpace(A, B, C, D, dt=T)`` with input ``f_d`` and outputs
    ``f`` (true contact force), ``x`` (n·X) and ``z`` (t̂·X), states named as
    :attr:`admit_rs.Simulation.state` (without ``sample``). Extra attributes:
    ``operating_point`` (state label → value), ``operating_outputs`` (f, x, z there),
    ``force_desired``, ``penetration``, ``equilibrium`` (bool), ``caveats`` (what the model
    assumes, in words: contact kept, smoothed Coulomb friction as its slope at rest, noise
    and resolution off, actuator limits inactive or saturated), and ``force_loop``: the
    loop gain L(z) cut where the measured force enters the filter (input e_f, output f̃;
    the closed loop is L's negative unity feedback), whose
    ``control.stability_margins`` are :func:`predict`'s margins.

    ``friction="rest"`` (SPEC §12) linearises smoothed Coulomb friction c·tanh(q̇/ε) to its
    slope c/ε at rest, which is right for small signals; a number A [rad/s] uses instead its
    describing-function gain at a joint-velocity amplitude A (:func:`friction_gain`);
    ``"step"`` finds A per scenario as the peak joint speed of its own predicted step
    transient 0 → f_d (a few fixed-point iterations): the large-signal view that a force
    step from rest needs, and what SPEC §7's simulated verdict judges (docs/analysis.md).

    Raises :class:`admit_rs.errors.AnalysisError` (a ``ValueError``) when there is no
    contact equilibrium (wall out of reach, f_d ≤ 0), when it is singular (a pole at 1,
    e.g. ``admittance.ka = 0``) or without a wall or force loop.

    Example:
        >>> import admit_rs as ar
        >>> sys = ar.analysis.linearize(ar.paper.scenario("fig14"))
        >>> sys.nstates, sys.dt, sys.output_labels
        (18, 0.001, ['f', 'x', 'z'])
    """
    import control

    scenario = _check_scenario(scenario, "linearize")
    if isinstance(friction, str) and friction == "step":
        raw_step = _predict_step(scenario, [{}], None)
        _raise_if(raw_step["error"][0])
        friction = float(raw_step["friction_amplitude"][0])
    scenario = _with_friction(scenario, friction)
    if at is not None and not (isinstance(at, int | float) and not isinstance(at, bool)):
        raise ParameterTypeError(f"at must be a number of seconds or None, got {type(at).__name__}")
    _check_friction(scenario)
    raw = _core.linearize(scenario._to_core(), None if at is None else float(at))
    sys = control.ss(
        raw["a"], raw["b"], raw["c"], raw["d"], raw["period"],
        inputs=["f_d"], outputs=["f", "x", "z"], states=list(raw["labels"]),
        name=(scenario.label or "closed_loop").replace(".", "_"),
    )  # fmt: skip
    # The force loop cut where the measured force f̃ = c̃ x enters the filter (f_d enters
    # only as e_f = f_d − f̃): L(z) = c̃ (zI − A − B c̃)⁻¹ B, so that A = A₀ − B c̃.
    c_m = np.asarray(raw["c_measured"], dtype=float).reshape(1, -1)
    b = np.asarray(raw["b"], dtype=float)
    sys.force_loop = control.ss(
        np.asarray(raw["a"]) + b @ c_m, b, c_m, np.zeros((1, 1)), raw["period"],
        inputs=["e_f"], outputs=["f_measured"], states=list(raw["labels"]),
        name="force_loop",
    )  # fmt: skip
    sys.operating_point = dict(zip(raw["labels"], map(float, raw["state"]), strict=True))
    sys.operating_outputs = dict(zip(["f", "x", "z"], raw["outputs"], strict=True))
    sys.force_desired = float(raw["force_desired"])
    sys.reference_normal = float(raw["reference_normal"])
    sys.penetration = float(raw["penetration"])
    sys.equilibrium = bool(raw["equilibrium"])
    sys.newton_iterations = int(raw["iterations"])
    sys.caveats = tuple(raw["caveats"]) + (
        () if friction == "rest" else
        (f"Coulomb friction as its describing-function gain at |q̇| = {friction} rad/s",))
    return sys


def friction_gain(amplitude: float, smoothing: float) -> float:
    """Describing-function gain of c·tanh(q̇/ε) for q̇ = A sin(ωt), relative to its slope
    c/ε at rest: (ε/(πA)) ∫₀^{2π} tanh(A sin θ / ε) sin θ dθ. 1 for A → 0, ≈ 4ε/(πA) for
    A ≫ ε."""
    if amplitude <= 0:
        return 1.0
    theta = np.linspace(0.0, 2 * np.pi, 2049)[:-1]
    ratio = amplitude / smoothing
    integral = float(np.mean(np.tanh(ratio * np.sin(theta)) * np.sin(theta))) * 2 * np.pi
    return integral / (np.pi * ratio)


def _with_friction(scenario: Scenario, friction: Any) -> Scenario:
    """``friction="rest"``: Coulomb friction as its slope at q̇ = 0 (SPEC §12). A number A
    [rad/s]: as its describing-function gain at a joint-velocity amplitude A (the Coulomb
    force is zero at rest either way, so the equilibrium is unchanged)."""
    if isinstance(friction, str) and friction == "rest":
        return scenario
    if isinstance(friction, str):
        raise ArgumentError(f"friction must be 'rest', 'step' or an amplitude in rad/s, got "
                            f"{friction!r}")  # fmt: skip
    if isinstance(friction, bool) or not isinstance(friction, int | float):
        raise ParameterTypeError(
            f"friction must be 'rest' or an amplitude in rad/s, got {friction!r}"
        )
    if not (math.isfinite(friction) and friction >= 0):
        raise ParameterError(f"friction = {friction} is invalid: must be finite and >= 0")
    robot = scenario.robot
    eps = getattr(robot, "friction_smoothing", None)
    coulomb = getattr(robot, "coulomb_friction", None)
    if eps is None or coulomb is None or eps <= 0:
        return scenario
    gain = friction_gain(float(friction), float(eps))
    scaled = tuple(float(c) * gain for c in np.atleast_1d(coulomb))
    return scenario.replace(**{"robot.coulomb_friction": scaled})


def _check_friction(scenario: Scenario) -> None:
    robot = scenario.robot
    eps = getattr(robot, "friction_smoothing", 1.0)
    coulomb = getattr(robot, "coulomb_friction", 0.0)
    if eps is not None and eps <= 0 and np.any(np.asarray(coulomb) != 0):
        raise AnalysisError(
            "cannot linearise: exact Coulomb friction (robot.friction_smoothing <= 0) is not "
            "differentiable at rest; use a smoothing > 0 (the default is 0.01 rad/s)"
        )


def _raise_if(error: str | None) -> None:
    if error is not None:
        raise AnalysisError(error)


def predict(
    scenario: Scenario, friction: Any = "step", margins: Margins | None = None
) -> dict[str, float | bool | str]:
    """What the linear model predicts for ``scenario`` (SPEC §12, §17).

    ``force_ss_error`` (f_d − f) and ``x_ss_error`` (n·X_d − n·X) at the equilibrium;
    ``overshoot_pct``, ``rise_time_63``, ``settling_time`` of the predicted step response
    f = f_d·s(t) in the definitions of SPEC §7 (NaN when ρ ≥ 1); ``spectral_radius``
    ρ = max |eig A|, ``dominant_frequency`` [Hz] and ``dominant_damping`` ζ of that pole;
    the force loop's ``gain_margin`` (factor), ``phase_margin`` [deg] and ``delay_margin``
    [samples] (:class:`Margins` says where the loop is cut); ``peak_joint_speed`` and
    ``friction_amplitude`` [rad/s] (the describing-function amplitude used); ``stable``:
    ρ < 1 and every margin of ``margins`` (default :class:`Margins()`) met; ``verdict``
    says which one failed. A loop without a contact equilibrium (it cannot hold the tool on
    the surface: it bounces or leaves it) is predicted unstable: ``stable`` False, the
    numbers NaN and ``verdict`` ``"unstable: no contact equilibrium: ..."`` with the
    reason (SPEC §23); a scenario the model does not cover raises :class:`AnalysisError`.

    ``friction``: as in :func:`linearize`; the default ``"step"`` (Coulomb friction at its
    describing-function gain for the step's own joint speeds) is the linearisation
    validated against simulation in docs/analysis.md. ``"rest"`` (the slope at q̇ = 0,
    SPEC §12's small-signal model) predicts stability where the runs bounce.

    Example:
        >>> import admit_rs as ar
        >>> p = ar.analysis.predict(ar.paper.scenario("fig14"))
        >>> p["stable"], round(p["spectral_radius"], 4), p["verdict"]
        (True, 0.9948, 'stable')
    """
    scenario = _check_scenario(scenario, "predict")
    _check_friction(scenario)
    row = _predict_points(scenario, [{}], None, friction, margins).row(0, named=True)
    error = row.pop("error")
    if error is not None and not error.startswith(NO_EQUILIBRIUM):
        raise AnalysisError(error)
    out: dict[str, float | bool | str] = {}
    for k, v in row.items():
        out[k] = bool(v) if k == "stable" else str(v) if k == "verdict" else float(v)
    if error is not None:
        # No steady contact to hold: the loop cannot keep contact (SPEC §23), a prediction
        # of its own, not an exception.
        out["stable"] = False
        out["verdict"] = f"unstable: {error}"
    return out


NO_EQUILIBRIUM = "no contact equilibrium"
"""How the core's error for a loop without a steady contact begins (:func:`predict` reads
it as a predicted loss of contact)."""


def _numeric_axis(scenario: Scenario, spec: Any, axis: str) -> tuple[str, list[float]]:
    if not isinstance(spec, Mapping) or len(spec) != 1:
        raise ParameterTypeError(f"{axis} must be a dict with one dotted path: {{path: values}}")
    ((path, values),) = spec.items()
    if not isinstance(path, str):
        raise ParameterTypeError(f"{axis}: the path must be a str, got {type(path).__name__}")
    path = _check_path(scenario, path)
    current = scenario
    for part in path.split("."):
        current = getattr(current, part)
    # An optional number (None: its default) is numeric too.
    if isinstance(current, bool) or not isinstance(current, int | float | None):
        raise ParameterError(
            f"{path} = {current!r} is invalid: must be a numeric parameter to map over "
            f"(it is {type(current).__name__})"
        )
    try:
        out = [float(v) for v in values]
    except (TypeError, ValueError):
        raise ParameterError(
            f"{path} values are invalid: must be a sequence of numbers, got {values!r}"
        ) from None
    if not out:
        raise ArgumentError(f"{axis}: no values for {path}")
    if isinstance(current, int):
        if any(v != round(v) for v in out):
            raise ParameterError(f"{path} values are invalid: must be integers, got {out}")
    return path, out


def _cell_configs(
    scenario: Scenario, points: Sequence[Mapping[str, float]]
) -> list[dict[str, Any]]:
    base = scenario._to_core()
    ints = {p for p in points[0] if isinstance(_value_at(scenario, p), int)} if points else set()
    return [
        _core_dict_with(base, {path: int(round(value)) if path in ints else _core_value(value)
                               for path, value in point.items()})  # fmt: skip
        for point in points
    ]


def _value_at(scenario: Scenario, path: str) -> Any:
    current: Any = scenario
    for part in path.split("."):
        current = getattr(current, part)
    return current


def _predict_points(
    scenario: Scenario,
    points: Sequence[Mapping[str, float]],
    threads: int | None = None,
    friction: Any = "step",
    margins: Margins | None = None,
) -> pl.DataFrame:
    if isinstance(friction, str) and friction == "step":
        raw = _predict_step(scenario, points, threads)
    else:
        raw = _core.predict_batch(_cell_configs(_with_friction(scenario, friction), points),
                                  threads)  # fmt: skip
    columns: dict[str, Any] = {}
    for path in points[0] if points else []:
        ints = isinstance(_value_at(scenario, path), int)
        columns[path] = [int(round(p[path])) if ints else p[path] for p in points]
    for name in PREDICTION_NAMES:
        columns[name] = raw[name]
    if "friction_amplitude" in raw:
        columns["friction_amplitude"] = raw["friction_amplitude"]
    if "friction_amplitude" not in columns:
        amp = friction if isinstance(friction, int | float) else 0.0
        columns["friction_amplitude"] = [float(amp)] * len(points)
    columns["error"] = pl.Series("error", raw["error"], dtype=pl.String)
    return (margins or Margins()).apply(pl.DataFrame(columns))


def _predict_step(
    scenario: Scenario, points: Sequence[Mapping[str, float]], threads: int | None
) -> dict[str, Any]:
    """``friction="step"``: per cell, Coulomb friction as its describing-function gain at
    the peak joint speed A of the cell's own predicted step transient. From the slope at
    rest (A = 0), A is updated to the geometric mean of itself and the new peak speed,
    at most ``STEP_ITERATIONS`` times, while the cell stays stable (friction only loses
    gain as A grows, so a cell unstable at some A stays unstable)."""
    robot = scenario.robot
    eps = getattr(robot, "friction_smoothing", None)
    coulomb = getattr(robot, "coulomb_friction", None)
    base = _cell_configs(scenario, points)
    raw = {k: (np.asarray(v) if k != "error" else list(v))
           for k, v in _core.predict_batch(base, threads).items()}  # fmt: skip
    amp = np.zeros(len(points))
    if eps is None or coulomb is None or eps <= 0:
        raw["friction_amplitude"] = amp
        return raw
    c0 = np.atleast_1d(np.asarray(coulomb, dtype=float))
    for it in range(STEP_ITERATIONS):
        peak = np.asarray(raw["peak_joint_speed"], dtype=float)
        live = np.asarray(raw["stable"], dtype=bool) & np.isfinite(peak) & (peak > 0)
        new = np.where(live, np.sqrt(np.maximum(amp, 0) * peak) if it else peak, amp)
        todo = np.nonzero(live & ~np.isclose(new, amp, rtol=0.05))[0]
        if todo.size == 0:
            break
        amp[todo] = new[todo]
        configs = [
            _core_dict_with(base[i], {"robot.coulomb_friction":
                                      list(c0 * friction_gain(float(amp[i]), eps))})  # fmt: skip
            for i in todo
        ]
        update = _core.predict_batch(configs, threads)
        for name, values in update.items():
            for i, v in zip(todo, values, strict=True):
                raw[name][i] = v
    raw["friction_amplitude"] = amp
    return raw


def stability_map(
    scenario: Scenario,
    x: Mapping[str, Sequence[float]],
    y: Mapping[str, Sequence[float]],
    threads: int | None = None,
    friction: Any = "step",
    margins: Margins | None = None,
) -> pl.DataFrame:
    """:func:`predict` on every cell of the grid ``x`` × ``y`` (``{dotted path: values}``
    each), computed in Rust on all cores (or ``threads``).

    One row per cell, x varying fastest: the two parameter columns, the fields of
    :func:`predict` and ``error`` (None, or why the cell has no prediction, e.g. no contact
    equilibrium: its fields are then NaN and ``stable`` False). Paths must name numeric
    parameters (``ParameterError`` otherwise). ``friction`` and ``margins``: as in
    :func:`predict`.

    Example:
        >>> import admit_rs as ar
        >>> t = ar.analysis.stability_map(ar.paper.scenario("fig14"),
        ...     x={"wall.stiffness": [1e4, 1e5]}, y={"admittance.b": [200, 800]})
        >>> t.columns[:3], t.height
        (['wall.stiffness', 'admittance.b', 'force_ss_error'], 4)
    """
    scenario = _check_scenario(scenario, "stability_map")
    _check_friction(scenario)
    xp, xs = _numeric_axis(scenario, x, "x")
    yp, ys = _numeric_axis(scenario, y, "y")
    if xp == yp:
        raise ArgumentError(f"x and y are the same parameter {xp}")
    points = [{xp: xv, yp: yv} for yv in ys for xv in xs]
    # Validate one cell of each extreme through the Python blocks (clear messages).
    for p in (points[0], points[-1]):
        scenario.replace(**p)
    return _predict_points(scenario, points, threads, friction, margins)


@dataclass(frozen=True)
class TuneResult:
    """What :func:`tune` found and how the simulator judged it."""

    gains: dict[str, float]
    """The chosen values of the ``vary`` parameters."""
    predicted: pl.DataFrame
    """Predictions at every ``over`` grid point with the chosen gains: the step metrics
    with friction at rest (small signal), ``stable`` and ``spectral_radius`` with
    ``friction="step"`` (large signal)."""
    verification: pl.DataFrame
    """The box's corners and centre simulated with the chosen gains and the motion held
    (the linearised setup): the ``over`` parameters, predicted and simulated ``stable``
    (the simulated one: the loop's dynamics, SPEC §23, null if not assessed), ``passed``
    (the scenario's ``criteria`` met) with its ``verdict``, ``overshoot_pct``,
    ``settling_time``; and the scenario as given, its motion reference included:
    ``stable_with_motion``, ``passed_with_motion``, ``verdict_with_motion``,
    ``overshoot_pct_with_motion``; the first-contact figures of both, ``impact_peak``,
    ``bounces``, ``impact_peak_with_motion``, ``bounces_with_motion``."""
    worst_settling_time: float
    """Predicted worst-case settling time over the box [s] (the search's objective)."""
    verified: bool
    """Every verification run passes its criteria (so is stable too), with the motion held
    and with it, the runs with
    the motion held are within the overshoot limit, and every run within ``max_impact_peak``
    and ``max_bounces`` when they are set."""
    max_overshoot_pct: float
    stability_margin: float
    evaluated: int
    """Number of predictions made."""
    predicted_overshoot_limit: float = math.nan
    """The tightest overshoot limit the predictions had to meet in the last round."""
    rounds: int = 1
    """Search rounds (1 + corrections after a failed verification)."""
    max_impact_peak: float | None = None
    """The bound on the simulated ``impact_peak`` [N] (None: not bounded)."""
    max_bounces: int | None = None
    """The bound on the simulated ``bounces`` (None: not bounded)."""

    def worst(self, name: str) -> tuple[float, float]:
        """(predicted, simulated) worst value of ``overshoot_pct`` or ``settling_time`` over
        every point that was predicted (the box grid and the verified corners and centre)
        and every point simulated with the motion held (NaN: none)."""
        pred = [self.predicted[name]]
        if self.verification.height:
            pred.append(self.verification[f"predicted_{name}"])
        predicted = pl.concat(pred).drop_nans().max()
        simulated = (self.verification[name].drop_nans().max() if self.verification.height
                     else None)  # fmt: skip
        return (math.nan if predicted is None else float(predicted),  # type: ignore[arg-type]
                math.nan if simulated is None else float(simulated))  # type: ignore[arg-type]

    def summary(self) -> str:
        """A few lines of text: the gains, the true worst case predicted and simulated over
        every point, the verification and, if it fails, why."""
        gains = ", ".join(f"{k} = {v:.4g}" for k, v in self.gains.items())
        v = self.verification
        over_pred, over_sim = self.worst("overshoot_pct")
        settle_pred, settle_sim = self.worst("settling_time")
        points = self.predicted.height + v.height
        lines = [
            f"gains: {gains}",
            f"predicted at {points} points (the box grid, its corners and centre): worst "
            f"overshoot {over_pred:.2f} %, worst settling {settle_pred:.3f} s, max spectral "
            f"radius {float(self.predicted['spectral_radius'].max()):.5f} "  # type: ignore[arg-type]
            f"(round {self.rounds}, predicted overshoot limit "
            f"{self.predicted_overshoot_limit:.3g} %)",
        ]
        if v.height:
            held = int(v["passed"].fill_null(False).sum())
            moving = int(v["passed_with_motion"].fill_null(False).sum())
            moving_stable = int(v["stable_with_motion"].fill_null(False).sum())
            lines.append(
                f"simulated at {v.height} points (corners and centre), motion held: {held} "
                f"passed, worst overshoot {over_sim:.2f} % (limit {self.max_overshoot_pct:g} "
                f"%), worst settling {settle_sim:.3f} s; with the scenario's motion: "
                f"{moving} passed, {moving_stable} stable -> "
                + ("verified" if self.verified else "NOT verified")
            )
            lines += [f"  {reason}" for reason in self._failures()]
        return "\n".join(lines)

    def _failures(self) -> list[str]:
        """Why the verification failed, one line per failing point."""
        out = []
        over = list(self.verification.columns[: self.verification.columns.index("point")])
        for r in self.verification.iter_rows(named=True):
            at = ", ".join(f"{k} = {r[k]:.4g}" for k in over) + f" ({r['point']})"
            if r["passed"] is not True:
                out.append(f"{at}, motion held: {r['verdict']}")
            elif r["overshoot_pct"] > self.max_overshoot_pct:
                out.append(f"{at}, motion held: overshoot {r['overshoot_pct']:.2f} % > "
                           f"{self.max_overshoot_pct:g} %")  # fmt: skip
            if r["passed_with_motion"] is not True:
                out.append(f"{at}, with motion: {r['verdict_with_motion']}")
        return out


def _axis_points(lo: float, hi: float, n: int) -> list[float]:
    if lo > 0 and hi / lo >= 4:
        return [float(v) for v in np.geomspace(lo, hi, n)]
    return [float(v) for v in np.linspace(lo, hi, n)]


def _box(scenario: Scenario, spec: Any, name: str) -> dict[str, tuple[float, float]]:
    if not isinstance(spec, Mapping) or not spec:
        raise ParameterTypeError(f"{name} must be a non-empty dict {{path: (lo, hi)}}")
    out = {}
    for path, bounds in spec.items():
        p, _ = _numeric_axis(scenario, {path: [0.0]}, name)
        try:
            lo, hi = (float(v) for v in bounds)
        except (TypeError, ValueError):
            raise ParameterError(
                f"{name}[{path!r}] = {bounds!r} is invalid: must be a pair (lo, hi) of numbers"
            ) from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ParameterError(f"{name}[{path!r}] = {bounds!r} is invalid: must be lo <= hi")
        out[p] = (lo, hi)
    return out


def _held(scenario: Scenario) -> Scenario:
    """The scenario with its motion held at s(0), as the linearisation freezes it."""
    s0 = float(_core_signal_at(scenario, 0.0))
    return scenario.replace(z_reference=Step(value=s0, time=0.0, initial=s0))


def _core_signal_at(scenario: Scenario, t: float) -> float:
    from admit_rs.config import Sine

    z = scenario.z_reference
    if isinstance(z, Step):
        return float(z.value if t >= z.time else z.initial)
    if isinstance(z, Sine):
        return float(z.offset + z.amplitude * math.sin(z.omega * t + z.phase))
    return float(np.interp(t, z.times, z.values))


def _predict_both(
    scenario: Scenario, points: Sequence[Mapping[str, float]], threads: int | None
) -> pl.DataFrame:
    """Predictions with ``friction="step"``: a force step from rest is a large signal."""
    return _predict_points(scenario, points, threads, "step")


def _check_count(name: str, value: Any, low: int, high: int) -> None:
    """A whole-number argument from ``low`` to ``high``, else a ParameterError naming it."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise _parameter_error(name, repr(value), f"an integer from {low} to {high}")


def tune(
    scenario: Scenario,
    vary: Mapping[str, tuple[float, float]],
    over: Mapping[str, tuple[float, float]],
    max_overshoot_pct: float = 10.0,
    stability_margin: float = 0.001,
    grid: int = 7,
    over_points: int = 4,
    refine: int = 2,
    verify: bool = True,
    verify_duration: float | None = None,
    threads: int | None = None,
    corrections: int = 3,
    max_impact_peak: float | None = None,
    max_bounces: int | None = None,
) -> TuneResult:
    """Gains that minimise the worst-case predicted settling time over the ``over`` box
    while every point of it is predicted stable with a margin (ρ ≤ 1 − ``stability_margin``)
    and within ``max_overshoot_pct``; then verified by simulating the box's corners and
    centre.

    ``vary``: ``{path: (lo, hi)}`` of the gains to choose (e.g. ``admittance.b``,
    ``admittance.ka``). ``over``: ``{path: (lo, hi)}`` of what is uncertain (e.g.
    ``wall.stiffness``). The search is a ``grid``-point grid per gain (geometric when hi/lo
    ≥ 4) refined ``refine`` times around the best cell; the box is sampled with
    ``over_points`` values per parameter (its corners included), and each candidate is
    judged by its worst case there. Predictions use ``friction="step"`` (a force step from
    rest is a large signal). The force step is judged with the motion held at s(0), as
    linearised; the verification simulates that, and also the scenario as given
    (``passed_with_motion``): the gains are chosen on ``passed`` (the scenario's criteria
    met) and ``stable`` is reported beside it (SPEC §23). If the simulated overshoot exceeds
    the limit (or a run fails its criteria), the excess of the simulated over the predicted
    overshoot is carried to the nearest grid points as a tighter limit there (the margin
    doubled after an unstable run) and the search repeated, at most ``corrections`` times;
    ``predicted_overshoot_limit`` (the tightest limit used) and ``rounds`` say what was
    needed. ``max_impact_peak`` [N] and ``max_bounces`` bound the first contact (SPEC §16):
    the linear model cannot predict an impact, so they are judged on the verification runs
    (held and with motion); an impact above its bound is carried back as an overshoot limit
    100 (impact_peak − max_impact_peak) / f_d tighter at the nearest grid points, as an
    overshoot excess is. Raises :class:`AnalysisError` if no candidate qualifies.

    Example (docs/analysis.md): ``ar.analysis.tune(sc, vary={"admittance.b": (100, 3000),
    "admittance.ka": (0.2, 5)}, over={"wall.stiffness": (1e4, 1e5)}, max_overshoot_pct=10)``.
    """
    scenario = _check_scenario(scenario, "tune")
    _check_friction(scenario)
    if not (isinstance(max_overshoot_pct, int | float) and math.isfinite(max_overshoot_pct)):
        raise ParameterError(f"max_overshoot_pct = {max_overshoot_pct!r} is invalid: must be "
                             "a finite number")  # fmt: skip
    for name, value, low, high in (("grid", grid, 2, 100), ("over_points", over_points, 1, 100),
                                   ("refine", refine, 0, 20), ("corrections", corrections, 0, 20)):
        _check_count(name, value, low, high)
    for name, bound in (("max_impact_peak", max_impact_peak), ("max_bounces", max_bounces)):
        if bound is not None and not (
            isinstance(bound, int | float) and not isinstance(bound, bool)
            and math.isfinite(bound) and bound >= 0
        ):
            raise ParameterError(f"{name} = {bound!r} is invalid: must be a finite number "
                                 ">= 0 or None")  # fmt: skip
    vbox = _box(scenario, vary, "vary")
    obox = _box(scenario, over, "over")
    if set(vbox) & set(obox):
        raise ArgumentError(f"{sorted(set(vbox) & set(obox))} given in both vary and over")
    over_grid = [
        dict(zip(obox, combo, strict=True))
        for combo in itertools.product(*(_axis_points(lo, hi, over_points)
                                         for lo, hi in obox.values()))
    ]  # fmt: skip
    evaluated = 0
    # Per over-grid point: what the simulator showed beyond the prediction (overshoot).
    offset = np.zeros(len(over_grid))
    rounds = 0
    last: tuple[Any, ...] | None = None
    while True:
        rounds += 1
        try:
            gains, worst_settling, n = _search(scenario, vbox, obox, over_grid,
                                               max_overshoot_pct - offset, stability_margin,
                                               grid, refine, threads)  # fmt: skip
        except AnalysisError:
            if last is None:
                raise
            # The corrected constraints leave nothing: report the last, unverified answer.
            rounds -= 1
            gains, worst_settling, predicted, verification, verified, offset = last
            break
        evaluated += n
        predicted = _predict_both(scenario, [{**gains, **o} for o in over_grid], threads)
        evaluated += predicted.height
        verification = (_verify(scenario, gains, obox, verify_duration, threads) if verify
                        else pl.DataFrame())  # fmt: skip
        # Null (not assessed) counts as not stable.
        within = _within_contact_bounds(verification, max_impact_peak, max_bounces, "")
        held = bool(
            verify
            and verification.height > 0
            and verification["passed"].fill_null(False).all()
            and (verification["overshoot_pct"] <= max_overshoot_pct).all()
            and within
        )
        verified = held and bool(
            verification["passed_with_motion"].fill_null(False).all()
            and _within_contact_bounds(verification, max_impact_peak, max_bounces,
                                       "_with_motion")
        )  # fmt: skip
        # The corrections below act on the held step; the motion's verdict cannot be
        # corrected by an overshoot limit, so a held pass ends the search.
        if not verify or held or rounds > corrections:
            break
        last = (gains, worst_settling, predicted, verification, verified, offset.copy())
        # The simulator disagrees: carry its excess over the prediction to the nearest
        # grid points (plus 0.5 %), double the margin if a run was unstable, search again.
        seen = (verification["overshoot_pct"] - verification["predicted_overshoot_pct"])
        near = _nearest(obox, over_grid, verification.select(list(obox)).rows(named=True))
        if max_impact_peak is not None:
            # An impact above its bound, as the overshoot it would take to stay below it.
            fd = _final_force(scenario)
            impact = 100.0 * (verification["impact_peak"] - max_impact_peak) / fd
            seen = pl.Series([max(a, b) for a, b in zip(seen.fill_nan(-math.inf),
                                                         impact.fill_nan(-math.inf),
                                                         strict=True)])  # fmt: skip
        for g, v in enumerate(near):
            excess = float(seen[v])
            if math.isfinite(excess):
                offset[g] = max(offset[g], excess + 0.5)
        if not verification["stable"].fill_null(False).all():
            stability_margin *= 2
    limit = float(np.min(max_overshoot_pct - offset))
    return TuneResult(
        gains=gains,
        predicted=predicted,
        verification=verification,
        worst_settling_time=worst_settling,
        verified=verified,
        max_overshoot_pct=max_overshoot_pct,
        stability_margin=stability_margin,
        evaluated=evaluated,
        predicted_overshoot_limit=limit,
        rounds=rounds,
        max_impact_peak=max_impact_peak,
        max_bounces=max_bounces,
    )


def _within_contact_bounds(
    verification: pl.DataFrame, max_impact: float | None, max_bounces: int | None, suffix: str
) -> bool:
    """Every verification run's impact peak and bounces within their bounds (if set)."""
    if verification.height == 0:
        return max_impact is None and max_bounces is None
    ok = True
    if max_impact is not None:
        ok &= bool((verification[f"impact_peak{suffix}"].fill_nan(math.inf) <= max_impact).all())
    if max_bounces is not None:
        ok &= bool((verification[f"bounces{suffix}"].fill_nan(math.inf) <= max_bounces).all())
    return ok


def _final_force(scenario: Scenario) -> float:
    """|f_d| at the end of the run (the scale of an overshoot in %), at least 1e-12 N."""
    end = scenario.force_reference(scenario.duration)
    return max(abs(float(np.asarray(end))), 1e-12)


def _nearest(
    obox: Mapping[str, tuple[float, float]],
    grid: Sequence[Mapping[str, float]],
    probes: Sequence[Mapping[str, float]],
) -> list[int]:
    """For each grid point, the index of the nearest probe in the box's normalised (log
    where geometric) coordinates."""

    def coords(p: Mapping[str, float]) -> np.ndarray:
        out = []
        for k, (lo, hi) in obox.items():
            if lo > 0 and hi / lo >= 4:
                out.append((math.log(p[k]) - math.log(lo)) / (math.log(hi) - math.log(lo)))
            else:
                out.append((p[k] - lo) / (hi - lo) if hi > lo else 0.0)
        return np.array(out)

    pc = np.array([coords(p) for p in probes])
    return [int(np.argmin(np.sum((pc - coords(g)) ** 2, axis=1))) for g in grid]


def _search(
    scenario: Scenario,
    vbox: Mapping[str, tuple[float, float]],
    obox: Mapping[str, tuple[float, float]],
    over_grid: Sequence[Mapping[str, float]],
    limit: Any,
    stability_margin: float,
    grid: int,
    refine: int,
    threads: int | None,
) -> tuple[dict[str, float], float, int]:
    """Grid search with zoom: the gains with the least worst-case predicted settling time
    that meet the constraints at every point of ``over_grid``."""
    evaluated = 0
    ranges = dict(vbox)
    best: tuple[float, dict[str, float]] | None = None
    for _ in range(refine + 1):
        axes = {p: _axis_points(lo, hi, grid) for p, (lo, hi) in ranges.items()}
        candidates = [dict(zip(axes, c, strict=True)) for c in itertools.product(*axes.values())]
        points = [{**c, **o} for c in candidates for o in over_grid]
        table = _predict_both(scenario, points, threads)
        evaluated += table.height
        m = len(over_grid)
        rho = table["spectral_radius"].to_numpy().reshape(-1, m)
        over_pct = table["overshoot_pct"].to_numpy().reshape(-1, m)
        settle = table["settling_time"].to_numpy().reshape(-1, m)
        # Stable by ar.analysis.Margins() (damping, gain, phase and delay margins) too.
        margins_ok = table["stable"].to_numpy().astype(bool).reshape(-1, m)
        with np.errstate(invalid="ignore"):
            ok = (
                np.all(margins_ok, axis=1)
                & np.all(rho <= 1 - stability_margin, axis=1)
                & np.all(over_pct <= np.asarray(limit)[None, :] if np.ndim(limit) else
                         over_pct <= limit, axis=1)
                & np.all(np.isfinite(settle), axis=1)
            )
        worst = np.where(ok, np.max(np.where(np.isfinite(settle), settle, np.inf), axis=1),
                         np.inf)  # fmt: skip
        i = int(np.argmin(worst))
        if np.isfinite(worst[i]) and (best is None or worst[i] <= best[0]):
            best = (float(worst[i]), candidates[i])
        if best is None:
            raise AnalysisError(
                f"no gains in {dict(vbox)} keep every point of {dict(obox)} predicted stable "
                f"(margin {stability_margin}) within {np.min(limit):.3g} % overshoot"
            )
        # Zoom in: one grid cell either side of the best, inside the original bounds.
        new = {}
        for p, (lo, hi) in ranges.items():
            pts = axes[p]
            j = pts.index(best[1][p]) if best[1][p] in pts else None
            new[p] = (lo, hi) if j is None else (pts[max(j - 1, 0)], pts[min(j + 1, len(pts) - 1)])
        ranges = new
    assert best is not None
    return best[1], best[0], evaluated


def _verify(
    scenario: Scenario,
    gains: Mapping[str, float],
    obox: Mapping[str, tuple[float, float]],
    duration: float | None,
    threads: int | None,
) -> pl.DataFrame:
    corners = [dict(zip(obox, c, strict=True)) for c in itertools.product(*obox.values())]
    centre = {p: (math.sqrt(lo * hi) if lo > 0 and hi / lo >= 4 else (lo + hi) / 2)
              for p, (lo, hi) in obox.items()}  # fmt: skip
    points = [{**gains, **p} for p in [*corners, centre]]
    given = scenario if duration is None else scenario.replace(duration=duration)
    held = _held(given)
    sim = _core.simulate_batch(_cell_configs(held, points), threads, False)
    moving = _core.simulate_batch(_cell_configs(given, points), threads, False)
    pred = _predict_both(held, points, threads)
    columns: dict[str, Any] = {p: [pt[p] for pt in [*corners, centre]] for p in obox}
    columns["point"] = ["corner"] * len(corners) + ["centre"]
    columns["predicted_stable"] = pred["stable"]
    columns["stable"] = pl.Series(sim["stable"], dtype=pl.Boolean)
    columns["passed"] = pl.Series(sim["passed"], dtype=pl.Boolean)
    columns["verdict"] = pl.Series(sim["verdict"], dtype=pl.String)
    columns["predicted_overshoot_pct"] = pred["overshoot_pct"]
    columns["overshoot_pct"] = sim["metrics"]["overshoot_pct"]
    columns["predicted_settling_time"] = pred["settling_time"]
    columns["settling_time"] = sim["metrics"]["settling_time"]
    columns["stable_with_motion"] = pl.Series(moving["stable"], dtype=pl.Boolean)
    columns["passed_with_motion"] = pl.Series(moving["passed"], dtype=pl.Boolean)
    columns["verdict_with_motion"] = pl.Series(moving["verdict"], dtype=pl.String)
    columns["overshoot_pct_with_motion"] = moving["metrics"]["overshoot_pct"]
    for name in ("impact_peak", "bounces"):
        columns[name] = sim["metrics"][name]
        columns[f"{name}_with_motion"] = moving["metrics"][name]
    return pl.DataFrame(columns)
