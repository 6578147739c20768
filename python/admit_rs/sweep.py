"""Monte Carlo and grid sweeps over any scenario parameter, run in the Rust core.

Example:
    >>> import admit_rs as ar
    >>> table = ar.sweep(ar.paper.scenario("fig19").replace(duration=4.0),
    ...                  vary={"wall.stiffness": ar.LogUniform(1e4, 1e5)},
    ...                  samples=4, seed=0, progress=False)
    >>> table.select("run_id", "stable", "verdict").to_dicts()[0]
    {'run_id': 0, 'stable': True, 'verdict': 'stable'}

Each run draws its random numbers from a generator seeded by ``(seed, run_id)`` only, and
runs share nothing, so the table is bit-identical on 1 thread or many, in any chunking,
resumed from a checkpoint, or computed on Dask workers.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import itertools
import json
import math
import os
import tempfile
import time
import types
import typing
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np
import polars as pl
from polars.exceptions import PanicException

from admit_rs import _core
from admit_rs._trace import trace_frame
from admit_rs.blocks._base import _parameter_error
from admit_rs.blocks.scenario import position_error_unread
from admit_rs.config import (
    Scenario,
    _Block,
    _check_path,
    _core_dict_with,
    _core_value,
    _python_error,
)
from admit_rs.errors import (
    AdmitError,
    ArgumentError,
    ParameterError,
    ParameterTypeError,
    closest,
    for_run,
)

if TYPE_CHECKING:
    from dask.distributed import Client

__all__ = [
    "CheckpointMismatchError",
    "CheckpointWarning",
    "Choice",
    "DistributionError",
    "LogUniform",
    "Normal",
    "SweepInterrupted",
    "Uniform",
    "sweep",
]

DEFAULT_CHUNK_SIZE = 256
"""Runs per checkpoint file and per Dask task."""


class DistributionError(AdmitError, ValueError):
    """A distribution with impossible parameters (low > high, negative sigma, ...)."""


class CheckpointMismatchError(AdmitError, ValueError):
    """A checkpoint folder holds a different sweep than the one asked for."""


class CheckpointWarning(UserWarning):
    """A checkpoint chunk file that cannot be used (unreadable, or not this sweep's): it is
    named in the message, its runs are computed again and the file is replaced."""


class LaneBuildWarning(UserWarning):
    """``ADMIT_RS_LANES`` names no lane build, or one this CPU cannot run: sweeps take the
    default build (the message names it and the closest valid names)."""


LANE_BUILDS = ("auto", "portable", "avx2", "avx512")


def _check_lane_env() -> None:
    """Warns (once, at import) where ``ADMIT_RS_LANES`` is set but not taken: the core
    then falls back to the default build silently (docs/performance-history.md §14)."""
    value = os.environ.get("ADMIT_RS_LANES")
    if value is None or value.strip() in ("", "auto"):
        return
    name = value.strip()
    taken = _core._lane_path()
    if name == taken:
        return
    if name in LANE_BUILDS:
        why = f"ADMIT_RS_LANES={value!r}: this CPU cannot run that build"
    else:
        close = closest(name.lower(), LANE_BUILDS)
        hint = f"did you mean {', '.join(close)}?" if close else f"valid: {', '.join(LANE_BUILDS)}"
        why = f"ADMIT_RS_LANES={value!r} is not a lane build ({hint})"
    warnings.warn(
        f"{why}; sweeps use the {taken!r} build",
        LaneBuildWarning,
        stacklevel=2,
    )


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep. ``table`` holds every run that finished (checkpointed chunks
    stay on disk); rerunning the same call with the same ``checkpoint`` resumes.

    The one admit_rs exception that is not an :class:`~admit_rs.AdmitError`: AdmitError is
    an ``Exception``, and a Ctrl-C must not be swallowed by ``except Exception``. Catch it
    as ``except (ar.AdmitError, ar.SweepInterrupted)`` or as ``KeyboardInterrupt``."""

    def __init__(self, table: pl.DataFrame) -> None:
        super().__init__(f"sweep interrupted after {table.height} finished runs")
        self.table = table


def _finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise DistributionError(f"{name} = {value} is invalid: must be finite")
    return value


@dataclass(frozen=True)
class Uniform:
    """Uniform on [low, high]."""

    low: float
    high: float

    def __post_init__(self) -> None:
        if _finite("low", self.low) > _finite("high", self.high):
            raise DistributionError(f"Uniform: low = {self.low} > high = {self.high}")

    def draw(self, rng: np.random.Generator) -> float:
        return float(rng.uniform(self.low, self.high))


@dataclass(frozen=True)
class LogUniform:
    """log-uniform on [low, high], 0 < low ≤ high (for stiffnesses and gains)."""

    low: float
    high: float

    def __post_init__(self) -> None:
        if _finite("low", self.low) <= 0:
            raise DistributionError(f"LogUniform: low = {self.low} is invalid: must be > 0")
        if self.low > _finite("high", self.high):
            raise DistributionError(f"LogUniform: low = {self.low} > high = {self.high}")

    def draw(self, rng: np.random.Generator) -> float:
        return float(math.exp(rng.uniform(math.log(self.low), math.log(self.high))))


@dataclass(frozen=True)
class Normal:
    """Normal(mean, std), optionally truncated to [low, high] by rejection."""

    mean: float
    std: float
    low: float | None = None
    high: float | None = None

    MAX_TRIES = 10_000

    def __post_init__(self) -> None:
        _finite("mean", self.mean)
        if _finite("std", self.std) < 0:
            raise DistributionError(f"Normal: std = {self.std} is invalid: must be >= 0")
        lo = -math.inf if self.low is None else float(self.low)
        hi = math.inf if self.high is None else float(self.high)
        if math.isnan(lo) or math.isnan(hi) or lo > hi:
            raise DistributionError(f"Normal: bounds [{self.low}, {self.high}] are empty")
        if self.std == 0 and not lo <= self.mean <= hi:
            raise DistributionError(f"Normal: std = 0 and mean {self.mean} outside the bounds")

    def draw(self, rng: np.random.Generator) -> float:
        lo = -math.inf if self.low is None else self.low
        hi = math.inf if self.high is None else self.high
        for _ in range(self.MAX_TRIES):
            x = float(rng.normal(self.mean, self.std))
            if lo <= x <= hi:
                return x
        raise DistributionError(
            f"Normal({self.mean}, {self.std}) truncated to [{lo}, {hi}]: no draw inside the"
            f" bounds in {self.MAX_TRIES} tries; the bounds are too far in the tail"
        )


@dataclass(frozen=True)
class Choice:
    """One of ``values`` (numbers, strings or building blocks), optionally weighted."""

    values: tuple[Any, ...]
    weights: tuple[float, ...] | None = field(default=None)

    def __post_init__(self) -> None:
        object.__setattr__(self, "values", tuple(self.values))
        if not self.values:
            raise DistributionError("Choice: values is empty")
        if self.weights is not None:
            w = tuple(float(x) for x in self.weights)
            if len(w) != len(self.values) or any(not math.isfinite(x) or x < 0 for x in w):
                raise DistributionError("Choice: weights must be one finite w >= 0 per value")
            if sum(w) <= 0:
                raise DistributionError("Choice: weights sum to 0")
            object.__setattr__(self, "weights", w)

    def draw(self, rng: np.random.Generator) -> Any:
        p = None if self.weights is None else np.asarray(self.weights) / sum(self.weights)
        return self.values[int(rng.choice(len(self.values), p=p))]


Distribution = Uniform | LogUniform | Normal | Choice


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


def _run_chunk(
    base: dict[str, Any],
    rows: Sequence[dict[str, Any]],
    run_ids: Sequence[int],
    seed: int,
    threads: int | None,
    traces: bool,
    lanes: bool = True,
    dtypes: Mapping[str, Any] | None = None,
) -> tuple[pl.DataFrame, pl.DataFrame | None]:
    """Runs one chunk in the Rust core and returns its rows (and long traces); ``dtypes``
    gives each varied column's dtype (else inferred from this chunk's values).

    Top-level so that Dask workers can import it.
    """
    try:
        configs = _configs(base, rows, run_ids, seed)
        raw = _core.simulate_batch(configs, threads, traces, lanes)
    except ParameterError as e:
        raise for_run(_python_error(e), run_ids[getattr(e, "index", 0)]) from None
    n = len(run_ids)
    columns: dict[str, Any] = {
        "run_id": pl.Series("run_id", list(run_ids), dtype=pl.Int64),
        "seed": pl.Series("seed", [seed] * n, dtype=pl.Int64),
        "noise_seed": pl.Series("noise_seed", [c["seed"] for c in configs], dtype=pl.Int64),
    }
    for path in rows[0] if rows else []:
        dtype = (dtypes or {}).get(path)
        columns[path] = pl.Series(path, [_column_value(r[path], dtype) for r in rows],
                                  dtype=dtype, strict=False)  # fmt: skip
    columns.update(raw["metrics"])
    # True, False or None (not assessed: null), typed so that every chunk agrees.
    columns["stable"] = pl.Series("stable", raw["stable"], dtype=pl.Boolean)
    columns["passed"] = pl.Series("passed", raw["passed"], dtype=pl.Boolean)
    columns["verdict"] = pl.Series("verdict", raw["verdict"], dtype=pl.String)
    columns["diverged"] = raw["diverged"]
    columns["diverged_at"] = raw["diverged_at"]
    columns["divergence_cause"] = pl.Series(raw["divergence_cause"], dtype=pl.String)
    columns["substeps_used"] = pl.Series("substeps_used", raw["substeps"], dtype=pl.Int64)
    # NaN (a fixed count) as null: no estimate was made.
    columns["substep_error"] = pl.Series(
        "substep_error", raw["substep_error"], dtype=pl.Float64, nan_to_null=True
    )
    columns["substep_standing"] = pl.Series(raw["substep_standing"], dtype=pl.String)
    table = pl.DataFrame(columns)
    long = None
    if traces:
        long = pl.concat(
            [
                trace_frame(t).with_columns(pl.lit(rid, dtype=pl.Int64).alias("run_id"))
                for rid, t in zip(run_ids, raw["traces"], strict=True)
            ]
        )
        # The arm's own columns (q1..qn, tau1..taun): the three-link names, extended.
        long = long.select("run_id", *[c for c in long.columns if c != "run_id"])
    return table, long


def _run_chunk_remote(
    base: dict[str, Any],
    rows: Sequence[dict[str, Any]],
    run_ids: Sequence[int],
    seed: int,
    traces: bool,
    lanes: bool = True,
    dtypes: Mapping[str, Any] | None = None,
) -> tuple[pl.DataFrame, pl.DataFrame | None]:
    # One task per worker thread: the worker's own cores run it, one Rust thread each.
    return _run_chunk(base, rows, run_ids, seed, 1, traces, lanes, dtypes)


class _Checkpoint:
    """Finished chunks as Parquet files plus a manifest of the sweep's definition.

    Every file carries, in its Parquet key-value metadata, the sweep's fingerprint (a
    SHA-256 of the manifest: base scenario, vary, grid, samples, seed, traces,
    chunk_size, and lanes when off), its runs and a SHA-256 of its content
    (:func:`_checksum`). On resume a file is used only if all three match, so neither a
    damaged file, nor one copied from another sweep, nor a folder whose manifest was lost
    can put a wrong row in the table: such a file is named in a :class:`CheckpointWarning`
    and its runs are computed again.
    """

    def __init__(self, folder: str | os.PathLike[str], manifest: dict[str, Any]) -> None:
        self.folder = Path(folder)
        self.traces = bool(manifest.get("traces"))
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.folder / "manifest.json"
        text = json.dumps(manifest, sort_keys=True, indent=1)
        self.fingerprint = hashlib.sha256(text.encode()).hexdigest()
        old = self._read_manifest(path)
        if old is not None and old != json.loads(text):
            keys = sorted(k for k in set(old) | set(manifest) if old.get(k) != manifest.get(k))
            raise CheckpointMismatchError(
                f"checkpoint {self.folder} holds a different sweep (differs in"
                f" {', '.join(keys)}); use another folder or delete it"
            )
        if old is None:
            _atomic_write(path, lambda f: f.write(text.encode()))

    @staticmethod
    def _read_manifest(path: Path) -> dict[str, Any] | None:
        """The manifest on disk; ``None`` if there is none or it is unusable (then a
        CheckpointWarning names it and it is written again: every chunk is checked against
        the sweep's fingerprint anyway)."""
        if not path.exists():
            return None
        try:
            old = json.loads(path.read_bytes().decode("utf-8"))
            if not isinstance(old, dict):
                raise ArgumentError(f"a JSON {type(old).__name__}, not an object")
            return old
        except (OSError, ValueError) as e:  # JSONDecodeError, UnicodeDecodeError are ValueErrors
            reason = str(e).strip().splitlines()[0] if str(e).strip() else ""
            warnings.warn(
                f"checkpoint: {path} is unreadable ({type(e).__name__}: {reason}); writing it"
                " again for this sweep (every chunk is still checked against this sweep's"
                " fingerprint before it is used)",
                CheckpointWarning,
                stacklevel=4,
            )
            return None

    def _path(self, kind: str, index: int) -> Path:
        return self.folder / f"{kind}-{index:06d}.parquet"

    @staticmethod
    def _digest_of(path: Path) -> str:
        h = hashlib.sha256()
        with path.open("rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        return h.hexdigest()

    def _seal(self, path: Path) -> None:
        """Writes the SHA-256 of ``path``'s bytes beside it (``<name>.sha256``)."""
        digest = self._digest_of(path).encode()
        _atomic_write(_sidecar(path), lambda f: f.write(digest))

    def _intact(self, path: Path) -> str | None:
        """Why ``path`` must not be parsed, or ``None``: its bytes are checked against the
        checksum beside it before Parquet reads them, because a flipped length in a page
        can make the reader allocate exabytes and abort the process."""
        seal = _sidecar(path)
        if not seal.exists():
            return f"{path} has no checksum file {seal.name} beside it (an older or foreign file)"
        if seal.read_bytes().strip() != self._digest_of(path).encode():
            return (f"{path} is damaged or not this sweep's (its bytes do not match"
                    f" {seal.name})")  # fmt: skip
        return None

    def _read(self, path: Path, ids: range) -> tuple[pl.DataFrame | None, str | None]:
        """A chunk or traces file, or why it cannot be used."""
        meta = pl.read_parquet_metadata(path)
        frame = pl.read_parquet(path)
        if _FINGERPRINT not in meta or _CHECKSUM not in meta:
            return None, f"{path} has no fingerprint or checksum (an older or foreign file)"
        if meta[_FINGERPRINT] != self.fingerprint:
            theirs, ours = meta[_FINGERPRINT][:12], self.fingerprint[:12]
            return None, f"{path} is from another sweep (fingerprint {theirs}, this one's {ours})"
        if meta.get(_RUNS) != _runs(ids):
            runs = meta.get(_RUNS)
            return None, f"{path} is not the chunk of runs {_runs(ids)} (its runs: {runs})"
        if meta[_CHECKSUM] != _checksum(frame):
            return None, f"{path} is damaged (its content does not match its checksum)"
        return frame, None

    def load(
        self, index: int, plan: _Plan, ids: range
    ) -> tuple[pl.DataFrame, pl.DataFrame | None] | None:
        """Chunk ``index`` if it is on disk, readable and this sweep's; else ``None`` (to
        compute), with a :class:`CheckpointWarning` naming a file that is not usable."""
        path = self._path("chunk", index)
        if not path.exists():
            return None
        tpath = self._path("traces", index)
        table = long = None
        # The bytes are checked before Parquet parses them (see `_intact`).
        problem = self._intact(path)
        if problem is None and self.traces and tpath.exists():
            problem = self._intact(tpath)
        if problem is None:
            try:
                # The run_ids check first: a chunk copied under another index says so.
                table = pl.read_parquet(path)
                foreign = _foreign(table, None, plan, ids)
                if foreign:
                    problem = f"{path} is {foreign}"
                else:
                    table, problem = self._read(path, ids)
                if problem is None and self.traces:
                    if not tpath.exists():
                        problem = f"{path} has no {tpath.name} beside it"
                    else:
                        long, problem = self._read(tpath, ids)
                if problem is None and table is not None:
                    foreign = _foreign(table, long, plan, ids)
                    problem = f"{path} is {foreign}" if foreign else None
            except (Exception, PanicException) as e:  # a damaged file can fail in any way
                reason = str(e).strip().splitlines()[0] if str(e).strip() else ""
                problem = f"{path} is unreadable ({type(e).__name__}: {reason[:200]})"
        if problem is not None or table is None:
            warnings.warn(
                f"checkpoint: {problem}; recomputing runs {ids.start}..{ids.stop - 1}"
                " (the file will be replaced)",
                CheckpointWarning,
                stacklevel=3,
            )
            return None
        return table, long

    def save(
        self, index: int, ids: range, table: pl.DataFrame, traces: pl.DataFrame | None
    ) -> None:
        # Traces first, the chunk last and atomically: a chunk file means a finished chunk.
        if traces is not None:
            tpath = self._path("traces", index)
            _atomic_parquet(traces, tpath, self._metadata(ids, traces))
            self._seal(tpath)
        path = self._path("chunk", index)
        _atomic_parquet(table, path, self._metadata(ids, table))
        self._seal(path)

    def _metadata(self, ids: range, frame: pl.DataFrame) -> dict[str, str]:
        return {_FINGERPRINT: self.fingerprint, _RUNS: _runs(ids), _CHECKSUM: _checksum(frame)}


def _sidecar(path: Path) -> Path:
    """The file holding the SHA-256 of ``path``'s bytes."""
    return path.with_name(path.name + ".sha256")


_FINGERPRINT = "admit_rs.sweep_fingerprint"
_RUNS = "admit_rs.runs"
_CHECKSUM = "admit_rs.content_sha256"
"""Keys of a checkpoint file's Parquet metadata."""


def _runs(ids: range) -> str:
    return f"{ids.start}..{ids.stop - 1}"


def _checksum(frame: pl.DataFrame) -> str:
    """SHA-256 of a table's content: column names, dtypes, null masks and values (numbers
    as their bytes, anything else as JSON), independent of how polars chunks it in memory."""
    h = hashlib.sha256()
    h.update(json.dumps([frame.height, frame.columns, [str(d) for d in frame.dtypes]]).encode())
    for s in frame.get_columns():
        h.update(s.is_null().to_numpy().tobytes())
        if s.dtype.is_numeric() or s.dtype == pl.Boolean:
            filled = s.fill_null(False if s.dtype == pl.Boolean else 0)
            h.update(filled.to_numpy().tobytes())
        else:
            h.update(json.dumps(s.to_list(), default=repr).encode())
    return h.hexdigest()


def _same(a: Any, b: Any) -> bool:
    """Equal as read back from Parquet: tuples as lists, NaN equal to NaN."""
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)


def _foreign(table: pl.DataFrame, long: pl.DataFrame | None, plan: _Plan, ids: range) -> str | None:
    """Why a readable chunk file is not chunk ``ids`` of this sweep, or ``None`` if it is."""
    name = f"chunk of runs {ids.start}..{ids.stop - 1}"
    if "run_id" not in table.columns or table["run_id"].to_list() != list(ids):
        return f"not the {name} of this sweep (other run_ids)"
    missing = [c for c in ("seed", *plan.paths, "stable", "passed") if c not in table.columns]
    if missing:
        return f"not the {name} of this sweep (no column {', '.join(missing)})"
    if table["seed"].to_list() != [plan.seed] * len(ids):
        return f"not the {name} of this sweep (another seed)"
    rows = plan.rows[ids.start : ids.stop]
    for path in plan.paths:
        expected = [_column_value(r[path], plan.dtypes.get(path)) for r in rows]
        if not _same(table[path].to_list(), expected):
            return f"not the {name} of this sweep (other {path} values)"
    if long is not None and set(long["run_id"].unique().to_list()) != set(ids):
        return f"not the {name} of this sweep (its traces hold other run_ids)"
    return None


def _read_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_UMASK = _read_umask()
"""The process umask, read once at import (os.umask can only be read by setting it)."""


def _atomic_write(path: Path, write: Callable[[IO[bytes]], Any]) -> None:
    """Writes ``path`` through a new temporary file beside it, then renames it into place.

    The temporary file is created with O_CREAT | O_EXCL (:func:`tempfile.mkstemp`) under a
    random name, so a file or symlink planted in the folder is never opened or followed;
    the rename replaces ``path`` itself (a symlink there is replaced, not followed)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        # mkstemp makes the file 0600; give it the mode open() would have (0666 & ~umask).
        os.fchmod(fd, 0o666 & ~_UMASK)
        with os.fdopen(fd, "wb") as f:
            write(f)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _atomic_parquet(
    frame: pl.DataFrame, path: Path, metadata: dict[str, str] | None = None
) -> None:
    _atomic_write(path, lambda f: frame.write_parquet(f, metadata=metadata))


def _chunks(n: int, size: int) -> Iterator[tuple[int, range]]:
    for index, start in enumerate(range(0, n, size)):
        yield index, range(start, min(start + size, n))


def sweep(
    scenario: Scenario,
    vary: Mapping[str, Distribution] | None = None,
    grid: Mapping[str, Sequence[Any]] | None = None,
    samples: int | None = None,
    seed: int = 0,
    *,
    threads: int | None = None,
    traces: bool | str | os.PathLike[str] = False,
    checkpoint: str | os.PathLike[str] | None = None,
    client: Client | None = None,
    chunk_size: int = DEFAULT_CHUNK_SIZE,
    progress: bool = True,
    lanes: bool = True,
    twin: bool = False,
) -> pl.DataFrame | tuple[pl.DataFrame, pl.DataFrame]:
    """Runs ``scenario`` over a grid and/or random draws of its parameters.

    Args:
        scenario: the base scenario.
        vary: dotted path → distribution (``Uniform``, ``LogUniform``, ``Normal``, ``Choice``);
            ``samples`` draws per grid point.
        grid: dotted path → list of values, full factorial.
        samples: draws per grid point (required with ``vary``; default 1).
        seed: run ``run_id`` draws from a generator seeded by ``(seed, run_id)`` only.
        threads: Rust threads (default: all cores).
        traces: ``True``: also return every run's trace as a long table (run_id, t, ...).
            A folder: write each chunk's traces there as ``traces-NNNNNN.parquet`` as it
            finishes and keep none in memory (read them with ``pl.scan_parquet``).
        checkpoint: folder; finished chunks are written there as Parquet and a rerun of
            the same call computes only the missing ones.
        client: a ``dask.distributed.Client``: chunks run as tasks on its workers.
        chunk_size: runs per checkpoint file and per Dask task.
        progress: show a tqdm bar (runs/s, ETA).
        lanes: run the runs four or eight at a time in SIMD lanes (SPEC §13, about 2.4x the
            scalar path). The table is the same bits on any threads, chunking, resume, Dask
            or CPU (AVX2 or AVX-512 build, docs/performance-history.md §14).
            ``False``: the scalar path, each run ``ar.simulate``'s bits. A lane run's
            arithmetic is the scalar run's except ``exp`` (and sin/cos on URDF chains),
            within 2 ulp; how far that moves its metrics is the run's own sensitivity
            (docs/sweeps.md): ≤ 1e-9 relative where the run is insensitive (``twin``
            measures it), any digit, verdict or divergence time where it is not.
        twin: also run every row on the other path (lanes ↔ scalar: a perturbation of the
            last bits) and add ``lane_gap``, the largest relative difference of any metric
            between the two (0: equal; inf when the verdict or the divergence differ). A
            row with ``lane_gap`` > 1e-9 is sensitive: its metrics are not reproducible
            beyond that, whichever path computed them. Computed after the sweep (not
            checkpointed); costs a second run of every row.

    Returns:
        One row per run: ``run_id``, ``seed``, a column per varied path, the metrics of
        :data:`admit_rs.METRICS`, ``stable``, ``passed``, ``verdict``, ``diverged``,
        ``diverged_at``,
        ``divergence_cause``, ``substeps_used`` (the RK4 substeps the run was integrated
        with: its own count or what ``substeps="auto"`` chose for it), ``substep_error``
        and ``substep_standing`` (``"auto"``: the estimated largest force error [N] and
        ``"met"``, ``"diverged"``, ``"not converging"`` or ``"limit"``; null for a fixed
        count); with ``traces``, the tuple ``(table, traces)``. Each run
        is judged by its scenario's ``criteria`` (``criteria.*`` paths can be varied too):
        ``passed`` is False for a run that fails one, ``stable`` False only for an
        unstable one (diverged, or an oscillation or loss of contact the loop sustains by
        itself: SPEC §23; a ripple the motion drives is stable and fails ``passed``),
        ``verdict`` names the failed criteria; both are null for a run too short to
        assess; ``diverged`` says whether it stopped early. A run that fails a criterion the
        loop may sustain is run a second time with its drives held to tell which.

    Raises:
        TypeError: unknown path (with the closest valid ones) or wrong type.
        DistributionError, ValueError: impossible distribution or sweep definition.
        ParameterError: a drawn or listed value outside its range (names the run_id), or
            a ``checkpoint`` path that is a file.
        CheckpointMismatchError: ``checkpoint`` holds a different sweep.

    Warns:
        CheckpointWarning: a chunk file in ``checkpoint`` is unreadable, damaged (its
            content does not match its checksum) or not this sweep's (another fingerprint,
            other runs); the message names it, its runs are computed again and the file is
            overwritten, so the table still equals a clean run. Also for an unreadable
            ``manifest.json``, which is written again.
        SweepInterrupted: Ctrl-C; ``.table`` holds the finished runs.
    """
    if not isinstance(chunk_size, int) or chunk_size < 1:
        raise ArgumentError(f"chunk_size = {chunk_size!r} is invalid: must be an integer >= 1")
    if threads is not None and (not isinstance(threads, int) or threads < 1):
        raise ArgumentError(f"threads = {threads!r} is invalid: must be an integer >= 1")
    if checkpoint is not None and Path(checkpoint).exists() and not Path(checkpoint).is_dir():
        err = ParameterError(
            f"checkpoint = {str(checkpoint)!r} is invalid: must be a folder or a path that does "
            "not exist yet (it is a file)"
        )
        err.field, err.value = "checkpoint", repr(str(checkpoint))
        err.allowed = "a folder or a path that does not exist yet"
        raise err
    plan = _plan(scenario, vary, grid, samples, seed)
    keep_traces = traces is not False
    trace_dir = None if isinstance(traces, bool) else Path(traces)
    if trace_dir is not None:
        trace_dir.mkdir(parents=True, exist_ok=True)
    plan.manifest["traces"] = keep_traces
    plan.manifest["chunk_size"] = chunk_size
    if not lanes:
        # The scalar path differs from the lanes in the last bits (issue #53 item 2): a
        # checkpoint of one is not the other's. (Only off is written, so checkpoints made
        # before this key still resume with lanes on.)
        plan.manifest["lanes"] = False
    store = _Checkpoint(checkpoint, plan.manifest) if checkpoint is not None else None
    n = len(plan.rows)
    done: dict[int, tuple[pl.DataFrame, pl.DataFrame | None]] = {}
    todo = []
    for index, ids in _chunks(n, chunk_size):
        loaded = store.load(index, plan, ids) if store is not None else None
        if loaded is not None:
            done[index] = loaded
        else:
            todo.append((index, ids))

    from tqdm.auto import tqdm

    def spill(index: int, table: pl.DataFrame, long: pl.DataFrame | None) -> None:
        if trace_dir is not None and long is not None:
            _atomic_parquet(long, trace_dir / f"traces-{index:06d}.parquet")
            long = None  # on disk now; do not hold it in memory
        done[index] = (table, long)

    ranges = dict(_chunks(n, chunk_size))

    def finish(index: int, chunk: tuple[pl.DataFrame, pl.DataFrame | None]) -> None:
        if store is not None:
            store.save(index, ranges[index], *chunk)
        spill(index, *chunk)

    for index in list(done):  # chunks resumed from a checkpoint
        spill(index, *done[index])
    bar = tqdm(total=n, unit="run", desc="sweep", disable=not progress, smoothing=0.1)
    bar.update(sum(t.height for t, _ in done.values()))
    # Sub-batches of the chunk each index is computing; a chunk counts once it is in `done`,
    # so an interrupt between the two bookkeeping steps can neither lose nor double it.
    partial: dict[int, list[tuple[pl.DataFrame, pl.DataFrame | None]]] = {}
    try:
        if client is not None:
            _run_on_dask(client, plan, todo, keep_traces, finish, bar, lanes)
        else:
            _run_local(plan, todo, threads, keep_traces, finish, partial, bar, lanes)
    except KeyboardInterrupt:
        # One Ctrl-C can arrive as two KeyboardInterrupts: polars chains its own SIGINT
        # handler in front of Python's, so a press during a Parquet write raises inside
        # polars and again from Python's handler at the next function call, which is the
        # one below. Retry the gathering (milliseconds) rather than let that echo replace
        # SweepInterrupted with a bare interrupt. The loop is here, not in the callee,
        # because the echo fires on entering the callee, before any try inside it.
        attempts = 5
        while True:
            try:
                table = _finished_runs(done, partial, plan, bar)
                break
            except KeyboardInterrupt:
                attempts -= 1
                if attempts == 0:
                    raise  # Ctrl-C held down: give up on the table and stop.
        raise SweepInterrupted(table) from None
    bar.close()
    table, long = _assemble([done[i] for i in sorted(done)], plan)
    if twin:
        table = _with_lane_gap(table, plan, threads, lanes)
    if traces is True:
        return table, long if long is not None else pl.DataFrame()
    return table


LANE_GAP_SCALE = 1e-9
"""Floor of the scale in ``lane_gap``: differences of metrics near 0 count absolutely."""


def _with_lane_gap(
    table: pl.DataFrame, plan: _Plan, threads: int | None, lanes: bool
) -> pl.DataFrame:
    """``table`` with ``lane_gap``: each row run again on the other path (lanes ↔ scalar)."""
    ids = table["run_id"].to_list()
    gaps = np.zeros(len(ids))
    for start in range(0, len(ids), 1024):
        sub = ids[start : start + 1024]
        configs = _configs(plan.base, [plan.rows[i] for i in sub], sub, plan.seed)
        other = _core.simulate_batch(configs, threads, False, not lanes)
        mine = table.slice(start, len(sub))
        gap = np.zeros(len(sub))
        for name, values in other["metrics"].items():
            a, b = mine[name].to_numpy().astype(float), np.asarray(values, dtype=float)
            both_nan = np.isnan(a) & np.isnan(b)
            scale = np.maximum(np.maximum(np.abs(a), np.abs(b)), LANE_GAP_SCALE)
            with np.errstate(invalid="ignore"):
                rel = np.where(both_nan, 0.0, np.abs(a - b) / scale)
            gap = np.maximum(gap, np.where(np.isnan(rel), np.inf, rel))
        # Another verdict, or a divergence at another time (or only on one path).
        differs = np.zeros(len(sub), dtype=bool)
        for verdict in ("stable", "passed"):
            differs |= np.asarray(mine[verdict].to_list(), dtype=object) != np.asarray(
                other[verdict], dtype=object)
        at_a = mine["diverged_at"].to_numpy().astype(float)
        at_b = np.asarray(other["diverged_at"], dtype=float)
        differs |= ~((at_a == at_b) | (np.isnan(at_a) & np.isnan(at_b)))
        gaps[start : start + len(sub)] = np.where(differs, np.inf, gap)
    return table.with_columns(pl.Series("lane_gap", gaps, dtype=pl.Float64))


def _finished_runs(
    done: Mapping[int, tuple[pl.DataFrame, pl.DataFrame | None]],
    partial: Mapping[int, list[tuple[pl.DataFrame, pl.DataFrame | None]]],
    plan: _Plan,
    bar: Any,
) -> pl.DataFrame:
    """The table of every run that finished, gathered after Ctrl-C."""
    bar.close()
    pieces = [done[i] for i in sorted(done)]
    pieces += [p for i in sorted(partial) if i not in done for p in partial[i]]
    return _assemble(pieces, plan)[0]


# Target wall time of one in-process Rust call of a sweep [s].
_CALL_SECONDS = 0.3


def _run_local(
    plan: _Plan,
    todo: list[tuple[int, range]],
    threads: int | None,
    traces: bool,
    finish: Callable[[int, tuple[pl.DataFrame, pl.DataFrame | None]], None],
    partial: dict[int, list[tuple[pl.DataFrame, pl.DataFrame | None]]],
    bar: Any,
    lanes: bool = True,
) -> None:
    # Rust calls of about `_CALL_SECONDS` each: short enough that Ctrl-C (seen between
    # calls) stops the sweep within a second or so, long enough that the Python work around
    # a call (configs in, tables out) stays a few per cent. The first call runs one lane
    # group per thread; later ones are sized from the rate measured so far. Results do not
    # depend on the sizes (every run's numbers depend on its scenario alone).
    # A lane group is 8 runs on the AVX-512 build, else 4 (issue #25).
    width = 8 if lanes and _core._lane_path() == "avx512" else 4
    group = width * (threads or os.cpu_count() or 1)
    step, done, spent = group, 0, 0.0
    for index, ids in todo:
        pieces = partial.setdefault(index, [])
        start = ids.start
        while start < ids.stop:
            sub = range(start, min(start + step, ids.stop))
            rows = plan.rows[sub.start : sub.stop]
            began = time.perf_counter()
            pieces.append(
                _run_chunk(plan.base, rows, list(sub), plan.seed, threads, traces, lanes,
                           plan.dtypes)  # fmt: skip
            )
            spent += time.perf_counter() - began
            done += len(sub)
            bar.update(len(sub))
            start = sub.stop
            # Whole lane groups per thread, between one group and 64.
            want = done / max(spent, 1e-9) * _CALL_SECONDS
            step = group * min(max(round(want / group), 1), 64)
        finish(index, _concat(pieces))
        del partial[index]


def _run_on_dask(
    client: Client,
    plan: _Plan,
    todo: list[tuple[int, range]],
    traces: bool,
    finish: Callable[[int, tuple[pl.DataFrame, pl.DataFrame | None]], None],
    bar: Any,
    lanes: bool = True,
) -> None:
    from dask.distributed import as_completed

    base = client.scatter(plan.base, broadcast=True)
    futures = {
        client.submit(
            _run_chunk_remote,
            base,
            plan.rows[ids.start : ids.stop],
            list(ids),
            plan.seed,
            traces,
            lanes,
            plan.dtypes,
            key=f"admit-rs-chunk-{_key(plan)}-{index}",
            pure=False,
        ): index
        for index, ids in todo
    }
    try:
        for future in as_completed(futures):
            index = futures[future]
            chunk = future.result()
            finish(index, chunk)
            bar.update(chunk[0].height)
    except KeyboardInterrupt:
        client.cancel(list(futures))
        raise


def _key(plan: _Plan) -> str:
    return hashlib.sha1(json.dumps(plan.manifest, sort_keys=True).encode()).hexdigest()[:12]


def _concat(
    pieces: Sequence[tuple[pl.DataFrame, pl.DataFrame | None]],
) -> tuple[pl.DataFrame, pl.DataFrame | None]:
    tables = [t for t, _ in pieces]
    longs = [x for _, x in pieces if x is not None]
    return (
        pl.concat(tables, how="vertical_relaxed", rechunk=True) if tables else pl.DataFrame(),
        pl.concat(longs) if longs else None,
    )


def _assemble(
    pieces: Sequence[tuple[pl.DataFrame, pl.DataFrame | None]], plan: _Plan
) -> tuple[pl.DataFrame, pl.DataFrame | None]:
    table, long = _concat(pieces)
    if table.height:
        table = table.sort("run_id")
    if long is not None:
        long = long.sort("run_id", maintain_order=True)
    return table, long


_check_lane_env()
