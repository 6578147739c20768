"""Builds of admit_rs side by side, in one sitting: this checkout's against one or more others.

    python benches/ab_builds.py --baseline DIR [DIR ...] [--rounds 3] [--figures fig14,fig19_1]

DIR holds another build's ``admit_rs`` package, e.g. a wheel of an earlier commit unpacked
there: ``git worktree add /tmp/base <rev> && (cd /tmp/base && maturin build --release -o
/tmp/wheel) && python -m zipfile -e /tmp/wheel/*.whl DIR``. Each figure is measured in a fresh
process, the builds alternating round by round so that load from other jobs falls on both
alike. It prints one line per measurement and a table of medians with the ratio
this/baseline (with several baseline directories, all of them alternate with this build
and every ratio is to the first):

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
    parser.add_argument(
        "--baseline", type=Path, nargs="+", help="directories holding other builds' admit_rs"
    )
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--figures", default=",".join(FIGURES), help="comma-separated subset")
    parser.add_argument("--one", choices=FIGURES, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(args.one)))
        return
    if not args.baseline or not all((d / "admit_rs").is_dir() for d in args.baseline):
        raise SystemExit("--baseline DIR must hold an admit_rs package (see the docstring)")
    figures = [f for f in args.figures.split(",") if f]
    unknown = sorted(set(figures) - set(FIGURES))
    if unknown:
        raise SystemExit(f"--figures: unknown {unknown}; choose from {list(FIGURES)}")
    builds: list[tuple[str, Path | None]] = [(str(d), d) for d in args.baseline]
    builds.append(("this", None))
    got: dict[tuple[str, str], list[float]] = defaultdict(list)
    for r in range(1, args.rounds + 1):
        for what in figures:
            for build, path in builds:
                for name, value in run(what, path).items():
                    got[name, build].append(value)
                    print(f"round {r} {build:24s} {name:24s} {value:10.3f}", flush=True)
    print(f"\n{'figure':24s} {'build':24s} {'median':>10s} {'/ first':>8s}")
    for name in dict.fromkeys(n for n, _ in got):
        first = statistics.median(got[name, builds[0][0]])
        for build, _ in builds:
            m = statistics.median(got[name, build])
            print(f"{name:24s} {build:24s} {m:10.3f} {m / first:8.3f}")


if __name__ == "__main__":
    main()
