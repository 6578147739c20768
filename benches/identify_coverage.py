"""How often ar.identify's intervals hold the truth (issue #58 part 2): not a timed test.

    python benches/identify_coverage.py [--seeds 20] [--surface plane|sphere]

Records the cell of examples/identify_cell.py (the Panda pressing and sliding on a wall, a
flange sensor with bias, noise, a 60 Hz low-pass and 3 samples of latency) with as many noise
seeds, fits each and counts, per path, the seeds whose 95 % interval holds the true value;
prints the median interval width relative to the truth (the centre's: the widest axis's, in
metres) and the fit's time. ``--surface sphere``: the same tool sliding over a 0.2 m ball.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import time
from pathlib import Path

import admit_rs as ar

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "identify_cell.py"
spec = importlib.util.spec_from_file_location("identify_cell", EXAMPLE)
assert spec is not None and spec.loader is not None
cell = importlib.util.module_from_spec(spec)
spec.loader.exec_module(cell)


def at_contact(fit: ar.CellFit, run: ar.Result, position: float) -> float:
    """The x of the plane n·X = ``position`` (n fitted) at the mean contact point."""
    tr = run.trace
    touching = tr["f"].to_numpy() > 0
    centre = tr.select("x", "y", "z").to_numpy()[touching].mean(axis=0)
    n = fit.values["wall.normal"]
    return float((position - n[1] * centre[1] - n[2] * centre[2]) / n[0])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--surface", choices=("plane", "sphere"), default="plane")
    args = parser.parse_args()
    seeds, sphere = args.seeds, args.surface == "sphere"
    hits: dict[str, int] = {}
    widths: dict[str, list[float]] = {}
    times = []
    for seed in range(seeds):
        log, run = cell.recording(cell.SPHERE if sphere else cell.WALL, seed=seed)
        truth = cell.sphere_truths() if sphere else cell.truths(run)
        start = time.perf_counter()
        fit = ar.identify(log, cell.ARM, surface=args.surface)
        times.append(time.perf_counter() - start)
        if sphere and "wall.centre" in fit.intervals:
            inside = all(lo <= c <= hi for (lo, hi), c in zip(fit.intervals["wall.centre"],
                                                              truth["wall.centre"], strict=True))
            hits["wall.centre"] = hits.get("wall.centre", 0) + int(inside)
            widths.setdefault("wall.centre", []).append(
                max(hi - lo for lo, hi in fit.intervals["wall.centre"]))  # fmt: skip
        for path, true in truth.items():
            if not isinstance(true, float | int) or path not in fit.intervals:
                continue
            lo, hi = fit.intervals[path]
            if path == "wall.position":
                # x_e is along the fitted n (tilted by a milliradian or so): compare the
                # fitted plane's x where the tool touched with the true plane's.
                lo, hi = at_contact(fit, run, lo), at_contact(fit, run, hi)
            hits[path] = hits.get(path, 0) + int(lo <= true <= hi)
            widths.setdefault(path, []).append((hi - lo) / abs(true))
    print(f"{seeds} seeds, identify {statistics.median(times):.1f} s (median)")
    print(f"{'path':20s} {'truth inside':>13s} {'median width / truth':>21s}")
    for path in hits:
        print(f"{path:20s} {hits[path]:>6d}/{seeds:<6d} {statistics.median(widths[path]):21.3g}")


if __name__ == "__main__":
    main()
