"""The machinery every block shares: conversion to the core's dict, validation through the
Rust core on construction, NumPy scalars and sequences in their declared shape, the
unknown-keyword guard and the ``Fields:`` section of each docstring. Knows no block.
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
from pathlib import Path
from typing import Any, ClassVar, TypeAlias

import numpy as np
import numpy.typing as npt

from admit_rs import _core, _registry
from admit_rs.errors import ParameterError, ParameterTypeError, _copy, shown, unknown

Vector3: TypeAlias = tuple[float, float, float]
ArrayLike3: TypeAlias = "Iterable[float] | npt.NDArray[np.float64]"


def _vec3(name: str, value: Any) -> Vector3:
    if _holds_bool(value):
        raise ParameterTypeError(f"{name} must be a sequence of 3 numbers, got a bool")
    try:
        items = tuple(float(v) for v in value)
    except TypeError as e:
        raise ParameterTypeError(
            f"{name} must be a sequence of 3 numbers, got {shown(value)}"
        ) from e
    if len(items) != 3:
        raise ParameterTypeError(f"{name} must have 3 elements, got {len(items)}")
    return items  # type: ignore[return-value]


def _check_integer(name: str, value: Any, high: int) -> None:
    """Integers are ints (or integral floats) from 0 to ``high``; anything else is a
    ParameterError naming the field."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ParameterTypeError(f"{name} must be an int, got {type(value).__name__}")
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


_PACKAGE_DIR = Path(__file__).resolve().parent.parent


def _in_package(filename: str) -> bool:
    return Path(filename).resolve().is_relative_to(_PACKAGE_DIR)


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
            _CLASSES[cls.__name__] = cls

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
                raise ParameterTypeError(f"{f.name} must be a number, got a bool")
            if kind in ("float", "float | None") and not (
                isinstance(value, numbers.Real) or (value is None and kind != "float")
            ):
                got = "None" if value is None else type(value).__name__
                raise ParameterTypeError(f"{f.name} must be a number, got {got}")
            if isinstance(value, int) and not isinstance(value, bool) and "int" not in kind:
                if abs(value) > sys.float_info.max:
                    # float() would raise OverflowError deep in the conversion.
                    raise _parameter_error(f.name, shown(value), "a finite number")
            if isinstance(value, int) and not isinstance(value, bool) and "int" in kind and not (
                -(2**63) <= value < 2**64
            ):
                # The core's decoder would say "expected any value … as u128" (issue #53
                # item 17); the field's own bounds are checked once the value fits.
                allowed = "a whole number of at most 64 bits (-2^63 to 2^64 - 1)"
                raise _parameter_error(f.name, shown(value), allowed)

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


def _numbers(name: str, value: Any) -> float | tuple[float, ...]:
    """One number, or a sequence of numbers as a tuple."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    if _holds_bool(value):
        raise ParameterTypeError(f"{name} must be a number or a sequence of numbers, got a bool")
    try:
        return tuple(float(v) for v in np.ravel(np.asarray(value, dtype=float)))
    except (TypeError, ValueError) as e:
        raise ParameterTypeError(
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


_CLASSES: dict[str, type[_Block]] = {}
"""Every block class of the core's registry, by name (filled as each is defined)."""


def _field_names(cls: type[Any]) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


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
                raise ParameterTypeError(f"{cls.__name__}: both {key} and {new} given")
            _warn_renamed(f"{cls.__name__}({key}=...)", f"{cls.__name__}({new}=...)")
            kwargs[new] = kwargs.pop(key)
        init(self, *args, **kwargs)

    cls.__init__ = __init__  # type: ignore[method-assign]


def _attribute_docs() -> dict[str, dict[str, str]]:
    """Class name -> {field: the string literal written under it} in the blocks' sources."""
    out: dict[str, dict[str, str]] = {}
    nodes = [node for path in sorted(Path(__file__).parent.glob("*.py"))
             for node in ast.parse(path.read_text(encoding="utf-8")).body]  # fmt: skip
    for node in nodes:
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
