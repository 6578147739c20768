"""Sweeps: determinism, checkpoints and resume, Ctrl-C, Dask, errors, plots."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time

import admit_rs as ar
import numpy as np
import polars as pl
import pytest

BASE = ar.paper.scenario("fig19").replace(duration=0.5)
VARY = {
    "wall.stiffness": ar.LogUniform(1e4, 1e5),
    "wall.position_error": ar.Uniform(0.0, 0.01),
    "controller.model.mass_scale": ar.Normal(1.0, 0.1, low=0.5, high=1.5),
}


def run(**kw):
    kw.setdefault("progress", False)
    return ar.sweep(BASE, **kw)


def test_table_layout_and_values():
    table = run(vary=VARY, samples=6, seed=3)
    assert table.height == 6
    assert table["run_id"].to_list() == list(range(6))
    assert (table["seed"] == 3).all()
    for col in ["wall.stiffness", "wall.position_error", "controller.model.mass_scale",
                *ar.METRIC_NAMES, "stable", "diverged_at", "divergence_cause"]:  # fmt: skip
        assert col in table.columns
    k = table["wall.stiffness"].to_numpy()
    assert ((k >= 1e4) & (k <= 1e5)).all()
    # Each row is exactly the single run with those parameters.
    row = table.row(4, named=True)
    single = ar.simulate(BASE.replace(**{p: row[p] for p in VARY}))
    for name in ar.METRIC_NAMES:
        np.testing.assert_equal(row[name], single.metrics[name])


def test_draws_depend_on_seed_and_run_id_only():
    a = run(vary=VARY, samples=8, seed=5)
    b = run(vary={"wall.stiffness": VARY["wall.stiffness"]}, samples=8, seed=5)
    # The first path's draws are the same whatever else is varied: same (seed, run_id).
    assert a["wall.stiffness"].equals(b["wall.stiffness"])
    c = run(vary=VARY, samples=8, seed=6)
    assert not a["wall.stiffness"].equals(c["wall.stiffness"])


def test_bit_identical_across_threads_and_chunking():
    ref = run(vary=VARY, samples=10, seed=1, threads=1)
    assert ref.equals(run(vary=VARY, samples=10, seed=1, threads=2))
    assert ref.equals(run(vary=VARY, samples=10, seed=1, chunk_size=3))
    assert ref.equals(run(vary=VARY, samples=10, seed=1, threads=2, chunk_size=1))


def test_grid_times_samples():
    table = run(grid={"admittance.b": [400.0, 800.0], "admittance.ka": [0.5, 1.0]},
                vary={"wall.stiffness": ar.Uniform(2e4, 4e4)}, samples=2)  # fmt: skip
    assert table.height == 8
    assert table["admittance.b"].to_list() == [400.0] * 4 + [800.0] * 4
    assert table["admittance.ka"].to_list() == [0.5, 0.5, 1.0, 1.0] * 2
    grid_only = run(grid={"admittance.b": [200.0, 400.0, 800.0]})
    assert grid_only.height == 3


def test_choice_of_blocks_and_values():
    table = run(vary={"controller": ar.Choice([ar.ModelFree(), ar.TimeDelayControl()])},
                samples=6, seed=0)  # fmt: skip
    names = set(table["controller"].to_list())
    assert names <= {repr(ar.ModelFree()), repr(ar.TimeDelayControl())}
    mf = table.filter(pl.col("controller") == repr(ar.ModelFree()))
    tdc = table.filter(pl.col("controller") == repr(ar.TimeDelayControl()))
    assert mf.height and tdc.height
    assert mf["z_rms_error"].min() > 5 * tdc["z_rms_error"].max()


def test_unstable_run_is_a_row():
    """Model-free control diverges at K_A = 0.1: a row with stable = False, not an error."""
    table = ar.sweep(ar.paper.scenario("fig12").replace(duration=0.5),
                     grid={"controller.command_divisor": [5.0, 0.1]}, progress=False)  # fmt: skip
    # The 0.5-s run that completes is too short to assess (null); the diverged one is not.
    assert table["stable"].to_list() == [None, False]
    assert table["verdict"][0].startswith("not assessed")
    bad = table.row(1, named=True)
    assert bad["diverged_at"] > 0 and "velocity" in bad["divergence_cause"]
    assert np.isnan(bad["force_ss_error"])
    assert table.row(0, named=True)["divergence_cause"] is None


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: ar.Uniform(2.0, 1.0), "low = 2.0 > high = 1.0"),
        (lambda: ar.LogUniform(0.0, 1.0), "must be > 0"),
        (lambda: ar.Normal(1.0, -0.1), "std = -0.1"),
        (lambda: ar.Normal(1.0, 0.1, low=2.0, high=1.0), "empty"),
        (lambda: ar.Uniform(0.0, float("nan")), "finite"),
        (lambda: ar.Choice([]), "empty"),
        (lambda: ar.Choice([1, 2], weights=[1.0]), "one finite w"),
    ],
)
def test_bad_distributions(make, match):
    with pytest.raises(ar.DistributionError, match=match) as info:
        make()
    assert isinstance(info.value, ValueError)


def test_bad_sweep_definitions():
    with pytest.raises(TypeError, match=r"did you mean wall\.stiffness"):
        run(vary={"wall.stifness": ar.Uniform(1.0, 2.0)}, samples=2)
    with pytest.raises(ValueError, match="samples is required"):
        run(vary=VARY)
    with pytest.raises(ValueError, match="both vary and grid"):
        run(vary={"admittance.b": ar.Uniform(1, 2)}, grid={"admittance.b": [1.0]}, samples=1)
    with pytest.raises(ValueError, match="seed"):
        run(grid={"admittance.b": [1.0]}, seed=-1)
    with pytest.raises(ValueError, match="chunk_size"):
        run(grid={"admittance.b": [1.0]}, chunk_size=0)
    with pytest.raises(TypeError, match="must be a Uniform"):
        run(vary={"admittance.b": (1, 2)}, samples=1)
    # A drawn value out of range: a ParameterError naming the run and the field.
    with pytest.raises(ar.ParameterError, match=r"^run_id 1: admittance\.b = -5") as info:
        run(grid={"admittance.b": [400.0, -5.0]})
    assert (info.value.field, info.value.run_id) == ("admittance.b", 1)


def test_traces_long_table():
    table, traces = run(grid={"admittance.b": [400.0, 800.0]}, traces=True)
    assert traces.columns == ["run_id", *ar.TRACE_COLUMNS]
    assert traces.height == 2 * 501
    one = ar.simulate(BASE.replace(**{"admittance.b": 800.0})).trace
    # Lanes agree with simulate to 1e-9 (SPEC §13); the scalar path is the same bits.
    from_sweep = traces.filter(pl.col("run_id") == 1).drop("run_id")
    assert not from_sweep.equals(one)  # the lanes' exp is not libm's
    assert from_sweep.columns == one.columns
    for name in one.columns:
        np.testing.assert_allclose(from_sweep[name], one[name], rtol=1e-9, atol=1e-12)
    _, scalar = run(grid={"admittance.b": [400.0, 800.0]}, traces=True, lanes=False)
    assert scalar.filter(pl.col("run_id") == 1).drop("run_id").equals(one)


def test_checkpoint_resume_equals_clean_run(tmp_path):
    clean = run(vary=VARY, samples=9, seed=2, chunk_size=4)
    ck = tmp_path / "ck"
    first = run(vary=VARY, samples=9, seed=2, chunk_size=4, checkpoint=ck)
    assert first.equals(clean)
    files = sorted(p.name for p in ck.glob("chunk-*.parquet"))
    assert files == ["chunk-000000.parquet", "chunk-000001.parquet", "chunk-000002.parquet"]
    # A crash that lost chunk 1: the rerun computes only that one.
    (ck / "chunk-000001.parquet").unlink()
    mtime = (ck / "chunk-000000.parquet").stat().st_mtime_ns
    assert run(vary=VARY, samples=9, seed=2, chunk_size=4, checkpoint=ck).equals(clean)
    assert (ck / "chunk-000000.parquet").stat().st_mtime_ns == mtime
    # A different sweep in the same folder is an error, not a silent mix.
    with pytest.raises(ar.CheckpointMismatchError, match="seed"):
        run(vary=VARY, samples=9, seed=3, chunk_size=4, checkpoint=ck)


def test_checkpoint_checksum_lands_before_its_chunk(tmp_path, monkeypatch):
    # A SIGKILL between the two writes must leave a checksum without a chunk (recomputed
    # quietly), never a chunk without its checksum (CI once caught that as a warning).
    module = sys.modules["admit_rs._checkpoint"]
    real, order = module._atomic_write, []

    def recording(path, write):
        order.append(path.name)
        real(path, write)

    monkeypatch.setattr(module, "_atomic_write", recording)
    run(vary=VARY, samples=4, seed=2, chunk_size=4, checkpoint=tmp_path / "ck")
    chunks = [name for name in order if name.startswith("chunk-")]
    assert chunks == ["chunk-000000.parquet.sha256", "chunk-000000.parquet"]


SCRIPT = textwrap.dedent(
    """
    import sys, admit_rs as ar
    base = ar.paper.scenario("fig19").replace(duration=2.0)
    try:
        ar.sweep(base, vary={"wall.stiffness": ar.LogUniform(1e4, 1e5)}, samples=400, seed=7,
                 chunk_size=8, threads=1, checkpoint=sys.argv[1], progress=False)
    except ar.SweepInterrupted as e:
        print("INTERRUPTED", e.table.height, flush=True)
        sys.exit(130)
    print("FINISHED", flush=True)
    """
)


def _start(tmp_path, ck):
    script = tmp_path / "sweep_job.py"
    script.write_text(SCRIPT)
    proc = subprocess.Popen([sys.executable, str(script), str(ck)], stdout=subprocess.PIPE,
                            text=True)  # fmt: skip
    deadline = time.monotonic() + 120
    while len(list(ck.glob("chunk-*.parquet"))) < 2:
        assert proc.poll() is None, "the sweep ended before it could be interrupted"
        assert time.monotonic() < deadline
        time.sleep(0.05)
    return proc


def _expected():
    base = ar.paper.scenario("fig19").replace(duration=2.0)
    return base, {"wall.stiffness": ar.LogUniform(1e4, 1e5)}


def test_resume_after_kill_equals_clean_run(tmp_path):
    ck = tmp_path / "ck"
    proc = _start(tmp_path, ck)
    proc.kill()  # SIGKILL: no cleanup at all
    proc.communicate(timeout=30)
    kept = len(list(ck.glob("chunk-*.parquet")))
    assert 2 <= kept < 50
    base, vary = _expected()
    resumed = ar.sweep(base, vary=vary, samples=400, seed=7, chunk_size=8, checkpoint=ck,
                       progress=False)  # fmt: skip
    clean = ar.sweep(base, vary=vary, samples=400, seed=7, chunk_size=8, progress=False)
    assert resumed.equals(clean)


def test_ctrl_c_stops_within_a_second_and_keeps_what_finished(tmp_path):
    ck = tmp_path / "ck"
    proc = _start(tmp_path, ck)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    assert proc.stdout is not None
    out = proc.stdout.readline()  # printed as the sweep returns, before interpreter exit
    stopped = time.monotonic() - sent
    out += proc.communicate(timeout=30)[0]
    assert proc.returncode == 130, out
    assert out.startswith("INTERRUPTED")
    finished = int(out.split()[1])
    assert finished >= 16
    assert stopped < 1.0 + 0.5  # one sub-batch (4 runs of 2 s on 1 thread) plus the table
    assert len(list(ck.glob("chunk-*.parquet"))) * 8 <= finished


def test_ctrl_c_during_a_checkpoint_write_is_one_interrupt(tmp_path, monkeypatch):
    # Polars chains its own SIGINT handler in front of Python's, so one Ctrl-C during a
    # Parquet write raises a KeyboardInterrupt inside polars and a second one from Python's
    # handler at the next call: inside the sweep's clean-up. CI once caught that as a bare
    # KeyboardInterrupt. Here a real SIGINT lands in a long polars write of chunk 2.
    import os
    import threading

    module = sys.modules["admit_rs._checkpoint"]  # where a checkpoint chunk is written
    real = module._parquet_bytes
    big = pl.DataFrame({f"c{i}": np.arange(2_000_000, dtype=float) for i in range(4)})
    calls = {"n": 0}

    def slow_write(frame, metadata):
        calls["n"] += 1
        if calls["n"] == 2:  # chunk 2's checkpoint
            kick = threading.Timer(0.02, os.kill, (os.getpid(), signal.SIGINT))
            kick.start()
            big.write_parquet(tmp_path / "big.parquet")  # ~0.1 s of polars work
            for _ in range(500):  # in case the write beat the signal
                time.sleep(0.01)
        return real(frame, metadata)

    monkeypatch.setattr(module, "_parquet_bytes", slow_write)
    try:
        run(vary=VARY, samples=40, seed=5, chunk_size=8, threads=1, checkpoint=tmp_path / "ck")
    except ar.SweepInterrupted as e:
        table = e.table
        time.sleep(0.01)  # a second, pending interrupt would fire here at the latest
    except KeyboardInterrupt as e:  # would stop the whole pytest session: report instead
        pytest.fail(f"a bare KeyboardInterrupt escaped the sweep: {e!r}")
    else:
        pytest.fail("the sweep was not interrupted")
    # Chunk 1 was on disk, chunk 2 finished but its checkpoint was cut: both are kept.
    assert table["run_id"].to_list() == list(range(16))
    assert len(list((tmp_path / "ck").glob("chunk-*.parquet"))) == 1
    assert table.equals(run(vary=VARY, samples=16, seed=5))


def test_dask_local_cluster_equals_local():
    from dask import distributed

    local = run(vary=VARY, samples=12, seed=4, chunk_size=5)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:  # fmt: skip
        remote = run(vary=VARY, samples=12, seed=4, chunk_size=5, client=client)
    assert remote.equals(local)


def test_sweep_plots():
    # 4-s runs: long enough to be assessed (a 0.5-s run's stable is null).
    table = ar.sweep(BASE.replace(duration=4.0), progress=False,
                     grid={"wall.stiffness": [1e4, 3e4, 1e5], "wall.position_error": [0.0, 0.01]})
    fig = ar.plot.sweep_heatmap(table, x="wall.stiffness", y="wall.position_error",
                                metric="force_peak")  # fmt: skip
    assert fig.axes[0].get_xlabel() == "wall.stiffness [N/m]"
    # A grid is drawn as categories: one cell per listed value, its tick labelled with it.
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == [
        "$10^{4}$", "$3\\times10^{4}$", "$10^{5}$",
    ]  # fmt: skip
    assert [t.get_text() for t in ax.get_yticklabels()] == ["0", "0.01"]
    assert ax.get_xlim() == (-0.5, 2.5)
    # 3 × 2 grid cells, each holding exactly its run's peak (one run per cell).
    cells = np.ma.filled(fig.axes[0].collections[0].get_array(), np.nan).ravel()
    np.testing.assert_allclose(np.sort(cells), np.sort(table["force_peak"].to_numpy()))
    lin = ar.plot.sweep_heatmap(table, x="wall.stiffness", y="wall.position_error",
                                metric="force_peak", logx=False)  # fmt: skip
    assert lin.axes[0].get_xscale() == "linear"
    log = ar.plot.sweep_heatmap(table, x="wall.stiffness", y="wall.position_error",
                                metric="force_peak", logx=True)  # fmt: skip
    assert log.axes[0].get_xscale() == "log"
    mixed = ar.sweep(ar.paper.scenario("fig14").replace(duration=4.0, **{"admittance.b": 200.0}),
                     grid={"wall.stiffness": [1e4, 7e5]}, progress=False)  # fmt: skip
    fig = ar.plot.sweep_scatter(mixed, x="wall.stiffness", metric="force_peak")
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert labels == ["stable (1)", "unstable (1)"]
    fig = ar.plot.sweep_hist(table, "force_peak")
    assert "6 stable, 0 unstable" in fig.axes[0].get_title()


def test_cli_sweep(tmp_path):
    from admit_rs import cli

    toml = tmp_path / "sweep.toml"
    toml.write_text(
        'base = "fig19"\nsamples = 3\nseed = 1\n[overrides]\nduration = 0.5\n'
        '[vary."wall.stiffness"]\ndist = "loguniform"\nlow = 1e4\nhigh = 1e5\n'
    )
    out = tmp_path / "r.parquet"
    assert cli.main(["sweep", str(toml), "-o", str(out), "--no-progress"]) == 0
    table = pl.read_parquet(out)
    assert table.height == 3
    expected = ar.sweep(BASE, vary={"wall.stiffness": ar.LogUniform(1e4, 1e5)}, samples=3,
                        seed=1, progress=False)  # fmt: skip
    assert table.equals(expected)
    toml.write_text('base = "fig19"\nsamples = 3\n[vary."wall.stiffness"]\ndist = "gauss"\n')
    assert cli.main(["sweep", str(toml), "-o", str(out)]) == 2


def test_example_toml_parses():
    from pathlib import Path

    from admit_rs.cli import load_sweep

    kwargs = load_sweep(Path(__file__).parent.parent / "examples" / "stiffness_sweep.toml")
    assert kwargs["samples"] == 1000
    assert isinstance(kwargs["vary"]["wall.stiffness"], ar.LogUniform)
    assert kwargs["scenario"].wall.position_error == 0.01


def test_traces_to_parquet_folder(tmp_path):
    out = tmp_path / "traces"
    table = run(grid={"admittance.b": [200.0, 400.0, 800.0]}, traces=out, chunk_size=2)
    assert isinstance(table, pl.DataFrame) and table.height == 3
    assert sorted(p.name for p in out.glob("*.parquet")) == [
        "traces-000000.parquet", "traces-000001.parquet",
    ]  # fmt: skip
    on_disk = pl.scan_parquet(out / "*.parquet").collect().sort("run_id", maintain_order=True)
    _, in_memory = run(grid={"admittance.b": [200.0, 400.0, 800.0]}, traces=True)
    assert on_disk.equals(in_memory)


def test_damaged_or_foreign_checkpoint_chunk_is_named_and_recomputed(tmp_path):
    clean = run(vary=VARY, samples=9, seed=2, chunk_size=3)
    ck = tmp_path / "ck"
    assert run(vary=VARY, samples=9, seed=2, chunk_size=3, checkpoint=ck).equals(clean)
    # Truncate chunk 1 (as a full disk or a copy cut short would) and put chunk 0's file
    # where chunk 2 belongs (a foreign file).
    damaged = ck / "chunk-000001.parquet"
    damaged.write_bytes(damaged.read_bytes()[: damaged.stat().st_size // 2])
    for suffix in ["", ".sha256"]:  # with its checksum file: intact, but not chunk 2
        (ck / f"chunk-000002.parquet{suffix}").write_bytes(
            (ck / f"chunk-000000.parquet{suffix}").read_bytes()
        )
    before = (ck / "chunk-000000.parquet").read_bytes()
    with pytest.warns(ar.CheckpointWarning) as record:
        resumed = run(vary=VARY, samples=9, seed=2, chunk_size=3, checkpoint=ck)
    messages = sorted(str(w.message) for w in record)
    assert len(messages) == 2
    # Its bytes no longer match its checksum file: named before Parquet parses them.
    assert f"checkpoint: {damaged} is damaged or not this sweep's (" in messages[0]
    assert messages[0].endswith("recomputing runs 3..5 (the file will be replaced)")
    assert messages[1] == (
        f"checkpoint: {ck / 'chunk-000002.parquet'} is not the chunk of runs 6..8 of this sweep"
        " (other run_ids); recomputing runs 6..8 (the file will be replaced)"
    )
    assert record[0].filename == __file__
    assert resumed.equals(clean)
    assert (ck / "chunk-000000.parquet").read_bytes() == before  # the good chunk was reused
    # The files were replaced: a second resume reads them all without a warning.
    assert run(vary=VARY, samples=9, seed=2, chunk_size=3, checkpoint=ck).equals(clean)


@pytest.mark.parametrize("kw", [{"threads": 1}, {"chunk_size": 2}, {"threads": 2, "chunk_size": 1}])
def test_grid_of_ints_and_floats_is_one_table_whatever_the_threads_or_chunks(kw):
    # Issue 21 item 11: b given as ints, k_a as a float then ints; a sub-batch starting at
    # k_a = 1 used to infer an Int64 column and fail on 0.1 (polars TypeError).
    sc = ar.paper.scenario("fig14").replace(duration=0.5)
    typed = ar.sweep(sc, grid={"admittance.b": [200, 400, 800], "admittance.ka": [0.1, 1, 2]},
                     progress=False, **kw)  # fmt: skip
    floats = ar.sweep(sc, grid={"admittance.b": [200.0, 400.0, 800.0],
                                "admittance.ka": [0.1, 1.0, 2.0]}, progress=False)  # fmt: skip
    assert typed.schema["admittance.b"] == pl.Float64
    assert typed.schema["admittance.ka"] == pl.Float64
    assert typed["admittance.ka"].to_list() == [0.1, 1.0, 2.0] * 3
    assert typed.equals(floats)
    # An int field keeps ints (an integral float is the same run), None stays null.
    t = ar.sweep(sc, grid={"substeps": [10.0, 20], "sensor.cutoff": [None, 30]}, chunk_size=1,
                 progress=False)  # fmt: skip
    assert t.schema["substeps"] == pl.Int64 and t.schema["sensor.cutoff"] == pl.Float64
    assert t["sensor.cutoff"].to_list() == [None, 30.0, None, 30.0]
    # A vector field: ints or floats, tuple, list or array, one normal and one dtype.
    t = ar.sweep(sc, grid={"wall.normal": [(1, 0, 0), np.array([1.0, 0.0, -0.1])]},
                 chunk_size=1, progress=False)  # fmt: skip
    assert t.schema["wall.normal"] == pl.List(pl.Float64)
    assert t["wall.normal"].to_list() == [[1.0, 0.0, 0.0], [1.0, 0.0, -0.1]]


def test_run_configs_copy_only_the_tables_they_change():
    """A sweep's runs share every table they do not vary with the base (no deep copy per
    run, a URDF text included) and never write into it."""
    import copy

    from admit_rs.config import _core_dict_with

    base = ar.paper.scenario("fig19")._to_core()
    before = copy.deepcopy(base)
    run = _core_dict_with(base, {"wall.stiffness": 5.0, "wall.gap": 0.1, "seed": 3})
    assert (run["wall"]["stiffness"], run["wall"]["gap"], run["seed"]) == (5.0, 0.1, 3)
    assert base == before
    assert run["robot"] is base["robot"] and run["wall"] is not base["wall"]
    nested = _core_dict_with(base, {"controller.model.mass_scale": 1.2})
    assert nested["controller"]["model"]["mass_scale"] == 1.2 and base == before
    assert nested["controller"]["model"] is not base["controller"]["model"]


@pytest.mark.parametrize("seed", [-1, 2**63, 2**70, True, 1.5])
def test_a_sweep_seed_outside_the_tables_int64_is_refused_up_front(seed):
    """Issue #53, item 15: a seed >= 2**63 ran a batch, then failed in polars."""
    with pytest.raises(ar.ParameterError) as info:
        run(grid={"admittance.b": [400.0]}, seed=seed)
    assert info.value.field == "seed" and info.value.allowed == "an integer from 0 to 2**63 - 1"


def test_the_largest_seed_runs():
    table = run(grid={"admittance.b": [400.0]}, seed=2**63 - 1)
    assert table["seed"].to_list() == [2**63 - 1]
