"""A sweep's checkpoint (:func:`admit_rs.sweep`, ``checkpoint=``): finished chunks as
Parquet files, each sealed with the sweep's fingerprint, its runs and a checksum of its
content, written atomically; on resume a file is used only if all three match."""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import os
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import polars as pl
from polars.exceptions import PanicException

from admit_rs._sweep_plan import _column_value, _Plan
from admit_rs.errors import (
    AdmitError,
    ArgumentError,
)

__all__ = ["CheckpointMismatchError", "CheckpointWarning"]


class CheckpointMismatchError(AdmitError, ValueError):
    """A checkpoint folder holds a different sweep than the one asked for."""


class CheckpointWarning(UserWarning):
    """A checkpoint chunk file that cannot be used (unreadable, or not this sweep's): it is
    named in the message, its runs are computed again and the file is replaced."""


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

    @staticmethod
    def _write_sealed(path: Path, frame: pl.DataFrame, metadata: dict[str, str]) -> None:
        """Writes ``frame`` to ``path`` with the SHA-256 of its bytes beside it
        (``<name>.sha256``). The checksum lands first and the file last, each atomically, so a
        kill between the two leaves a checksum without a file (nothing to resume from, no
        warning), never a file without its checksum."""
        data = _parquet_bytes(frame, metadata)
        digest = hashlib.sha256(data).hexdigest().encode()
        _atomic_write(_sidecar(path), lambda f: f.write(digest))
        _atomic_write(path, lambda f: f.write(data))

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
        tpath = self._path("traces", index)
        for planted in (path, tpath):
            if planted.exists() and not planted.is_file():
                # Neither read nor replaceable (issue #53 item 17: IsADirectoryError).
                raise ArgumentError(
                    f"checkpoint: {planted} is not a file (a directory?): it cannot hold runs"
                    f" {ids.start}..{ids.stop - 1}; remove it or use another folder"
                )
        if not path.exists():
            return None
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
            self._write_sealed(tpath, traces, self._metadata(ids, traces))
        path = self._path("chunk", index)
        self._write_sealed(path, table, self._metadata(ids, table))

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


def _parquet_bytes(frame: pl.DataFrame, metadata: dict[str, str]) -> bytes:
    """``frame`` as the bytes of a Parquet file with ``metadata`` in its footer."""
    buffer = io.BytesIO()
    frame.write_parquet(buffer, metadata=metadata)
    return buffer.getvalue()


def _atomic_parquet(
    frame: pl.DataFrame, path: Path, metadata: dict[str, str] | None = None
) -> None:
    _atomic_write(path, lambda f: frame.write_parquet(f, metadata=metadata))


