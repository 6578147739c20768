"""Sweep throughput against a Numba ``prange`` peer: runs/s of the 10-s fig. 19 sweep.

    python benches/sweep_compare.py [--runs 2000] [--duration 10] [--threads 1 2]
                                    [--lane-builds portable avx2 avx512]

Not a test: prints a table. The sweep is fig. 19 (TDC eq. 18 + Scheme 2, wall error) over
k_e ~ LogUniform(1e4, 1e5) × wall error ~ Uniform(0, 0.01) m, metrics only (no traces).

The peer is written here to be strong and honest: one ``@njit(parallel=True)`` function runs
the whole sweep with ``prange`` over runs; each run is the closed-form loop of
``benches/peers.py`` (the same per-period functions its fig. 14 peer uses, agreeing with
admit_rs's trace to 2e-11) with its metrics accumulated online, keeping no trace. It computes
fewer metrics than admit_rs (force_peak, force_rms_error, force_ss_error): any difference in
work favours the peer. Before anything is timed, both must agree on force_peak and
force_rms_error to 1e-9 relative on every run; the script stops otherwise.

admit_rs is timed through ``ar.sweep`` (the parameter draws, the Rust batch with the GIL
released and the Polars table included). Both run in this one process, on 1 and 2 threads.

The JAX peer (``benches/jax_peer.py``, optional: skipped with a message when jax is absent)
is the same model again, ``jax.vmap`` over runs of a ``lax.scan`` over periods, float64. It
runs in one subprocess per XLA flag setting (as shipped, and ``--xla_cpu_max_isa=AVX2``: the
flag is read when jax starts) and thread count (1: pinned to one core; 2: two host devices,
the runs sharded over them); each checks its agreement with admit_rs's table on every run
before it times (same 1e-9), and the script stops otherwise. Its compile time is reported
apart from the table; the table's JAX time is the best of ``--jax-repeats`` compiled calls.
Each lane build of ``--lane-builds`` (default: every one this CPU runs; issue #25: 4-wide
portable and AVX2, 8-wide AVX-512) gets a row too, forced through ``_core._lane_path`` after
its table was checked to be the default build's bit for bit.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import admit_rs as ar
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import jax_peer  # noqa: E402
import peers  # noqa: E402
from compare import check_preset  # noqa: E402

JAX_FLAGS = ["", "--xla_cpu_max_isa=AVX2"]

TRANSIENT, WINDOW = 1.0, 2.0


def _metrics_kernel(n, substeps, period, p, ctl, flt, ref, x0, wall_estimate, tau0, q0):
    """One run, metrics accumulated online: (force_peak, force_rms_error, force_ss_error,
    diverged)."""
    late = math.ceil(TRANSIENT / period - 1e-9)
    steady = math.ceil(((n - 1) * period - WINDOW) / period - 1e-9)
    q1, q2, q3 = q0
    w1 = w2 = w3 = 0.0
    memory = (tau0[0], tau0[1], tau0[2], 0.0, 0.0, 0.0, 0.0, 0.0)
    peak = -math.inf
    squares = 0.0
    steady_sum = 0.0
    for k in range(n):
        tau, rec, memory = _control(
            k, q1, q2, q3, w1, w2, w3, memory, period, p, ctl, flt, ref, x0, wall_estimate
        )
        force, f_d = rec[7], rec[8]
        peak = max(peak, force)
        if k >= late:
            squares += (f_d - force) * (f_d - force)
        if k >= steady:
            steady_sum += f_d - force
        if k + 1 < n:
            q1, q2, q3, w1, w2, w3 = _advance(
                q1, q2, q3, w1, w2, w3, tau[0], tau[1], tau[2], p, substeps, period
            )
            if _diverged(q1, q2, q3, w1, w2, w3, ctl[5]):
                return peak, math.nan, math.nan, True
    return peak, math.sqrt(squares / (n - late)), steady_sum / (n - steady), False


def _sweep_kernel(stiffness, wall_estimate, n, substeps, period, p, ctl, flt, ref, x0, tau0, q0):
    """Every run of the sweep, in parallel over runs (``prange``)."""
    runs = stiffness.shape[0]
    out = np.empty((runs, 3))
    diverged = np.zeros(runs, dtype=np.bool_)
    for i in numba.prange(runs):
        p_i = (
            p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11], p[12],
            stiffness[i], p[14],
        )  # fmt: skip
        peak, rms, ss, div = _metrics_kernel_jit(
            n, substeps, period, p_i, ctl, flt, ref, x0, wall_estimate[i], tau0, q0
        )
        out[i, 0] = peak
        out[i, 1] = rms
        out[i, 2] = ss
        diverged[i] = div
    return out, diverged


def _compile():
    global numba, _metrics_kernel_jit
    import numba

    _metrics_kernel_jit = peers.jit_kernel(_metrics_kernel)
    fresh = type(_sweep_kernel)(
        _sweep_kernel.__code__,
        {**_sweep_kernel.__globals__, "_metrics_kernel_jit": _metrics_kernel_jit, "numba": numba},
    )
    return numba.njit(parallel=True)(fresh)


def peer_sweep(kernel, c: peers.Fig14, stiffness: np.ndarray, error: np.ndarray):
    args = peers._kernel_args(c)
    n, substeps, period, p, ctl, flt, ref, x0, _, tau0, q0 = args
    wall = peers.setup(c).wall
    return kernel(stiffness, wall + error, n, substeps, period, p, ctl, flt, ref, x0, tau0, q0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=2000)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--jax-repeats", type=int, default=2)
    parser.add_argument("--skip-jax", action="store_true")
    parser.add_argument("--lane-builds", nargs="*", default=None)
    args = parser.parse_args()
    from admit_rs import _core

    builds = list(_core._lane_runs()) if args.lane_builds is None else args.lane_builds
    if not peers.HAVE_NUMBA:
        raise SystemExit("numba is not installed: pip install -e '.[bench]'")
    preset = ar.paper.scenario("fig19")
    check_preset(preset, peers.Fig14(position_error=0.01))
    base = preset.replace(duration=args.duration)
    c = peers.Fig14(duration=args.duration, position_error=0.01)
    vary = {"wall.stiffness": ar.LogUniform(1e4, 1e5), "wall.position_error": ar.Uniform(0, 0.01)}

    def admit(threads: int, lanes: bool = True, build: str = "auto"):
        _core._lane_path(build)
        try:
            return ar.sweep(
                base, vary=vary, samples=args.runs, seed=0, threads=threads, progress=False,
                lanes=lanes,
            )  # fmt: skip
        finally:
            _core._lane_path("auto")

    kernel = _compile()
    # Agreement first, on every run of the sweep.
    table = admit(max(args.threads))
    # The lanes agree with the scalar path (= ar.simulate) to SPEC §13's 1e-9.
    scalar_table = admit(max(args.threads), lanes=False)
    for name in ["force_peak", "force_rms_error"]:
        a, b = table[name].to_numpy(), scalar_table[name].to_numpy()
        rel = np.max(np.abs(a - b) / np.abs(b))
        print(f"lanes vs scalar {name}: max relative difference {rel:.1e}")
        if not rel <= 1e-9:
            raise SystemExit(f"lanes differ from the scalar path by {rel:.1e}: not timing")
    for build in builds:
        if not admit(max(args.threads), build=build).equals(table):
            raise SystemExit(f"the {build} lane build's table differs: not timing")
    print(f"lane builds {builds} (default {_core._lane_path()}): the same table, bit for bit")
    stiffness = table["wall.stiffness"].to_numpy().copy()
    error = table["wall.position_error"].to_numpy().copy()
    start = time.perf_counter()
    out, diverged = peer_sweep(kernel, c, stiffness, error)
    compile_s = time.perf_counter() - start
    assert not diverged.any() and not table["diverged"].any()
    for col, name in enumerate(["force_peak", "force_rms_error"]):
        ours = table[name].to_numpy()
        rel = np.max(np.abs(out[:, col] - ours) / np.abs(ours))
        print(f"agreement {name}: max relative difference {rel:.1e} over {len(ours)} runs")
        if not rel <= 1e-9:
            raise SystemExit(f"{name} differs from the peer by {rel:.1e} > 1e-9: not timing")
    jax_runs = jax_sweeps(args, table, stiffness, error)

    print(f"\n{args.runs} runs of {args.duration} s (fig19, k_e x wall error), metrics only, "
          f"{os.cpu_count()} cores; Numba compile + first sweep {compile_s:.1f} s")  # fmt: skip
    print(f"{'implementation':38s} {'threads':>7s} {'wall [s]':>9s} {'runs/s':>8s}")
    rates = {}
    # The build ar.sweep takes by default on this CPU (avx512: 8 lanes, else 4).
    default = _core._lane_path()
    default_name = f"admit_rs (lanes, ar.sweep: {default})"
    for threads in args.threads:
        for lanes, name in [(False, "admit_rs (scalar, ar.sweep)"),
                            (True, default_name)]:  # fmt: skip
            start = time.perf_counter()
            admit(threads, lanes)
            elapsed = time.perf_counter() - start
            rates[name, threads] = args.runs / elapsed
            print(f"{name:38s} {threads:7d} {elapsed:9.2f} {args.runs / elapsed:8.1f}")
        for build in builds:
            start = time.perf_counter()
            admit(threads, build=build)
            elapsed = time.perf_counter() - start
            name = f"admit_rs ({8 if build == 'avx512' else 4} lanes, {build})"
            rates[name, threads] = args.runs / elapsed
            print(f"{name:38s} {threads:7d} {elapsed:9.2f} {args.runs / elapsed:8.1f}")
        numba.set_num_threads(threads)
        start = time.perf_counter()
        peer_sweep(kernel, c, stiffness, error)
        elapsed = time.perf_counter() - start
        rates["numba", threads] = args.runs / elapsed
        print(f"{'Numba @njit(parallel=True) prange':38s} {threads:7d} {elapsed:9.2f} "
              f"{args.runs / elapsed:8.1f}")  # fmt: skip
        for flag in JAX_FLAGS if jax_runs else []:
            elapsed = min(jax_runs[flag, threads]["times_s"])
            rates["jax", flag, threads] = args.runs / elapsed
            name = f"JAX vmap+scan ({flag.lstrip('-') if flag else 'as shipped'})"
            print(f"{name:38s} {threads:7d} {elapsed:9.2f} {args.runs / elapsed:8.1f}")
    for threads in args.threads:
        lanes = rates[default_name, threads]
        scalar = rates["admit_rs (scalar, ar.sweep)", threads]
        print(f"on {threads} thread(s): lanes / Numba {lanes / rates['numba', threads]:.2f}x, "
              f"scalar / Numba {scalar / rates['numba', threads]:.2f}x, "
              f"lanes / scalar {lanes / scalar:.2f}x")  # fmt: skip
        if jax_runs:
            best = max(rates["jax", flag, threads] for flag in JAX_FLAGS)
            print(f"on {threads} thread(s): lanes / best JAX {lanes / best:.2f}x, "
                  f"scalar / best JAX {scalar / best:.2f}x")  # fmt: skip
    for (flag, threads), r in sorted(jax_runs.items()):
        print(f"JAX {flag or 'as shipped'}, {threads} thread(s): compile {r['compile_s']:.1f} s "
              f"(not in the table), XLA devices {len(r['devices'])}, "
              f"cores {r['cores']}")  # fmt: skip


def jax_sweeps(args, table, stiffness, error) -> dict:
    """The JAX peer's sessions (``jax_peer.sessions``), agreement checked in each; {} when
    jax is absent or skipped."""
    if args.skip_jax:
        return {}
    if not jax_peer.HAVE_JAX:
        print("JAX peer skipped: jax is not installed (pip install 'jax[cpu]')")
        return {}
    data = {
        "duration": args.duration,
        "stiffness": stiffness,
        "error": error,
        "force_peak": table["force_peak"].to_numpy(),
        "force_rms_error": table["force_rms_error"].to_numpy(),
    }
    reports = jax_peer.sessions(data, args.threads, args.jax_repeats, JAX_FLAGS)
    for (flag, threads), r in sorted(reports.items()):
        gaps = ", ".join(f"{k} {v:.1e}" for k, v in r["agreement"].items())
        print(f"JAX agreement ({flag or 'as shipped'}, {threads} thread(s)): max relative "
              f"difference {gaps} over {len(stiffness)} runs")  # fmt: skip
    return reports


_control = peers._control
_advance = peers._advance
_diverged = peers._diverged
numba = None
_metrics_kernel_jit = None

if __name__ == "__main__":
    main()
