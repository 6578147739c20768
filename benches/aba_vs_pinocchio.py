"""ABA per call: admit_rs (Criterion, Rust) against Pinocchio (timed here, from Python).

Run ``cargo bench --bench chain -- chain_aba`` first; this script reads Criterion's
estimates from ``target/criterion`` and times ``pin.aba`` on the same URDF files with the
same tip force, at 1024 random states cycled as in the Rust bench. Pinocchio's per-call time
is the loop's time minus that of a trivial Pinocchio binding call (``pin.isNormalized(model,
q)``, which converts q and returns a bool), so the Python loop and the call itself are not
charged to Pinocchio. Converting the list of external forces costs Pinocchio's binding
more than the algorithm, so ABA without external forces (a lower bound on Pinocchio's cost
for our problem) is timed too, and the ratio against it is the conservative one. Prints a
Markdown table.

    python benches/aba_vs_pinocchio.py [--repeats 7] [--cpp]

``--cpp`` also compiles ``benches/pinocchio_aba.cpp`` against the `pin` wheel's headers and
libraries (it needs Eigen 3.4 headers, e.g. Debian's ``libeigen3-dev``, the urdfdom headers,
``liburdfdom-headers-dev``, and g++) and times Pinocchio's ABA in C++, with no binding in
the way. Both sides are then built for baseline x86-64 (the wheel's libraries fix
Pinocchio's Eigen ABI, so no -march=native; Criterion times admit_rs's baseline code too).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parent.parent
ARMS = [
    ("three_link3", "three_link.urdf", "tip"),
    ("ur5_6", "ur5.urdf", "tool0"),
    ("panda7", "panda.urdf", "panda_hand_tcp"),
]


def pin_configuration(model: pin.Model, q: np.ndarray) -> np.ndarray:
    out: list[float] = []
    for i, joint in enumerate(model.joints[1:]):
        out += [np.cos(q[i]), np.sin(q[i])] if joint.nq == 2 else [q[i]]
    return np.array(out)


def time_loop(fn, args: list, repeats: int) -> float:
    """Best-of-``repeats`` seconds per call over the argument list."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for a in args:
            fn(*a)
        best = min(best, (time.perf_counter() - start) / len(args))
    return best


def pinocchio_aba(file: str, tip: str, repeats: int) -> tuple[float, float, float]:
    model = pin.buildModelFromXML((ROOT / "examples" / "data" / file).read_text())
    data = model.createData()
    frame = model.getFrameId(tip)
    last = model.frames[frame].parentJoint
    rng = np.random.default_rng(0)
    calls, plain, trivial = [], [], []
    for _ in range(1024):
        q = pin_configuration(model, rng.uniform(-2, 2, model.nv))
        v = rng.uniform(-2, 2, model.nv)
        tau = 5 * rng.uniform(-2, 2, model.nv)
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        force = np.array([-10.0, 0.5, 1.0])
        wrench = pin.Force(force, np.cross(data.oMf[frame].translation, force))
        fext = [pin.Force.Zero() for _ in range(model.njoints)]
        fext[last] = data.oMi[last].actInv(wrench)
        calls.append((model, data, q, v, tau, fext))
        plain.append((model, data, q, v, tau))
        trivial.append((model, q))
    total = time_loop(pin.aba, calls, repeats)
    without_fext = time_loop(pin.aba, plain, repeats)
    overhead = time_loop(pin.isNormalized, trivial, repeats)
    return total, without_fext, overhead


def criterion_ns(name: str) -> float | None:
    path = ROOT / "target" / "criterion" / "chain_aba" / name / "new" / "estimates.json"
    if not path.exists():
        return None
    return float(json.loads(path.read_text())["median"]["point_estimate"])


def cpp_aba() -> dict[str, float]:
    """Compiles and runs benches/pinocchio_aba.cpp: ns per call of C++ pinocchio::aba."""
    prefix = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix"
    exe = ROOT / "target" / "pinocchio_aba"
    defines = ["-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
               "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
               "-DPINOCCHIO_WITH_URDFDOM"]  # fmt: skip
    subprocess.run(
        ["g++", "-O3", "-DNDEBUG", "-std=c++17", *defines, f"-I{prefix / 'include'}",
         "-I/usr/include/eigen3", str(ROOT / "benches" / "pinocchio_aba.cpp"), "-o", str(exe),
         f"-L{prefix / 'lib'}", "-lpinocchio_default", "-lpinocchio_parsers",
         "-lurdfdom_model", f"-Wl,-rpath,{prefix / 'lib'}"],
        check=True,
    )  # fmt: skip
    args = [str(exe)]
    for _, file, tip in ARMS:
        args += [str(ROOT / "examples" / "data" / file), tip]
    out = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    times = {}
    for line, (name, _, _) in zip(out.splitlines(), ARMS, strict=True):
        times[name] = float(line.split()[1])
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--cpp", action="store_true", help="also time pinocchio::aba in C++")
    args = parser.parse_args()
    if args.cpp:
        cpp = cpp_aba()
        print("| arm | admit_rs ABA [ns] | pinocchio::aba in C++ [ns] | ratio admit_rs / C++ |")
        print("|---|---|---|---|")
        for name, _, _ in ARMS:
            ours = criterion_ns(name)
            ratio = f"{ours / cpp[name]:.2f}" if ours is not None else "–"
            shown = f"{ours:.0f}" if ours is not None else "–"
            print(f"| {name} | {shown} | {cpp[name]:.0f} | {ratio} |")
        print(file=sys.stderr)
    print("| arm | admit_rs ABA with tip wrench [ns] | pin.aba with fext [ns] "
          "| pin.aba without fext [ns] | trivial call [ns] "
          "| ratio vs (fext − trivial) | ratio vs (no fext − trivial) |")
    print("|---|---|---|---|---|---|---|")
    for name, file, tip in ARMS:
        total, plain, overhead = pinocchio_aba(file, tip, args.repeats)
        ours = criterion_ns(name)

        def ratio(t: float, ours: float | None = ours, overhead: float = overhead) -> str:
            return f"{ours / ((t - overhead) * 1e9):.2f}" if ours is not None else "–"

        ours_s = f"{ours:.0f}" if ours is not None else "(run cargo bench first)"
        print(f"| {name} | {ours_s} | {total * 1e9:.0f} | {plain * 1e9:.0f} | "
              f"{overhead * 1e9:.0f} | {ratio(total)} | {ratio(plain)} |")


if __name__ == "__main__":
    main()
