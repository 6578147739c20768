"""Building blocks of a scenario: frozen, keyword-only dataclasses.

Every block validates itself through the Rust core when it is constructed, so a bad value
fails where it is written, with a :class:`~admit_rs.errors.ParameterError` (a ``ValueError``)
that names the field, the value and the allowed range. Defaults are the paper preset
(SPEC §1-§6); ``Scenario()`` is the fig. 14 run (TDC, Scheme 2, b = 800, k_a = 1).
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import inspect
import math
import numbers
import sys
import textwrap
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal, TypeAlias

import numpy as np
import numpy.typing as npt

from admit_rs import _core, _registry
from admit_rs.errors import (
    ParameterError,
    UnknownParameterError,
    _copy,
    closest,
    shown,
    unknown,
    within,
)

Vector3: TypeAlias = tuple[float, float, float]
ArrayLike3: TypeAlias = "Iterable[float] | npt.NDArray[np.float64]"


def _vec3(name: str, value: Any) -> Vector3:
    if _holds_bool(value):
        raise TypeError(f"{name} must be a sequence of 3 numbers, got a bool")
    try:
        items = tuple(float(v) for v in value)
    except TypeError as e:
        raise TypeError(f"{name} must be a sequence of 3 numbers, got {shown(value)}") from e
    if len(items) != 3:
        raise TypeError(f"{name} must have 3 elements, got {len(items)}")
    return items  # type: ignore[return-value]


def _check_integer(name: str, value: Any, high: int) -> None:
    """Integers are ints (or integral floats) from 0 to ``high``; anything else is a
    ParameterError naming the field."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(f"{name} must be an int, got {type(value).__name__}")
    if not (isinstance(value, int) or math.isfinite(value)) or not (
        value == int(value) and 0 <= value <= high
    ):
        err = ParameterError(
            f"{name} = {shown(value)} is invalid: must be an integer from 0 to {high}"
        )
        err.field, err.value, err.allowed = name, shown(value), f"an integer from 0 to {high}"
        raise err


def _parameter_error(name: str, value: str, allowed: str) -> ParameterError:
    """A ParameterError naming the field, the value (as shown) and the allowed range."""
    err = ParameterError(f"{name} = {value} is invalid: must be {allowed}")
    err.field, err.value, err.allowed = name, value, allowed
    return err


def _core_value(value: Any) -> Any:
    """A field's value as the core decodes it (serde through pythonize): blocks as dicts,
    tuples as lists, NumPy scalars as Python numbers."""
    if isinstance(value, _Block):
        return value._to_core()
    if isinstance(value, tuple):
        return [_core_value(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _core_dict_with(base: Mapping[str, Any], changes: Mapping[str, Any]) -> dict[str, Any]:
    """The core dict ``base`` with ``changes`` (dotted path -> value, as the core takes it)
    set, copying only the tables on those paths: the rest is shared with ``base``, which the
    core only reads (a sweep's runs no longer deep-copy every table, a URDF text included,
    per run)."""
    out = dict(base)
    copied: set[int] = {id(out)}
    for path, value in changes.items():
        *parents, leaf = path.split(".")
        node = out
        for part in parents:
            child = node[part]
            if id(child) not in copied:
                child = dict(child)
                copied.add(id(child))
                node[part] = child
            node = child
        node[leaf] = value
    return out


def _declared_shape(name: str, annotation: str, value: Any) -> Any:
    """``value`` as the tuple (or tuple of rows) ``annotation`` declares, if it is a sequence
    of numbers; else ``value`` itself."""
    if ("tuple" not in annotation and "Vector3" not in annotation) or value is None:
        return value
    if isinstance(value, str | bytes | Mapping | numbers.Number | _Block):
        return value
    try:
        grid = np.asarray(value, dtype=float)
    except OverflowError:  # an int beyond the float range
        raise _parameter_error(name, shown(value), "finite numbers") from None
    except (TypeError, ValueError):
        return value  # ragged, or not numbers: the core names the field and the fault
    if grid.ndim == 2 and "tuple[tuple" in annotation:
        return tuple(tuple(float(v) for v in row) for row in grid)
    return tuple(float(v) for v in np.ravel(grid))


def _plain_scalar(value: Any, depth: int = 2) -> Any:
    """``value`` with NumPy scalars, also inside tuples and lists (``depth`` levels: no field
    nests deeper, and the core refuses deeper values), as Python ones; ``value`` itself when
    it holds none."""
    if isinstance(value, np.generic):
        return value.item()
    if depth > 0 and isinstance(value, tuple | list):
        items = [_plain_scalar(v, depth - 1) for v in value]
        if any(a is not b for a, b in zip(items, value, strict=True)):
            return tuple(items)
    return value


_PACKAGE_DIR = Path(__file__).resolve().parent


def _in_package(filename: str) -> bool:
    return Path(filename).resolve().parent == _PACKAGE_DIR


def _warn_renamed(old: str, new: str) -> None:
    """DeprecationWarning for a renamed field, attributed to the first caller outside
    admit_rs (the user's line, however deep the library's own calls go)."""
    level, frame = 2, sys._getframe(1)  # stacklevel 2 is our caller
    while frame is not None and _in_package(frame.f_code.co_filename):
        level, frame = level + 1, frame.f_back  # type: ignore[assignment]
    warnings.warn(
        f"{old} is deprecated and will be removed in the next release; use {new}",
        DeprecationWarning,
        stacklevel=level,
    )


def _python_error(err: ParameterError, prefix: str = "") -> ParameterError:
    """The core's ParameterError in Python field names (the core's key for
    ``controller.command_divisor`` is ``ka``). ``prefix`` is the field's place, if the
    core's path does not say it."""
    field = getattr(err, "field", "")
    parts = (prefix + field).split(".")
    if parts[-2:] != ["controller", "ka"]:
        return err
    new_field = field[: -len("ka")] + "command_divisor"
    new = _copy(err, f"{new_field} = {err.value} is invalid: must be {err.allowed}", new_field)
    if hasattr(err, "index"):
        new.index = err.index  # type: ignore[attr-defined]
    return new


class _Block:
    """Shared machinery: conversion to the core's dict and validation through Rust."""

    _key: ClassVar[str] = ""
    """The block's key in the core's registry, schema and defaults."""
    _kind: ClassVar[str | None] = None
    """The ``kind`` tag of its dict and TOML table (None: untagged)."""
    _core_kind: ClassVar[str | None] = None
    """The ``kind`` the core's declaration tags this block with where ``_kind`` (the
    Python/TOML tag) is None: a Wall is a ``plane`` to the core, an untagged table in TOML."""
    _check: ClassVar[str] = ""
    """The family the core validates it as (``_core.check_block``)."""
    _PYTHON_ONLY: ClassVar[frozenset[str]] = frozenset({"label"})
    """Fields that stay in Python (not in the Rust declaration, not sent to the core)."""
    _RENAMED: ClassVar[dict[str, str]] = {}
    """Deprecated field name -> its new name; the old one still works, with a warning."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        # A block's key, tags and family are the core's registry's, by its class name.
        super().__init_subclass__(**kwargs)
        kind = _registry.BY_CLASS.get(cls.__name__)
        if kind is not None:
            cls._key, cls._kind, cls._core_kind = kind.key, kind.tag, kind.core_tag
            cls._check = kind.family

    def _to_core(self) -> dict[str, Any]:
        """The dict the core decodes by the block's serde declaration (Python field names,
        ``kind`` on tagged blocks)."""
        out: dict[str, Any] = {}
        kind = self._kind if self._kind is not None else self._core_kind
        if kind is not None:
            out["kind"] = kind
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            if f.name in self._PYTHON_ONLY:
                continue
            out[f.name] = _core_value(getattr(self, f.name))
        return out

    def _reject_bools(self) -> None:
        """A bool where the field takes numbers, or a non-number in a ``float`` field, is a
        TypeError naming the field. (Below a tagged block the core's decoder loses the
        field's name and could only say "scenario must be a number".)"""
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value, kind = getattr(self, f.name), str(f.type)
            if "bool" not in kind and _holds_bool(value):
                raise TypeError(f"{f.name} must be a number, got a bool")
            if kind in ("float", "float | None") and not (
                isinstance(value, numbers.Real) or (value is None and kind != "float")
            ):
                got = "None" if value is None else type(value).__name__
                raise TypeError(f"{f.name} must be a number, got {got}")
            if isinstance(value, int) and not isinstance(value, bool) and "int" not in kind:
                if abs(value) > sys.float_info.max:
                    # float() would raise OverflowError deep in the conversion.
                    raise ParameterError(
                        f"{f.name} = {shown(value)} is invalid: must be a finite number"
                    )

    def _plain_scalars(self) -> None:
        """NumPy scalars (alone or in sequences) become the Python numbers they hold, so a
        block prints, compares, pickles and exports to TOML as the value it stands for
        (``np.float64(5e4)`` would be written as its repr; ``np.int64`` is no ``int``)."""
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            plain = _plain_scalar(value)
            if plain is not value:
                self._set(f.name, plain)

    def _declared_shapes(self) -> None:
        """A sequence (a list, a NumPy array) given for a field declared as a tuple becomes
        that tuple of floats (rows of them for a grid), so that a field the Rust declaration
        adds needs no conversion written here; anything else is left for the core to judge."""
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            shaped = _declared_shape(f.name, str(f.type), value)
            if shaped is not value:
                self._set(f.name, shaped)

    def _validate(self) -> None:
        self._plain_scalars()
        self._reject_bools()
        self._declared_shapes()
        try:
            _core.check_block(self._check, self._to_core())
        except ParameterError as e:
            raise _python_error(e, f"{self._check}.") from None

    def __post_init__(self) -> None:
        # Every block checks itself in Rust on construction, so a bad value fails where
        # it is written.
        self._validate()

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)

    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict (tuples as lists), with a ``kind`` tag on tagged blocks."""
        out: dict[str, Any] = {}
        if self._kind is not None:
            out["kind"] = self._kind
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if isinstance(value, _Block):
                out[f.name] = value.to_dict()
            else:
                out[f.name] = _core_value(value)
        return out


@dataclass(frozen=True, kw_only=True)
class Robot(_Block):
    """The three-link arm of Table 1 (SPEC §1).

    Example:
        >>> import admit_rs as ar
        >>> robot = ar.Robot()
        >>> robot.dynamics(robot.q0)["gravity"].round(2)
        array([ 0.  , 50.39, 10.12])
    """

    # generated by admit_rs._codegen: fields of "three_link"
    lengths: Vector3 = (0.66, 0.43, 0.43)
    """Link lengths l1, l2, l3 [m]."""
    masses: Vector3 = (30.0, 17.4, 4.8)
    """Link masses [kg]."""
    mass_model: Literal["rod", "point"] = "rod"
    """``"rod"``: uniform thin rods; ``"point"``: a point mass at each link's end."""
    viscous_friction: Vector3 = (3.0, 3.0, 3.0)
    """Viscous friction per joint [N·m·s/rad]."""
    coulomb_friction: Vector3 = (5.0, 5.0, 5.0)
    """Coulomb friction per joint [N·m]."""
    friction_smoothing: float = 0.01
    """ε [rad/s] of sgn(q̇) ≈ tanh(q̇/ε); ε ≤ 0 uses the exact sign."""
    gravity: float = 9.81
    """Gravity along -z [m/s²]."""
    q0: Vector3 = (0.0, 0.7853981633974483, -0.7853981633974483)
    """Initial joint angles [rad]."""
    # end of generated fields

    def __post_init__(self) -> None:
        for name in ("lengths", "masses", "viscous_friction", "coulomb_friction", "q0"):
            try:
                self._set(name, _vec3(name, getattr(self, name)))
            except TypeError as e:
                raise TypeError(
                    f"{e} (ar.Robot is the paper's three-link arm; load any other serial arm "
                    "from its URDF with ar.UrdfArm(path, tip_link), see docs/arms.md)"
                ) from None
        self._validate()

    def dynamics(
        self, q: ArrayLike3, qd: ArrayLike3 = (0.0, 0.0, 0.0)
    ) -> dict[str, npt.NDArray[np.float64]]:
        """D, C, G, J, J̇q̇, tip position and friction at (q, q̇).

        Keys: ``inertia`` (D), ``coriolis`` (C), ``gravity`` (G), ``jacobian`` (J),
        ``jdot_qd`` (J̇q̇), ``position`` (tip [x, y, z]), ``friction`` (τ_f).
        """
        return _core.robot_terms(self._to_core(), _vec3("q", q), _vec3("qd", qd))

    def forward_dynamics(
        self,
        q: ArrayLike3,
        qd: ArrayLike3,
        tau: ArrayLike3,
        tip_force: ArrayLike3 = (0.0, 0.0, 0.0),
    ) -> npt.NDArray[np.float64]:
        """q̈ of eq. (1): D q̈ = τ + Jᵀ F_tip − C − G − τ_f."""
        return _core.forward_dynamics(
            self._to_core(),
            _vec3("q", q),
            _vec3("qd", qd),
            _vec3("tau", tau),
            _vec3("tip_force", tip_force),
        )

    def tip_position(self, q: ArrayLike3) -> npt.NDArray[np.float64]:
        """Forward kinematics [x, y, z] [m]."""
        return self.dynamics(q)["position"]


def _numbers(name: str, value: Any) -> float | tuple[float, ...]:
    """One number, or a sequence of numbers as a tuple."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    if _holds_bool(value):
        raise TypeError(f"{name} must be a number or a sequence of numbers, got a bool")
    try:
        return tuple(float(v) for v in np.ravel(np.asarray(value, dtype=float)))
    except (TypeError, ValueError) as e:
        raise TypeError(
            f"{name} must be a number or a sequence of numbers, got {shown(value)}"
        ) from e


def _holds_bool(value: Any, depth: int = 2) -> bool:
    """A bool, or a sequence (or matrix: ``depth`` levels) holding one: Python counts True
    as 1, so without this check ``admittance.b=True`` would pass as b = 1. Deeper nesting
    is not searched (no field nests deeper; the core rejects it without recursing)."""
    if isinstance(value, bool | np.bool_):
        return True
    if isinstance(value, np.ndarray):
        return bool(value.dtype == np.bool_)
    return (
        depth > 0
        and isinstance(value, tuple | list)
        and any(_holds_bool(v, depth - 1) for v in value)
    )


@dataclass(frozen=True)
class UrdfArm(_Block):
    """A serial arm from a URDF file (SPEC §11), usable wherever :class:`Robot` is.

    The chain runs from ``base_link`` (default: the URDF's root) to ``tip_link``; revolute,
    continuous and prismatic joints move, fixed joints merge their links into the parent
    body. D, C q̇ + G, J, J̇q̇ and forward dynamics come from the recursive algorithms
    (RNEA, CRBA, ABA) in Rust. The document's text is kept in the block (``urdf``), so a
    scenario carries it to other processes (Dask) without the file.

    Example:
        >>> import admit_rs as ar
        >>> arm = ar.UrdfArm("examples/data/panda.urdf", "panda_hand_tcp")  # doctest: +SKIP
        >>> arm.dof, arm.task                                               # doctest: +SKIP
        (7, 'pose')
    """

    path: str | Path = ""
    """The URDF file it was read from (its text is read once, into ``urdf``; kept as a str)."""
    # generated by admit_rs._codegen: fields of "urdf" (positional: tip_link)
    tip_link: str = ""
    """The link whose origin is the tip (contact point and task frame)."""
    _: dataclasses.KW_ONLY
    urdf: str = field(default="", repr=False, compare=True)
    """The URDF document (read from ``path`` when not given)."""
    base_link: str | None = None
    """The chain's base link; ``None``: the URDF's root link."""
    q0: tuple[float, ...] | None = None
    """Initial joint positions [rad or m], one per joint; ``None``: zero, clipped into the URDF's
    position limits."""
    viscous_friction: float | tuple[float, ...] = 0.0
    """Viscous friction [N·m·s/rad]: one number for every joint or one per joint."""
    coulomb_friction: float | tuple[float, ...] = 0.0
    """Coulomb friction [N·m]: one number for every joint or one per joint."""
    friction_smoothing: float = 0.01
    """ε [rad/s] of sgn(q̇) ≈ tanh(q̇/ε); ε ≤ 0 uses the exact sign."""
    gravity: float = 9.81
    """Gravity along -z of the base frame [m/s²]."""
    task: Literal["position", "pose"] | None = None
    """Task space: ``"position"`` (tip position) or ``"pose"`` (position and orientation, held at
    its start); ``None``: position below 6 joints, pose from 6."""
    orientation_gains: tuple[float, float] | None = None
    """(K_P [1/s²], K_D [1/s]) of the orientation in a pose task; ``None``: the controller's kp,
    kd (both divided by its command_divisor K_A, as in eq. 39)."""
    damping: float = 0.001
    """λ of the damped pseudo-inverse J⁺ = Jᵀ(J Jᵀ + λ² I)⁻¹ of eqs. 7 and 17."""
    orientation: Literal["hold", "surface"] = "hold"
    """A pose task's orientation: ``"hold"`` (its start value R0) or ``"surface"`` (R0 turned by
    the rotation that takes the estimated surface's normal at the start to its normal at the tip,
    so the tool stays normal to the part as it curves; SPEC §15)."""
    # end of generated fields

    _PYTHON_ONLY: ClassVar[frozenset[str]] = frozenset({"path"})

    def __post_init__(self) -> None:
        for name in ("path", "tip_link", "urdf"):
            if not isinstance(getattr(self, name), str):
                value = getattr(self, name)
                if name == "path" and isinstance(value, Path):
                    self._set(name, str(value))
                    continue
                raise TypeError(f"{name} must be a str, got {type(value).__name__}")
        if not self.urdf:
            if not self.path:
                raise TypeError("UrdfArm needs a path (or the document as urdf=...)")
            try:
                text = Path(self.path).read_text(encoding="utf-8")
            except UnicodeDecodeError as e:
                err = ParameterError(
                    f"path = {self.path!r} is invalid: must be a URDF file in UTF-8 (byte "
                    f"{e.start} is not UTF-8)"
                )
                err.field, err.value, err.allowed = "path", repr(self.path), "a UTF-8 URDF file"
                raise err from None
            except OSError as e:
                err = ParameterError(
                    f"path = {self.path!r} is invalid: must be a readable URDF file ({e.strerror})"
                )
                err.field, err.value, err.allowed = "path", repr(self.path), "a readable URDF file"
                raise err from None
            self._set("urdf", text)
        if not self.tip_link:
            raise TypeError("UrdfArm needs tip_link, the link whose origin is the tip")
        if self.q0 is not None:
            self._set("q0", _numbers("q0", self.q0))
            if isinstance(self.q0, float):
                self._set("q0", (self.q0,))
        for name in ("viscous_friction", "coulomb_friction"):
            self._set(name, _numbers(name, getattr(self, name)))
        if self.orientation_gains is not None:
            gains = _numbers("orientation_gains", self.orientation_gains)
            if isinstance(gains, float) or len(gains) != 2:
                err = ParameterError(
                    f"orientation_gains = {shown(self.orientation_gains)} is invalid: must be "
                    "two numbers (K_P, K_D) or None"
                )
                err.field, err.value = "orientation_gains", shown(self.orientation_gains)
                err.allowed = "two numbers (K_P, K_D) or None"
                raise err
            self._set("orientation_gains", gains)
        if self.base_link is not None and not isinstance(self.base_link, str):
            err = ParameterError(
                f"base_link = {self.base_link!r} is invalid: must be a link name (str) or None"
            )
            err.field, err.value, err.allowed = "base_link", repr(self.base_link), "a str or None"
            raise err
        if self.task not in (None, "position", "pose"):
            err = ParameterError(
                f"task = {self.task!r} is invalid: must be one of 'position', 'pose' or None"
            )
            err.field, err.value, err.allowed = "task", repr(self.task), "'position', 'pose', None"
            raise err
        self._validate()

    @functools.cached_property
    def _info(self) -> dict[str, Any]:
        return dict(_core.urdf_info(self._to_core()))

    @property
    def dof(self) -> int:
        """The number of joints of the chain."""
        return len(self._info["joint_names"])

    @property
    def joint_names(self) -> list[str]:
        """The URDF names of the chain's joints, base to tip."""
        return list(self._info["joint_names"])

    @property
    def position_limits(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(lower, upper) position limits per joint [rad or m]; ±inf where none."""
        return np.asarray(self._info["lower"]), np.asarray(self._info["upper"])

    @property
    def effort_limits(self) -> npt.NDArray[np.float64]:
        """Effort limit per joint [N·m or N]; inf where the URDF gives none."""
        return np.asarray(self._info["effort"])

    @property
    def initial_position(self) -> npt.NDArray[np.float64]:
        """q0 as used: the given one, or zero clipped into the limits."""
        return np.asarray(self._info["q0"])

    @property
    def task_kind(self) -> str:
        """The task in use: ``"position"`` or ``"pose"``."""
        return str(self._info["task"])

    def dynamics(
        self, q: Iterable[float], qd: Iterable[float] | None = None
    ) -> dict[str, npt.NDArray[np.float64]]:
        """D, C q̇, G, J (6×n, rows 0–2 linear, world-aligned at the tip), J̇q̇ (6), the tip's
        position and rotation, and friction at (q, q̇).

        Keys: ``inertia``, ``coriolis``, ``gravity``, ``jacobian``, ``jdot_qd``,
        ``position``, ``rotation``, ``friction``.
        """
        q = [float(v) for v in q]
        qd = [0.0] * len(q) if qd is None else [float(v) for v in qd]
        return dict(_core.urdf_terms(self._to_core(), q, qd))

    def forward_dynamics(
        self,
        q: Iterable[float],
        qd: Iterable[float],
        tau: Iterable[float],
        tip_force: ArrayLike3 = (0.0, 0.0, 0.0),
    ) -> npt.NDArray[np.float64]:
        """q̈ (ABA): D q̈ = τ + Jᵀ F_tip − C q̇ − G − τ_f, F_tip a world force at the tip."""
        out = _core.urdf_terms(
            self._to_core(),
            [float(v) for v in q],
            [float(v) for v in qd],
            [float(v) for v in tau],
            list(_vec3("tip_force", tip_force)),
        )
        return np.asarray(out["acceleration"])

    def tip_position(self, q: Iterable[float]) -> npt.NDArray[np.float64]:
        """Forward kinematics [x, y, z] [m]."""
        return self.dynamics(q)["position"]


@dataclass(frozen=True, kw_only=True)
class _Surface(_Block):
    """The contact-law fields every surface shares (SPEC §10, §15): the tip feels −f N + F_t
    while it penetrates, N the surface's inward normal at the tip, f from the contact law on
    the penetration δ and its rate δ̇ = N·Ẋ, and Coulomb friction
    F_t = −μ f v_t / √(|v_t|² + v_s²) along the surface."""

    # generated by admit_rs._codegen: fields shared by "wall", "sphere", "cylinder", "height_field"
    stiffness: float = 30000.0
    """Environment stiffness k_e [N/m] (Hunt–Crossley: [N/m^p]); unknown to the controller."""
    damping: float = 0.0
    """Contact damping c [N·s/m]."""
    model: Literal["kelvin_voigt", "hunt_crossley"] = "kelvin_voigt"
    """Contact law: ``"kelvin_voigt"`` (spring and damper) or ``"hunt_crossley"``."""
    exponent: float = 1.0
    """Hunt–Crossley exponent p, from 1 to 10 (ignored by Kelvin–Voigt)."""
    friction: float = 0.0
    """Coulomb friction coefficient μ along the surface (0: frictionless), from 0 to 10."""
    stiction_velocity: float = 0.001
    """Slip speed v_s [m/s] below which friction is regularised: F_t = −μ f v_t / √(|v_t|² +
    v_s²)."""
    position_error: float = 0.0
    """Error of the controller's estimate of the surface [m], along its normal: the controller
    believes the surface ``position_error`` further along n."""
    gap: float = 0.0
    """Free space before contact [m]: the true surface starts ``gap`` further along n than where
    it would touch the tip at q0 (a Wall: than its ``position``). 0: touching at zero force."""
    # end of generated fields

    def __post_init__(self) -> None:
        for name in ("normal", "axis"):
            if hasattr(self, name):
                self._set(name, _vec3(name, getattr(self, name)))
        self._validate()

    def directions(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The unit normal n̂ the controller's task frame controls force along (for a
        curved surface: its inward normal at the point nearest the tip's start) and the
        motion direction t̂ = normalise(e_z − (e_z·n̂) n̂) (e_x if n ∥ e_z), as the core
        computes them: force and ``x_*`` metrics are along n̂, motion and ``z_*`` metrics
        along t̂.

        Example:
            >>> import admit_rs as ar
            >>> n, t = ar.Wall(normal=(1, 0, -1)).directions()
            >>> n.round(4).tolist(), t.round(4).tolist()
            ([0.7071, 0.0, -0.7071], [0.7071, 0.0, 0.7071])
        """
        n, t = _core.surface_directions(self._to_core())
        return np.asarray(n, dtype=float), np.asarray(t, dtype=float)

    @property
    def tilted(self) -> bool:
        """Whether n̂ is not the paper's +x (then n·X and t̂·X are not the world x, z)."""
        n, _ = self.directions()
        return bool(np.max(np.abs(n - np.array([1.0, 0.0, 0.0]))) > 1e-12)

    @property
    def planar(self) -> bool:
        """Whether the surface is a plane (a Wall, or nothing curved about it)."""
        return isinstance(self, Wall)


@dataclass(frozen=True, kw_only=True)
class Wall(_Surface):
    """A unilateral wall {X : n·X = x_e}; the tip feels −f n (and friction) while it
    penetrates.

    Penetration δ = n·X − x_e, rate δ̇ = n·Ẋ. Kelvin–Voigt: f = max(0, k δ + c δ̇);
    Hunt–Crossley: f = max(0, k δ^p + c δ^p δ̇). The default is the paper's wall: normal to
    x, no damping, no friction, touching the tip at q0 (SPEC §2).

    Example:
        >>> import admit_rs as ar
        >>> ar.Wall(stiffness=5e4, damping=50.0, normal=(1, 0, -1)).normal
        (1.0, 0.0, -1.0)
    """

    # generated by admit_rs._codegen: fields of "wall"
    normal: Vector3 = (1.0, 0.0, 0.0)
    """Normal n pointing into the wall (any length; normalised). Force is controlled along n,
    motion along t̂ = normalise(e_z − (e_z·n) n)."""
    position: float | None = None
    """Wall position x_e along n [m]; ``None`` puts the plane through the tip at q0 (touching,
    zero force)."""
    # end of generated fields


@dataclass(frozen=True, kw_only=True)
class Sphere(_Surface):
    """A sphere of radius R (SPEC §15): a ball touched from outside, or a bowl from inside.

    Outside, its centre is at X0 + (gap + R) n; inside (``inside=True``) at X0 − (R − gap) n,
    X0 the tip at q0, so the tip starts ``gap`` from the surface either way. Penetration
    δ = R − |X − c| outside, |X − c| − R inside; the inward normal N lies along the line to
    the centre.

    Example:
        >>> import admit_rs as ar
        >>> sc = ar.Scenario(wall=ar.Sphere(radius=0.2, friction=0.3))
        >>> sc.wall.radius, sc.wall.friction
        (0.2, 0.3)
    """

    # generated by admit_rs._codegen: fields of "sphere"
    radius: float = 0.1
    """Radius R [m], from 0 (exclusive) to 1e9."""
    normal: Vector3 = (1.0, 0.0, 0.0)
    """Approach normal n pointing into the surface at the point the tip starts beside (any
    length; normalised). Force is controlled along n, motion along t̂ = normalise(e_z − (e_z·n)
    n)."""
    inside: bool = False
    """``False``: the tip touches the outside (a ball); ``True``: the inside (a bowl)."""
    # end of generated fields


@dataclass(frozen=True, kw_only=True)
class Cylinder(_Surface):
    """A circular cylinder of radius R about ``axis`` (SPEC §15): a shaft touched from
    outside, or a bore from inside; δ and N as for :class:`Sphere`, with the distance to the
    axis line.

    Example:
        >>> import admit_rs as ar
        >>> ar.Cylinder(radius=0.05, axis=(0, 1, 0), inside=True).axis
        (0.0, 1.0, 0.0)
    """

    # generated by admit_rs._codegen: fields of "cylinder"
    radius: float = 0.1
    """Radius R [m], from 0 (exclusive) to 1e9."""
    axis: Vector3 = (0.0, 0.0, 1.0)
    """Direction of the cylinder's axis (any length; normalised); not parallel to n."""
    normal: Vector3 = (1.0, 0.0, 0.0)
    """Approach normal n pointing into the surface at the point the tip starts beside (any
    length; normalised; its part along the axis is ignored). Force is controlled along n, motion
    along t̂ = normalise(e_z − (e_z·n) n)."""
    inside: bool = False
    """``False``: the tip touches the outside (a shaft); ``True``: the inside (a bore)."""
    # end of generated fields


Heights: TypeAlias = tuple[tuple[float, ...], ...]


def _heights(value: Any) -> Heights:
    """A grid of heights as a tuple of rows (from a NumPy array or nested sequences)."""
    if isinstance(value, str | bytes) or _holds_bool(value):
        raise TypeError(f"heights must be a 2-D grid of numbers, got {shown(value)}")
    try:
        grid = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as e:
        raise TypeError(f"heights must be a 2-D grid of numbers: {e}") from None
    if grid.ndim != 2:
        raise _parameter_error(
            "heights", f"an array of shape {grid.shape}", "a 2-D grid of at least 2×2 heights"
        )
    return tuple(tuple(float(h) for h in row) for row in grid)


@dataclass(frozen=True, kw_only=True)
class HeightField(_Surface):
    """A scanned part (SPEC §15): the surface n·X = x_e + h(u, v) over a grid of heights
    centred on the tip's start X0, (u, v) the coordinates of X − X0 along t̂ and
    b̂ = n × t̂, x_e = n·X0 + gap.

    h is bicubic (C¹) between nodes, shifted so that h(0, 0) = 0, and continues beyond the
    grid as the tangent plane at its edge. δ = (n·X − x_e − h)/√(1 + |∇h|²), the inward
    normal N ∝ n − h_u t̂ − h_v b̂. Build one from a NumPy array (``heights=array``) or from
    a file with :meth:`from_file`.

    Example:
        >>> import admit_rs as ar, numpy as np
        >>> u = (np.arange(5) - 2) * 0.01
        >>> hf = ar.HeightField(heights=np.add.outer(0.1 * u, 0 * u), spacing=(0.01, 0.01))
        >>> len(hf.heights), len(hf.heights[0])
        (5, 5)
    """

    # generated by admit_rs._codegen: fields of "height_field"
    heights: tuple[tuple[float, ...], ...] = ((0.0, 0.0), (0.0, 0.0))
    """Heights h[i][j] [m] at u_i = (i − (rows − 1)/2)·du, v_j = (j − (cols − 1)/2)·dv along n
    (positive: further into the part); at least 2×2, shifted so that h(0, 0) = 0."""
    spacing: tuple[float, float] = (0.01, 0.01)
    """Grid spacing (du, dv) [m] along t̂ and b̂ = n × t̂."""
    normal: Vector3 = (1.0, 0.0, 0.0)
    """Normal n pointing into the part (any length; normalised): heights are measured along it.
    Force is controlled along n, motion along t̂ = normalise(e_z − (e_z·n) n)."""
    # end of generated fields

    def __post_init__(self) -> None:
        self._set("heights", _heights(self.heights))
        if _holds_bool(self.spacing):
            raise TypeError("spacing must be 2 numbers, got a bool")
        try:
            spacing = tuple(float(d) for d in self.spacing)
        except TypeError as e:
            raise TypeError(f"spacing must be 2 numbers, got {shown(self.spacing)}") from e
        if len(spacing) != 2:
            raise TypeError(f"spacing must have 2 elements, got {len(spacing)}")
        self._set("spacing", spacing)
        super().__post_init__()

    @classmethod
    def from_file(cls, path: str | Path, **fields: Any) -> HeightField:
        """A height field from a grid of heights [m] in a file: ``.npy`` (a 2-D array) or
        ``.csv``/``.txt`` (rows of comma- or whitespace-separated numbers; ``#`` starts a
        comment). ``fields`` are the other fields (``spacing``, ``normal``, ``friction``, …).

        Example:
            >>> import admit_rs as ar, numpy as np, tempfile, pathlib
            >>> f = pathlib.Path(tempfile.mkdtemp()) / "scan.csv"
            >>> np.savetxt(f, np.zeros((3, 4)), delimiter=",")
            >>> hf = ar.HeightField.from_file(f, spacing=(0.002, 0.002))
            >>> len(hf.heights), len(hf.heights[0])
            (3, 4)
        """
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no height field file at {path}")
        if path.suffix.lower() == ".npy":
            grid = np.load(path, allow_pickle=False)
        else:
            text = path.read_text(encoding="utf-8")
            delimiter = "," if "," in text else None
            try:
                grid = np.loadtxt(path, delimiter=delimiter, ndmin=2, comments="#")
            except ValueError as e:
                raise _parameter_error(
                    "heights", f"the file {path.name}", f"rows of numbers ({e})"
                ) from None
        return cls(heights=grid, **fields)


Surface: TypeAlias = Wall | Sphere | Cylinder | HeightField
"""Any surface block: what ``Scenario.wall`` and ``Scenario.wall_estimate`` hold."""


@dataclass(frozen=True, kw_only=True)
class ForceSensor(_Block):
    """The force sensor (SPEC §10, §15): bias, noise, resolution, low-pass, latency, in that
    order, on one axis along the estimated normal n̂ or on the three axes of the tip frame.

    u_k = f_k + bias + noise, rounded to a multiple of ``resolution``; y_k = y_{k−1} +
    α (u_k − y_{k−1}) with α = 1 − exp(−2π f_c T) and y_0 = u_0; the output is y delayed by
    ``latency`` samples (holding y_0 before). The default reads the force exactly. Noise is
    drawn from (``Scenario.seed``, sample index), so runs are reproducible.

    ``frame="tip"`` is a 3-axis F/T sensor: the force on the surface (plus a tool's weight)
    in the tip frame, each axis with its own bias, noise, rounding and low-pass, one latency;
    the controller rotates the reading to the world with the current tip rotation and feeds
    its component along n̂ to the filter. A tool of ``tool_mass`` between the sensor and the
    tip adds its weight m_t g to the reading and its mass to the arm; the controller takes
    off the weight of ``tool_mass_estimate`` (docs/surfaces.md).

    Example:
        >>> import admit_rs as ar
        >>> ar.ForceSensor(noise_std=0.5, cutoff=30.0, latency=2)
        ForceSensor(bias=0.0, noise_std=0.5, resolution=0.0, cutoff=30.0, latency=2, \
frame='normal', tool_mass=0.0, tool_mass_estimate=None)
        >>> ar.ForceSensor(frame="tip", bias=(0.2, 0.0, -0.1), tool_mass=0.8).bias
        (0.2, 0.0, -0.1)
    """

    # generated by admit_rs._codegen: fields of "sensor"
    bias: float | Vector3 = 0.0
    """Constant offset added to the reading [N]: one number (along n̂), or one per axis of the
    tip frame (``frame="tip"``)."""
    noise_std: float = 0.0
    """Standard deviation of white Gaussian noise [N], on each axis."""
    resolution: float = 0.0
    """Quantisation step [N] of each axis; 0: none."""
    cutoff: float | None = None
    """First-order low-pass cut-off f_c [Hz] of each axis, at most the Nyquist frequency
    1/(2·period) (a scenario with a higher one is rejected); ``None``: no filter."""
    latency: int = 0
    """Delay of the output in whole controller periods (0 to 100 000)."""
    frame: Literal["normal", "tip"] = "normal"
    """``"normal"``: one axis along the estimated normal n̂ (a load cell); ``"tip"``: three axes
    in the tip frame (an F/T sensor; the three-link arm's link 3 frame, x along the link, y along
    the pitch axes; a URDF arm's tip link frame), rotated to the world with the current tip
    rotation, the component along n̂ fed to the filter."""
    tool_mass: float = 0.0
    """Mass of a tool between the sensor and the tip [kg]: its weight adds to the reading and its
    mass to the arm's tip."""
    tool_mass_estimate: float | None = None
    """The tool mass the controller believes [kg]: it subtracts this weight from the reading and
    its computed-torque model carries this mass; ``None``: ``tool_mass``."""
    # end of generated fields

    def __post_init__(self) -> None:
        bias = self.bias
        if not isinstance(bias, numbers.Real) or isinstance(bias, bool):
            if isinstance(bias, str | bytes) or not isinstance(bias, Iterable):
                raise TypeError(
                    f"bias must be a number or a sequence of 3 numbers, got {shown(bias)}"
                )
            self._set("bias", _vec3("bias", bias))
        self._validate()


@dataclass(frozen=True, kw_only=True)
class Actuator(_Block):
    """The motors (SPEC §10): the command is delayed, rate-limited, then clamped per joint.

    TDC's τ_{k−1} is the torque applied in the previous period, so limits cause no wind-up.

    Example:
        >>> import admit_rs as ar
        >>> ar.Actuator(torque_limit=(60, 40, 20)).torque_limit
        (60.0, 40.0, 20.0)
    """

    # generated by admit_rs._codegen: fields of "actuator"
    torque_limit: float | tuple[float, ...] | None = None
    """|τ_j| limit [N·m]: one number for every joint or one per joint; ``None``: unlimited."""
    rate_limit: float | None = None
    """Largest |dτ/dt| [N·m/s]: the torque moves at most ``rate_limit``·T per period."""
    delay: int = 0
    """Delay of the command in whole controller periods (0 to 100 000)."""
    # end of generated fields

    def __post_init__(self) -> None:
        limit = self.torque_limit
        if limit is not None and not isinstance(limit, int | float):
            try:
                self._set("torque_limit", tuple(float(v) for v in limit))
            except TypeError as e:
                raise TypeError(
                    f"torque_limit must be a number, a sequence of numbers or None, got {limit!r}"
                ) from e
        self._validate()

    @classmethod
    def from_urdf(
        cls, arm: UrdfArm, rate_limit: float | None = None, delay: int = 0
    ) -> Actuator:
        """Torque limits from the URDF's effort limits (joints without one: unlimited,
        written as 1e300)."""
        if not isinstance(arm, UrdfArm):
            raise TypeError(f"from_urdf() takes an admit_rs.UrdfArm, got {type(arm).__name__}")
        effort = arm.effort_limits
        limit = None if np.all(np.isinf(effort)) else tuple(
            float(e) if np.isfinite(e) else 1e300 for e in effort
        )
        return cls(torque_limit=limit, rate_limit=rate_limit, delay=delay)


@dataclass(frozen=True, kw_only=True)
class ModelError(_Block):
    """How the controller's arm model differs from the plant (for sweeps)."""

    # generated by admit_rs._codegen: fields of "model"
    mass_scale: float = 1.0
    """Factor on every link mass (and inertia) in the controller's model [dimensionless]."""
    friction_scale: float = 1.0
    """Factor on viscous and Coulomb friction in the controller's model [dimensionless]."""
    # end of generated fields


class _Controller(_Block):
    _RENAMED: ClassVar[dict[str, str]] = {"ka": "command_divisor"}

    @property
    def ka(self) -> float:
        """Deprecated name of :attr:`command_divisor` (K_A of eq. 39); warns."""
        _warn_renamed("controller.ka", "controller.command_divisor")
        return self.command_divisor  # type: ignore[attr-defined, no-any-return]

    def __post_init__(self) -> None:
        model = getattr(self, "model", None)
        if model is not None and not isinstance(model, ModelError):
            raise TypeError(f"model must be an admit_rs.ModelError, got {type(model).__name__}")
        self._validate()


@dataclass(frozen=True, kw_only=True)
class ComputedTorque(_Controller):
    """Computed torque, eq. (7) with V of eq. (39): τ = D̂ J⁻¹(V − J̇q̇) + Ĉ + Ĝ + τ̂_f."""

    # generated by admit_rs._codegen: fields of "computed_torque"
    command_divisor: float = 0.1
    """K_A of eq. (39), formerly ``ka``: V = (Ẍ_d + K_D ė + K_P e) / K_A, it divides the whole
    Cartesian command, feed-forward included (only the feedback with ``scale_feedforward=False``)
    [dimensionless]."""
    kd: float = 20.0
    """K_D of eq. (39) [1/s]."""
    kp: float = 100.0
    """K_P of eq. (39) [1/s²]."""
    scale_feedforward: bool = True
    """``True`` (SPEC, the paper as written): K_A⁻¹ multiplies Ẍ_d too. ``False``: V = Ẍ_d +
    K_A⁻¹(K_D ė + K_P e), a variant reading (see docs/reproduction.md)."""
    contact_compensation: bool = False
    """Add f J_xᵀ to cancel the measured contact force."""
    model: ModelError = field(default_factory=ModelError)
    """The controller's model of the arm."""
    # end of generated fields


@dataclass(frozen=True, kw_only=True)
class _ConstantInertiaLaw(_Controller):
    """Fields shared by the laws built on a constant inertia D̄ (eqs. 17 and 18)."""

    # generated by admit_rs._codegen: fields shared by "model_free", "time_delay"
    command_divisor: float = 5.0
    """K_A of eq. (39), formerly ``ka``: V = (Ẍ_d + K_D ė + K_P e) / K_A, it divides the whole
    Cartesian command, feed-forward included (only the feedback with ``scale_feedforward=False``)
    [dimensionless]."""
    kd: float = 20.0
    """K_D of eq. (39) [1/s]."""
    kp: float = 100.0
    """K_P of eq. (39) [1/s²]."""
    scale_feedforward: bool = True
    """``True`` (SPEC, the paper as written): K_A⁻¹ multiplies Ẍ_d too. ``False``: V = Ẍ_d +
    K_A⁻¹(K_D ė + K_P e), a variant reading (see docs/reproduction.md)."""
    inertia: float | tuple[float, ...] | tuple[tuple[float, ...], ...] = 0.1
    """Constant inertia D̄ [kg·m²]: one number (D̄ = α I, the paper's), one per joint (D̄ =
    diag(...)) or an n×n symmetric positive definite matrix (rows), for URDF arms whose inertias
    differ by orders of magnitude between shoulder and wrist."""
    torque_constant: float = 200.0
    """Torque constant K_t (eq. 18)."""
    # end of generated fields

    def __post_init__(self) -> None:
        if not isinstance(self.inertia, int | float) or isinstance(self.inertia, bool):
            arr = np.asarray(self.inertia, dtype=float)
            if arr.ndim == 2:
                self._set("inertia", tuple(tuple(float(v) for v in row) for row in arr))
            else:
                self._set("inertia", _numbers("inertia", self.inertia))
        super().__post_init__()


@dataclass(frozen=True, kw_only=True)
class ModelFree(_ConstantInertiaLaw):
    """Model-free ("nonmodel") control: eq. (18) without the delay estimate, τ = D̄ K_t Jᵀ V."""

    # generated by admit_rs._codegen: fields of "model_free"
    # end of generated fields


@dataclass(frozen=True, kw_only=True)
class TimeDelayControl(_ConstantInertiaLaw):
    """Time-delayed control: eq. (18) (default) or eq. (17).

    τ_k = D̄ K_t Jᵀ V_k + τ_{k−1} − D̄ q̈_{k−1}, with q̈_{k−1} = (q̇_k − q̇_{k−1})/T,
    τ_{−1} = Ĝ(q0) and q̈_{−1} = 0.
    """

    # generated by admit_rs._codegen: fields of "time_delay"
    law: Literal["jacobian_transpose", "inverse_jacobian"] = "jacobian_transpose"
    """``"jacobian_transpose"``: eq. (18); ``"inverse_jacobian"``: eq. (17)."""
    model: ModelError = field(default_factory=ModelError)
    """Used only for the initial torque τ_{−1} = Ĝ(q0)."""
    # end of generated fields

    @classmethod
    def for_arm(
        cls,
        arm: UrdfArm,
        *,
        inertia_fraction: float = 0.8,
        torque_constant: float = 50.0,
        kp: float = 600.0,
        kd: float = 50.0,
        **kwargs: Any,
    ) -> TimeDelayControl:
        """TDC tuned for a URDF arm (docs/arms.md): D̄ = ``inertia_fraction``·D(q0) (the
        full matrix: TDC needs the spectral radius of I − D⁻¹D̄ below 1, which a scalar D̄
        cannot give an arm whose wrist is 100× lighter than its shoulder), a smaller K_t
        and stiffer K_P, K_D (eq. 18's loop gain grows with the eigenvalues of J Jᵀ: 3.3–3.4
        at q0 for the UR5's and the Panda's 6-D pose task, 0.79 for the paper's arm)."""
        dbar = inertia_fraction * arm.dynamics(arm.initial_position)["inertia"]
        return cls(
            inertia=tuple(tuple(float(v) for v in row) for row in dbar),
            torque_constant=torque_constant,
            kp=kp,
            kd=kd,
            **kwargs,
        )


Controller: TypeAlias = ComputedTorque | ModelFree | TimeDelayControl


@dataclass(frozen=True, kw_only=True)
class AdmittanceFilter(_Block):
    """Admittance filter m ẍ_a + b ẋ_a + k x_a = k_a e_f (eq. 30; k = 0 is eq. 38).

    Discretised exactly with a zero-order hold. Use :meth:`scheme1` or :meth:`scheme2`
    for the paper's two designs.

    Example:
        >>> import admit_rs as ar
        >>> ar.AdmittanceFilter.scheme2(b=400, ka=0.1)
        AdmittanceFilter(m=1.0, b=400, k=0.0, ka=0.1, sigma=0.0)
    """

    # generated by admit_rs._codegen: fields of "admittance"
    m: float = 1.0
    """Mass [kg]."""
    b: float = 800.0
    """Damping [N·s/m]."""
    k: float = 0.0
    """Stiffness [N/m]; 0 is Scheme 2."""
    ka: float = 1.0
    """Filter gain k_a of eqs. (30)/(38): the filter input is k_a e_f [dimensionless]."""
    sigma: float = 0.0
    """Adaptation gain σ of the adaptive force-error term (Jung, Hsia & Bonitz 2004): ψ_{k+1} =
    ψ_k + σ e_f,k is added to e_f [per sample]; 0 is the plain filter."""
    # end of generated fields

    @classmethod
    def scheme1(
        cls, *, b: float = 800.0, k: float = 400.0, ka: float = 0.1, m: float = 1.0
    ) -> AdmittanceFilter:
        """Scheme 1, eq. (30): keeps a steady-state offset f_d·r/(1+r), r = k_a k_e / k."""
        return cls(m=m, b=b, k=k, ka=ka)

    @classmethod
    def scheme2(cls, *, b: float = 800.0, ka: float = 0.1, m: float = 1.0) -> AdmittanceFilter:
        """Scheme 2, eq. (38): k = 0; no steady-state force error."""
        return cls(m=m, b=b, k=0.0, ka=ka)

    @classmethod
    def adaptive(
        cls, *, b: float = 800.0, sigma: float = 0.005, ka: float = 1.0, m: float = 1.0
    ) -> AdmittanceFilter:
        """Scheme 2 with the adaptive force-error term of Jung, Hsia & Bonitz (2004) (SPEC
        §16): m ẍ_a + b ẋ_a = k_a (e_f + ψ), ψ_{k+1} = ψ_k + σ e_f,k. It tracks a surface at an
        unknown position, or receding at a constant rate, with zero steady force error, where
        Scheme 2 keeps b v / k_a. The loop is critically damped near σ = k_a k_e T / (4 b)
        (0.0094 for fig. 14's k_a = 1, k_e = 3e4, b = 800); docs/first_contact.md.

        Example:
            >>> import admit_rs as ar
            >>> ar.AdmittanceFilter.adaptive(b=800, sigma=0.005)
            AdmittanceFilter(m=1.0, b=800, k=0.0, ka=1.0, sigma=0.005)
        """
        return cls(m=m, b=b, k=0.0, ka=ka, sigma=sigma)

    def discretize(self, period: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The exact ZOH pair (Ad, Bd) for the state [x_a, ẋ_a] and period T."""
        return _core.filter_discretize(self._to_core(), float(period))

    def response(
        self, force_error: Iterable[float] | npt.NDArray[np.float64], period: float
    ) -> dict[str, npt.NDArray[np.float64]]:
        """Runs the discrete filter on a force-error sequence: ``x_a``, ``xa_dot``, ``xa_ddot``."""
        return _core.filter_response(
            self._to_core(), float(period), [float(e) for e in force_error]
        )


@dataclass(frozen=True, kw_only=True)
class ImpedanceReference(_Block):
    """The baseline of eq. (20): x_d = x̂_e + f_d / k_eff, k_eff = k k̂_e / (k + k̂_e).

    No force feedback: it tracks f_d only if the assumed stiffness is the true one.
    """

    # generated by admit_rs._codegen: fields of "impedance"
    k: float = 10000.0
    """Impedance stiffness [N/m]."""
    assumed_stiffness: float = 30000.0
    """The wall stiffness the designer assumes, k̂_e [N/m]."""
    # end of generated fields


ForceControl: TypeAlias = AdmittanceFilter | ImpedanceReference


class _Signal(_Block):
    """A signal of time: a force reference f_d(t) or a motion s(t); callable on t."""


@dataclass(frozen=True, kw_only=True)
class Step(_Signal):
    """``initial`` before ``time``, ``value`` from ``time`` on."""

    # generated by admit_rs._codegen: fields of "step"
    value: float = 10.0
    """Value from ``time`` on [unit of the signal: N for a force, m for z]."""
    time: float = 0.0
    """Step time [s]."""
    initial: float = 0.0
    """Value before ``time`` [unit of the signal]."""
    # end of generated fields

    def __call__(self, t: float | npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        return np.where(np.asarray(t) >= self.time, self.value, self.initial)


@dataclass(frozen=True, kw_only=True)
class Sine(_Signal):
    """``offset + amplitude · sin(omega t + phase)``, omega in rad/s."""

    # generated by admit_rs._codegen: fields of "sine"
    offset: float = 0.0
    """Mean value [unit of the signal: N for a force, m for z]."""
    amplitude: float = 1.0
    """Amplitude [unit of the signal]."""
    omega: float = 1.0
    """Angular frequency [rad/s], >= 0 (a negative one is a phase shift: use ``phase``)."""
    phase: float = 0.0
    """Phase at t = 0 [rad]."""
    # end of generated fields

    def __call__(self, t: float | npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        return self.offset + self.amplitude * np.sin(self.omega * np.asarray(t) + self.phase)


@dataclass(frozen=True, kw_only=True)
class Sampled(_Signal):
    """A signal given by samples, linearly interpolated and held outside its span.

    The rate fed forward is the segment's slope; the acceleration is zero.

    Example:
        >>> import numpy as np, admit_rs as ar
        >>> t = np.linspace(0, 10, 101)
        >>> ar.Sampled(times=t, values=10 + np.clip(t, 0, 2))(1.0).item()
        11.0
    """

    # generated by admit_rs._codegen: fields of "sampled"
    times: tuple[float, ...] = (0.0,)
    """Sample times, increasing [s]."""
    values: tuple[float, ...] = (0.0,)
    """Sample values, one per time [unit of the signal: N for a force, m for z]."""
    # end of generated fields

    def __call__(self, t: float | npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        return np.interp(np.asarray(t, dtype=float), self.times, self.values)


Signal: TypeAlias = Step | Sine | Sampled


@dataclass(frozen=True, kw_only=True)
class Criteria(_Block):
    """What a run must meet to be called stable (SPEC §17): ``Result.stable``,
    ``Result.verdict`` and a sweep table's ``stable``/``verdict`` columns are judged by it.

    A diverged run is unstable. Otherwise every limit that is set is checked and each one
    that fails is named in the verdict with its value and limit; a force-controlled run
    whose assessed window (from 1 s into the contact phase: t ≥ 1 s for a run that starts
    touching, first contact + 1 s for one that crosses free space) is shorter than
    ``min_assessed`` is "not assessed"
    (``stable`` is ``None``, null in tables). Position-only runs are judged on divergence
    and, if set, ``max_path_error`` and ``max_torque_saturation``.

    Example:
        >>> import admit_rs as ar
        >>> sc = ar.paper.scenario("fig14").replace(**{"criteria.force_limit": 11.0})
        >>> print(ar.simulate(sc).verdict.replace(" (", "\\n("))
        unstable: impact peak 12.57 N
        (within 0.5 s of first contact at t = 0.001 s) above force_limit 11 N
        (force peak 12.58 N later)
    """

    # generated by admit_rs._codegen: fields of "criteria"
    max_force_oscillation: float = 0.1
    """Largest force_oscillation (std(f − f_d) over the last 2 s of the contact phase / mean
    |f_d|) of a stable force-controlled run [fraction of f_d]."""
    max_contact_loss: float = 0.05
    """Largest contact_loss (fraction of samples with f = 0 from first contact + 1 s; t ≥ 1 s for
    a run that starts touching) of a stable force-controlled run [fraction]."""
    force_limit: float | None = None
    """Largest contact force anywhere in the run (force_peak, the impact peak included) [N];
    ``None``: not judged."""
    max_bounces: float | None = None
    """Largest number of bounces (contact lost after first contact) [count]; ``None``: not
    judged."""
    max_path_error: float | None = None
    """Largest path_rms_error [m]; ``None``: not judged."""
    max_torque_saturation: float | None = None
    """Largest torque_saturation (fraction of samples with a joint at its torque limit)
    [fraction]; ``None``: not judged."""
    min_assessed: float = 1.0
    """Shortest assessed window (assessed_time, from first contact + 1 s to the end) a
    force-controlled run needs for a verdict [s]; shorter runs are "not assessed"."""
    # end of generated fields


@dataclass(frozen=True, kw_only=True)
class GuardedApproach(_Block):
    """A guarded approach (SPEC §16): position control along the estimated normal n̂ from
    the start at ``speed``, at ``contact_speed`` within ``slowdown_distance`` of the estimated
    surface (and beyond it), until the **measured** normal force exceeds ``threshold`` (so
    sensor noise, low-pass and latency delay the switch); then force control takes over
    bumplessly (X_d and Ẋ_d continue), with ``reanchor`` the estimated surface moved to the
    tip's measured position there. The discrete equations are in docs/first_contact.md.

    Example:
        >>> import admit_rs as ar
        >>> fig19 = ar.paper.scenario("fig19").replace(duration=1.0)
        >>> plain = ar.simulate(fig19).metrics["impact_peak"]
        >>> guarded = ar.simulate(fig19.replace(approach=ar.GuardedApproach()))
        >>> round(plain, 1), round(guarded.metrics["impact_peak"], 1)
        (36.0, 13.9)
    """

    # generated by admit_rs._codegen: fields of "approach"
    speed: float = 0.05
    """Approach speed along the estimated normal n̂ in free space [m/s]."""
    contact_speed: float = 0.01
    """Speed within slowdown_distance of the estimated surface, and beyond it [m/s]."""
    slowdown_distance: float = 0.005
    """Distance before the estimated surface at which the approach slows to contact_speed [m]."""
    threshold: float = 1.0
    """Measured normal force above which contact is detected and force control takes over [N]."""
    reanchor: bool = True
    """Move the estimated surface to the tip's measured position along n̂ where contact was
    detected."""
    acceleration: float | None = 1.0
    """Largest |dv/dt| of the approach along n̂ [m/s²], fed forward as Ẍ_d; ``None``: velocity
    steps."""
    # end of generated fields



@dataclass(frozen=True, kw_only=True)
class Scenario(_Block):
    """One closed-loop run. The defaults are the paper's fig. 14 (TDC + Scheme 2).

    Example:
        >>> import admit_rs as ar
        >>> sc = ar.Scenario().replace(**{"wall.stiffness": 5e4, "admittance.b": 400})
        >>> sc.wall.stiffness, sc.admittance.b
        (50000.0, 400)
    """

    # generated by admit_rs._codegen: fields of "scenario"
    robot: Robot | UrdfArm = field(default_factory=Robot)
    """The arm (plant): the paper's three-link arm or a URDF arm."""
    wall: Surface | None = field(default_factory=Wall)
    """The surface the tool touches (SPEC §15): Wall, Sphere, Cylinder or HeightField; ``None``:
    free space."""
    wall_estimate: Surface | None = None
    """The controller's belief about the surface (SPEC §15): force along its normal n̂, motion
    along its tangent, x̂_e its position + position_error; its stiffness and damping are not
    read. ``None``: the true wall offset by its position_error."""
    controller: Controller = field(default_factory=TimeDelayControl)
    """The inner position loop: ComputedTorque, ModelFree or TimeDelayControl."""
    admittance: ForceControl | None = field(default_factory=AdmittanceFilter)
    """The outer force loop; ``None`` is position-only control (x held at X0 x)."""
    approach: GuardedApproach | None = None
    """A guarded approach (SPEC §16) before force control takes over; ``None``: force control
    from t = 0."""
    force_reference: Signal = field(default_factory=Step)
    """Desired contact force f_d(t) [N]."""
    z_reference: Signal = field(default_factory=lambda: Sine(amplitude=0.05))
    """Desired motion s(t) along t̂ from the start [m]; z_d = z0 + s(t) for the paper's wall."""
    sensor: ForceSensor = field(default_factory=ForceSensor)
    """The force sensor; the default reads the force exactly."""
    actuator: Actuator = field(default_factory=Actuator)
    """The motors; the default applies the command exactly."""
    seed: int = 0
    """Seed of the sensor noise (0 to 2^53). Sweeps derive each run's from (seed, run_id)."""
    period: float = 0.001
    """Controller period T [s]."""
    substeps: int | Literal["auto"] = 10
    """RK4 substeps per period (1 to 10000), or ``"auto"``: the fewest whose force trace is
    within ``tolerance`` of the exact one, estimated by comparing whole runs (Richardson,
    docs/substeps.md)."""
    tolerance: float = 0.0001
    """Largest error [N] on the force trace (f and f_t at every sample) that ``substeps="auto"``
    accepts; not read for a fixed count."""
    duration: float = 10.0
    """Run length [s], a multiple of ``period``."""
    velocity_limit: float = 100.0
    """A run stops as unstable when any |q̇| reaches this [rad/s]."""
    criteria: Criteria = field(default_factory=Criteria)
    """What a run must meet to be called stable (SPEC §17)."""
    # end of generated fields
    label: str = ""
    """Free text carried into results and plots; :meth:`replace` drops it when it changes
    anything else (pass ``label=`` to keep one). Without a label, plots and exports
    describe the scenario from its fields (:func:`describe`)."""

    def __post_init__(self) -> None:
        for name, allowed in _UNIONS.items():
            value = getattr(self, name)
            if not isinstance(value, allowed):
                names = " | ".join("None" if a is type(None) else a.__name__ for a in allowed)
                raise TypeError(f"{name} must be {names}, got {type(value).__name__}")
        if not isinstance(self.label, str):
            raise TypeError(f"label must be a str, got {type(self.label).__name__}")
        self._plain_scalars()
        _check_integer("seed", self.seed, 2**53)
        self._reject_bools()
        try:
            _core.validate(self._to_core())
        except ParameterError as e:
            raise _python_error(e) from None

    def replace(self, **changes: Any) -> Scenario:
        """A copy with fields changed; nested fields by dotted path.

        ``sc.replace(**{"wall.stiffness": 5e4}, duration=2.0)``. Unknown paths raise
        ``TypeError`` naming the closest valid ones.

        A label describes the scenario it was written for, so a copy that changes anything
        but the label has none (``""``) unless ``label=`` is passed: plots, results and
        exports then describe it from its fields (:func:`describe`), never by a stale name.

        Example:
            >>> import admit_rs as ar
            >>> sc = ar.paper.scenario("fig14")
            >>> sc.label, sc.replace(**{"admittance.ka": 2.0}).label
            ('TDC, Scheme 2, k_a=1', '')
            >>> sc.replace(duration=10.0).label  # nothing changed: the label still holds
            'TDC, Scheme 2, k_a=1'
        """
        new: Scenario = _replace_paths(self, changes)
        if "label" not in changes and new.label and new != self:
            new._set("label", "")
        return new

    @property
    def samples(self) -> int:
        """N = duration / period + 1."""
        return round(self.duration / self.period) + 1

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Scenario:
        """Builds a scenario from the nested dict of :meth:`to_dict` (or a parsed TOML file).

        TOML has no null: ``wall = false`` and ``admittance = false`` stand for ``None``
        (free space, position-only control), as :func:`admit_rs.export.toml` writes them."""
        return _from_dict(cls, data, "")



def _short(x: float) -> str:
    """A number for a label: 30 000, 0.1, 1.5e+06."""
    x = float(x)
    if math.isfinite(x) and x == int(x) and abs(x) < 1e6:
        return f"{int(x):_}".replace("_", " ")
    return f"{x:.4g}"


def describe(scenario: Scenario) -> str:
    """A one-line description derived from the scenario's fields (never stored, so never
    stale): arm, inner loop, force loop, environment and force reference. Plots and
    exports use it wherever the scenario has no label of its own.

    Example:
        >>> import admit_rs as ar
        >>> ar.describe(ar.paper.scenario("fig14"))
        'three-link arm, TDC, Scheme 2 (b=800, k_a=1), k_e=30 000, f_d step 10 N'
        >>> ar.describe(ar.paper.scenario("fig5").replace(wall=ar.Wall(normal=(1, 0, -1))))
        'three-link arm, CT, position only, k_e=30 000, normal (0.7071, 0, -0.7071)'
    """
    if not isinstance(scenario, Scenario):
        raise TypeError(f"describe() takes an admit_rs.Scenario, got {type(scenario).__name__}")
    robot = scenario.robot
    if isinstance(robot, UrdfArm):
        name = Path(robot.path).stem if robot.path else "URDF"
        parts = [f"{name} arm ({robot.tip_link})"]
    else:
        parts = ["three-link arm" if robot == Robot() else "three-link arm (modified)"]
    short = {ComputedTorque: "CT", ModelFree: "MF", TimeDelayControl: "TDC"}
    parts.append(short.get(type(scenario.controller), type(scenario.controller).__name__))
    adm = scenario.admittance
    if adm is None:
        parts.append("position only")
    elif isinstance(adm, AdmittanceFilter):
        gains = f"b={_short(adm.b)}, k_a={_short(adm.ka)}"
        if adm.m != 1.0:
            gains = f"m={_short(adm.m)}, " + gains
        if adm.k == 0.0:
            parts.append(f"Scheme 2 ({gains})")
        else:
            parts.append(f"Scheme 1 (k={_short(adm.k)}, {gains})")
    else:
        parts.append("impedance reference (eq. 20)")
    wall = scenario.wall
    if wall is None:
        parts.append("free space")
    else:
        if isinstance(wall, Sphere | Cylinder):
            inside = " (inside)" if wall.inside else ""
            parts.append(f"{type(wall).__name__.lower()} R={_short(wall.radius)} m{inside}")
        elif isinstance(wall, HeightField):
            rows, cols = len(wall.heights), len(wall.heights[0])
            parts.append(f"height field {rows}×{cols}")
        parts.append(f"k_e={_short(wall.stiffness)}")
        if wall.friction:
            parts.append(f"μ={_short(wall.friction)}")
        if wall.tilted:
            n, _ = wall.directions()
            parts.append("normal (" + ", ".join(_short(round(v, 4)) for v in n) + ")")
        if wall.position_error:
            parts.append(f"wall error {_short(wall.position_error)} m")
    if adm is not None:
        ref = scenario.force_reference
        if isinstance(ref, Step):
            parts.append(f"f_d step {_short(ref.value)} N")
        elif isinstance(ref, Sine):
            parts.append(f"f_d {_short(ref.offset)} + {_short(ref.amplitude)} sin"
                         f"({_short(ref.omega)} t) N")  # fmt: skip
        else:
            parts.append("f_d sampled")
    return ", ".join(parts)


def parameter_paths(obj: Any, prefix: str = "") -> list[str]:
    """Every dotted path of scalar parameters below ``obj`` (a block or a scenario)."""
    paths: list[str] = []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        path = f"{prefix}{f.name}"
        if isinstance(value, _Block):
            paths.extend(parameter_paths(value, path + "."))
        else:
            paths.append(path)
    return paths


def _replace_paths(obj: Any, changes: Mapping[str, Any]) -> Any:
    canonical: dict[str, Any] = {}
    for path, value in changes.items():
        canonical[_check_path(obj, path)] = value
    return _apply(obj, canonical)


def _check_path(obj: Any, path: str) -> str:
    """The path in current field names; raises UnknownParameterError (a TypeError) for a
    path that names no field, with the closest valid ones. A deprecated field name is
    replaced by its new one, with a DeprecationWarning."""
    node: Any = obj
    walked: list[str] = []
    for part in path.split("."):
        if not isinstance(node, _Block):
            where = ".".join(walked)
            raise TypeError(f"cannot set {path}: {where} is {type(node).__name__}")
        names = {f.name for f in dataclasses.fields(node)}  # type: ignore[arg-type]
        if part not in names and part in node._RENAMED and node._RENAMED[part] in names:
            new = node._RENAMED[part]
            _warn_renamed(".".join([*walked, part]), ".".join([*walked, new]))
            part = new
        if part not in names:
            raise unknown(f"{path}: no such parameter in {type(obj).__name__}", path,
                          parameter_paths(obj))  # fmt: skip
        node = getattr(node, part)
        walked.append(part)
    return ".".join(walked)


def _apply(obj: Any, changes: Mapping[str, Any]) -> Any:
    direct: dict[str, Any] = {}
    nested: dict[str, dict[str, Any]] = {}
    for path, value in changes.items():
        head, _, rest = path.partition(".")
        if rest:
            nested.setdefault(head, {})[rest] = value
        else:
            direct[head] = value
    for head, sub in nested.items():
        if head in direct:
            raise TypeError(f"both {head} and {head}.{next(iter(sub))} given")
        try:
            direct[head] = _apply(getattr(obj, head), sub)
        except ParameterError as e:
            raise within(e, head) from None
    return dataclasses.replace(obj, **direct)


_CLASSES: dict[str, type[_Block]] = {
    name: obj
    for name, obj in list(globals().items())
    if isinstance(obj, type) and issubclass(obj, _Block) and name in _registry.BY_CLASS
}
"""Every registered block class by name (tests/test_schema.py checks that each kind of the
core's registry has one)."""
_SLOTS: dict[str, tuple[type[_Block], ...]] = {
    name: tuple(_CLASSES[k.cls] for k in _registry.FAMILIES[family])
    for name, (family, _) in _registry.SLOTS.items()
}
"""The block types each field (and TOML table) may hold, by its name (the same in every
parent): its family's classes, from the core's registry."""
_UNIONS: dict[str, tuple[type, ...]] = {
    f.name: _SLOTS[f.name] + ((type(None),) if _registry.SLOTS[f.name][1] else ())
    for f in dataclasses.fields(Scenario)
    if f.name in _SLOTS
}
"""What each of the scenario's block fields may hold (None where the core allows it)."""
_SLOT_DEFAULTS: dict[str, Any] = {
    **{f.name: getattr(Scenario(), f.name) for f in dataclasses.fields(Scenario)},
    "model": ModelError(),
}
"""The default block of each table: what a table without ``kind`` extends."""


def _field_names(cls: type[Any]) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


def _kind_of(t: type[_Block]) -> str:
    return t._kind or t._core_kind or t.__name__


def _table_type(key: str, table: Mapping[str, Any], where: str) -> type[_Block]:
    """The block type of TOML table ``key``, by its ``kind`` tag; a table without ``kind``
    is the field's default block. A table without ``kind`` whose keys fit only another
    kind is still read as that kind, with a DeprecationWarning (keys are no longer a way
    to choose a kind; the next release reads such a table as the default block)."""
    types = _SLOTS[key]
    kinds = {_kind_of(t): t for t in types}
    if "kind" in table:
        kind = table["kind"]
        if len(types) == 1 and types[0]._kind is None:
            raise UnknownParameterError(f"{where}.kind: a {key} table takes no kind", "kind")
        if kind not in kinds:
            raise UnknownParameterError(
                f"{where}.kind: unknown kind {kind!r} for {key}; one of {list(kinds)}",
                str(kind),
                closest(str(kind), kinds),
            )
        return kinds[kind]
    if len(types) == 1:
        return types[0]
    if Wall in types:
        return Wall  # a surface table without a kind is a plane (SPEC §15)
    # No kind: the field's default block. Choosing a kind by the keys is deprecated.
    keys = set(table)
    fit = [t for t in types if keys <= set(_field_names(t)) | set(t._RENAMED)]
    default = type(_SLOT_DEFAULTS[key])
    if default in fit:
        return default
    if len(fit) == 1:
        _warn_kind_guessed(where, _kind_of(fit[0]))
        return fit[0]
    if fit:
        raise UnknownParameterError(
            f"{where}: these keys fit several kinds ({', '.join(_kind_of(t) for t in fit)});"
            f" add kind = one of {list(kinds)}"
        )
    # No type has every key: name the first unknown key of the type missing the fewest.
    best = min(types, key=lambda t: len(keys - set(_field_names(t)) - set(t._RENAMED)))
    bad = sorted(keys - set(_field_names(best)) - set(best._RENAMED))[0]
    allowed = sorted({n for t in types for n in _field_names(t)})
    err = unknown(f"{where}: unknown key {bad!r}", bad, allowed)
    raise UnknownParameterError(
        f"{err} ({key} kinds: {', '.join(kinds)}; add kind = ... to choose one)",
        bad,
        err.suggestions,
    )


def _warn_kind_guessed(where: str, kind: str) -> None:
    """DeprecationWarning for a table whose kind was chosen by its keys."""
    level, frame = 2, sys._getframe(1)
    while frame is not None and _in_package(frame.f_code.co_filename):
        level, frame = level + 1, frame.f_back  # type: ignore[assignment]
    warnings.warn(
        f"{where}: a table without kind is the field's default block; choosing the kind by "
        f"its keys is deprecated and will be removed in the next release: add kind = {kind!r}",
        DeprecationWarning,
        stacklevel=level,
    )


def _from_dict(cls: type[Any], data: Mapping[str, Any], path: str) -> Any:
    names = _field_names(cls)
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        if key == "kind":
            continue
        if key not in names:
            renamed = cls._RENAMED.get(key)
            if renamed is None or renamed not in names:
                article = "an" if cls.__name__[0] in "AEIOU" else "a"
                raise unknown(f"{path}{key}: unknown key in {article} {cls.__name__} table",
                              key, names)  # fmt: skip
            _warn_renamed(f"{path}{key}", f"{path}{renamed}")
            key = renamed
        if value is False and type(None) in _UNIONS.get(key, ()) and cls is Scenario:
            value = None  # TOML has no null: `wall = false` is free space (export.toml)
        elif value is False and _false_is_none(cls, key):
            value = None  # `acceleration = false`: None where the default is a number
        elif isinstance(value, Mapping) and key in _SLOTS:
            sub = _table_type(key, value, f"{path}{key}")
            value = _from_dict(sub, value, f"{path}{key}.")
        elif isinstance(value, list):
            value = tuple(value)
        kwargs[key] = value
    return cls(**kwargs)


def _false_is_none(cls: type[Any], key: str) -> bool:
    """Whether ``key = false`` in a TOML table of ``cls`` stands for None: a field that may
    be None but defaults to a number (TOML has no null; export.toml writes it so)."""
    for f in dataclasses.fields(cls):
        if f.name == key:
            kind = str(f.type)
            return "None" in kind and "bool" not in kind and f.default is not None
    return False


def _guard_init(cls: type[_Block]) -> None:
    """Wraps the dataclass ``__init__``: an unknown keyword raises UnknownParameterError
    with the closest field names; a deprecated name warns and is renamed."""
    init = cls.__init__
    names = _field_names(cls)

    @functools.wraps(init)
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        for key in [k for k in kwargs if k not in names]:
            new = cls._RENAMED.get(key)
            if new is None or new not in names:
                raise unknown(f"{cls.__name__}: unknown keyword {key!r}", key, names)
            if new in kwargs:
                raise TypeError(f"{cls.__name__}: both {key} and {new} given")
            _warn_renamed(f"{cls.__name__}({key}=...)", f"{cls.__name__}({new}=...)")
            kwargs[new] = kwargs.pop(key)
        init(self, *args, **kwargs)

    cls.__init__ = __init__  # type: ignore[method-assign]


_BLOCKS: tuple[type[_Block], ...] = tuple(
    obj
    for name, obj in list(globals().items())
    if isinstance(obj, type)
    and issubclass(obj, _Block)
    and dataclasses.is_dataclass(obj)
    and not name.startswith("_")
)
"""Every public block type: each public dataclass of this module built on ``_Block``, found
rather than listed, so a new block cannot miss its unknown-keyword guard and field docs
(tests/test_errors.py checks every block ``admit_rs`` exports against this)."""


def _attribute_docs() -> dict[str, dict[str, str]]:
    """Class name -> {field: the string literal written under it} in this file's source."""
    tree = ast.parse(Path(__file__).read_text(encoding="utf-8"))
    out: dict[str, dict[str, str]] = {}
    for node in tree.body:
        if not isinstance(node, ast.ClassDef):
            continue
        docs = out.setdefault(node.name, {})
        for stmt, nxt in zip(node.body, node.body[1:], strict=False):
            if (
                isinstance(stmt, ast.AnnAssign)
                and isinstance(stmt.target, ast.Name)
                and isinstance(nxt, ast.Expr)
                and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)
            ):
                docs[stmt.target.id] = " ".join(nxt.value.value.split())
    return out


def _default_text(f: dataclasses.Field[Any]) -> str:
    if f.default is not dataclasses.MISSING:
        return repr(f.default)
    if f.default_factory is not dataclasses.MISSING:
        value = f.default_factory()
        if isinstance(value, _Block) and value == type(value)():
            return f"{type(value).__name__}()"  # its own defaults: see help() of that block
        return repr(value)
    return "required"


def _document_fields(cls: type[_Block], docs: Mapping[str, Mapping[str, str]]) -> None:
    """Appends a ``Fields:`` section (name, type, default, meaning with unit) to the class
    docstring, from the attribute docstrings of the class and its bases."""
    if cls.__doc__ is None:  # python -OO
        return
    lines = ["", "", "Fields (keyword-only; units in brackets):"]
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        text = next((docs[c.__name__][f.name] for c in cls.__mro__
                     if f.name in docs.get(c.__name__, {})), "")  # fmt: skip
        lines.append(f"    {f.name} ({f.type}, default {_default_text(f)})")
        if text:
            lines += textwrap.wrap(text, 92, initial_indent=" " * 8, subsequent_indent=" " * 8)
    for old, new in cls._RENAMED.items():
        lines.append(f"    {old}: deprecated name of {new}; warns.")
    cls.__doc__ = inspect.cleandoc(cls.__doc__) + "\n".join(lines) + "\n"


_DOCS = _attribute_docs()
for _cls in _BLOCKS:
    _guard_init(_cls)
    _document_fields(_cls, _DOCS)
