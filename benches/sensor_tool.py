"""The cost of the 3-axis sensor and a tool (issue #22 part 4, SPEC §15): a 10-s fig. 14 run
with the one-axis sensor, with a tool, with the tip-frame sensor (ideal, and noisy with a
low-pass and latency) and with both, scalar (``ar.simulate``, best of ``--repeat`` rounds) and in
lanes (``ar.sweep`` of ``--samples`` runs over the wall stiffness, no traces, one thread,
best of every fifth round).

    python benches/sensor_tool.py [--repeat 15] [--samples 64]

Prints each case's time and its ratio to the plain run (docs/performance.md).
"""

from __future__ import annotations

import argparse
import math
import time

import admit_rs as ar


def cases() -> dict[str, ar.Scenario]:
    fig14 = ar.paper.scenario("fig14")
    noisy = {"noise_std": 0.05, "cutoff": 100.0, "latency": 1}
    return {
        "plain fig. 14": fig14,
        "tool 1 kg (one axis)": fig14.replace(sensor=ar.ForceSensor(tool_mass=1.0)),
        "tip frame, ideal": fig14.replace(sensor=ar.ForceSensor(frame="tip")),
        "one axis, noisy": fig14.replace(sensor=ar.ForceSensor(**noisy)),
        "tip frame, noisy": fig14.replace(sensor=ar.ForceSensor(frame="tip", **noisy)),
        "tip frame, noisy, tool": fig14.replace(
            sensor=ar.ForceSensor(frame="tip", tool_mass=1.0, **noisy)),
    }


def best(f, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--samples", type=int, default=64)
    args = parser.parse_args()
    # Rounds over every case, interleaved (a warm-up round first, not counted), so that
    # warm-up, clock changes and load from other jobs hit the cases alike; best per case.
    items = list(cases().items())
    vary = {"wall.stiffness": ar.Uniform(2e4, 4e4)}
    scalar = {name: math.inf for name, _ in items}
    lanes = {name: math.inf for name, _ in items}
    for round_ in range(args.repeat + 1):
        for name, sc in items:
            t = best(lambda sc=sc: ar.simulate(sc), 1)
            if round_ and round_ % 5 == 0:
                t_lanes = best(lambda sc=sc: ar.sweep(sc, vary=vary, samples=args.samples,
                                                      seed=0, threads=1, progress=False), 1)
                lanes[name] = min(lanes[name], t_lanes / args.samples)
            if round_:
                scalar[name] = min(scalar[name], t)
    rows = [(name, scalar[name], lanes[name]) for name, _ in items]
    plain = rows[0]
    print(f"{'case':30s} {'scalar [ms]':>12s} {'ratio':>6s} {'lanes [ms/run]':>15s} {'ratio':>6s}")
    for name, scalar, lane in rows:
        print(f"{name:30s} {1e3 * scalar:12.2f} {scalar / plain[1]:6.2f} {1e3 * lane:15.2f} "
              f"{lane / plain[2]:6.2f}")


if __name__ == "__main__":
    main()
