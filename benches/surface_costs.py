"""Where a curved surface's and friction's cost goes (issue #22): the plane run against the
plane with friction, a sphere believed flat and believed a sphere, each with and without
friction, and the plane believed a (nearly flat) sphere, one run at a time and in lanes.

    python benches/surface_costs.py [--repeats 7] [--runs 64] [--arm paper|panda]

Not a test: prints each variant's median time and its ratio to the plane, timed in
alternation. ``benches/surfaces.py`` states issue #22's targets; this script splits its
"sphere, μ = 0.3" ratio into friction, the sphere's contact geometry (the shared RK4 loop of
every non-plane surface) and the curved belief (docs/performance.md §16).
"""

from __future__ import annotations

import argparse

import admit_rs as ar
from surfaces import DATA, alternated


def variants(arm: str) -> dict[str, ar.Scenario]:
    base = ar.paper.scenario("fig14")
    if arm == "panda":
        panda = ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp",
                           q0=(0, -0.785, 0, -2.356, 0, 1.571, 0.785))  # fmt: skip
        base = base.replace(robot=panda, controller=ar.TimeDelayControl.for_arm(panda))
    sphere = ar.Sphere(radius=0.3, friction=0.3)
    smooth = ar.Sphere(radius=0.3)
    return {
        "plane": base,
        "plane, μ = 0.3": base.replace(**{"wall.friction": 0.3}),
        "sphere, μ = 0, believed flat": base.replace(wall=smooth, wall_estimate=ar.Wall()),
        "sphere, μ = 0.3, believed flat": base.replace(wall=sphere, wall_estimate=ar.Wall()),
        "sphere, μ = 0, believed a sphere": base.replace(wall=smooth),
        "sphere, μ = 0.3, believed a sphere": base.replace(wall=sphere),
        "plane, believed a sphere (R = 1 km)": base.replace(wall_estimate=ar.Sphere(radius=1e3)),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--runs", type=int, default=64, help="runs per lane sweep")
    ap.add_argument("--arm", choices=("paper", "panda"), default="paper")
    args = ap.parse_args()
    scenarios = variants(args.arm)
    grid = {"wall.stiffness": [2e4 + 1e3 * i for i in range(args.runs)]}
    jobs = {
        "scalar": lambda sc: ar.simulate(sc),
        "lanes": lambda sc: ar.sweep(sc, grid=grid, progress=False, threads=1),
    }
    print(f"admit_rs {ar.__version__}; {args.arm} arm; 10-s fig. 14 runs; "
          f"median of {args.repeats}; lanes build {ar._core._lane_path()}")  # fmt: skip
    print(f"{'variant':38} {'path':7} {'time [ms]':>10} {'× plane':>8}")
    for path, job in jobs.items():
        medians = alternated(scenarios, job, args.repeats)
        plane = medians["plane"]
        for name, t in medians.items():
            print(f"{name:38} {path:7} {t * 1e3:10.2f} {t / plane:8.3f}")


if __name__ == "__main__":
    main()
