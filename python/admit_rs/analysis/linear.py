"""The linear model (SPEC §12): the closed loop over one controller period linearised about
its steady contact equilibrium (:func:`linearize`), what it predicts (:func:`predict`) and
the same over a grid of two parameters (:func:`stability_map`). Reached as
:mod:`admit_rs.analysis`."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import polars as pl

from admit_rs import _core
from admit_rs.analysis._checks import _check_friction, _check_scenario, friction_gain
from admit_rs.analysis.forced import forced_response
from admit_rs.config import Scenario, _check_path, _core_dict_with, _core_value
from admit_rs.errors import AnalysisError, ArgumentError, ParameterError, ParameterTypeError

__all__ = [
    "NO_EQUILIBRIUM",
    "PREDICTION_NAMES",
    "Margins",
    "friction_gain",
    "linearize",
    "predict",
    "stability_map",
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
    e.g. ``admittance.ka = 0``), without a wall or force loop, or for ``at`` with a guarded
    approach (not supported yet); :class:`admit_rs.ParameterError` for an ``at`` outside
    the run.

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
    if at is not None and not 0.0 <= at <= scenario.duration:
        # (A NaN was blamed on z_reference.value, issue #53 item 9.)
        allowed = f"a time of the run, from 0 to its duration {scenario.duration:g} s, or None"
        err = ParameterError(f"at = {at!r} is invalid: must be {allowed}")
        err.field, err.value, err.allowed = "at", repr(at), allowed
        raise err
    if at is not None and scenario.approach is not None:
        # The run's state at `at` holds the approach's stage, which the linearised loop (the
        # contact phase, approach handed over) does not have (issue #53 item 9).
        raise AnalysisError(
            "linearize(at=...) with a guarded approach is not supported: the run's state there"
            " includes the approach's, which the linear model of the contact phase has none"
            " of; linearize about the contact equilibrium (at=None), or the same scenario"
            " with approach=None"
        )
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


def _raise_if(error: str | None) -> None:
    if error is not None:
        raise AnalysisError(error)


def predict(
    scenario: Scenario,
    friction: Any = "step",
    margins: Margins | None = None,
    motion: bool = True,
) -> dict[str, float | bool | str | None]:
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

    With the motion running (``motion=True``, SPEC §23; :func:`forced_response`, about
    0.5–1 s per scenario): ``force_oscillation`` and ``contact_loss`` as the simulated
    metrics, from the forced response to the references and to the friction reversals they
    drive; ``passed``: that loop is stable (friction at the motion's joint speeds) and
    within the scenario's ``max_force_oscillation`` and ``max_contact_loss``;
    ``tolerance_verdict`` in words. ``stable`` stays the held loop's answer, with
    ``margins``: a loop short of margin can still be predicted to pass. ``motion=False``
    leaves these out (NaN, ``passed`` equal to ``stable``).

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
    out: dict[str, float | bool | str | None] = {}
    for k, v in row.items():
        out[k] = bool(v) if k == "stable" else str(v) if k == "verdict" else float(v)
    if error is not None:
        # No steady contact to hold: the loop cannot keep contact (SPEC §23), a prediction
        # of its own, not an exception.
        out["stable"] = False
        out["verdict"] = f"unstable: {error}"
        out.update(passed=False, force_oscillation=math.nan, contact_loss=math.nan,
                   tolerance_verdict=f"unstable: {error}")  # fmt: skip
    elif motion:
        forced = forced_response(scenario)
        out.update(passed=forced.passed, force_oscillation=forced.force_oscillation,
                   contact_loss=forced.contact_loss, tolerance_verdict=forced.verdict)  # fmt: skip
    else:
        out.update(passed=bool(out["stable"]), force_oscillation=math.nan,
                   contact_loss=math.nan,
                   tolerance_verdict="not predicted (motion=False)")  # fmt: skip
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
    gain as A grows, so a cell unstable at some A stays unstable).

    The iteration reads only the poles and the peak speed, so it asks the core for those
    alone (``transient_only``: no margins, no long step response); each cell then gets
    one full prediction at its final A, the values a full prediction at every step would
    have left there."""
    robot = scenario.robot
    eps = getattr(robot, "friction_smoothing", None)
    coulomb = getattr(robot, "coulomb_friction", None)
    base = _cell_configs(scenario, points)
    amp = np.zeros(len(points))
    if eps is None or coulomb is None or eps <= 0:
        raw = dict(_core.predict_batch(base, threads))
        raw["friction_amplitude"] = amp
        return raw
    c0 = np.atleast_1d(np.asarray(coulomb, dtype=float))

    def at_amplitude(i: int) -> dict[str, Any]:
        if amp[i] == 0:
            return base[i]
        gain = friction_gain(float(amp[i]), eps)
        return _core_dict_with(base[i], {"robot.coulomb_friction": list(c0 * gain)})

    quick = _core.predict_batch(base, threads, transient_only=True)
    peak = np.asarray(quick["peak_joint_speed"], dtype=float)
    stable = np.asarray(quick["stable"], dtype=bool)
    for it in range(STEP_ITERATIONS):
        live = stable & np.isfinite(peak) & (peak > 0)
        new = np.where(live, np.sqrt(np.maximum(amp, 0) * peak) if it else peak, amp)
        todo = np.nonzero(live & ~np.isclose(new, amp, rtol=0.05))[0]
        if todo.size == 0:
            break
        amp[todo] = new[todo]
        update = _core.predict_batch([at_amplitude(int(i)) for i in todo], threads,
                                     transient_only=True)  # fmt: skip
        peak[todo] = update["peak_joint_speed"]
        stable[todo] = update["stable"]
    raw = dict(_core.predict_batch([at_amplitude(i) for i in range(len(points))], threads))
    raw["friction_amplitude"] = amp
    return raw


def stability_map(
    scenario: Scenario,
    x: Mapping[str, Sequence[float]],
    y: Mapping[str, Sequence[float]],
    threads: int | None = None,
    friction: Any = "step",
    margins: Margins | None = None,
    motion: bool = False,
) -> pl.DataFrame:
    """:func:`predict` on every cell of the grid ``x`` × ``y`` (``{dotted path: values}``
    each), computed in Rust on all cores (or ``threads``).

    ``motion=True`` adds the prediction with the motion running (:func:`forced_response`,
    SPEC §23): columns ``passed`` (None where not predicted), ``force_oscillation`` and
    ``contact_loss``, for :func:`admit_rs.plot.stability_map`'s ``by="passed"``. It costs
    0.3–1 s per cell, in Python, one cell after another (a 10 × 10 map: about a minute).

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
    table = _predict_points(scenario, points, threads, friction, margins)
    if not motion:
        return table
    passed: list[bool | None] = []
    ripple: list[float] = []
    loss: list[float] = []
    for point, error in zip(points, table["error"], strict=True):
        if error is not None:
            passed.append(False if error.startswith(NO_EQUILIBRIUM) else None)
            ripple.append(math.nan)
            loss.append(math.nan)
            continue
        response = forced_response(scenario.replace(**point))
        passed.append(response.passed)
        ripple.append(response.force_oscillation)
        loss.append(response.contact_loss)
    return table.with_columns(
        pl.Series("passed", passed, dtype=pl.Boolean),
        pl.Series("force_oscillation", ripple, dtype=pl.Float64),
        pl.Series("contact_loss", loss, dtype=pl.Float64),
    )
