"""A JAX peer of the fig. 19 sweep (used by ``benches/sweep_compare.py``).

The model is ``benches/peers.py``'s, per period (``_control``, ``_advance``, ``_accel``) ported
line by line to ``jax.numpy``: the same closed forms in the same order, so rounding and XLA's
libm, not modelling, are all that differ. The sweep is ``jax.vmap`` over runs of one run's
``jax.lax.scan`` over periods, with ``jax.lax.fori_loop`` over the RK4 substeps, in float64,
metrics (force_peak, force_rms_error, force_ss_error) accumulated online in the scan's carry:
no trace is kept. Branches become ``jnp.where`` selects, which is how a JAX user writes them.

Run as a script, this is one timing session in a fresh process, because ``XLA_FLAGS`` (such as
``--xla_cpu_max_isa=AVX2``) is read when jax initialises its backend: ``sweep_compare.py``
starts one subprocess per flag setting. The script reads the runs' parameters and admit_rs's
metrics from an ``.npz`` file, checks agreement on every run before timing (1e-9 relative on
force_peak and force_rms_error; it exits non-zero otherwise) and prints one JSON line.

    python benches/jax_peer.py IN.npz [--repeats 2]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

if __name__ == "__main__" and "JAX_PEER_CORES" in os.environ:
    # Pinned before numpy and jax start any thread, so that every thread inherits it.
    os.sched_setaffinity(0, {int(c) for c in os.environ["JAX_PEER_CORES"].split(",")})

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers  # noqa: E402

try:
    import jax  # noqa: E402

    # float64 throughout, as admit_rs and the Numba peer: set before any array is made.
    jax.config.update("jax_enable_x64", True)
    HAVE_JAX = True
except ImportError:  # reported by sweep_compare.py
    jax = None
    HAVE_JAX = False

TRANSIENT, WINDOW = 1.0, 2.0


def _accel(jnp, q1, q2, q3, w1, w2, w3, t1, t2, t3, p):
    """``peers._accel`` in jax.numpy (the contact force at the stage's state)."""
    l1, l2, l3, m2, m3, a2, a3, i2, i3, g, fv, fc, eps, ke, xe = p
    s1 = jnp.sin(q1)
    c1 = jnp.cos(q1)
    s2 = jnp.sin(q2)
    c2 = jnp.cos(q2)
    s3 = jnp.sin(q3)
    c3 = jnp.cos(q3)
    s23 = s2 * c3 + c2 * s3
    c23 = c2 * c3 - s2 * s3
    r = l2 * c2 + l3 * c23
    pen = c1 * r - xe
    f = jnp.where(pen > 0.0, ke * pen, 0.0)
    h = l2 * s2 + l3 * s23
    ct1 = s1 * r * f
    ct2 = c1 * h * f
    ct3 = c1 * l3 * s23 * f
    r2 = a2 * c2
    r3 = l2 * c2 + a3 * c23
    d11 = m2 * r2 * r2 + i2 * c2 * c2 + m3 * r3 * r3 + i3 * c23 * c23
    d22 = m2 * a2 * a2 + i2 + m3 * (l2 * l2 + a3 * a3 + 2.0 * l2 * a3 * c3) + i3
    d23 = m3 * (a3 * a3 + l2 * a3 * c3) + i3
    d33 = m3 * a3 * a3 + i3
    dd2 = (
        -2.0 * (m2 * a2 * a2 + i2) * c2 * s2
        - 2.0 * m3 * r3 * (l2 * s2 + a3 * s23)
        - 2.0 * i3 * c23 * s23
    )
    dd3 = -2.0 * m3 * r3 * a3 * s23 - 2.0 * i3 * c23 * s23
    hc = -m3 * l2 * a3 * s3
    cor1 = (dd2 * w2 + dd3 * w3) * w1
    cor2 = 2.0 * hc * w2 * w3 + hc * w3 * w3 - 0.5 * dd2 * w1 * w1
    cor3 = -hc * w2 * w2 - 0.5 * dd3 * w1 * w1
    g2 = g * (m2 * r2 + m3 * r3)
    g3 = g * m3 * a3 * c23
    fr1 = fv * w1 + fc * jnp.tanh(w1 / eps)
    fr2 = fv * w2 + fc * jnp.tanh(w2 / eps)
    fr3 = fv * w3 + fc * jnp.tanh(w3 / eps)
    b1 = t1 + ct1 - cor1 - 0.0 - fr1
    b2 = t2 + ct2 - cor2 - g2 - fr2
    b3 = t3 + ct3 - cor3 - g3 - fr3
    det = d22 * d33 - d23 * d23
    return b1 / d11, (d33 * b2 - d23 * b3) / det, (d22 * b3 - d23 * b2) / det


def _control(jnp, k, state, memory, period, p, ctl, flt, ref, x0, wall_estimate):
    """``peers._control`` in jax.numpy: the torque, (f, f_d) and the next memory."""
    q1, q2, q3, w1, w2, w3 = state
    l1, l2, l3 = p[0], p[1], p[2]
    ke, xe = p[13], p[14]
    ka, kd, kp, inertia, kt, _ = ctl
    ad00, ad01, ad10, ad11, bd0, bd1, fm, fb, fk, fka = flt
    f_d, z_off, z_amp, z_om, z_ph = ref
    x0x, x0y, x0z = x0
    tp1, tp2, tp3, pw1, pw2, pw3, fs0, fs1 = memory
    gain = inertia * kt
    t = k * period
    s1 = jnp.sin(q1)
    c1 = jnp.cos(q1)
    s2 = jnp.sin(q2)
    c2 = jnp.cos(q2)
    s3 = jnp.sin(q3)
    c3 = jnp.cos(q3)
    s23 = s2 * c3 + c2 * s3
    c23 = c2 * c3 - s2 * s3
    r = l2 * c2 + l3 * c23
    hh = l2 * s2 + l3 * s23
    px = c1 * r
    py = s1 * r
    pz = l1 + hh
    j00 = -s1 * r
    j01 = -c1 * hh
    j02 = -c1 * l3 * s23
    j10 = c1 * r
    j11 = -s1 * hh
    j12 = -s1 * l3 * s23
    j20 = 0.0
    j21 = r
    j22 = l3 * c23
    pen = px - xe
    force = jnp.where(pen > 0.0, ke * pen, 0.0)
    # The references depend on k only (not on the run): vmap leaves them unbatched.
    arg = z_om * t + z_ph
    zs = jnp.sin(arg)
    zc = jnp.cos(arg)
    z_val = z_off + z_amp * zs
    z_rate = z_amp * z_om * zc
    z_acc = -z_amp * z_om * z_om * zs
    ef = f_d - force
    xa = fs0
    xa_dot = fs1
    xa_acc = (fka * ef - fb * xa_dot - fk * xa) / fm
    fs0, fs1 = ad00 * xa + ad01 * xa_dot + bd0 * ef, ad10 * xa + ad11 * xa_dot + bd1 * ef
    x_ref = wall_estimate + xa
    dpz = x0z + z_val
    vx = j00 * w1 + j01 * w2 + j02 * w3
    vy = j10 * w1 + j11 * w2 + j12 * w3
    vz = j20 * w1 + j21 * w2 + j22 * w3
    v1 = (xa_acc + ((xa_dot - vx) * kd + (x_ref - px) * kp)) / ka
    v2 = (0.0 + ((0.0 - vy) * kd + (x0y - py) * kp)) / ka
    v3 = (z_acc + ((z_rate - vz) * kd + (dpz - pz) * kp)) / ka
    first = k == 0
    a1 = jnp.where(first, 0.0, (w1 - pw1) / period)
    a2 = jnp.where(first, 0.0, (w2 - pw2) / period)
    a3 = jnp.where(first, 0.0, (w3 - pw3) / period)
    tau1 = (j00 * v1 + j10 * v2 + j20 * v3) * gain + (tp1 - a1 * inertia)
    tau2 = (j01 * v1 + j11 * v2 + j21 * v3) * gain + (tp2 - a2 * inertia)
    tau3 = (j02 * v1 + j12 * v2 + j22 * v3) * gain + (tp3 - a3 * inertia)
    return (tau1, tau2, tau3), (force, f_d), (tau1, tau2, tau3, w1, w2, w3, fs0, fs1)


def _advance(jnp, lax, state, tau, p, substeps, period, unroll):
    """``peers._advance``: RK4 over one period with τ held, a ``fori_loop`` over substeps."""
    t1, t2, t3 = tau
    h = period / substeps
    half = h / 2.0
    sixth = h / 6.0

    def substep(_, y):
        q1, q2, q3, w1, w2, w3 = y
        e1, e2, e3 = _accel(jnp, q1, q2, q3, w1, w2, w3, t1, t2, t3, p)
        bq1, bq2, bq3 = q1 + w1 * half, q2 + w2 * half, q3 + w3 * half
        bw1, bw2, bw3 = w1 + e1 * half, w2 + e2 * half, w3 + e3 * half
        f1, f2, f3 = _accel(jnp, bq1, bq2, bq3, bw1, bw2, bw3, t1, t2, t3, p)
        cq1, cq2, cq3 = q1 + bw1 * half, q2 + bw2 * half, q3 + bw3 * half
        cw1, cw2, cw3 = w1 + f1 * half, w2 + f2 * half, w3 + f3 * half
        g1, g2, g3 = _accel(jnp, cq1, cq2, cq3, cw1, cw2, cw3, t1, t2, t3, p)
        dq1, dq2, dq3 = q1 + cw1 * h, q2 + cw2 * h, q3 + cw3 * h
        dw1, dw2, dw3 = w1 + g1 * h, w2 + g2 * h, w3 + g3 * h
        k1, k2, k3 = _accel(jnp, dq1, dq2, dq3, dw1, dw2, dw3, t1, t2, t3, p)
        return (
            q1 + (w1 + (bw1 + cw1) * 2.0 + dw1) * sixth,
            q2 + (w2 + (bw2 + cw2) * 2.0 + dw2) * sixth,
            q3 + (w3 + (bw3 + cw3) * 2.0 + dw3) * sixth,
            w1 + (e1 + (f1 + g1) * 2.0 + k1) * sixth,
            w2 + (e2 + (f2 + g2) * 2.0 + k2) * sixth,
            w3 + (e3 + (f3 + g3) * 2.0 + k3) * sixth,
        )

    return lax.fori_loop(0, substeps, substep, state, unroll=unroll)


def build(c: peers.Fig14, unroll_substeps: bool | int = True, unroll_periods: int = 1):
    """The jitted sweep for preset ``c``: ``(stiffness[runs], wall_estimate[runs]) ->
    (peak, rms, ss, diverged)``, each of shape ``(runs,)``."""
    import jax.numpy as jnp
    from jax import lax

    n, substeps, period, p, ctl, flt, ref, x0, _, tau0, q0 = peers._kernel_args(c)
    late = math.ceil(TRANSIENT / period - 1e-9)
    steady = math.ceil(((n - 1) * period - WINDOW) / period - 1e-9)
    vlim = ctl[5]

    def one_run(ke, wall_estimate):
        p_i = (*p[:13], ke, p[14])
        zero = jnp.zeros_like(ke)

        def sample(k, carry):
            """Measure and control at sample k, and fold f into the metrics."""
            state, memory, peak, squares, steady_sum, diverged = carry
            tau, (force, f_d), memory_next = _control(
                jnp, k, state, memory, period, p_i, ctl, flt, ref, x0, wall_estimate
            )
            err = f_d - force
            # After a divergence the metrics freeze (the Numba peer returns there).
            live = ~diverged
            peak = jnp.where(live, jnp.maximum(peak, force), peak)
            squares = jnp.where(live & (k >= late), squares + err * err, squares)
            steady_sum = jnp.where(live & (k >= steady), steady_sum + err, steady_sum)
            return tau, memory_next, (peak, squares, steady_sum)

        def period_step(carry, k):
            state, memory, peak, squares, steady_sum, diverged = carry
            tau, memory, (peak, squares, steady_sum) = sample(k, carry)
            state = _advance(jnp, lax, state, tau, p_i, substeps, period, unroll_substeps)
            finite = jnp.all(jnp.isfinite(jnp.stack(state)))
            fast = (jnp.abs(state[3]) >= vlim) | (jnp.abs(state[4]) >= vlim)
            fast = fast | (jnp.abs(state[5]) >= vlim)
            diverged = diverged | ~finite | fast
            return (state, memory, peak, squares, steady_sum, diverged), None

        state = tuple(zero + v for v in (*q0, 0.0, 0.0, 0.0))
        memory = tuple(zero + v for v in (*tau0, 0.0, 0.0, 0.0, 0.0, 0.0))
        carry = (state, memory, zero - jnp.inf, zero, zero, jnp.zeros_like(ke, dtype=bool))
        carry, _ = lax.scan(period_step, carry, jnp.arange(n - 1), unroll=unroll_periods)
        # The last sample is measured, never integrated past.
        _, _, (peak, squares, steady_sum) = sample(n - 1, carry)
        diverged = carry[5]
        rms = jnp.where(diverged, jnp.nan, jnp.sqrt(squares / (n - late)))
        ss = jnp.where(diverged, jnp.nan, steady_sum / (n - steady))
        return peak, rms, ss, diverged

    return jax.jit(jax.vmap(one_run))


def sessions(
    data: dict, threads: list[int], repeats: int, flags: list[str]
) -> dict[tuple[str, int], dict]:
    """Run this script once per (XLA flag, thread count) in a fresh process (``XLA_FLAGS`` is
    read when jax initialises) and return each session's report.

    ``data`` holds the runs' parameters and admit_rs's metrics (``main`` checks agreement
    against them before timing). One thread: the process is pinned to one core, so XLA's
    thread pool has that core only. Two or more: as many host devices, the runs sharded
    over them, so that XLA runs one partition on each.
    """
    import subprocess
    import tempfile

    reports = {}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "runs.npz"
        np.savez(path, **data)
        for t in threads:
            for flag in flags:
                env = dict(os.environ)
                xla = [flag] if flag else []
                if t > 1:
                    xla.append(f"--xla_force_host_platform_device_count={t}")
                env["XLA_FLAGS"] = " ".join(xla)
                env["JAX_PEER_CORES"] = ",".join(map(str, sorted(os.sched_getaffinity(0))[:t]))
                done = subprocess.run(
                    [sys.executable, __file__, str(path), "--repeats", str(repeats)],
                    env=env, capture_output=True, text=True,
                )  # fmt: skip
                lines = done.stdout.strip().splitlines()
                if not lines:
                    raise SystemExit(f"JAX session failed ({flag or 'as shipped'}):\n"
                                     f"{done.stderr[-2000:]}")  # fmt: skip
                report = json.loads(lines[-1])
                if done.returncode != 0:
                    raise SystemExit(f"JAX peer disagrees ({flag or 'as shipped'}, {t} "
                                     f"thread(s)): {report}; not timing")  # fmt: skip
                reports[flag, t] = report
    return reports


def main() -> None:
    parser = argparse.ArgumentParser(description="one JAX timing session (see module doc)")
    parser.add_argument("data", type=Path)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--unroll-substeps", type=int, default=1)
    parser.add_argument("--unroll-periods", type=int, default=1)
    args = parser.parse_args()
    if not HAVE_JAX:
        raise SystemExit("jax is not installed: pip install 'jax[cpu]'")
    data = np.load(args.data)
    c = peers.Fig14(duration=float(data["duration"]), position_error=0.01)
    wall = peers.setup(c).wall
    # With several host devices (XLA_FLAGS=--xla_force_host_platform_device_count=N, set by
    # the caller) the runs are sharded over them: XLA then runs one partition per device
    # thread, which is how JAX uses more than one core for a batch of small element-wise ops.
    devices = jax.devices()
    if len(devices) > 1:
        from jax.sharding import Mesh, NamedSharding, PartitionSpec

        placement = NamedSharding(Mesh(np.array(devices), ("runs",)), PartitionSpec("runs"))
    else:
        placement = devices[0]
    stiffness = jax.device_put(data["stiffness"], placement)
    estimate = jax.device_put(wall + data["error"], placement)
    sweep = build(c, args.unroll_substeps, args.unroll_periods)
    start = time.perf_counter()
    compiled = sweep.lower(stiffness, estimate).compile()
    compile_s = time.perf_counter() - start
    start = time.perf_counter()
    peak, rms, _, diverged = (np.asarray(a) for a in compiled(stiffness, estimate))
    first_s = time.perf_counter() - start
    agreement = {}
    for name, ours in [("force_peak", peak), ("force_rms_error", rms)]:
        ref = data[name]
        agreement[name] = float(np.max(np.abs(ours - ref) / np.abs(ref)))
    report = {
        "jax": jax.__version__,
        "xla_flags": os.environ.get("XLA_FLAGS", ""),
        "devices": [str(d) for d in jax.devices()],
        "cores": sorted(os.sched_getaffinity(0)),
        "compile_s": compile_s,
        "first_s": first_s,
        "agreement": agreement,
        "diverged": int(diverged.sum()),
    }
    if diverged.any() or not all(v <= 1e-9 for v in agreement.values()):
        print(json.dumps(report))
        raise SystemExit(1)
    times = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        jax.block_until_ready(compiled(stiffness, estimate))
        times.append(time.perf_counter() - start)
    report["times_s"] = times
    print(json.dumps(report))


if __name__ == "__main__":
    main()
