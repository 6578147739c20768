"""A block from its nested dict or TOML table (``Scenario.from_dict``): each table's block
chosen by its ``kind`` among its registry family, ``false`` for None where TOML has no null."""

from __future__ import annotations

import dataclasses
import sys
import warnings
from collections.abc import Mapping
from typing import Any

from admit_rs import _registry
from admit_rs.blocks._base import _CLASSES, _Block, _field_names, _in_package, _warn_renamed
from admit_rs.errors import UnknownParameterError, closest, unknown


def _slot_types(key: str) -> tuple[type[_Block], ...]:
    """The block types field (and table) ``key`` may hold: its registry family's classes."""
    family, _ = _registry.SLOTS[key]
    return tuple(_CLASSES[k.cls] for k in _registry.FAMILIES[family])


def _default_type(parent: type[Any], key: str) -> type[Any] | None:
    """The type of field ``key``'s default in block ``parent``: what a table without
    ``kind`` extends."""
    for f in dataclasses.fields(parent):
        if f.name == key and f.default_factory is not dataclasses.MISSING:
            return type(f.default_factory())
    return None


def _kind_of(t: type[_Block]) -> str:
    return t._kind or t._core_kind or t.__name__


def _table_type(
    parent: type[Any], key: str, table: Mapping[str, Any], where: str
) -> type[_Block]:
    """The block type of TOML table ``key``, by its ``kind`` tag; a table without ``kind``
    is the field's default block. A table without ``kind`` whose keys fit only another
    kind is still read as that kind, with a DeprecationWarning (keys are no longer a way
    to choose a kind; the next release reads such a table as the default block)."""
    types = _slot_types(key)
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
    untagged = [t for t in types if t._kind is None]
    if untagged:
        return untagged[0]  # a surface table without a kind is a plane (SPEC §15)
    # No kind: the field's default block. Choosing a kind by the keys is deprecated.
    keys = set(table)
    fit = [t for t in types if keys <= set(_field_names(t)) | set(t._RENAMED)]
    default = _default_type(parent, key)
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
        nullable = key in _registry.SLOTS and _registry.SLOTS[key][1]
        if value is False and nullable and cls._key == "scenario":
            value = None  # TOML has no null: `wall = false` is free space (export.toml)
        elif value is False and _false_is_none(cls, key):
            value = None  # `acceleration = false`: None where the default is a number
        elif isinstance(value, Mapping) and key in _registry.SLOTS:
            sub = _table_type(cls, key, value, f"{path}{key}")
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
