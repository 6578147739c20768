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

import hashlib
import json
import os
import time
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import polars as pl

from admit_rs import _core
from admit_rs._checkpoint import (
    CheckpointMismatchError,
    CheckpointWarning,
    _atomic_parquet,
    _Checkpoint,
)
from admit_rs._sweep_plan import _column_value, _configs, _Plan, _plan, noise_seed
from admit_rs._trace import trace_frame
from admit_rs.config import (
    Scenario,
    _python_error,
)
from admit_rs.distributions import (
    Choice,
    Distribution,
    DistributionError,
    LogUniform,
    Normal,
    Uniform,
)
from admit_rs.errors import (
    ArgumentError,
    ParameterError,
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
    "noise_seed",
    "sweep",
]

DEFAULT_CHUNK_SIZE = 256
"""Runs per checkpoint file and per Dask task."""


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
        ``"met"``, ``"diverged"``, ``"not converging"``, ``"limit"`` or ``"not assessed"``
        (no contact force to judge: NaN error); null for a fixed
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

