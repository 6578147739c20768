"""Predicted against simulated verdicts with the motion running (issue #54, SPEC §23).

On fig. 14 and fig. 8 with their sine motion, a k_e × b × latency grid (5 × 4 × 2 = 40
cells each): how often ``analysis.predict``'s ``stable`` agrees with the simulated
``stable`` (the loop's dynamics) and with the simulated ``passed`` (the criteria), and how
many simulated runs are out of tolerance (stable, not passed). Run:

    python examples/stable_or_out_of_tolerance.py
"""

from __future__ import annotations

import itertools
import time

import admit_rs as ar
import polars as pl

STIFFNESS = [1e4, 3.2e4, 1e5, 3.2e5, 1e6]
DAMPING = [100.0, 400.0, 1000.0, 2500.0]
LATENCY = [0, 3]


def grid(figure: str) -> pl.DataFrame:
    base = ar.paper.scenario(figure)
    cells = [{"wall.stiffness": k, "admittance.b": b, "sensor.latency": lat}
             for lat, b, k in itertools.product(LATENCY, DAMPING, STIFFNESS)]
    table = ar.sweep(base, grid={"wall.stiffness": STIFFNESS, "admittance.b": DAMPING,
                                 "sensor.latency": LATENCY}, progress=False)
    predicted = []
    for cell in cells:
        try:
            predicted.append(ar.analysis.predict(base.replace(**cell))["stable"])
        except ar.AnalysisError:
            predicted.append(None)
    pred = pl.DataFrame({**{k: [c[k] for c in cells] for k in cells[0]},
                         "predicted_stable": predicted})
    return table.join(pred, on=list(cells[0]))


def main() -> None:
    for figure in ("fig14", "fig8"):
        start = time.perf_counter()
        t = grid(figure)
        n = t.height
        agree_stable = int((t["predicted_stable"] == t["stable"]).sum())
        agree_passed = int((t["predicted_stable"] == t["passed"]).sum())
        out_of_tolerance = int((t["stable"] & ~t["passed"]).sum())
        unstable = int((~t["stable"]).sum())
        no_prediction = t["predicted_stable"].null_count()
        print(f"{figure}: {n} cells in {time.perf_counter() - start:.1f} s; predicted `stable` "
              f"agrees with simulated `stable` on {agree_stable}/{n}, with simulated `passed` "
              f"on {agree_passed}/{n}; simulated: {unstable} unstable, {out_of_tolerance} out "
              f"of tolerance; {no_prediction} cells without a prediction")
        for row in t.filter(t["predicted_stable"] != t["stable"]).iter_rows(named=True):
            print(f"  k_e = {row['wall.stiffness']:.3g}, b = {row['admittance.b']:g}, latency "
                  f"{row['sensor.latency']}: predicted {row['predicted_stable']}, simulated "
                  f"{row['stable']}: {row['verdict'][:150]}")


if __name__ == "__main__":
    main()
