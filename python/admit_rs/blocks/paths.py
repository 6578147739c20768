"""Dotted parameter paths (``"wall.stiffness"``) into a block: listing them and replacing
values by them, with the closest valid names for a typo."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from admit_rs.blocks._base import _Block, _warn_renamed
from admit_rs.errors import ParameterError, ParameterTypeError, unknown, within


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
            raise ParameterTypeError(f"cannot set {path}: {where} is {type(node).__name__}")
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
            raise ParameterTypeError(f"both {head} and {head}.{next(iter(sub))} given")
        try:
            direct[head] = _apply(getattr(obj, head), sub)
        except ParameterError as e:
            raise within(e, head) from None
    return dataclasses.replace(obj, **direct)
