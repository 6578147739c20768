"""Two builds of admit_rs side by side, in one sitting: this checkout's against a baseline.

    python benches/ab_builds.py --baseline DIR [--rounds 3]

DIR holds another build's ``admit_rs`` package, e.g. a wheel of an earlier commit unpacked
there: ``git worktree add /tmp/base <rev> && (cd /tmp/base && maturin build --release -o
/tmp/wheel) && python -m zipfile -e /tmp/wheel/*.whl DIR``. Each figure is measured in a fresh
process, the two builds alternating round by round so that load from other jobs falls on both
alike. It prints one line per measurement and a table of medians with the ratio
this/baseline:

- ``fig14_ms``: the median of 40 ``ar.simulate(fig14)`` (one 10-s run; lower is better);
- ``fig19_runs_per_s_{1,2}t``: an 800-run fig. 19 sweep in lanes (k_e × wall error, 10 s
  each) on 1 and 2 threads (higher is better);
- ``panda_{lanes,scalar}_s``: 16 four-second Panda runs (TDC ``for_arm`` + Scheme 2) on one
  thread, in lanes and on the scalar path (lower is better).

It is not a test. The numbers are recorded in docs/performance.md.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

DATA = Path(__file__).resolve().parent.parent / "examples" / "data"
FIGURES = ("fig14", "fig19_1", "fig19_2", "panda")


def measure(what: str) -> dict[str, float]:
    """One figure, in this process (whichever admit_rs it imports)."""
    import admit_rs as ar

    if what == "fig14":
        sc = ar.paper.scenario("fig14")
        for _ in range(3):
            ar.simulate(sc)
        times = []
        for _ in range(40):
            t = time.perf_counter()
            ar.simulate(sc)
            times.append(time.perf_counter() - t)
        return {"fig14_ms": 1e3 * statistics.median(times)}
    if what.startswith("fig19"):
        threads = int(what[-1])
        base = ar.paper.scenario("fig19").replace(duration=10.0)
        vary = {
            "wall.stiffness": ar.LogUniform(1e4, 1e5),
            "wall.position_error": ar.Uniform(0, 0.01),
        }
        ar.sweep(base, vary=vary, samples=40, seed=0, threads=threads, progress=False)
        t = time.perf_counter()
        ar.sweep(base, vary=vary, samples=800, seed=0, threads=threads, progress=False, lanes=True)
        return {f"fig19_runs_per_s_{threads}t": 800 / (time.perf_counter() - t)}
    arm = ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp",
                     q0=(0, -0.785, 0, -2.356, 0, 1.571, 0.785))  # fmt: skip
    base = ar.paper.scenario("fig14").replace(
        robot=arm, controller=ar.TimeDelayControl.for_arm(arm), duration=4.0
    )
    vary = {"wall.stiffness": ar.LogUniform(1e4, 1e5)}
    ar.sweep(base, vary=vary, samples=4, seed=1, threads=1, progress=False)
    out = {}
    for lanes in (True, False):
        t = time.perf_counter()
        ar.sweep(base, vary=vary, samples=16, seed=1, threads=1, progress=False, lanes=lanes)
        out["panda_lanes_s" if lanes else "panda_scalar_s"] = time.perf_counter() - t
    return out


def run(what: str, baseline: Path | None) -> dict[str, float]:
    """`measure(what)` in a fresh process, importing the baseline's package if given."""
    env = dict(os.environ)
    if baseline is not None:
        env["PYTHONPATH"] = str(baseline)
    # Run from a neutral directory so that neither checkout's python/ shadows the other.
    out = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--one", what],
        env=env, cwd="/", check=True, capture_output=True, text=True,
    )  # fmt: skip
    result: dict[str, float] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, help="a directory holding the baseline's admit_rs")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--one", choices=FIGURES, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(args.one)))
        return
    if args.baseline is None or not (args.baseline / "admit_rs").is_dir():
        raise SystemExit("--baseline DIR must hold an admit_rs package (see the docstring)")
    got: dict[tuple[str, str], list[float]] = defaultdict(list)
    for r in range(1, args.rounds + 1):
        for what in FIGURES:
            for build, path in (("baseline", args.baseline), ("this", None)):
                for name, value in run(what, path).items():
                    got[name, build].append(value)
                    print(f"round {r} {build:8s} {name:24s} {value:10.3f}", flush=True)
    print(f"\n{'figure':24s} {'baseline':>10s} {'this':>10s} {'this/baseline':>14s}")
    for name in dict.fromkeys(n for n, _ in got):
        a, b = statistics.median(got[name, "baseline"]), statistics.median(got[name, "this"])
        print(f"{name:24s} {a:10.3f} {b:10.3f} {b / a:14.3f}")


if __name__ == "__main__":
    main()
