"""The 7-joint sweep of issue #12: the Panda's runs in SIMD lanes against the scalar path.

16 four-second runs of fig. 14's task on the Panda (TDC for the arm + Scheme 2, wall
stiffness drawn from 1e4–1e5 N/m), one thread, metrics only; each path twice, best of two.
The target is lanes ≥ 2.5× scalar (docs/performance-history.md §10).

    python benches/panda_lanes.py
    ADMIT_RS_LANES=avx512 python benches/panda_lanes.py   # a lane build forced (issue #25)
"""

from __future__ import annotations

import time
from pathlib import Path

import admit_rs as ar

DATA = Path(__file__).resolve().parent.parent / "examples" / "data"


def main() -> None:
    arm = ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp",
                     q0=(0, -0.785, 0, -2.356, 0, 1.571, 0.785))  # fmt: skip
    base = ar.paper.scenario("fig14").replace(
        robot=arm, controller=ar.TimeDelayControl.for_arm(arm), duration=4.0
    )
    vary = {"wall.stiffness": ar.LogUniform(1e4, 1e5)}
    ar.sweep(base, vary=vary, samples=4, seed=1, threads=1, progress=False)  # warm-up
    best: dict[bool, float] = {}
    tables = {}
    for _ in range(2):
        for lanes in (True, False):
            t = time.perf_counter()
            tables[lanes] = ar.sweep(
                base, vary=vary, samples=16, seed=1, threads=1, progress=False, lanes=lanes
            )
            best[lanes] = min(best.get(lanes, float("inf")), time.perf_counter() - t)
    assert tables[True]["stable"].all() and tables[False]["stable"].all()
    gap = max(
        abs(a - b) / abs(b)
        for a, b in zip(tables[True]["force_peak"], tables[False]["force_peak"], strict=True)
    )
    print(f"lanes vs scalar force_peak: max relative difference {gap:.1e}")
    build = ar._core._lane_path()
    print(f"Panda, 16 runs of 4 s, 1 thread: lanes ({build} build) {best[True]:.3f} s, "
          f"scalar {best[False]:.3f} s")  # fmt: skip
    print(f"lanes / scalar {best[False] / best[True]:.2f}x (target 2.5x)")


if __name__ == "__main__":
    main()
