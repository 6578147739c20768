"""Where a build's time goes, by the admit_rs source the samples were inlined from.

    perf record -e cpu-clock -F 4000 -o OUT.data python SCRIPT.py
    python benches/perf_attribute.py OUT.data DIR/admit_rs/_core.abi3.so [--by stage|line]

The extension must carry line tables to be resolved (build it with
``CARGO_PROFILE_RELEASE_DEBUG=line-tables-only CARGO_PROFILE_RELEASE_STRIP=none maturin build
--release``; the code is the shipped fat-LTO build's otherwise). Every sample in
``_core.abi3.so`` is resolved by ``llvm-symbolizer --inlining`` into its chain of inlined
frames, then counted:

- ``--by stage`` (default): the RK4 substeps (any frame in ``rk4_period``) against the rest
  of a period, by the first frame below the lane loop, or else by the out-of-line function
  a sample was in (for a scalar run, every sample outside RK4);
- ``--by line``: the innermost admit_rs source line outside the RK4 substeps;
- ``--by rk4``: the innermost admit_rs source line inside them;
- ``--skip PATH``: with ``line`` or ``rk4``, frames in files whose path contains PATH are
  passed over (``--skip rust/src/scalar/`` counts a lane op at the line that called it).

Needs ``perf`` and ``llvm-symbolizer`` (Debian ``linux-perf``, ``llvm``). This guest has no
hardware counters, so ``cpu-clock`` sampling it is; sample skid puts a slow instruction's
time on the one after it. It is not a test; docs/performance-history.md §19 quotes its output.
"""

from __future__ import annotations

import argparse
import collections
import re
import subprocess

COLUMN = re.compile(r":\d+$")
MMAP = re.compile(r"\[(0x[0-9a-f]+)\((0x[0-9a-f]+)\) @ (0x[0-9a-f]+|0) ")


def samples(data: str) -> tuple[collections.Counter[int], int]:
    """Sample counts by file offset in _core.abi3.so (``text_shift`` turns them into
    addresses), and the number of all samples."""
    out = subprocess.run(
        ["perf", "script", "-i", data, "-F", "ip,dso", "--show-mmap-events"],
        capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    maps: list[tuple[int, int, int]] = []
    ips: collections.Counter[int] = collections.Counter()
    total = 0
    for line in out.splitlines():
        if "PERF_RECORD_MMAP" in line:
            m = MMAP.search(line)
            if m and "_core.abi3.so" in line:
                maps.append((int(m.group(1), 16), int(m.group(2), 16), int(m.group(3), 16)))
            continue
        parts = line.split()
        if len(parts) >= 2 and parts[-1].startswith("("):
            total += 1
            if "_core.abi3.so" in parts[-1]:
                ips[int(parts[0], 16)] += 1
    rel: collections.Counter[int] = collections.Counter()
    for ip, n in ips.items():
        for start, length, offset in maps:
            if start <= ip < start + length:
                rel[ip - start + offset] += n
    return rel, total


def text_shift(so: str) -> int:
    """Virtual address minus file offset of the executable segment."""
    out = subprocess.run(["readelf", "-lW", so], capture_output=True, text=True, check=True)
    for line in out.stdout.splitlines():
        f = line.split()
        if f and f[0] == "LOAD" and "E" in f[6:-1]:  # the flags, between MemSiz and Align
            return int(f[2], 16) - int(f[1], 16)
    return 0


def frames(so: str, addrs: list[int]) -> list[list[tuple[str, str]]]:
    """(function, file:line) per inlined frame, innermost first, for each address."""
    out = subprocess.run(
        ["llvm-symbolizer", "--obj=" + so, "--inlining", "--functions=linkage",
         "--relativenames"],
        input="\n".join(hex(a) for a in addrs) + "\n", capture_output=True, text=True,
        check=True,
    ).stdout  # fmt: skip
    result = []
    for block in out.strip("\n").split("\n\n"):
        lines = [x for x in block.splitlines() if x.strip()]
        result.append(list(zip(lines[0::2], lines[1::2], strict=False)))
    return result


def key(chain: list[tuple[str, str]], by: str, skip: str | None = None) -> str | None:
    """The row a sample counts in (``None``: not counted), from its inlined frames."""
    names = [f for f, _ in chain]
    in_rk4 = any("rk4_period" in n for n in names)
    if by == "stage":
        if in_rk4:
            return "RK4 substeps (rk4_period)"
        outer = names[::-1]
        at = next((i for i, n in enumerate(outer) if "lanes_loop" in n), None)
        if at is None or at + 1 >= len(outer):
            # A scalar run, or a function the lane loop calls out of line.
            return "outside the lane loop: " + outer[0][:70]
        return "lane loop > " + outer[at + 1].split("<")[0][:50]
    if in_rk4 != (by == "rk4"):
        return None
    ours = [(f, loc) for f, loc in chain
            if "rust/src/" in loc and not (skip and skip in loc)]  # fmt: skip
    if not ours:
        return None
    f, loc = ours[0]
    line = COLUMN.sub("", loc)
    return f"{line}  ({f.split('<')[0][:40]})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data")
    parser.add_argument("so")
    parser.add_argument("--by", choices=("stage", "line", "rk4"), default="stage")
    parser.add_argument("--top", type=int, default=25)
    parser.add_argument(
        "--skip",
        metavar="PATH",
        help="count a sample at its innermost frame outside files whose path contains PATH "
        "(e.g. rust/src/scalar/ for the lane types' ops)",
    )
    args = parser.parse_args()
    ips, total = samples(args.data)
    shift = text_shift(args.so)
    addrs = sorted(ips)
    counts: collections.Counter[str] = collections.Counter()
    for a, chain in zip(addrs, frames(args.so, [a + shift for a in addrs]), strict=True):
        k = key(chain, args.by, args.skip)
        if k is not None:
            counts[k] += ips[a]
    print(f"{total} samples, {sum(ips.values())} in _core.abi3.so")
    for k, n in counts.most_common(args.top):
        print(f"{100 * n / total:6.2f} % {n:7d}  {k}")


if __name__ == "__main__":
    main()
