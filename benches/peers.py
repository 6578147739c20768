"""Independent peers of the admit_rs core for the fig. 14 scenario (used by compare.py).

The scenario (SPEC §§1–6, fig. 14): three-link arm (rod masses, friction 3 q̇ + 5 tanh(q̇/0.01),
g = 9.81) against a wall k_e = 30 000 N/m at the tip's x at q0 = [0, π/4, −π/4]; time-delayed
control eq. (18) with D̄ = 0.1, K_t = 200, K_A = 5, K_D = 20, K_P = 100, τ_{−1} = G(q0),
q̈_{−1} = 0; Scheme 2 admittance filter (m = 1, b = 800, k = 0, k_a = 1) discretised exactly with
a zero-order hold; f_d = 10 N step, z_d = z0 + 0.05 sin t; T = 1 ms, 10 RK4 substeps with τ held,
10 s → 10 001 samples.

Two implementations, written from the SPEC the way a user writing the loop would: sin, cos and
tanh evaluated afresh at every RK4 stage, the dynamics as the textbook closed forms (the Rust
core since evaluates stage trig by angle addition and folds the parameter-only products; the
two agree to 2e-11 on every column, so rounding, not modelling, is all that differs):

* :func:`run_numpy` — plain NumPy: the state lives in small float64 arrays, trigonometry,
  friction and the RK4 combinations are vectorised over the joints; the 3×3 algebra is the
  closed form (D is block diagonal), as in the Rust core.
* :func:`run_numba` — one ``@njit`` function over the whole run: scalars only, closed-form 3×3
  algebra, no Python objects inside. ``run_python`` is the same code uncompiled (CPython floats
  and the ``math`` module), offered as a reference point for the NumPy peer.

Both return a ``(samples, 20)`` float64 array with the columns of :data:`COLUMNS` (the same as the
admit_rs trace).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

try:
    import numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - reported by compare.py
    numba = None
    HAVE_NUMBA = False

COLUMNS = (
    "t", "q1", "q2", "q3", "qd1", "qd2", "qd3", "x", "y", "z", "x_ref", "y_ref", "z_ref",
    "f", "f_d", "x_a", "tau1", "tau2", "tau3", "xa_dot",
)  # fmt: skip


@dataclass(frozen=True)
class Fig14:
    """The fig. 14 preset; every number here is checked against ``ar.paper.scenario("fig14")``
    by compare.py."""

    lengths: tuple[float, float, float] = (0.66, 0.43, 0.43)
    masses: tuple[float, float, float] = (30.0, 17.4, 4.8)
    viscous: float = 3.0
    coulomb: float = 5.0
    eps: float = 0.01
    gravity: float = 9.81
    q0: tuple[float, float, float] = (0.0, math.pi / 4, -math.pi / 4)
    stiffness: float = 30_000.0
    position_error: float = 0.0
    # time-delayed control, eq. (18)
    ka: float = 5.0
    kd: float = 20.0
    kp: float = 100.0
    inertia: float = 0.1
    torque_constant: float = 200.0
    # Scheme 2 admittance filter
    fm: float = 1.0
    fb: float = 800.0
    fk: float = 0.0
    fka: float = 1.0
    # references
    force: float = 10.0
    z_amplitude: float = 0.05
    z_omega: float = 1.0
    z_phase: float = 0.0
    z_offset: float = 0.0
    # timing
    period: float = 1e-3
    substeps: int = 10
    duration: float = 10.0

    @property
    def samples(self) -> int:
        return round(self.duration / self.period) + 1


@dataclass(frozen=True)
class Setup:
    """Constants computed once, before the loop (as ``Simulation::new`` does)."""

    arm: tuple[float, ...]  # l1 l2 l3 m2 m3 a2 a3 i2 i3 g fv fc eps
    x0: tuple[float, float, float]
    wall: float  # x_e
    wall_estimate: float  # x̂_e
    tau0: tuple[float, float, float]  # G(q0)
    ad: tuple[float, float, float, float]  # row-major
    bd: tuple[float, float]


def setup(c: Fig14) -> Setup:
    l1, l2, l3 = c.lengths
    _, m2, m3 = c.masses
    # Rod mass model: centre of mass at l/2, transverse inertia m l²/12.
    a2, a3 = l2 / 2.0, l3 / 2.0
    i2, i3 = m2 * l2 * l2 / 12.0, m3 * l3 * l3 / 12.0
    g = c.gravity
    q1, q2, q3 = c.q0
    s1, c1 = math.sin(q1), math.cos(q1)
    s2, c2 = math.sin(q2), math.cos(q2)
    s3, c3 = math.sin(q3), math.cos(q3)
    s23 = s2 * c3 + c2 * s3
    c23 = c2 * c3 - s2 * s3
    r = l2 * c2 + l3 * c23
    x0 = (c1 * r, s1 * r, l1 + l2 * s2 + l3 * s23)
    r2 = a2 * c2
    r3 = l2 * c2 + a3 * c23
    tau0 = (0.0, g * (m2 * r2 + m3 * r3), g * m3 * a3 * c23)
    m, b, k, ka = c.fm, c.fb, c.fk, c.fka
    aug = np.array([[0.0, 1.0, 0.0], [-k / m, -b / m, ka / m], [0.0, 0.0, 0.0]]) * c.period
    e = scipy.linalg.expm(aug)
    wall = x0[0]
    return Setup(
        arm=(l1, l2, l3, m2, m3, a2, a3, i2, i3, g, c.viscous, c.coulomb, c.eps),
        x0=x0,
        wall=wall,
        wall_estimate=wall + c.position_error,
        tau0=tau0,
        ad=(float(e[0, 0]), float(e[0, 1]), float(e[1, 0]), float(e[1, 1])),
        bd=(float(e[0, 2]), float(e[1, 2])),
    )


# --------------------------------------------------------------------------------------------
# (a) NumPy
# --------------------------------------------------------------------------------------------


def run_numpy(c: Fig14) -> np.ndarray:
    """The run in plain NumPy; returns the ``(samples, 20)`` trace."""
    s = setup(c)
    l1, l2, l3, m2, m3, a2, a3, i2, i3, g, _, _, _ = s.arm
    fv = np.full(3, c.viscous)
    fc = np.full(3, c.coulomb)
    eps = c.eps
    ke, xe = c.stiffness, s.wall
    # Constant parts of D, folded once (same expressions, same order as the Rust core).
    d22_0 = m2 * a2 * a2 + i2
    d22_1 = l2 * l2 + a3 * a3
    d22_2 = 2.0 * l2 * a3
    dd2_0 = -2.0 * (m2 * a2 * a2 + i2)
    n = c.samples
    period = c.period
    h = period / c.substeps
    half, sixth = h / 2.0, h / 6.0

    def accel(y: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """d/dt [q, q̇] for y = [q, q̇] (6-vector) under torque tau."""
        q, qd = y[:3], y[3:]
        sn, cs = np.sin(q), np.cos(q)
        s1, s2, s3 = sn.tolist()
        c1, c2, c3 = cs.tolist()
        w1, w2, w3 = qd.tolist()
        s23 = s2 * c3 + c2 * s3
        c23 = c2 * c3 - s2 * s3
        r = l2 * c2 + l3 * c23
        pen = c1 * r - xe
        f = ke * pen if pen > 0.0 else 0.0
        hh = l2 * s2 + l3 * s23
        r2 = a2 * c2
        r3 = l2 * c2 + a3 * c23
        d11 = m2 * r2 * r2 + i2 * c2 * c2 + m3 * r3 * r3 + i3 * c23 * c23
        d22 = d22_0 + m3 * (d22_1 + d22_2 * c3) + i3
        d23 = m3 * (a3 * a3 + l2 * a3 * c3) + i3
        d33 = m3 * a3 * a3 + i3
        dd2 = dd2_0 * c2 * s2 - 2.0 * m3 * r3 * (l2 * s2 + a3 * s23) - 2.0 * i3 * c23 * s23
        dd3 = -2.0 * m3 * r3 * a3 * s23 - 2.0 * i3 * c23 * s23
        hc = -m3 * l2 * a3 * s3
        # τ + Jᵀ[−f, 0, 0] − C − G − τ_f, as 3-vectors (same association as the Rust core)
        contact = np.array([s1 * r, c1 * hh, c1 * l3 * s23]) * f
        coriolis = np.array(
            [
                (dd2 * w2 + dd3 * w3) * w1,
                2.0 * hc * w2 * w3 + hc * w3 * w3 - 0.5 * dd2 * w1 * w1,
                -hc * w2 * w2 - 0.5 * dd3 * w1 * w1,
            ]
        )
        gravity = np.array([0.0, g * (m2 * r2 + m3 * r3), g * m3 * a3 * c23])
        friction = fv * qd + fc * np.tanh(qd / eps)
        rhs = tau + contact - coriolis - gravity - friction
        b1, b2, b3 = rhs.tolist()
        det = d22 * d33 - d23 * d23
        out = np.empty(6)
        out[:3] = qd
        out[3] = b1 / d11
        out[4] = (d33 * b2 - d23 * b3) / det
        out[5] = (d22 * b3 - d23 * b2) / det
        return out

    ad = np.array(s.ad).reshape(2, 2)
    bd = np.array(s.bd)
    fstate = np.zeros(2)
    trace = np.empty((n, 20))
    y = np.array([*c.q0, 0.0, 0.0, 0.0])
    tau_prev = np.array(s.tau0)
    qd_prev = None
    x0 = s.x0
    gain = c.inertia * c.torque_constant
    kp, kd, ka = c.kp, c.kd, c.ka
    for k in range(n):
        t = k * period
        q1, q2, q3, w1, w2, w3 = y.tolist()
        # measure: tip position, Jacobian, velocity, force
        s1, s2, s3 = math.sin(q1), math.sin(q2), math.sin(q3)
        c1, c2, c3 = math.cos(q1), math.cos(q2), math.cos(q3)
        s23 = s2 * c3 + c2 * s3
        c23 = c2 * c3 - s2 * s3
        r = l2 * c2 + l3 * c23
        hh = l2 * s2 + l3 * s23
        pos = np.array([c1 * r, s1 * r, l1 + hh])
        jac = np.array(
            [
                [-s1 * r, -c1 * hh, -c1 * l3 * s23],
                [c1 * r, -s1 * hh, -s1 * l3 * s23],
                [0.0, r, l3 * c23],
            ]
        )
        qd = y[3:]
        vel = jac @ qd
        pen = pos[0] - xe
        force = ke * pen if pen > 0.0 else 0.0
        # references
        f_d = c.force
        zs, zc = math.sin(c.z_omega * t + c.z_phase), math.cos(c.z_omega * t + c.z_phase)
        z_val = c.z_offset + c.z_amplitude * zs
        z_rate = c.z_amplitude * c.z_omega * zc
        z_acc = -c.z_amplitude * c.z_omega * c.z_omega * zs
        # admittance filter: output, then state update with e_f,k
        ef = f_d - force
        xa, xa_dot = fstate.tolist()
        xa_acc = (c.fka * ef - c.fb * xa_dot - c.fk * xa) / c.fm
        fstate = ad @ fstate + bd * ef
        x_ref = s.wall_estimate + xa
        des_p = np.array([x_ref, x0[1], x0[2] + z_val])
        des_v = np.array([xa_dot, 0.0, z_rate])
        des_a = np.array([xa_acc, 0.0, z_acc])
        # eq. (39) and TDC eq. (18)
        v = (des_a + ((des_v - vel) * kd + (des_p - pos) * kp)) / ka
        qdd_prev = np.zeros(3) if qd_prev is None else (qd - qd_prev) / period
        tau = jac.T @ v * gain + (tau_prev - qdd_prev * c.inertia)
        tau_prev = tau
        qd_prev = qd.copy()
        tl = tau.tolist()
        trace[k] = (
            t, q1, q2, q3, w1, w2, w3, pos[0], pos[1], pos[2], x_ref, x0[1], des_p[2],
            force, f_d, xa, tl[0], tl[1], tl[2], xa_dot,
        )  # fmt: skip
        if k + 1 < n:
            for _ in range(c.substeps):
                k1 = accel(y, tau)
                y2 = y + k1 * half
                k2 = accel(y2, tau)
                y3 = y + k2 * half
                k3 = accel(y3, tau)
                y4 = y + k3 * h
                k4 = accel(y4, tau)
                y = y + (k1 + (k2 + k3) * 2.0 + k4) * sixth
            if not np.isfinite(y).all() or (np.abs(y[3:]) >= 100.0).any():
                return trace[: k + 1]
    return trace


# --------------------------------------------------------------------------------------------
# (b) Numba: the whole run in one compiled function
# --------------------------------------------------------------------------------------------


def _accel(q1, q2, q3, w1, w2, w3, t1, t2, t3, p):
    """q̈ of eq. (1) with the contact force at the same state (``ThreeLinkArm::accelerate``)."""
    l1, l2, l3, m2, m3, a2, a3, i2, i3, g, fv, fc, eps, ke, xe = p
    s1 = math.sin(q1)
    c1 = math.cos(q1)
    s2 = math.sin(q2)
    c2 = math.cos(q2)
    s3 = math.sin(q3)
    c3 = math.cos(q3)
    s23 = s2 * c3 + c2 * s3
    c23 = c2 * c3 - s2 * s3
    r = l2 * c2 + l3 * c23
    pen = c1 * r - xe
    f = ke * pen if pen > 0.0 else 0.0
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
    fr1 = fv * w1 + fc * math.tanh(w1 / eps)
    fr2 = fv * w2 + fc * math.tanh(w2 / eps)
    fr3 = fv * w3 + fc * math.tanh(w3 / eps)
    b1 = t1 + ct1 - cor1 - 0.0 - fr1
    b2 = t2 + ct2 - cor2 - g2 - fr2
    b3 = t3 + ct3 - cor3 - g3 - fr3
    det = d22 * d33 - d23 * d23
    return b1 / d11, (d33 * b2 - d23 * b3) / det, (d22 * b3 - d23 * b2) / det


def _control(k, q1, q2, q3, w1, w2, w3, memory, period, p, ctl, flt, ref, x0, wall_estimate):
    """Measure, references, filter and TDC eq. (18) at sample k: returns the applied torque,
    the recorded quantities and the controller/filter memory for sample k + 1."""
    l1, l2, l3 = p[0], p[1], p[2]
    ke, xe = p[13], p[14]
    ka, kd, kp, inertia, kt, _ = ctl
    ad00, ad01, ad10, ad11, bd0, bd1, fm, fb, fk, fka = flt
    f_d, z_off, z_amp, z_om, z_ph = ref
    x0x, x0y, x0z = x0
    tp1, tp2, tp3, pw1, pw2, pw3, fs0, fs1 = memory
    gain = inertia * kt
    t = k * period
    # 1. measure
    s1 = math.sin(q1)
    c1 = math.cos(q1)
    s2 = math.sin(q2)
    c2 = math.cos(q2)
    s3 = math.sin(q3)
    c3 = math.cos(q3)
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
    force = ke * pen if pen > 0.0 else 0.0
    # 2. references
    arg = z_om * t + z_ph
    zs = math.sin(arg)
    zc = math.cos(arg)
    z_val = z_off + z_amp * zs
    z_rate = z_amp * z_om * zc
    z_acc = -z_amp * z_om * z_om * zs
    # 3. admittance filter: output at t_k, then advance with e_f,k
    ef = f_d - force
    xa = fs0
    xa_dot = fs1
    xa_acc = (fka * ef - fb * xa_dot - fk * xa) / fm
    fs0, fs1 = ad00 * xa + ad01 * xa_dot + bd0 * ef, ad10 * xa + ad11 * xa_dot + bd1 * ef
    x_ref = wall_estimate + xa
    dpz = x0z + z_val
    # 4. eq. (39), then TDC eq. (18)
    vx = j00 * w1 + j01 * w2 + j02 * w3
    vy = j10 * w1 + j11 * w2 + j12 * w3
    vz = j20 * w1 + j21 * w2 + j22 * w3
    v1 = (xa_acc + ((xa_dot - vx) * kd + (x_ref - px) * kp)) / ka
    v2 = (0.0 + ((0.0 - vy) * kd + (x0y - py) * kp)) / ka
    v3 = (z_acc + ((z_rate - vz) * kd + (dpz - pz) * kp)) / ka
    if k == 0:
        a1 = a2 = a3 = 0.0
    else:
        a1 = (w1 - pw1) / period
        a2 = (w2 - pw2) / period
        a3 = (w3 - pw3) / period
    tau1 = (j00 * v1 + j10 * v2 + j20 * v3) * gain + (tp1 - a1 * inertia)
    tau2 = (j01 * v1 + j11 * v2 + j21 * v3) * gain + (tp2 - a2 * inertia)
    tau3 = (j02 * v1 + j12 * v2 + j22 * v3) * gain + (tp3 - a3 * inertia)
    record = (t, px, py, pz, x_ref, x0y, dpz, force, f_d, xa, xa_dot)
    return (tau1, tau2, tau3), record, (tau1, tau2, tau3, w1, w2, w3, fs0, fs1)


def _advance(q1, q2, q3, w1, w2, w3, tau1, tau2, tau3, p, substeps, period):
    """RK4 over one period with τ held (``substeps`` steps); the contact force is evaluated
    inside `_accel` at every stage."""
    h = period / substeps
    half = h / 2.0
    sixth = h / 6.0
    for _ in range(substeps):
        e1, e2, e3 = _accel(q1, q2, q3, w1, w2, w3, tau1, tau2, tau3, p)
        bq1, bq2, bq3 = q1 + w1 * half, q2 + w2 * half, q3 + w3 * half
        bw1, bw2, bw3 = w1 + e1 * half, w2 + e2 * half, w3 + e3 * half
        f1, f2, f3 = _accel(bq1, bq2, bq3, bw1, bw2, bw3, tau1, tau2, tau3, p)
        cq1, cq2, cq3 = q1 + bw1 * half, q2 + bw2 * half, q3 + bw3 * half
        cw1, cw2, cw3 = w1 + f1 * half, w2 + f2 * half, w3 + f3 * half
        g1, g2, g3 = _accel(cq1, cq2, cq3, cw1, cw2, cw3, tau1, tau2, tau3, p)
        dq1, dq2, dq3 = q1 + cw1 * h, q2 + cw2 * h, q3 + cw3 * h
        dw1, dw2, dw3 = w1 + g1 * h, w2 + g2 * h, w3 + g3 * h
        k1, k2, k3 = _accel(dq1, dq2, dq3, dw1, dw2, dw3, tau1, tau2, tau3, p)
        q1 += (w1 + (bw1 + cw1) * 2.0 + dw1) * sixth
        q2 += (w2 + (bw2 + cw2) * 2.0 + dw2) * sixth
        q3 += (w3 + (bw3 + cw3) * 2.0 + dw3) * sixth
        w1 += (e1 + (f1 + g1) * 2.0 + k1) * sixth
        w2 += (e2 + (f2 + g2) * 2.0 + k2) * sixth
        w3 += (e3 + (f3 + g3) * 2.0 + k3) * sixth
    return q1, q2, q3, w1, w2, w3


def _diverged(q1, q2, q3, w1, w2, w3, vlim):
    finite = (
        math.isfinite(q1)
        and math.isfinite(q2)
        and math.isfinite(q3)
        and math.isfinite(w1)
        and math.isfinite(w2)
        and math.isfinite(w3)
    )
    return not finite or abs(w1) >= vlim or abs(w2) >= vlim or abs(w3) >= vlim


def _kernel(n, substeps, period, p, ctl, flt, ref, x0, wall_estimate, tau0, q0):
    """The whole run: returns the (n, 20) trace (rows after a divergence are NaN)."""
    trace = np.full((n, 20), np.nan)
    q1, q2, q3 = q0
    w1 = w2 = w3 = 0.0
    memory = (tau0[0], tau0[1], tau0[2], 0.0, 0.0, 0.0, 0.0, 0.0)
    for k in range(n):
        tau, rec, memory = _control(
            k, q1, q2, q3, w1, w2, w3, memory, period, p, ctl, flt, ref, x0, wall_estimate
        )
        t, px, py, pz, x_ref, x0y, dpz, force, f_d, xa, xa_dot = rec
        # 5. record
        row = trace[k]
        row[0] = t
        row[1] = q1
        row[2] = q2
        row[3] = q3
        row[4] = w1
        row[5] = w2
        row[6] = w3
        row[7] = px
        row[8] = py
        row[9] = pz
        row[10] = x_ref
        row[11] = x0y
        row[12] = dpz
        row[13] = force
        row[14] = f_d
        row[15] = xa
        row[16] = tau[0]
        row[17] = tau[1]
        row[18] = tau[2]
        row[19] = xa_dot
        # 6. RK4 substeps with τ_k held
        if k + 1 < n:
            q1, q2, q3, w1, w2, w3 = _advance(
                q1, q2, q3, w1, w2, w3, tau[0], tau[1], tau[2], p, substeps, period
            )
            if _diverged(q1, q2, q3, w1, w2, w3, ctl[5]):
                break
    return trace


def jit_kernel(kernel, **options):
    """``kernel`` compiled with Numba, calling the compiled per-period functions."""
    helpers = {
        "_accel": _accel_jit,
        "_control": _control_jit,
        "_advance": _advance_jit,
        "_diverged": _diverged_jit,
    }
    fresh = type(kernel)(kernel.__code__, {**kernel.__globals__, **helpers})
    return numba.njit(**options)(fresh)


if HAVE_NUMBA:
    _accel_jit = numba.njit(inline="always")(_accel)

    def _jit_calling_accel(func):
        # The functions call `_accel` by global name: compile copies whose globals see the
        # jitted one.
        fresh = type(func)(func.__code__, {**func.__globals__, "_accel": _accel_jit})
        return numba.njit(inline="always")(fresh)

    _control_jit = numba.njit(inline="always")(_control)
    _advance_jit = _jit_calling_accel(_advance)
    _diverged_jit = numba.njit(inline="always")(_diverged)
    _kernel_jit = jit_kernel(_kernel)
else:
    _kernel_jit = None


def _kernel_args(c: Fig14) -> tuple:
    s = setup(c)
    p = (*s.arm, c.stiffness, s.wall)
    ctl = (c.ka, c.kd, c.kp, c.inertia, c.torque_constant, 100.0)
    flt = (*s.ad, *s.bd, c.fm, c.fb, c.fk, c.fka)
    ref = (c.force, c.z_offset, c.z_amplitude, c.z_omega, c.z_phase)
    return (c.samples, c.substeps, c.period, p, ctl, flt, ref, s.x0, s.wall_estimate, s.tau0, c.q0)


def run_numba(c: Fig14) -> np.ndarray:
    """The run as one compiled Numba function (compiles on first call)."""
    if _kernel_jit is None:
        raise RuntimeError("numba is not installed (pip install numba)")
    return _kernel_jit(*_kernel_args(c))


def run_python(c: Fig14) -> np.ndarray:
    """The Numba kernel uncompiled: CPython floats and the math module."""
    return _kernel(*_kernel_args(c))
