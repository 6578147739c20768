"""Peak memory of a sweep over a height field (issue #53, item 16): each run's grid used
to be decoded and interpolated anew, 720 KB of heights and 2.9 MB of Hermite nodes per run
for a 300 × 300 grid. Runs in a fresh process and prints the growth of its peak resident
set across the sweep.

    python benches/height_field_memory.py [--size 300] [--runs 256] [--twin]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import textwrap


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=300)
    parser.add_argument("--runs", type=int, default=256)
    parser.add_argument("--twin", action="store_true")
    args = parser.parse_args()
    script = textwrap.dedent(f"""
        import resource, time
        import numpy as np
        import admit_rs as ar
        n = {args.size}
        u = np.linspace(-1.0, 1.0, n)
        heights = 0.002 * np.sin(3 * u)[:, None] * np.cos(2 * u)[None, :]
        field = ar.HeightField(heights=heights, spacing=(0.002, 0.002))
        sc = ar.paper.scenario("fig14").replace(wall=field, duration=0.2)
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        start = time.perf_counter()
        t = ar.sweep(sc, vary={{"wall.stiffness": ar.LogUniform(1e4, 1e5)}},
                     samples={args.runs}, seed=0, twin={args.twin}, progress=False)
        seconds = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        print(f"{{t.height}} runs, {{seconds:.2f}} s, peak RSS {{before / 1024:.0f}} -> "
              f"{{after / 1024:.0f}} MB (+{{(after - before) / 1024:.0f}} MB)")
    """)
    subprocess.run([sys.executable, "-c", script], check=True)


if __name__ == "__main__":
    main()
