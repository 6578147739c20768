"""admit_rs against strong peers on the fig. 14 run: NumPy, Numba, and (for reference) CPython.

    python benches/compare.py [--repeats 5] [--duration 10] [--skip-numpy] [--skip-python]

Not a test: prints tables (see docs/performance.md for a recorded run). In order:

1. the machine (CPU model, cores, clock, load) and library versions;
2. agreement: every peer's trace against admit_rs's, all 20 columns, max |Δ| with a 1e-9
   absolute criterion (the script stops if a peer disagrees: timing a different computation
   would be meaningless);
3. timing: median wall time over ``--repeats`` runs in this process, the implementations
   interleaved round-robin so that load from other jobs hits them alike; ratios to admit_rs;
4. a cost model: floating-point operations of one RK4 substep, counted by running a
   line-by-line transcription of the Rust core (``benches/core_model.py``, first checked to
   reproduce the core's trace) on counting floats and checked against the hand count; libm
   call costs measured here; the resulting floor on this core and admit_rs's time per substep;
5. how admit_rs's time grows with the run's duration and the number of substeps.

The peers live in ``benches/peers.py``. Numba is optional: without it (b) is skipped with a
message (``pip install numba``).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

# One BLAS thread: the NumPy peer's 3×3 products gain nothing from threads, and idle OpenBLAS
# workers spin on the second core of this 2-core machine, slowing whatever runs beside them.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import admit_rs as ar  # noqa: E402
import core_model  # noqa: E402
import peers  # noqa: E402

TOLERANCE = 1e-9
TARGET_NUMBA = 1.5
TARGET_NUMPY = 300.0
NUMPY_BUDGET_S = 60.0


# --------------------------------------------------------------------------------------------
# machine
# --------------------------------------------------------------------------------------------


def machine() -> dict[str, str]:
    info: dict[str, str] = {}
    try:
        text = Path("/proc/cpuinfo").read_text()
        fields = dict(
            line.split(":", 1) for line in text.splitlines() if ":" in line and line.strip()
        )
        fields = {k.strip(): v.strip() for k, v in fields.items()}
        family = fields.get("cpu family", "?")
        model = fields.get("model", "?")
        info["cpu"] = f"{fields.get('model name', '?')} (family {family}, model {model})"
        info["clock_mhz"] = fields.get("cpu MHz", "?")
    except OSError:
        info["cpu"] = platform.processor() or "?"
        info["clock_mhz"] = "?"
    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    info["cores"] = f"{os.cpu_count()} logical ({affinity} usable by this process)"
    try:
        info["load"] = " ".join(f"{x:.2f}" for x in os.getloadavg()) + " (1, 5, 15 min)"
    except OSError:
        info["load"] = "?"
    versions = [f"Python {platform.python_version()}", f"NumPy {np.__version__}"]
    if peers.HAVE_NUMBA:
        versions.append(f"Numba {peers.numba.__version__}")
    import scipy

    versions.append(f"SciPy {scipy.__version__}")
    versions.append(f"admit_rs {getattr(ar, '__version__', '?')}")
    info["software"] = ", ".join(versions)
    return info


def clock_ghz() -> float:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("cpu MHz"):
                return float(line.split(":")[1]) / 1000.0
    except (OSError, ValueError):
        pass
    return float("nan")


# --------------------------------------------------------------------------------------------
# the scenario, checked against the library's preset
# --------------------------------------------------------------------------------------------


def check_preset(sc: ar.Scenario, c: peers.Fig14) -> None:
    """Fails loudly if ``ar.paper.scenario("fig14")`` is no longer what the peers implement."""
    r, w, ctl, adm = sc.robot, sc.wall, sc.controller, sc.admittance
    expected = {
        "robot.lengths": (tuple(r.lengths), c.lengths),
        "robot.masses": (tuple(r.masses), c.masses),
        "robot.mass_model": (r.mass_model, "rod"),
        "robot.viscous_friction": (tuple(r.viscous_friction), (c.viscous,) * 3),
        "robot.coulomb_friction": (tuple(r.coulomb_friction), (c.coulomb,) * 3),
        "robot.friction_smoothing": (r.friction_smoothing, c.eps),
        "robot.gravity": (r.gravity, c.gravity),
        "robot.q0": (tuple(r.q0), c.q0),
        "wall.stiffness": (w.stiffness, c.stiffness),
        "wall.position": (w.position, None),
        "wall.position_error": (w.position_error, c.position_error),
        "controller": (type(ctl).__name__, "TimeDelayControl"),
        "controller.law": (ctl.law, "jacobian_transpose"),
        "controller.gains": (
            (ctl.command_divisor, ctl.kd, ctl.kp, ctl.scale_feedforward),
            (c.ka, c.kd, c.kp, True),
        ),
        "controller.inertia": ((ctl.inertia, ctl.torque_constant), (c.inertia, c.torque_constant)),
        "controller.model": (
            (ctl.model.mass_scale, ctl.model.friction_scale),
            (1.0, 1.0),
        ),
        "admittance": ((adm.m, adm.b, adm.k, adm.ka), (c.fm, c.fb, c.fk, c.fka)),
        "force_reference": (
            (type(sc.force_reference).__name__, sc.force_reference.value, sc.force_reference.time),
            ("Step", c.force, 0.0),
        ),
        "z_reference": (
            (
                type(sc.z_reference).__name__,
                sc.z_reference.offset,
                sc.z_reference.amplitude,
                sc.z_reference.omega,
                sc.z_reference.phase,
            ),
            ("Sine", c.z_offset, c.z_amplitude, c.z_omega, c.z_phase),
        ),
        "timing": ((sc.period, sc.substeps, sc.duration), (c.period, c.substeps, 10.0)),
        "velocity_limit": (sc.velocity_limit, 100.0),
    }
    bad = {k: v for k, v in expected.items() if v[0] != v[1]}
    if bad:
        raise SystemExit(f"fig14 preset differs from the peers' model: {bad}")


# --------------------------------------------------------------------------------------------
# agreement
# --------------------------------------------------------------------------------------------


def admit_trace(duration: float) -> np.ndarray:
    res = ar.simulate(ar.paper.scenario("fig14").replace(duration=duration))
    return res.trace.select(peers.COLUMNS).to_numpy()


def report_agreement(name: str, trace: np.ndarray, ref: np.ndarray) -> bool:
    if trace.shape != ref.shape:
        print(f"  {name}: shape {trace.shape} != admit_rs {ref.shape}")
        return False
    diff = np.abs(trace - ref).max(axis=0)
    worst = float(diff.max())
    ok = bool(np.all(diff <= TOLERANCE))
    f = peers.COLUMNS.index("f")
    rel_f = diff[f] / np.abs(ref[:, f]).max()
    same = sum(np.array_equal(trace[:, j], ref[:, j]) for j in range(ref.shape[1]))
    print(
        f"  {name:8s} {'OK' if ok else 'FAIL'}: max |Δ| over all columns {worst:.2e}; "
        f"f: {diff[f]:.2e} N ({rel_f:.1e} of max f); "
        f"{same}/{ref.shape[1]} columns bit-identical"
    )
    cells = [f"{c}={d:.1e}" for c, d in zip(peers.COLUMNS, diff, strict=True)]
    for i in range(0, len(cells), 7):
        print("      " + "  ".join(cells[i : i + 7]))
    return ok


# --------------------------------------------------------------------------------------------
# timing
# --------------------------------------------------------------------------------------------


def timed(fn: Callable[[], object]) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def round_robin(runs: dict[str, Callable[[], object]], repeats: int) -> dict[str, list[float]]:
    times: dict[str, list[float]] = {k: [] for k in runs}
    for _ in range(repeats):
        for name, fn in runs.items():
            times[name].append(timed(fn))
    return times


# --------------------------------------------------------------------------------------------
# cost model
# --------------------------------------------------------------------------------------------


class Counted:
    """A float that counts the arithmetic done on it, per part of the substep being run
    (`core_model.SECTION`), in one shared tally."""

    tally: dict[tuple[str, str], int] = {}

    __slots__ = ("v",)

    def __init__(self, v: float) -> None:
        self.v = float(v)

    @classmethod
    def bump(cls, key: str) -> None:
        k = (core_model.SECTION[0], key)
        cls.tally[k] = cls.tally.get(k, 0) + 1

    @staticmethod
    def _v(x: object) -> float:
        return x.v if isinstance(x, Counted) else float(x)  # type: ignore[arg-type]

    def _op(self, other: object, key: str, f: Callable[[float, float], float]) -> Counted:
        Counted.bump(key)
        return Counted(f(self.v, Counted._v(other)))

    def _rop(self, other: object, key: str, f: Callable[[float, float], float]) -> Counted:
        Counted.bump(key)
        return Counted(f(Counted._v(other), self.v))

    def __add__(self, o: object) -> Counted:
        return self._op(o, "add/sub", lambda a, b: a + b)

    def __radd__(self, o: object) -> Counted:
        return self._rop(o, "add/sub", lambda a, b: a + b)

    def __sub__(self, o: object) -> Counted:
        return self._op(o, "add/sub", lambda a, b: a - b)

    def __rsub__(self, o: object) -> Counted:
        return self._rop(o, "add/sub", lambda a, b: a - b)

    def __mul__(self, o: object) -> Counted:
        return self._op(o, "mul", lambda a, b: a * b)

    def __rmul__(self, o: object) -> Counted:
        return self._rop(o, "mul", lambda a, b: a * b)

    def __truediv__(self, o: object) -> Counted:
        return self._op(o, "div", lambda a, b: a / b)

    def __rtruediv__(self, o: object) -> Counted:
        return self._rop(o, "div", lambda a, b: a / b)

    # Sign operations and comparisons are bit operations, not flops; counted apart.
    def __neg__(self) -> Counted:
        Counted.bump("sign op")
        return Counted(-self.v)

    def __abs__(self) -> Counted:
        Counted.bump("sign op")
        return Counted(abs(self.v))

    def __gt__(self, o: object) -> bool:
        Counted.bump("compare")
        return self.v > Counted._v(o)

    def __eq__(self, o: object) -> bool:  # type: ignore[override]
        Counted.bump("compare")
        return self.v == Counted._v(o)

    __hash__ = None  # type: ignore[assignment]


class CountingMath:
    """Stands in for the ``math`` module inside the counted transcription."""

    @staticmethod
    def _call(name: str, f: Callable[[float], float], x: Counted) -> Counted:
        Counted.bump(name)
        return Counted(f(x.v))

    @staticmethod
    def sin(x: Counted) -> Counted:
        return CountingMath._call("sin", math.sin, x)

    @staticmethod
    def cos(x: Counted) -> Counted:
        return CountingMath._call("cos", math.cos, x)

    @staticmethod
    def exp(x: Counted) -> Counted:
        return CountingMath._call("exp", math.exp, x)

    @staticmethod
    def copysign(x: Counted, y: Counted) -> Counted:
        Counted.bump("sign op")
        return Counted(math.copysign(x.v, y.v))


FLOPS = ("add/sub", "mul", "div")

# Hand count of one RK4 substep of the core, part by part (flops = add/sub + mul + div), for a
# state in contact with the wall with the yaw joint at rest (as all of fig. 14). The line-by-
# line reasoning is in docs/performance-history.md §3; `cost_model` checks it against the count.
HAND_SUBSTEP = {
    # 4 stages × (contact 16 + D, C, G 51 + rest 14 + D⁻¹ 8 + Coulomb 5 + 5 + 0 + q̈ 17)
    "per stage (×4)": 4 * (16 + 51 + 14 + 8 + 10 + 17),
    # 4 × Trig::shifted (stages 2–4 and the next substep's stage 1): 3 angles × 21 + 6
    "stage trig by angle addition": 4 * (3 * 21 + 6),
    # stage states 3 × (3 + 6), dq 15, q + dq 3, q̇ update 18
    "RK4 combinations": 3 * 9 + 15 + 3 + 18,
}


def count_substep(trace: np.ndarray, row: int, c: peers.Fig14) -> dict[tuple[str, str], int]:
    """Runs the transcription of one substep on counting floats from trace row `row`."""
    s = peers.setup(c)
    arm = core_model.Arm.new(s.arm, c.stiffness, s.wall)
    col = peers.COLUMNS.index
    q = [Counted(trace[row, col(k)]) for k in ("q1", "q2", "q3")]
    qd = [Counted(trace[row, col(k)]) for k in ("qd1", "qd2", "qd3")]
    tau = [Counted(trace[row, col(k)]) for k in ("tau1", "tau2", "tau3")]
    Counted.tally = {}
    t1 = core_model.trig_new(q, CountingMath)
    core_model.substep(q, qd, t1, tau, c.period / c.substeps, arm, CountingMath)
    return dict(Counted.tally)


def check_transcription(trace: np.ndarray, c: peers.Fig14, rows: list[int]) -> float:
    """Max |Δ| between the transcription's period from row k and admit_rs's row k + 1."""
    s = peers.setup(c)
    arm = core_model.Arm.new(s.arm, c.stiffness, s.wall)
    col = peers.COLUMNS.index
    worst = 0.0
    for k in rows:
        row = trace[k]
        q, qd = core_model.period(
            [float(row[col(n)]) for n in ("q1", "q2", "q3")],
            [float(row[col(n)]) for n in ("qd1", "qd2", "qd3")],
            [float(row[col(n)]) for n in ("tau1", "tau2", "tau3")],
            c.period / c.substeps,
            c.substeps,
            arm,
            math,
        )
        nxt = trace[k + 1]
        got = np.array(q + qd)
        want = np.array([nxt[col(n)] for n in ("q1", "q2", "q3", "qd1", "qd2", "qd3")])
        worst = max(worst, float(np.max(np.abs(got - want))))
    return worst


def libm_costs(trace: np.ndarray, eps: float) -> dict[str, float]:
    """ns per sin+cos of one angle and per friction tanh, over the run's own arguments, timed
    through Numba. The core computes tanh as ±(1 − e)/(1 + e), e = exp(−2|x|) (one glibc
    `exp`, as timed here) and sin and cos with one `libm::sincos` call (timed here as the
    glibc sin + cos pair, which costs about the same: 9.4 vs 9.5 ns in a microbenchmark)."""
    if not peers.HAVE_NUMBA:
        return {}
    numba = peers.numba

    @numba.njit
    def sincos_sum(xs: np.ndarray, reps: int) -> float:
        acc = 0.0
        for _ in range(reps):
            for x in xs:
                acc += math.sin(x) + math.cos(x)
        return acc

    @numba.njit
    def tanh_sum(xs: np.ndarray, reps: int) -> float:
        acc = 0.0
        for _ in range(reps):
            for x in xs:
                e = math.exp(-2.0 * abs(x))
                acc += math.copysign((1.0 - e) / (1.0 + e), x)
        return acc

    @numba.njit
    def plain_sum(xs: np.ndarray, reps: int) -> float:
        acc = 0.0
        for _ in range(reps):
            for x in xs:
                acc += x
        return acc

    angles = np.ascontiguousarray(trace[:, 1:4].ravel())
    rates = trace[:, 4:7].ravel() / eps
    # The core skips the call for a joint at rest (the yaw joint here), so time the others.
    rates = np.ascontiguousarray(rates[rates != 0.0])
    reps = 20
    out = {}
    for key, fn, xs in (("sin+cos", sincos_sum, angles), ("tanh", tanh_sum, rates)):
        fn(xs[:10], 1)
        plain_sum(xs[:10], 1)
        best = min(timed(lambda f=fn, a=xs: f(a, reps)) for _ in range(5))
        base = min(timed(lambda a=xs: plain_sum(a, reps)) for _ in range(5))
        out[key] = (best - base) / (reps * xs.size) * 1e9
    out["tanh_fast_path_share"] = float(np.mean(np.abs(rates) > 22.0))
    return out


def substep_slope(scenario: ar.Scenario, repeats: int) -> float:
    """Seconds per RK4 substep alone: the slope of admit_rs's run time between 5 and 20
    substeps per period (the per-period work, trace and metrics cancel), fastest of
    `repeats` runs each so that background load does not bias it."""
    best = {}
    for n in (5, 20):
        scn = scenario.replace(substeps=n)
        ar.simulate(scn)
        best[n] = min(timed(lambda x=scn: ar.simulate(x)) for _ in range(repeats))
    periods = round(scenario.duration / scenario.period)
    return (best[20] - best[5]) / (15 * periods)


def cost_model(
    admit_seconds: float, trace: np.ndarray, c: peers.Fig14, scenario: ar.Scenario, repeats: int
) -> None:
    """`admit_seconds`: admit_rs's median for the run `c` (same duration as `trace`)."""
    print("\nCost model: one RK4 substep of the Rust core (integrator.rs `Plant::advance`,")
    print("robot.rs `Trig`, `accelerate_at`), transcribed line by line in benches/core_model.py")
    f = trace[:, peers.COLUMNS.index("f")]
    in_contact = np.flatnonzero(f[:-1] > 0.0)
    rows = [int(in_contact[i]) for i in np.linspace(0, len(in_contact) - 1, 25).astype(int)]
    worst = check_transcription(trace, c, rows)
    print(
        f"  the transcription, run on floats from {len(rows)} states of admit_rs's trace,"
        f" reproduces the next sample's q, q̇ to {worst:.1e}"
        f" -> {'faithful' if worst < 1e-12 else 'DIFFERS FROM THE CORE'}"
    )
    tally = count_substep(trace, rows[len(rows) // 2], c)
    fresh = "fresh sin/cos (once per period)"
    parts: dict[str, dict[str, int]] = {}
    for (part, key), n in tally.items():
        parts.setdefault(part, {})[key] = parts.setdefault(part, {}).get(key, 0) + n
    per_stage = ("contact force and Jᵀf", "D, C, G (folded constants)",
                 "rest = τ + Jᵀf − C − G − f_v q̇", "D⁻¹ (yaw scalar ⊕ 2×2 block)",
                 "Coulomb friction f_c tanh(q̇/ε)", "q̈ = D⁻¹ (rest − τ_c)")  # fmt: skip

    def flops(part: str) -> int:
        return sum(parts.get(part, {}).get(k, 0) for k in FLOPS)

    print(f"  {'part (per substep)':44s} {'flops':>6s}  {'of which div':>12s}  calls")
    for part in (*per_stage, "stage trig by angle addition", "RK4 combinations", fresh):
        d = parts.get(part, {})
        calls = ", ".join(f"{d[k]} {k}" for k in ("exp", "sin", "cos") if d.get(k))
        note = "  (per period, not per substep)" if part == fresh else ""
        print(f"  {part:44s} {flops(part):6d}  {d.get('div', 0):12d}  {calls}{note}")
    counted = {
        "per stage (×4)": sum(flops(p) for p in per_stage),
        "stage trig by angle addition": flops("stage trig by angle addition"),
        "RK4 combinations": flops("RK4 combinations"),
    }
    agree = counted == HAND_SUBSTEP
    per_substep = sum(counted.values())
    print(f"  counted {counted} vs hand count {HAND_SUBSTEP} -> {'agree' if agree else 'DISAGREE'}")
    exps = sum(d.get("exp", 0) for p, d in parts.items() if p != fresh)
    divs = sum(d.get("div", 0) for p, d in parts.items() if p != fresh)
    pairs_per_substep = parts.get(fresh, {}).get("sin", 0) / c.substeps
    fresh_flops = flops(fresh) / c.substeps
    print(
        f"  per substep: {per_substep} flops ({divs} divisions), {exps} exp; plus, once per"
        f" period, {flops(fresh)} flops and {parts.get(fresh, {}).get('sin', 0)} sin+cos pairs"
        f" (÷ {c.substeps} substeps)"
    )
    ghz = clock_ghz()
    flops_per_cycle = 4.0
    arith_ns = (per_substep + fresh_flops) / (flops_per_cycle * ghz)
    print(
        f"  arithmetic floor: {per_substep + fresh_flops:.1f} flops / ({flops_per_cycle:.0f}"
        f" flops/cycle × {ghz:.2f} GHz) = {arith_ns:.0f} ns  [2 FP add + 2 FP mul per cycle"
        " (Zen 3), scalar, no FMA (the AVX2 build enables FMA but Rust never fuses on its"
        " own), divisions pipelined]"
    )
    costs = libm_costs(trace, c.eps)
    if costs:
        libm_ns = exps * costs["tanh"] + pairs_per_substep * costs["sin+cos"]
        print(
            f"  calls (timed via Numba on the run's own arguments): tanh as the core computes it"
            f" (one exp) {costs['tanh']:.1f} ns, sin+cos of one angle {costs['sin+cos']:.1f} ns"
            f" -> {exps} × {costs['tanh']:.1f} + {pairs_per_substep:g} × {costs['sin+cos']:.1f}"
            f" = {libm_ns:.0f} ns"
        )
    else:
        libm_ns = float("nan")
        print("  libm call costs: need Numba to measure; see the Criterion libm/* numbers")
    floor = arith_ns + libm_ns
    n_sub = (c.samples - 1) * c.substeps
    measured = admit_seconds / n_sub * 1e9
    which = "the floor"
    if math.isnan(floor):
        floor = arith_ns
        which = "the arithmetic-only floor"
        print(f"  floor (arithmetic only, libm unknown) ≈ {floor:.0f} ns per substep")
    else:
        print(
            f"  floor ≈ {arith_ns:.0f} + {libm_ns:.0f} = {floor:.0f} ns per substep (throughput"
            " bound; ignores the dependency chain through the four stages)"
        )
    slope = substep_slope(scenario, repeats) * 1e9
    print(
        f"  measured, one substep: {slope:.0f} ns = {slope / floor:.2f} × {which} (slope of"
        f" the run time from 5 to 20 substeps per period, fastest of {repeats} each; Criterion's"
        " plant/rk4_substep measures the same thing)"
    )
    print(
        f"  measured, whole run: admit_rs fig14 median {admit_seconds * 1e3:.1f} ms /"
        f" ({c.samples - 1} × {c.substeps}) = {measured:.0f} ns per substep (includes the"
        f" per-period controller, filter, trace and metrics) = {measured / floor:.2f} × {which}"
    )


# --------------------------------------------------------------------------------------------
# main
# --------------------------------------------------------------------------------------------


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per implementation")
    parser.add_argument("--duration", type=float, default=10.0, help="simulated seconds")
    parser.add_argument("--skip-numpy", action="store_true", help="leave out the NumPy peer")
    parser.add_argument(
        "--skip-python", action="store_true", help="leave out the CPython reference point"
    )
    parser.add_argument("--skip-scaling", action="store_true", help="no duration/substep table")
    args = parser.parse_args()

    print("Machine")
    for k, v in machine().items():
        print(f"  {k:10s} {v}")

    sc = ar.paper.scenario("fig14")
    c = peers.Fig14(duration=args.duration)
    check_preset(sc, peers.Fig14())
    scenario = sc.replace(duration=args.duration)
    print(
        f"\nfig14: TDC eq. 18 + Scheme 2 (b=800, k_a=1), k_e=30000, f_d=10 N step, z sine;"
        f" {args.duration:g} s = {c.samples} samples × {c.substeps} RK4 substeps"
    )
    if not peers.HAVE_NUMBA:
        print("\n*** Numba is not installed: peer (b) is skipped. `pip install numba` to run it.")

    # -- agreement (also the first, untimed, call of each peer) --------------------------------
    print(
        f"\nAgreement with admit_rs's trace (all {len(peers.COLUMNS)} columns, |Δ| ≤ {TOLERANCE:g})"
    )
    ref = admit_trace(args.duration)
    ok = True
    first: dict[str, float] = {}
    if peers.HAVE_NUMBA:
        compile_s = timed(lambda: peers.run_numba(peers.Fig14(duration=0.002)))
        first["numba"] = compile_s
        ok &= report_agreement("Numba", peers.run_numba(c), ref)
    numpy_duration = args.duration
    if not args.skip_numpy:
        start = time.perf_counter()
        trace_np = peers.run_numpy(c)
        first["numpy"] = time.perf_counter() - start
        ok &= report_agreement("NumPy", trace_np, ref)
        if first["numpy"] > NUMPY_BUDGET_S:
            numpy_duration = max(c.period, round(args.duration * 20.0 / first["numpy"], 3))
    python_duration = args.duration
    if not args.skip_python:
        start = time.perf_counter()
        trace_py = peers.run_python(c)
        first["python"] = time.perf_counter() - start
        ok &= report_agreement("CPython", trace_py, ref)
        if first["python"] > NUMPY_BUDGET_S:
            python_duration = max(c.period, round(args.duration * 20.0 / first["python"], 3))
    if not ok:
        raise SystemExit("a peer disagrees with admit_rs beyond 1e-9: not timing it")

    # -- timing ---------------------------------------------------------------------------------
    runs: dict[str, Callable[[], object]] = {"admit_rs": lambda: ar.simulate(scenario)}
    durations = {"admit_rs": args.duration}
    if peers.HAVE_NUMBA:
        runs["numba"] = lambda: peers.run_numba(c)
        durations["numba"] = args.duration
    if not args.skip_numpy:
        c_np = peers.Fig14(duration=numpy_duration)
        runs["numpy"] = lambda: peers.run_numpy(c_np)
        durations["numpy"] = numpy_duration
    if not args.skip_python:
        c_py = peers.Fig14(duration=python_duration)
        runs["python"] = lambda: peers.run_python(c_py)
        durations["python"] = python_duration
    # Warm-up of admit_rs (the peers' first calls happened above).
    ar.simulate(scenario)
    times = round_robin(runs, args.repeats)
    load_after = " ".join(f"{x:.2f}" for x in os.getloadavg())
    labels = {
        "admit_rs": "(c) admit_rs: ar.simulate (Rust core + polars DataFrame)",
        "numba": "(b) Numba @njit, whole run in one function",
        "numpy": "(a) NumPy, small arrays",
        "python": "    CPython floats + math (the Numba kernel, uncompiled)",
    }
    scale = {k: args.duration / d for k, d in durations.items()}
    med = {k: statistics.median(v) * scale[k] for k, v in times.items()}
    print(
        f"\nWall time of one {args.duration:g}-s run, median of {args.repeats} (min … max),"
        f" interleaved; load average after: {load_after}"
    )
    print(f"  {'implementation':60s} {'median':>10s} {'min … max':>21s} {'÷ admit_rs':>11s}")
    for k, v in times.items():
        note = "" if scale[k] == 1.0 else f"   [timed {durations[k]:g} s, ×{scale[k]:g}]"
        lo, hi = min(v) * scale[k], max(v) * scale[k]
        print(
            f"  {labels[k]:60s} {fmt_s(med[k]):>10s} {fmt_s(lo):>9s} … {fmt_s(hi):<9s}"
            f" {med[k] / med['admit_rs']:10.1f}×{note}"
        )
    if "numba" in first:
        print(f"  Numba compile time (first call, not in the table): {first['numba']:.2f} s")
    print("\nTargets (from the issue; informational; ratio of medians, and of fastest runs)")
    fastest = {k: min(v) * scale[k] for k, v in times.items()}
    for key, name, target, fmt in (
        ("numba", "Numba", TARGET_NUMBA, ".2f"),
        ("numpy", "NumPy", TARGET_NUMPY, ".0f"),
    ):
        if key in med:
            r = med[key] / med["admit_rs"]
            r_min = fastest[key] / fastest["admit_rs"]
            print(
                f"  admit_rs ≥ {target:g}× faster than {name}: {r:{fmt}}× (fastest runs:"
                f" {r_min:{fmt}}×) -> {met(r >= target)}"
            )

    cost_model(statistics.median(times["admit_rs"]), ref, c, scenario, args.repeats)

    if not args.skip_scaling:
        scaling(sc, args.repeats)


def scaling(sc: ar.Scenario, repeats: int) -> None:
    print("\nadmit_rs cost vs duration and substeps (ar.simulate, median of", repeats, "runs)")
    cases = [("duration", d, 10) for d in (2.0, 5.0, 10.0)] + [
        ("substeps", 10.0, s) for s in (5, 10, 20)
    ]
    print(
        f"  {'duration':>8s} {'substeps':>8s} {'median':>9s} {'ns/substep':>11s} {'trace MB':>9s}"
    )
    for _, d, s in cases:
        scn = sc.replace(duration=d, substeps=s)
        ar.simulate(scn)
        t = statistics.median(timed(lambda x=scn: ar.simulate(x)) for _ in range(repeats))
        res = ar.simulate(scn)
        n_sub = round(d / sc.period) * s
        mb = res.trace.estimated_size() / 1e6
        print(f"  {d:8g} {s:8d} {fmt_s(t):>9s} {t / n_sub * 1e9:11.0f} {mb:9.2f}")


def fmt_s(seconds: float) -> str:
    return f"{seconds * 1e3:.1f} ms" if seconds < 1.0 else f"{seconds:.2f} s"


def met(flag: bool) -> str:
    return "MET" if flag else "NOT MET"


if __name__ == "__main__":
    main()
