"""Where a curved surface's and friction's cost goes (issue #22): the plane run against the
plane with friction, a sphere believed flat and believed a sphere, each with and without
friction, the plane believed a (nearly flat) sphere, and the scanned part of
examples/polishing.py believed flat, believed right, and with friction; one run at a time
and in lanes.

    python benches/surface_costs.py [--repeats 7] [--runs 64] [--arm paper|panda]

Not a test: prints each variant's median time and its ratio to the plane, timed in
alternation. ``benches/surfaces.py`` states issue #22's targets; this script splits its
"sphere, μ = 0.3" ratio into friction, the sphere's contact geometry (the shared RK4 loop of
every non-plane surface) and the curved belief (docs/performance-history.md §16).
"""

from __future__ import annotations

import argparse
import dataclasses

import admit_rs as ar
from surfaces import DATA, report, scanned_part


def variants(arm: str) -> dict[str, ar.Scenario]:
    base = ar.paper.scenario("fig14")
    if arm == "panda":
        panda = ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp",
                           q0=(0, -0.785, 0, -2.356, 0, 1.571, 0.785))  # fmt: skip
        base = base.replace(robot=panda, controller=ar.TimeDelayControl.for_arm(panda))
    sphere = ar.Sphere(radius=0.3, friction=0.3)
    smooth = ar.Sphere(radius=0.3)
    part = scanned_part()
    return {
        "plane": base,
        "plane, μ = 0.3": base.replace(**{"wall.friction": 0.3}),
        "sphere, μ = 0, believed flat": base.replace(wall=smooth, wall_estimate=ar.Wall()),
        "sphere, μ = 0.3, believed flat": base.replace(wall=sphere, wall_estimate=ar.Wall()),
        "sphere, μ = 0, believed a sphere": base.replace(wall=smooth),
        "sphere, μ = 0.3, believed a sphere": base.replace(wall=sphere),
        "plane, believed a sphere (R = 1 km)": base.replace(wall_estimate=ar.Sphere(radius=1e3)),
        "height field, μ = 0, believed flat": base.replace(wall=part, wall_estimate=ar.Wall()),
        "height field, μ = 0": base.replace(wall=part),
        "height field, μ = 0.3": base.replace(wall=dataclasses.replace(part, friction=0.3)),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--runs", type=int, default=64, help="runs per lane sweep")
    ap.add_argument("--arm", choices=("paper", "panda"), default="paper")
    args = ap.parse_args()
    scenarios = variants(args.arm)
    report(scenarios, args.runs, args.repeats, f"{args.arm} arm; 10-s fig. 14 runs")


if __name__ == "__main__":
    main()
