"""Times scenarios against the first of them, interleaved: what benches/first_contact.py and
benches/sensor_tool.py share (a helper module, not a bench).

Each round runs every case once through ``ar.simulate`` (scalar; a warm-up round first, not
counted) and, every fifth round, as a one-thread ``ar.sweep`` of ``samples`` runs over the
wall stiffness without traces (lanes), so that warm-up, clock changes and load from other jobs
hit the cases alike. Each case keeps its best time.
"""

from __future__ import annotations

import argparse
import math
import time

import admit_rs as ar


def _once(f) -> float:
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


def time_cases(cases: dict[str, ar.Scenario], repeat: int, samples: int) -> list[tuple]:
    """(name, best scalar seconds, best lane seconds per run) of each case, in order."""
    vary = {"wall.stiffness": ar.Uniform(2e4, 4e4)}
    scalar = dict.fromkeys(cases, math.inf)
    lanes = dict.fromkeys(cases, math.inf)
    for round_ in range(repeat + 1):
        for name, sc in cases.items():
            t = _once(lambda sc=sc: ar.simulate(sc))
            if round_ and round_ % 5 == 0:
                t_lanes = _once(lambda sc=sc: ar.sweep(sc, vary=vary, samples=samples, seed=0,
                                                       threads=1, progress=False))  # fmt: skip
                lanes[name] = min(lanes[name], t_lanes / samples)
            if round_:
                scalar[name] = min(scalar[name], t)
    return [(name, scalar[name], lanes[name]) for name in cases]


def print_ratios(rows: list[tuple]) -> None:
    """Each case's times and their ratios to the first case's."""
    plain = rows[0]
    print(f"{'case':30s} {'scalar [ms]':>12s} {'ratio':>6s} {'lanes [ms/run]':>15s} {'ratio':>6s}")
    for name, scalar, lane in rows:
        print(f"{name:30s} {1e3 * scalar:12.2f} {scalar / plain[1]:6.2f} {1e3 * lane:15.2f} "
              f"{lane / plain[2]:6.2f}")


def main(cases: dict[str, ar.Scenario]) -> None:
    """The command line of a bench built on this module: ``--repeat`` rounds, ``--samples``
    runs per lane sweep."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--samples", type=int, default=64)
    args = parser.parse_args()
    print_ratios(time_cases(cases, args.repeat, args.samples))
