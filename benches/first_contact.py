"""The cost of the guarded approach and the adaptive filter (issue #23): a 10-s fig. 14 run
plain, with ``AdmittanceFilter.adaptive`` and with ``GuardedApproach()``, scalar
(``ar.simulate``, best of ``--repeat`` rounds) and in lanes (``ar.sweep`` of ``--samples`` runs over
the wall stiffness, no traces, best of every fifth round).

    PYTHONPATH=python python benches/first_contact.py [--repeat 15] [--samples 64]

The ratio to the plain run is what docs/performance.md states (target ≤ 1.1×).
"""

from __future__ import annotations

import argparse
import math
import time

import admit_rs as ar


def cases() -> dict[str, ar.Scenario]:
    fig14 = ar.paper.scenario("fig14")
    return {
        "plain fig. 14": fig14,
        "adaptive filter": fig14.replace(admittance=ar.AdmittanceFilter.adaptive()),
        "guarded approach": fig14.replace(approach=ar.GuardedApproach()),
        "guarded approach, 5 mm gap": fig14.replace(
            approach=ar.GuardedApproach(), **{"wall.gap": 0.005}),
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
