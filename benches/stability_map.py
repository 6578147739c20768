"""How long a 40×40 stability map takes (issue #11: ≤ 2 s on this 2-core machine), against
the same 1 600 cells simulated as 10-s sweeps.

    python benches/stability_map.py [--sweep]      # --sweep also times the 1 600 runs

Prints the median of 3 map timings (fig. 14's setup, k_e × b, log-spaced), its per-cell
cost, the share of cells with a prediction, and with --sweep the simulated time.
"""

from __future__ import annotations

import os
import statistics
import sys
import time

import admit_rs as ar
import numpy as np


def main() -> None:
    sc = ar.paper.scenario("fig14")
    ke = [float(v) for v in np.geomspace(1e4, 1e6, 40)]
    b = [float(v) for v in np.geomspace(50, 2000, 40)]
    print(f"cores: {os.cpu_count()}")
    for friction in ("rest", "step"):
        times = []
        for _ in range(3):
            start = time.perf_counter()
            t = ar.analysis.stability_map(sc, x={"wall.stiffness": ke}, y={"admittance.b": b},
                                          friction=friction)  # fmt: skip
            times.append(time.perf_counter() - start)
        med = statistics.median(times)
        ok = t["error"].is_null().sum()
        print(f"40x40 map, friction={friction!r}: median {med:.2f} s of {len(times)} "
              f"({[round(x, 2) for x in times]}), {1e3 * med / t.height:.2f} ms per cell, "
              f"{ok}/{t.height} cells predicted, {int(t['stable'].sum())} stable")
    if "--sweep" in sys.argv:
        start = time.perf_counter()
        sw = ar.sweep(sc, grid={"admittance.b": b, "wall.stiffness": ke}, progress=False)
        print(f"the same 1 600 cells simulated (10 s each): {time.perf_counter() - start:.1f} s,"
              f" {int(sw['stable'].sum())} stable")


if __name__ == "__main__":
    main()
