"""A sweep's plan (:func:`admit_rs.sweep`): its rows (the grid crossed with the draws of
``vary``, each from a generator seeded by ``(seed, run_id)``), the manifest a checkpoint is
fingerprinted by, and each run's config dict for the core."""

from __future__ import annotations

import dataclasses
import itertools
import math
import types
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import polars as pl

from admit_rs.blocks._base import _parameter_error
from admit_rs.blocks.scenario import position_error_unread
from admit_rs.config import (
    Scenario,
    _Block,
    _check_path,
    _core_dict_with,
    _core_value,
)
from admit_rs.distributions import Choice, Distribution, LogUniform, Normal, Uniform
from admit_rs.errors import (
    ArgumentError,
    ParameterTypeError,
)


def _describe(value: Any) -> Any:
    """A JSON-able description, for checkpoint manifests."""
    if isinstance(value, _Block):
        return {"block": type(value).__name__, **value.to_dict()}
    if isinstance(value, Uniform | LogUniform | Normal | Choice):
        d = {"dist": type(value).__name__}
        for k, v in value.__dict__.items():
            d[k] = _describe(v)
        return d
    if isinstance(value, tuple | list):
        return [_describe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    return value


def _column_value(value: Any, dtype: Any = None) -> Any:
    """A varied value as its table column holds it: blocks (and, in a column whose values
    mix shapes, every value) as their repr."""
    if isinstance(value, _Block) or (dtype == pl.String and not isinstance(value, str)):
        return repr(value)
    return value


def _field_types(scenario: Scenario, path: str) -> tuple[type, ...]:
    """The types a dotted path's field is declared with (``float | None`` ->
    ``(float, NoneType)``), from the block's annotations; ``()`` when unknown."""
    *parents, leaf = path.split(".")
    owner: Any = scenario
    for part in parents:
        owner = getattr(owner, part, None)
    if not dataclasses.is_dataclass(owner):
        return ()
    try:
        hint = typing.get_type_hints(type(owner)).get(leaf)
    except (NameError, TypeError):  # an annotation that does not resolve: no coercion
        return ()
    if hint is None:
        return ()
    args = typing.get_args(hint)
    members = args if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
    # Plain types, and tuple[float, ...] (a vector field) as itself.
    return tuple(m for m in members if isinstance(m, type) or typing.get_origin(m) is tuple)


def _normalise(types_: tuple[type, ...], value: Any) -> Any:
    """A listed or drawn value in its field's declared type, so that the table does not
    depend on how it was typed (``200`` and ``200.0`` for a float field are both 200.0;
    an integral ``10.0`` for an int field is 10). Booleans are left alone (the core
    rejects a bool where a number belongs)."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, list | tuple | np.ndarray):
        vector = any(typing.get_origin(t) is tuple and float in typing.get_args(t) for t in types_)
        if vector:  # (1, 0, -1) and (1.0, 0.0, -1.0) are one normal
            return tuple(_normalise((float,), v) for v in value)
        return value
    if isinstance(value, bool) or not isinstance(value, int | float):
        return value
    if float in types_ and int not in types_ and isinstance(value, int):
        return float(value)
    if int in types_ and float not in types_ and isinstance(value, float):
        if math.isfinite(value) and value == int(value):
            return int(value)
    return value


def _dtype(values: list[Any]) -> Any:
    """The one polars dtype of a varied column, from all its values (not from the first
    ones of a chunk): every chunk, thread count and resume builds it alike. Values that
    no single dtype holds (a number and a tuple for one field) become their repr."""
    try:
        return pl.Series(values, strict=True).dtype
    except (TypeError, ValueError, pl.exceptions.PolarsError):
        return pl.String


@dataclass(frozen=True)
class _Plan:
    """Everything that defines a sweep: the runs' parameters, in run_id order."""

    base: dict[str, Any]
    paths: list[str]
    rows: list[dict[str, Any]]
    seed: int
    manifest: dict[str, Any]
    dtypes: dict[str, Any] = field(default_factory=dict)
    """The polars dtype of each varied column."""


def _plan(
    scenario: Scenario,
    vary: Mapping[str, Distribution] | None,
    grid: Mapping[str, Sequence[Any]] | None,
    samples: int | None,
    seed: int,
) -> _Plan:
    if not isinstance(scenario, Scenario):
        raise ParameterTypeError(
            f"sweep() takes an admit_rs.Scenario, got {type(scenario).__name__}"
        )
    vary = dict(vary or {})
    grid = {k: list(v) for k, v in (grid or {}).items()}
    if not isinstance(seed, int) or isinstance(seed, bool) or not 0 <= seed < 2**63:
        # The table's seed column is a 64-bit integer.
        raise _parameter_error("seed", repr(seed), "an integer from 0 to 2**63 - 1")
    # Paths in current field names (a deprecated name warns once, here).
    vary = {_check_path(scenario, p): d for p, d in vary.items()}
    grid = {_check_path(scenario, p): v for p, v in grid.items()}
    both = set(vary) & set(grid)
    if both:
        raise ArgumentError(f"{sorted(both)} given in both vary and grid")
    if scenario.wall_estimate is not None and "wall.position_error" in {*vary, *grid}:
        raise position_error_unread("varied")
    for path, dist in vary.items():
        if not isinstance(dist, Uniform | LogUniform | Normal | Choice):
            raise ParameterTypeError(
                f"vary[{path!r}] must be a Uniform, LogUniform, Normal or Choice"
            )
    for path, values in grid.items():
        if not values:
            raise ArgumentError(f"grid[{path!r}] is empty")
    declared = {path: _field_types(scenario, path) for path in [*grid, *vary]}
    grid = {path: [_normalise(declared[path], v) for v in values] for path, values in grid.items()}
    if samples is None:
        if vary:
            raise ArgumentError("samples is required with vary (how many draws per grid point)")
        samples = 1
    if not isinstance(samples, int) or isinstance(samples, bool) or samples < 1:
        raise ArgumentError(f"samples = {samples!r} is invalid: must be an integer >= 1")

    rows = []
    points = list(itertools.product(*grid.values())) if grid else [()]
    for g, point in enumerate(points):
        for s in range(samples):
            run_id = g * samples + s
            row: dict[str, Any] = dict(zip(grid, point, strict=True))
            rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, run_id])))
            for path, dist in vary.items():
                row[path] = _normalise(declared[path], dist.draw(rng))
            rows.append(row)
    manifest = {
        "format": 1,
        "scenario": _describe(scenario),
        "vary": {k: _describe(v) for k, v in vary.items()},
        "grid": {k: _describe(v) for k, v in grid.items()},
        "samples": samples,
        "seed": seed,
    }
    paths = list(grid) + list(vary)
    dtypes = {p: _dtype([_column_value(r[p]) for r in rows]) for p in paths}
    return _Plan(scenario._to_core(), paths, rows, seed, manifest, dtypes)


def noise_seed(seed: int, run_id: int) -> int:
    """The sensor-noise seed (``Scenario.seed``) of run ``run_id`` of a sweep with ``seed``.

    Derived from (seed, run_id) alone, like the parameter draws, so a run's noise does not
    depend on the thread count, the chunking, a resume or Dask; ``scenario.replace(seed=
    noise_seed(seed, run_id))`` reproduces the run with :func:`admit_rs.simulate`.
    """
    state = np.random.SeedSequence([seed, run_id, 1]).generate_state(1, np.uint64)[0]
    return int(state) >> 11  # 53 bits: exact as a float in the core's config


def _configs(
    base: dict[str, Any], rows: Sequence[dict[str, Any]], run_ids: Sequence[int], seed: int
) -> list[dict[str, Any]]:
    out = []
    for row, run_id in zip(rows, run_ids, strict=True):
        # A varied "seed" path overrides the run's own noise seed.
        changes = {"seed": noise_seed(seed, run_id)}
        changes.update((path, _core_value(value)) for path, value in row.items())
        out.append(_core_dict_with(base, changes))
    return out


