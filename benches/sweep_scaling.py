"""Sweep throughput: runs/s on 1 and N threads, and on a Dask LocalCluster.

    python benches/sweep_scaling.py [--samples 200] [--duration 10]

Not a test: prints a table. Every configuration computes the same sweep (fig. 19 over
stiffness × wall error) and the tables are checked to be identical.
"""

from __future__ import annotations

import argparse
import os
import time

import admit_rs as ar


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--samples", type=int, default=200)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--skip-dask", action="store_true")
    args = parser.parse_args()
    base = ar.paper.scenario("fig19").replace(duration=args.duration)
    vary = {
        "wall.stiffness": ar.LogUniform(1e4, 1e5),
        "wall.position_error": ar.Uniform(0.0, 0.01),
    }

    def timed(**kw: object) -> tuple[float, object]:
        start = time.perf_counter()
        table = ar.sweep(base, vary=vary, samples=args.samples, seed=0, progress=False, **kw)
        return time.perf_counter() - start, table

    cores = os.cpu_count() or 1
    rows = []
    reference = None
    for threads in sorted({1, cores}):
        elapsed, table = timed(threads=threads)
        reference = reference if reference is not None else table
        assert table.equals(reference), "tables differ between thread counts"
        rows.append((f"rayon, {threads} thread(s)", elapsed))
    if not args.skip_dask:
        from dask.distributed import Client, LocalCluster

        start = time.perf_counter()
        with (
            LocalCluster(
                n_workers=cores, threads_per_worker=1, processes=True, dashboard_address=None
            ) as cluster,
            Client(cluster) as client,
        ):
            startup = time.perf_counter() - start
            elapsed, table = timed(client=client, chunk_size=max(1, args.samples // (4 * cores)))
        assert table.equals(reference), "Dask table differs from the local one"
        rows.append((f"Dask LocalCluster, {cores} workers (+{startup:.1f} s start-up)", elapsed))
    n = args.samples
    print(f"{n} runs of {args.duration} s (fig19 over k_e x wall error), {cores} cores")
    print(f"{'configuration':55s} {'wall [s]':>9s} {'runs/s':>8s} {'speed-up':>9s}")
    for name, elapsed in rows:
        print(f"{name:55s} {elapsed:9.2f} {n / elapsed:8.1f} {rows[0][1] / elapsed:9.2f}")


if __name__ == "__main__":
    main()
