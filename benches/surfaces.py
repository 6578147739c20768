"""What a curved surface and friction cost (issue #22): runs/s on a plane, on a sphere with
friction and on a height field with friction, one run at a time and in lanes.

    python benches/surfaces.py [--repeats 7] [--runs 64] [--duration 10] [--arm paper|panda]

Not a test: prints a table. The scenario is fig. 14 (TDC + Scheme 2, 10 N, a 0.05 m sine
along the surface), on the paper's arm or (``--arm panda``) on the Panda with TDC
``for_arm``, as ``benches/panda_lanes.py`` runs it. The sphere has R = 0.3 m and μ = 0.3; the
height field is a 41×41 grid at 5 mm (the scanned part of examples/polishing.py) with μ = 0.3;
the controller believes the true shape in both (the curved belief of SPEC §15). Each variant
is timed in alternation with the plane, median of ``--repeats``; the ratios are what issue
#22's targets are stated in (sphere with friction ≤ 1.15×, height field ≤ 1.3× the plane,
scalar and in lanes).
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from pathlib import Path

import admit_rs as ar

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples"))
from polishing import scanned_part  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "examples" / "data"


def variants(duration: float, arm: str) -> dict[str, ar.Scenario]:
    base = ar.paper.scenario("fig14").replace(duration=duration)
    if arm == "panda":
        panda = ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp",
                           q0=(0, -0.785, 0, -2.356, 0, 1.571, 0.785))  # fmt: skip
        base = base.replace(robot=panda, controller=ar.TimeDelayControl.for_arm(panda))
    return {
        "plane": base,
        "sphere, μ = 0.3": base.replace(wall=ar.Sphere(radius=0.3, friction=0.3)),
        "height field, μ = 0.3": base.replace(
            wall=dataclasses.replace(scanned_part(), friction=0.3)
        ),
    }


def timed(f) -> float:
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


def alternated(scenarios: dict[str, ar.Scenario], job, repeats: int) -> dict[str, float]:
    """Each scenario's median time under ``job`` over ``repeats`` rounds, the scenarios
    alternated within a round (so that load drifts hit all), after one warm-up each."""
    times: dict[str, list[float]] = {name: [] for name in scenarios}
    for sc in scenarios.values():
        job(sc)  # warm-up
    for _ in range(repeats):
        for name, sc in scenarios.items():
            times[name].append(timed(lambda sc=sc: job(sc)))
    return {name: statistics.median(t) for name, t in times.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--runs", type=int, default=64, help="runs per lane sweep")
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--arm", choices=("paper", "panda"), default="paper")
    args = ap.parse_args()
    scenarios = variants(args.duration, args.arm)
    report(scenarios, args.runs, args.repeats, f"{args.arm} arm; {args.duration:g}-s runs")


def report(scenarios: dict[str, ar.Scenario], runs: int, repeats: int, what: str) -> None:
    """Prints each scenario's median time and its ratio to ``scenarios["plane"]``, one run
    at a time (``ar.simulate``) and in lanes (a ``runs``-run sweep over the wall stiffness
    on one thread)."""
    grid = {"wall.stiffness": [2e4 + 1e3 * i for i in range(runs)]}
    jobs = {
        "scalar": lambda sc: ar.simulate(sc),
        "lanes": lambda sc: ar.sweep(sc, grid=grid, progress=False, threads=1),
    }
    print(f"admit_rs {ar.__version__}; {what}; median of {repeats}; "
          f"lanes build {ar._core._lane_path()}")  # fmt: skip
    width = max(len(name) for name in scenarios)
    print(f"{'variant':{width}} {'path':7} {'time [ms]':>10} {'× plane':>8}")
    for path, job in jobs.items():
        medians = alternated(scenarios, job, repeats)
        plane = medians["plane"]
        for name, t in medians.items():
            print(f"{name:{width}} {path:7} {t * 1e3:10.2f} {t / plane:8.3f}")


if __name__ == "__main__":
    main()
