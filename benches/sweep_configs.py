"""What building a sweep's run configs costs in Python, before the core sees them.

    python benches/sweep_configs.py [--runs 400]

Not a test: prints the best of 5 timings of ``sweep._configs`` (each run's dict from the
base and its overrides, copying only the tables it changes) against a deep copy per run (what
it did before), for fig. 19 and for the Panda (whose URDF text a deep copy duplicated), and
checks both give the same dicts.
"""

from __future__ import annotations

import argparse
import copy
import time
from collections.abc import Callable
from typing import Any

import admit_rs as ar
from admit_rs.sweep import _configs, noise_seed


def deep_copies(base: dict[str, Any], rows: list[dict[str, Any]], seed: int) -> list[Any]:
    out = []
    for run_id, row in enumerate(rows):
        config = copy.deepcopy(base)
        config["seed"] = noise_seed(seed, run_id)
        for path, value in row.items():
            *parents, leaf = path.split(".")
            node = config
            for part in parents:
                node = node[part]
            node[leaf] = value
        out.append(config)
    return out


def best(f: Callable[[], object], rounds: int = 5) -> float:
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=400)
    args = parser.parse_args()
    panda = ar.UrdfArm("examples/data/panda.urdf", "panda_hand_tcp",
                       q0=(0, -0.785, 0, -2.356, 0, 1.571, 0.785))  # fmt: skip
    cases = {
        "fig. 19": ar.paper.scenario("fig19").replace(duration=2.0),
        "Panda": ar.paper.scenario("fig14").replace(
            robot=panda, controller=ar.TimeDelayControl.for_arm(panda)
        ),
    }
    rows = [{"wall.stiffness": 1e4 + i, "wall.position_error": 1e-5 * i} for i in range(args.runs)]
    ids = list(range(args.runs))
    print(f"{args.runs} run configs, best of 5")
    for name, sc in cases.items():
        base = sc._to_core()
        shared = best(lambda base=base: _configs(base, rows, ids, 0))
        deep = best(lambda base=base: deep_copies(base, rows, 0))
        made = _configs(base, rows, ids, 0)
        for config, old in zip(made, deep_copies(base, rows, 0), strict=True):
            assert config == old
        print(f"  {name:8s} deep copy per run {deep * 1e3:8.2f} ms   shared tables "
              f"{shared * 1e3:8.2f} ms")


if __name__ == "__main__":
    main()
