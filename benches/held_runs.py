"""What the held runs of SPEC §23 cost a sweep whose runs mostly fail their criteria.

1 000 fig. 14 runs log-uniform over k_e 1e4–1e6 N/m × b 100–2 500 N·s/m (most of them fail
max_force_oscillation or max_contact_loss, so each is run again with its drives held), timed
with the held runs and with ``Criteria(held_run=False)``. Run:

    python benches/held_runs.py [RUNS] [THREADS]
"""

from __future__ import annotations

import sys
import time

import admit_rs as ar


def main(runs: int = 1000, threads: int | None = None) -> None:
    base = ar.paper.scenario("fig14")
    box = {"wall.stiffness": ar.LogUniform(1e4, 1e6), "admittance.b": ar.LogUniform(100, 2500)}
    for held in (True, False):
        sc = base.replace(**{"criteria.held_run": held})
        start = time.perf_counter()
        table = ar.sweep(sc, vary=box, samples=runs, seed=0, threads=threads, progress=False)
        elapsed = time.perf_counter() - start
        failed = int((~table["passed"]).sum())
        print(f"held_run={held}: {runs} runs in {elapsed:.2f} s ({failed} failing their "
              f"criteria, {table['stable'].null_count()} with stability not told)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1000,
         int(sys.argv[2]) if len(sys.argv) > 2 else None)
