"""What ``substeps="auto"`` chooses and what it costs (issue #25 part 2, docs/substeps.md).

    python benches/substeps_auto.py            # choices, errors and single-run times
    python benches/substeps_auto.py --sweep 10000   # + fig. 19 sweeps: auto vs fixed counts

Not a test: prints tables. For fig. 14, fig. 19, the UR5 and the Panda (10-s runs, k_e = 3e4)
at tolerance 1e-4 and 1e-6 N: the count chosen, the counts tried, the estimate, the true
error against 100 substeps, and the time of the auto run beside the fixed runs at the
default 10 and at the chosen count (fastest of ``--repeats``). With ``--sweep N``: N fig. 19
runs (``examples/stiffness_sweep.py``'s distribution) at auto 1e-4 and at fixed 10 and 3,
on all cores, in lanes.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import admit_rs as ar
import numpy as np

DATA = Path(__file__).resolve().parent.parent / "examples" / "data"


def cases() -> dict[str, ar.Scenario]:
    ur5 = ar.UrdfArm(DATA / "ur5.urdf", "tool0",
                     q0=(0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0))  # fmt: skip
    panda = ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp",
                       q0=(0, -0.785, 0, -2.356, 0, 1.571, 0.785))  # fmt: skip
    fig14 = ar.paper.scenario("fig14")
    return {
        "fig14": fig14,
        "fig19": ar.paper.scenario("fig19"),
        "ur5": fig14.replace(robot=ur5, controller=ar.TimeDelayControl.for_arm(ur5)),
        "panda": fig14.replace(robot=panda, controller=ar.TimeDelayControl.for_arm(panda)),
    }


def best(f, repeats: int) -> tuple[float, object]:
    out, times = None, []
    for _ in range(repeats):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


def gap(a, b) -> float:
    if a.height != b.height:
        return float("inf")
    return max(float(np.max(np.abs(a[c].to_numpy() - b[c].to_numpy()))) for c in ("f", "f_t"))


def singles(repeats: int) -> None:
    print("| case | tolerance | chosen | tried | estimate | true (vs 100) | auto | fixed 10 | "
          "fixed chosen |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for name, sc in cases().items():
        reference = ar.simulate(sc.replace(substeps=100))
        t10, _ = best(lambda sc=sc: ar.simulate(sc.replace(substeps=10)), repeats)
        for tol in (1e-4, 1e-6):
            auto = sc.replace(substeps="auto", tolerance=tol)
            t_auto, r = best(lambda auto=auto: ar.simulate(auto), repeats)
            fixed = sc.replace(substeps=r.substeps)
            t_n, _ = best(lambda fixed=fixed: ar.simulate(fixed), repeats)
            tried = (r.substep_note or "").rsplit("tried ", 1)[-1].rstrip(")")
            print(f"| {name} | {tol:g} N | {r.substeps} | {tried} | {r.substep_error:.2e} | "
                  f"{gap(r.trace, reference.trace):.2e} | {t_auto * 1e3:.1f} ms | "
                  f"{t10 * 1e3:.1f} ms | {t_n * 1e3:.1f} ms |", flush=True)  # fmt: skip


def sweeps(n: int) -> None:
    base = ar.paper.scenario("fig19")
    vary = {"wall.stiffness": ar.LogUniform(1e4, 1e5),
            "wall.position_error": ar.Uniform(-0.02, 0.02)}  # fmt: skip
    kw = {"vary": vary, "seed": 0, "progress": False}
    ar.sweep(base, samples=64, **kw)  # warm-up
    runs = [("auto, tolerance 1e-4 N", base.replace(substeps="auto", tolerance=1e-4)),
            ("fixed 10 (default)", base), ("fixed 3", base.replace(substeps=3))]  # fmt: skip
    for label, sc in runs:
        t = time.perf_counter()
        table = ar.sweep(sc, samples=n, **kw)
        dt = time.perf_counter() - t
        used = table["substeps_used"].value_counts().sort("substeps_used").rows()
        print(f"{label}: {n} runs in {dt:.2f} s ({n / dt:.0f} runs/s); substeps used {used}",
              flush=True)  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--sweep", type=int, default=0)
    a = p.parse_args()
    lines = Path("/proc/cpuinfo").read_text().splitlines()
    cpu = next((line.split(":", 1)[1].strip() for line in lines
                if line.startswith("model name")), platform.processor())  # fmt: skip
    print(f"{cpu}, {os.cpu_count()} cores, lane build {ar._core._lane_path()}")
    singles(a.repeats)
    if a.sweep:
        sweeps(a.sweep)


if __name__ == "__main__":
    main()
