"""Type stubs for the Rust extension ``admit_rs._core``.

The functions take plain nested dicts as produced by ``Scenario._to_core()`` and the
blocks' ``_to_core()`` (Python field names, ``kind`` on tagged blocks), decoded by the
blocks' serde declaration in Rust (:func:`schema`); users call them through the
dataclasses in :mod:`admit_rs.config`. A bad value raises ``ParameterError`` naming the
dotted field, an unknown key ``UnknownParameterError`` with the closest valid names, a
wrong type ``TypeError``.
"""

from typing import Any, Final, TypedDict

import numpy as np
import numpy.typing as npt

__version__: Final[str]
TRACE_COLUMNS: Final[list[str]]
"""Trace column names in order: t, q1..q3, qd1..qd3, x, y, z, x_ref, y_ref, z_ref, f,
f_measured, f_d, penetration, x_a, xa_dot, fx, fy, fz, f_t, slip_speed, tau1..tau3,
tau_cmd1..tau_cmd3 (an n-joint arm has q1..qn and so on)."""
METRIC_NAMES: Final[list[str]]
"""Float metric names (see ``admit_rs.METRICS``); ``stable`` and ``diverged`` come besides."""
PREDICTION_NAMES: Final[list[str]]
"""Fields of `predict_batch`'s columns, in order (the Rust `Prediction`)."""

# Errors: the extension raises admit_rs.errors.ParameterError (defined in Python so that it
# is both a ValueError and an admit_rs.AdmitError); it defines no exception class itself.

class FlatTrace(TypedDict):
    """A recorded run in one buffer: column ``names[c]`` is ``data[c * len:(c + 1) * len]``
    (``admit_rs._trace.trace_frame`` slices it into a DataFrame without a copy)."""

    names: list[str]
    len: int
    data: npt.NDArray[np.float64]

def defaults() -> dict[str, dict[str, Any]]:
    """Every block's Rust ``Default``, serialised by its serde declaration, keyed like
    :func:`schema`; tagged blocks carry ``kind``."""

def schema() -> dict[str, dict[str, Any]]:
    """Every block's JSON schema (draft 2020-12) from its Rust declaration: ``properties``
    in declaration order with ``description`` (the field docs), ``type``, ``default`` and
    ``x-ui`` slider hints. Keyed by the registry's keys (three_link, urdf, wall, sphere,
    cylinder, height_field, sensor, actuator, model, computed_torque, model_free,
    time_delay, admittance, impedance, step, sine, sampled, criteria, approach, scenario)."""

def registry() -> list[dict[str, Any]]:
    """The block registry (``rust/src/schema/registry.rs``): one dict per family, in order,
    with ``name``, ``python`` (the Python type of a field holding it), ``type_name`` (its
    Rust schema name, the ``$defs`` key a field refers to) and ``kinds`` (dicts with
    ``key``, ``class``, ``tag`` and ``core_tag``)."""

def check_block(family: str, params: dict[str, Any]) -> None:
    """Validate one block of a registry family (robot, surface, sensor, actuator, model,
    controller, force_control, signal, criteria, approach)."""

def surface_directions(
    params: dict[str, Any],
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(n̂, t̂) of a surface block: its inward normal at the point nearest the tip's start
    and the motion direction for it."""

def validate(scenario: dict[str, Any]) -> None:
    """Validate a whole scenario dict, cross-field checks included."""

def simulate(scenario: dict[str, Any]) -> dict[str, Any]:
    """Run one scenario with the GIL released.

    Returns ``{"columns": FlatTrace,
    "metrics": {name: float, "stable": bool | None, "passed": bool | None, "diverged": bool},
    "verdict": str, "diverged_at": float | None, "divergence_cause": str | None}``;
    ``stable`` (the loop's dynamics, SPEC §23), ``passed`` and ``verdict`` are judged by
    the scenario's ``criteria`` (None: not assessed); a run that fails a criterion the loop
    may sustain is judged by its held run too (run here). With ``substeps="auto"`` also
    ``"substeps"`` (the count chosen),
    ``"substep_error"`` (its estimated largest force error [N]), ``"substep_standing"``
    ("met", "diverged", "not converging", "limit") and ``"substep_note"`` (a sentence).
    """

def robot_terms(
    robot: dict[str, Any], q: tuple[float, float, float], qd: tuple[float, float, float]
) -> dict[str, npt.NDArray[np.float64]]:
    """D (``inertia``), C (``coriolis``), G (``gravity``), J (``jacobian``), ``jdot_qd``,
    tip ``position`` and ``friction`` at (q, q̇)."""

def urdf_terms(
    robot: dict[str, Any],
    q: list[float],
    qd: list[float],
    tau: list[float] | None = None,
    tip_force: list[float] = ...,
) -> dict[str, npt.NDArray[np.float64]]:
    """A URDF arm's D (``inertia``), C q̇ (``coriolis``), G (``gravity``), the 6×n tip
    ``jacobian`` (rows 0–2 linear, world-aligned), ``jdot_qd`` (6), tip ``position`` and
    ``rotation``, ``friction``; with ``tau`` also q̈ (``acceleration``, ABA) under the world
    force ``tip_force`` at the tip."""

def urdf_info(robot: dict[str, Any]) -> dict[str, Any]:
    """A URDF arm's ``joint_names``, position limits ``lower``/``upper``, ``effort`` limits,
    the ``q0`` in use and the ``task`` (``"position"`` or ``"pose"``)."""

def forward_dynamics(
    robot: dict[str, Any],
    q: tuple[float, float, float],
    qd: tuple[float, float, float],
    tau: tuple[float, float, float],
    tip_force: tuple[float, float, float],
) -> npt.NDArray[np.float64]:
    """q̈ of eq. (1): D q̈ = τ + Jᵀ F_tip − C − G − τ_f."""

def filter_discretize(
    params: dict[str, Any], period: float
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Exact ZOH matrices (Ad 2×2, Bd 2) of an admittance filter."""

def filter_response(
    params: dict[str, Any], period: float, force_error: list[float]
) -> dict[str, npt.NDArray[np.float64]]:
    """Run the discrete filter (adaptive when ``sigma`` > 0): ``x_a``, ``xa_dot``,
    ``xa_ddot`` per sample."""

def _lane_path(path: str | None = None) -> str:
    """Hidden (tests, benches; issue #25): force the lane loop's build ("portable", "avx2",
    "avx512"; "auto": the default) in this process; returns the build in effect. ValueError
    for an unknown name or a build this CPU cannot run."""

def _lane_runs() -> dict[str, int]:
    """Hidden: the builds this CPU runs and, for each, the runs whose stages ran in lanes on
    it since the process started."""

def simulate_batch(
    scenarios: list[dict[str, Any]],
    threads: int | None = None,
    traces: bool = False,
    lanes: bool = True,
) -> dict[str, Any]:
    """Run a batch on ``threads`` threads (None: all cores), GIL released; ``lanes``: runs
    four or eight at a time in SIMD lanes (within 1e-9 of the scalar path).

    Returns ``{"metrics": {name: ndarray}, "stable": list[bool | None],
    "passed": list[bool | None], "verdict": list[str],
    "diverged": ndarray[bool],
    "diverged_at": ndarray (NaN when the run completed), "divergence_cause": list[str | None],
    "substeps": ndarray[int64] (the count each run was integrated with: its own, or what
    ``"auto"`` chose), "substep_error": ndarray (``"auto"``: the estimated largest force
    error [N]; NaN for a fixed count), "substep_standing": list[str | None] ("met",
    "diverged", "not converging", "limit"; None for a fixed count),
    "traces": list[FlatTrace] | None}``.
    An invalid scenario raises ``ParameterError`` (with ``index``) before anything runs.
    """

def linearize(
    scenario: dict[str, Any], at: float | None = None, driven: bool = False
) -> dict[str, Any]:
    """The one-period closed loop linearised about its contact equilibrium (or the state
    at time ``at``), GIL released: ``a`` (n×n), ``b`` (n×1), ``c`` (3×n), ``d`` (3×1)
    and ``c_measured`` (n: the measured force f̃ = c_measured·x, what the force loop feeds
    back) as ndarrays, ``labels``, ``state`` (the operating point), ``force_desired``,
    ``outputs`` ([f, n·X, t̂·X] there), ``reference_normal``, ``penetration``,
    ``period``, ``equilibrium``, ``iterations``, ``caveats``. ``driven`` adds the inputs
    u = (s, ṡ, s̈, τ_1 … τ_N) (the motion reference and a torque added to each joint's):
    ``b_drive`` (n×m), ``d_drive`` (3×m), ``c_measured_drive`` (m), ``drive_labels`` and
    ``curvature`` (n + 4 symmetric (n+m)×(n+m) matrices: the second derivatives of each
    row of Φ, then of f, n·X, t̂·X, f̃, in (x, u)). Raises
    ``admit_rs.errors.AnalysisError`` without a contact equilibrium or a singular one."""

def reference_samples(scenario: dict[str, Any]) -> dict[str, Any]:
    """The references at each sample t_k = k·T as the loop reads them: ``force`` (f_d),
    ``motion`` (s), ``motion_rate`` (ṡ), ``motion_accel`` (s̈), ndarrays of the run's
    sample count."""

def predict_batch(
    scenarios: list[dict[str, Any]], threads: int | None = None, transient_only: bool = False
) -> dict[str, Any]:
    """Linearise and predict every scenario on ``threads`` threads (None: all cores),
    GIL released: one ndarray per prediction field (``force_ss_error``, ``x_ss_error``,
    ``overshoot_pct``, ``rise_time_63``, ``settling_time``, ``spectral_radius``,
    ``dominant_frequency``, ``dominant_damping``, ``stable`` (bool: ρ < 1 only),
    ``peak_joint_speed``, the force loop's ``gain_margin``, ``phase_margin`` [deg] and
    ``delay_margin`` [samples]) and ``error`` (list of None or why a scenario has no
    prediction; its fields are then NaN). ``transient_only``: only the poles and
    ``peak_joint_speed``, the margins and step metrics NaN (a map's friction iteration)."""

class Stepper:
    """The loop of one scenario, stepped (``admit_rs.Simulation`` wraps it). One thread at
    a time: a call while another thread is inside ``step`` raises ``AdmitError``."""

    def __init__(self, scenario: dict[str, Any]) -> None: ...
    def reset(self) -> None: ...
    def step(self, n: int) -> int:
        """Take up to ``n`` samples with the GIL released; returns how many were taken."""
    def sample(self) -> int:
        """Index of the next sample."""
    def samples(self) -> int:
        """Samples in the whole run."""
    def state(self) -> npt.NDArray[np.float64]: ...
    def state_labels(self) -> list[str]: ...
    def set_state(self, values: list[float]) -> None: ...
    def trace(self) -> FlatTrace:
        """The samples so far (a copy)."""
    def outcome(self) -> dict[str, Any] | None:
        """``None`` while the run goes on; then ``metrics``, ``diverged_at``,
        ``divergence_cause`` as from :func:`simulate`."""
