"""One timed fig. 19 sweep on one lane build (issue #25): 10-s runs, k_e × wall error, the
default 10 substeps (or the fourth argument), 2 threads (or the third), metrics only, after a
16-run warm-up.
Run builds in alternating fresh processes to compare them; the printed checksum must match
across builds.

    python benches/lane_builds.py avx2 10000
    python benches/lane_builds.py avx512 10000
    python benches/lane_builds.py avx512 400 1     # one thread
    python benches/lane_builds.py avx2 300 1 1     # one thread, 1 substep (the period's work)
"""

from __future__ import annotations

import sys
import time

import admit_rs as ar
from admit_rs import _core


def main() -> None:
    build, runs = sys.argv[1], int(sys.argv[2])
    threads = int(sys.argv[3]) if len(sys.argv) > 3 else 2
    substeps = int(sys.argv[4]) if len(sys.argv) > 4 else 10
    _core._lane_path(build)
    base = ar.paper.scenario("fig19").replace(duration=10.0, substeps=substeps)
    vary = {"wall.stiffness": ar.LogUniform(1e4, 1e5), "wall.position_error": ar.Uniform(0, 0.01)}
    ar.sweep(base, vary=vary, samples=16, seed=0, threads=threads, progress=False)  # warm-up
    t = time.perf_counter()
    table = ar.sweep(base, vary=vary, samples=runs, seed=0, threads=threads, progress=False)
    dt = time.perf_counter() - t
    print(f"{_core._lane_path()}: {runs} runs on {threads} thread(s) in {dt:.2f} s = "
          f"{runs / dt:.1f} runs/s, checksum {table['force_rms_error'].sum()!r}")  # fmt: skip


if __name__ == "__main__":
    main()
