"""Predicted against simulated answers with the motion running (issue #54, SPEC §23).

On fig. 14 and fig. 8 with their sine motion, a k_e × b × latency grid (5 × 4 × 2 = 40
cells each): how often ``analysis.predict``'s ``stable`` agrees with the simulated
``stable`` (the loop's dynamics), how often its ``passed`` (the forced response with the
motion running, docs/analysis.md §3b) agrees with the simulated ``passed`` (the criteria),
and how close the predicted ``force_oscillation`` is to the simulated one on cells stable
in both. Run:

    python examples/stable_or_out_of_tolerance.py
"""

from __future__ import annotations

import itertools
import math
import time

import admit_rs as ar
import polars as pl

STIFFNESS = [1e4, 3.2e4, 1e5, 3.2e5, 1e6]
DAMPING = [100.0, 400.0, 1000.0, 2500.0]
LATENCY = [0, 3]
CLOSE = 0.3
"""Predicted force oscillation within 30 % of the simulated one counts as close."""


def grid(figure: str) -> pl.DataFrame:
    base = ar.paper.scenario(figure)
    cells = [{"wall.stiffness": k, "admittance.b": b, "sensor.latency": lat}
             for lat, b, k in itertools.product(LATENCY, DAMPING, STIFFNESS)]
    table = ar.sweep(base, grid={"wall.stiffness": STIFFNESS, "admittance.b": DAMPING,
                                 "sensor.latency": LATENCY}, progress=False)
    rows = []
    for cell in cells:
        p = ar.analysis.predict(base.replace(**cell))
        rows.append({**cell, "predicted_stable": p["stable"], "predicted_passed": p["passed"],
                     "predicted_oscillation": p["force_oscillation"],
                     "predicted_verdict": p["tolerance_verdict"]})
    return table.join(pl.DataFrame(rows), on=list(cells[0]))


def main() -> None:
    for figure in ("fig14", "fig8"):
        start = time.perf_counter()
        t = grid(figure)
        n = t.height
        agree_stable = int((t["predicted_stable"] == t["stable"]).sum())
        agree_passed = int((t["predicted_passed"] == t["passed"]).fill_null(False).sum())
        both = t.filter(t["stable"] & t["predicted_oscillation"].is_finite())
        ratio = both["predicted_oscillation"] / both["force_oscillation"]
        close = int(((ratio - 1).abs() <= CLOSE).sum())
        print(f"{figure}: {n} cells in {time.perf_counter() - start:.1f} s; predicted `stable` "
              f"agrees with simulated `stable` on {agree_stable}/{n}; predicted `passed` "
              f"with simulated `passed` on {agree_passed}/{n}; predicted force oscillation "
              f"within {CLOSE:.0%} of the simulated on {close}/{both.height} cells stable in "
              f"both (ratio {ratio.min():.2f}–{ratio.max():.2f})")
        differs = (t["predicted_passed"] != t["passed"]).fill_null(True)
        for row in t.filter(differs).iter_rows(named=True):
            print(f"  passed differs at k_e = {row['wall.stiffness']:.3g}, b = "
                  f"{row['admittance.b']:g}, latency {row['sensor.latency']}: predicted "
                  f"{row['predicted_passed']} ({row['predicted_verdict'][:90]}), simulated "
                  f"{row['passed']} ({row['verdict'][:90]})")
        for row in both.iter_rows(named=True):
            r = row["predicted_oscillation"] / row["force_oscillation"]
            if not math.isfinite(r) or abs(r - 1) > CLOSE:
                print(f"  oscillation off at k_e = {row['wall.stiffness']:.3g}, b = "
                      f"{row['admittance.b']:g}, latency {row['sensor.latency']}: predicted "
                      f"{row['predicted_oscillation']:.4f}, simulated "
                      f"{row['force_oscillation']:.4f} ({r:.2f}x)")


if __name__ == "__main__":
    main()
