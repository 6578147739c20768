"""Checkpoints a user can trust (issue 21 items 16-18): every chunk carries the sweep's
fingerprint and a checksum of its content, damage anywhere is named and recomputed, and
no file or symlink planted in the folder is followed."""

from __future__ import annotations

import hashlib
import json
import os
import warnings

import admit_rs as ar
import numpy as np
import polars as pl
import pytest

BASE = ar.paper.scenario("fig19").replace(duration=0.2)
GRID = {"admittance.b": [400.0, 800.0, 1600.0], "wall.stiffness": [2e4, 4e4]}


def run(base=BASE, **kw):
    kw.setdefault("progress", False)
    return ar.sweep(base, grid=GRID, chunk_size=2, **kw)


def resume(ck, base=BASE):
    """The sweep resumed from ``ck`` and the CheckpointWarnings it gave."""
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        table = run(base, checkpoint=ck)
    assert all(issubclass(w.category, ar.CheckpointWarning) for w in record), [
        str(w.message) for w in record
    ]
    return table, [str(w.message) for w in record]


@pytest.fixture(scope="module")
def clean():
    return run()


def test_bit_flips_over_every_byte_region_are_named_or_harmless(tmp_path, clean):
    ck = tmp_path / "ck"
    assert run(checkpoint=ck).equals(clean)
    chunk = ck / "chunk-000001.parquet"
    original = chunk.read_bytes()
    size = len(original)
    # One bit in each of 96 regions spread over the file (magic, column chunks, page
    # headers, footer, footer length, trailing magic) and in each of the last 12 bytes.
    offsets = sorted(set(np.linspace(0, size - 1, 96).astype(int)) | set(range(size - 12, size)))
    named = 0
    for n, offset in enumerate(offsets):
        damaged = bytearray(original)
        damaged[offset] ^= 1 << (n % 8)
        chunk.write_bytes(bytes(damaged))
        table, messages = resume(ck)
        assert table.equals(clean), f"bit flip at byte {offset} of {size} changed the table"
        if messages:
            assert len(messages) == 1 and f"checkpoint: {chunk} " in messages[0], messages
            assert messages[0].endswith("recomputing runs 2..3 (the file will be replaced)")
            named += 1
            assert chunk.read_bytes() != bytes(damaged)  # replaced by a good file
        chunk.write_bytes(original)
    assert named >= len(offsets) // 2  # most flips matter; each of those was named


def test_a_chunk_copied_from_a_sweep_with_another_base_scenario_is_recomputed(tmp_path):
    other = BASE.replace(**{"wall.position_error": 0.0})  # same grid, seed and run_ids
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    clean = run(checkpoint=ours)
    run(other, checkpoint=theirs)
    # Chunk 0 with its checksum file (its own fingerprint then names it), chunk 2 without.
    for name in ["chunk-000000.parquet", "chunk-000000.parquet.sha256", "chunk-000002.parquet"]:
        (ours / name).write_bytes((theirs / name).read_bytes())
    table, messages = resume(ours)
    assert table.equals(clean)
    assert len(messages) == 2
    assert messages[0].startswith(f"checkpoint: {ours / 'chunk-000000.parquet'} is from another"
                                  " sweep (fingerprint ")  # fmt: skip
    assert messages[1].startswith(f"checkpoint: {ours / 'chunk-000002.parquet'} is damaged or not"
                                  " this sweep's (its bytes do not match")  # fmt: skip
    assert "recomputing runs 4..5" in messages[1]
    assert resume(ours)[1] == []


def test_manifest_deleted_and_scenario_changed_gives_the_new_scenario(tmp_path):
    ck = tmp_path / "ck"
    run(checkpoint=ck)
    (ck / "manifest.json").unlink()
    changed = BASE.replace(**{"wall.position_error": 0.005})
    table, messages = resume(ck, changed)
    assert table.equals(run(changed))
    assert len(messages) == 3 and all("is from another sweep" in m for m in messages)
    assert resume(ck, changed)[1] == []  # every chunk was replaced by the new sweep's


@pytest.mark.parametrize(
    "content", [b'{"format": 1, "scen', b"[1, 2]", b"\xff\xfe\x00garbage", b""],
    ids=["truncated", "not-an-object", "not-utf8", "empty"],
)
def test_damaged_manifest_is_named_rewritten_and_the_sweep_runs(tmp_path, clean, content):
    ck = tmp_path / "ck"
    run(checkpoint=ck)
    manifest = ck / "manifest.json"
    good = manifest.read_bytes()
    manifest.write_bytes(content)
    table, messages = resume(ck)
    assert table.equals(clean)
    assert len(messages) == 1
    assert messages[0].startswith(f"checkpoint: {manifest} is unreadable (")
    assert "writing it again for this sweep" in messages[0]
    assert manifest.read_bytes() == good
    assert resume(ck)[1] == []


def test_manifest_symlink_is_replaced_not_followed(tmp_path, clean):
    ck = tmp_path / "ck"
    ck.mkdir()
    precious = tmp_path / "precious.txt"
    precious.write_text("do not overwrite")
    (ck / "manifest.json").symlink_to(precious)
    with pytest.warns(ar.CheckpointWarning, match="manifest.json is unreadable"):
        assert run(checkpoint=ck).equals(clean)
    assert precious.read_text() == "do not overwrite"
    assert not (ck / "manifest.json").is_symlink()


def test_a_flipped_column_name_is_recomputed_not_a_polars_error_on_every_rerun(tmp_path, clean):
    ck = tmp_path / "ck"
    run(checkpoint=ck)
    chunk = ck / "chunk-000001.parquet"
    data = chunk.read_bytes()
    assert data.count(b"force_peak") >= 1
    chunk.write_bytes(data.replace(b"force_peak", b"forcd_peak"))
    table, messages = resume(ck)
    assert table.equals(clean)
    assert len(messages) == 1 and f"checkpoint: {chunk} " in messages[0]
    assert resume(ck)[1] == []  # replaced: the next rerun reads it without a word


def test_renamed_column_with_a_valid_file_is_named(tmp_path, clean):
    # The same damage written as a well-formed Parquet file (metadata kept): the checksum
    # covers column names and dtypes.
    ck = tmp_path / "ck"
    run(checkpoint=ck)
    chunk = ck / "chunk-000001.parquet"
    meta = pl.read_parquet_metadata(chunk)
    meta = {k: v for k, v in meta.items() if k.startswith("admit_rs.")}
    pl.read_parquet(chunk).rename({"force_peak": "forcd_peak"}).write_parquet(chunk,
                                                                              metadata=meta)
    # Its checksum file rewritten too: the content checksum inside the file still names it.
    seal = ck / "chunk-000001.parquet.sha256"
    seal.write_text(hashlib.sha256(chunk.read_bytes()).hexdigest())
    table, messages = resume(ck)
    assert table.equals(clean)
    assert messages == [
        f"checkpoint: {chunk} is damaged (its content does not match its checksum);"
        " recomputing runs 2..3 (the file will be replaced)"
    ]


def test_planted_tmp_symlink_is_not_followed(tmp_path, clean):
    ck = tmp_path / "ck"
    ck.mkdir()
    precious = tmp_path / "precious.txt"
    precious.write_text("do not overwrite")
    for i in range(4):
        (ck / f"chunk-{i:06d}.tmp").symlink_to(precious)
    os.symlink(precious, ck / "manifest.tmp")
    assert run(checkpoint=ck).equals(clean)
    assert precious.read_text() == "do not overwrite"
    assert all((ck / f"chunk-{i:06d}.tmp").is_symlink() for i in range(4))  # left alone
    assert sorted(p.name for p in ck.iterdir() if not p.is_symlink()) == [
        "chunk-000000.parquet", "chunk-000000.parquet.sha256", "chunk-000001.parquet",
        "chunk-000001.parquet.sha256", "chunk-000002.parquet", "chunk-000002.parquet.sha256",
        "manifest.json",
    ]  # fmt: skip
    # The trace folder of traces=PATH is written the same way.
    out = tmp_path / "traces"
    out.mkdir()
    (out / "traces-000000.tmp").symlink_to(precious)
    run(traces=out)
    assert precious.read_text() == "do not overwrite"


def test_chunk_metadata_names_the_sweep_and_runs(tmp_path):
    ck = tmp_path / "ck"
    run(checkpoint=ck)
    meta = pl.read_parquet_metadata(ck / "chunk-000001.parquet")
    manifest = json.dumps(json.loads((ck / "manifest.json").read_text()), sort_keys=True,
                          indent=1)  # fmt: skip
    import hashlib

    assert meta["admit_rs.sweep_fingerprint"] == hashlib.sha256(manifest.encode()).hexdigest()
    assert meta["admit_rs.runs"] == "2..3"
    assert len(meta["admit_rs.content_sha256"]) == 64


def test_damaged_traces_file_is_named_and_recomputed(tmp_path):
    ck = tmp_path / "ck"
    clean, clean_traces = run(checkpoint=ck, traces=True)
    traces = ck / "traces-000001.parquet"
    data = bytearray(traces.read_bytes())
    data[len(data) // 3] ^= 0x10  # inside the column data
    traces.write_bytes(bytes(data))
    with pytest.warns(ar.CheckpointWarning, match=f"checkpoint: {traces} is "):
        table, long = run(checkpoint=ck, traces=True)
    assert table.equals(clean) and long.equals(clean_traces)
    # Traces written by another sweep beside this sweep's chunk are not this chunk's.
    other = tmp_path / "other"
    run(BASE.replace(**{"wall.position_error": 0.0}), checkpoint=other, traces=True)
    traces.write_bytes((other / "traces-000001.parquet").read_bytes())
    seal = ck / "traces-000001.parquet.sha256"
    seal.write_bytes((other / "traces-000001.parquet.sha256").read_bytes())
    with pytest.warns(ar.CheckpointWarning, match="is from another sweep"):
        table, long = run(checkpoint=ck, traces=True)
    assert table.equals(clean) and long.equals(clean_traces)


def test_a_directory_in_a_chunk_s_place_is_named(tmp_path):
    """Issue #53 item 17: it raised a bare IsADirectoryError."""
    ck = tmp_path / "ck"
    run(checkpoint=ck)
    chunk = ck / "chunk-000001.parquet"
    chunk.unlink()
    chunk.mkdir()
    with pytest.raises(ar.errors.ArgumentError) as e:
        run(checkpoint=ck)
    assert str(e.value) == (f"checkpoint: {chunk} is not a file (a directory?): it cannot hold"
                            " runs 2..3; remove it or use another folder")


def test_checkpoint_files_get_the_usual_permissions(tmp_path):
    ck = tmp_path / "ck"
    run(checkpoint=ck)
    mask = os.umask(0o022)
    os.umask(mask)
    for p in ck.iterdir():
        assert p.stat().st_mode & 0o777 == 0o666 & ~mask, p


def test_a_checkpoint_of_the_lanes_is_not_resumed_by_the_scalar_path(tmp_path):
    """Issue #53 item 2: a ``lanes=False`` sweep resumed from a ``lanes=True`` checkpoint
    returned the lane rows without a word (they differ in the last bits)."""
    ck = tmp_path / "ck"
    run(checkpoint=ck)
    with pytest.raises(ar.CheckpointMismatchError, match=r"holds a different sweep \(differs in"
                       r" lanes\)"):  # fmt: skip
        run(checkpoint=ck, lanes=False)
    scalar = tmp_path / "scalar"
    first = run(checkpoint=scalar, lanes=False)
    again, warned = resume_scalar(scalar)
    assert again.equals(first) and warned == []
    assert first.equals(run(lanes=False))


def resume_scalar(ck):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        table = run(checkpoint=ck, lanes=False)
    return table, [str(w.message) for w in record]
