"""A line-by-line Python transcription of the Rust core's plant period, for the cost model.

`compare.py` runs it twice:

- on plain floats, from states of admit_rs's own fig. 14 trace, to check that it reproduces
  the next sample (so the transcription is the code that runs, not a paraphrase of it);
- on counting floats, to count the arithmetic of one RK4 substep, part by part.

Each function names the Rust function it transcribes and keeps its order of operations:
`rust/src/integrator.rs` `Plant::advance`; `rust/src/robot.rs` `Trig::new`, `Trig::shifted`,
`ThreeLinkArm::accelerate_at`, `dynamics_from` and `coulomb`; `environment.rs` `Wall::force`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

# The counting run attributes each operation to the part of the substep being executed.
SECTION: list[str] = ["other"]


def section(name: str) -> None:
    SECTION[0] = name


@dataclass(frozen=True)
class Arm:
    """`ThreeLinkArm` with its `InertiaConstants` (rust/src/robot.rs), folded in the same order."""

    l2: float
    l3: float
    a3: float
    g: float
    fv: float
    fc: float
    neg_two_inv_eps: float
    k2: float
    m3_l2: float
    m3_a3: float
    i3: float
    m3_l2_a3: float
    d22_0: float
    d22_c3: float
    d33: float
    g_m2_a2: float
    g_m3_a3: float
    ke: float
    xe: float

    @classmethod
    def new(cls, arm: tuple[float, ...], ke: float, xe: float) -> Arm:
        _l1, l2, l3, m2, m3, a2, a3, i2, i3, g, fv, fc, eps = arm
        k2 = m2 * a2 * a2 + i2
        d33 = m3 * a3 * a3 + i3
        return cls(
            l2=l2,
            l3=l3,
            a3=a3,
            g=g,
            fv=fv,
            fc=fc,
            neg_two_inv_eps=-2.0 / eps,
            k2=k2,
            m3_l2=m3 * l2,
            m3_a3=m3 * a3,
            i3=i3,
            m3_l2_a3=m3 * l2 * a3,
            d22_0=k2 + m3 * l2 * l2 + d33,
            d22_c3=2.0 * m3 * l2 * a3,
            d33=d33,
            g_m2_a2=g * m2 * a2,
            g_m3_a3=g * m3 * a3,
            ke=ke,
            xe=xe,
        )


Trig = tuple[Any, Any, Any, Any, Any, Any, Any, Any]  # s1 c1 s2 c2 s3 c3 s23 c23


def trig_new(q: list[Any], m: Any) -> Trig:
    """`Trig::new`: one sin/cos pair per joint, then s23 and c23 by angle addition."""
    section("fresh sin/cos (once per period)")
    s1, c1 = m.sin(q[0]), m.cos(q[0])
    s2, c2 = m.sin(q[1]), m.cos(q[1])
    s3, c3 = m.sin(q[2]), m.cos(q[2])
    return (s1, c1, s2, c2, s3, c3, s2 * c3 + c2 * s3, c2 * c3 - s2 * s3)


def trig_shifted(t: Trig, d: list[Any], q_shifted: Callable[[], list[Any]], m: Any) -> Trig:
    """`Trig::shifted`: sin/cos of q + δ from those of q (Taylor series for |δ| ≤ 1/128);
    `q_shifted` gives q + δ for the fresh evaluation beyond that (the compiler likewise
    computes it only on that branch)."""
    if any(abs(x) > 1.0 / 128.0 for x in d):
        return trig_new(q_shifted(), m)
    section("stage trig by angle addition")

    def sc(x: Any) -> tuple[Any, Any]:
        x2 = x * x
        s = x * (1.0 - x2 * (1.0 / 6.0) * (1.0 - x2 * (1.0 / 20.0)))
        c = 1.0 - x2 * 0.5 * (1.0 - x2 * (1.0 / 12.0) * (1.0 - x2 * (1.0 / 30.0)))
        return s, c

    def rot(s: Any, c: Any, x: Any) -> tuple[Any, Any]:
        sd, cd = sc(x)
        return s * cd + c * sd, c * cd - s * sd

    s1, c1 = rot(t[0], t[1], d[0])
    s2, c2 = rot(t[2], t[3], d[1])
    s3, c3 = rot(t[4], t[5], d[2])
    return (s1, c1, s2, c2, s3, c3, s2 * c3 + c2 * s3, c2 * c3 - s2 * s3)


def coulomb(v: Any, a: Arm, m: Any) -> Any:
    """`ThreeLinkArm::coulomb`: f_c tanh(q̇/ε) = f_c (1 − e)/(1 + e) with e = exp(−2|q̇|/ε) and
    the sign of q̇; 0 for a joint at rest, with no call."""
    if v == 0.0:
        return 0.0
    e = m.exp(abs(v) * a.neg_two_inv_eps)
    return m.copysign((a.fc * (1.0 - e)) / (1.0 + e), v)


def accelerate_at(t: Trig, qd: list[Any], tau: list[Any], a: Arm, m: Any) -> list[Any]:
    """`ThreeLinkArm::accelerate_at` with the wall's contact force (`Wall::force`)."""
    s1, c1, s2, c2, s3, c3, s23, c23 = t
    section("contact force and Jᵀf")
    r = a.l2 * c2 + a.l3 * c23
    pen = c1 * r - a.xe
    f = a.ke * pen if pen > 0.0 else 0.0
    h = a.l2 * s2 + a.l3 * s23
    ct = [s1 * r * f, c1 * h * f, c1 * a.l3 * s23 * f]
    section("D, C, G (folded constants)")
    m3r3 = a.m3_l2 * c2 + a.m3_a3 * c23
    r3 = a.l2 * c2 + a.a3 * c23
    i3cs = a.i3 * c23 * s23
    d11 = a.k2 * c2 * c2 + m3r3 * r3 + a.i3 * c23 * c23
    d22 = a.d22_0 + a.d22_c3 * c3
    d23 = a.d33 + a.m3_l2_a3 * c3
    p2 = a.k2 * c2 * s2 + m3r3 * (a.l2 * s2 + a.a3 * s23) + i3cs
    p3 = m3r3 * a.a3 * s23 + i3cs
    hc = -(a.m3_l2_a3 * s3)
    w1, w2, w3 = qd
    w11 = w1 * w1
    cor = [
        -2.0 * (p2 * w2 + p3 * w3) * w1,
        hc * w3 * (2.0 * w2 + w3) + p2 * w11,
        -hc * w2 * w2 + p3 * w11,
    ]
    grav = [0.0, a.g_m2_a2 * c2 + a.g * m3r3, a.g_m3_a3 * c23]
    section("rest = τ + Jᵀf − C − G − f_v q̇")
    # The x − 0.0 of G1 is folded by the compiler (x − 0.0 = x for every x), so not counted.
    rest = [
        tau[0] + ct[0] - cor[0] - a.fv * w1,
        tau[1] + ct[1] - cor[1] - grav[1] - a.fv * w2,
        tau[2] + ct[2] - cor[2] - grav[2] - a.fv * w3,
    ]
    section("D⁻¹ (yaw scalar ⊕ 2×2 block)")
    inv_d11 = 1.0 / d11
    inv_det = 1.0 / (d22 * a.d33 - d23 * d23)
    k22, k23, k33 = a.d33 * inv_det, -d23 * inv_det, d22 * inv_det
    section("Coulomb friction f_c tanh(q̇/ε)")
    tc = [coulomb(w, a, m) for w in qd]
    section("q̈ = D⁻¹ (rest − τ_c)")
    return [
        rest[0] * inv_d11 - tc[0] * inv_d11,
        (k22 * rest[1] + k23 * rest[2]) - (k22 * tc[1] + k23 * tc[2]),
        (k23 * rest[1] + k33 * rest[2]) - (k23 * tc[1] + k33 * tc[2]),
    ]


def _axpy(x: list[Any], y: list[Any], k: Any) -> list[Any]:
    return [xi + yi * k for xi, yi in zip(x, y, strict=True)]


def _scale(x: list[Any], k: Any) -> list[Any]:
    return [xi * k for xi in x]


def substep(
    q: list[Any], qd: list[Any], t1: Trig, tau: list[Any], h: float, a: Arm, m: Any
) -> tuple[list[Any], list[Any], Trig]:
    """The body of `Plant::advance`'s substep loop: classical RK4, stage trig from `t1`."""
    acc: Callable[[Trig, list[Any]], list[Any]] = lambda t, v: accelerate_at(t, v, tau, a, m)  # noqa: E731
    h2, h6 = h / 2.0, h / 6.0

    def plus(x: list[Any], y: list[Any]) -> Callable[[], list[Any]]:
        return lambda: [xi + yi for xi, yi in zip(x, y, strict=True)]

    a1 = acc(t1, qd)
    section("RK4 combinations")
    d2, qd2 = _scale(qd, h2), _axpy(qd, a1, h2)
    a2 = acc(trig_shifted(t1, d2, plus(q, d2), m), qd2)
    section("RK4 combinations")
    d3, qd3 = _scale(qd2, h2), _axpy(qd, a2, h2)
    a3 = acc(trig_shifted(t1, d3, plus(q, d3), m), qd3)
    section("RK4 combinations")
    d4, qd4 = _scale(qd3, h), _axpy(qd, a3, h)
    a4 = acc(trig_shifted(t1, d4, plus(q, d4), m), qd4)
    section("RK4 combinations")
    dq = [(v + (v2 + v3) * 2.0 + v4) * h6 for v, v2, v3, v4 in zip(qd, qd2, qd3, qd4, strict=True)]
    q = [x + y for x, y in zip(q, dq, strict=True)]
    t1 = trig_shifted(t1, dq, lambda: q, m)
    section("RK4 combinations")
    qd = [
        v + (x1 + (x2 + x3) * 2.0 + x4) * h6
        for v, x1, x2, x3, x4 in zip(qd, a1, a2, a3, a4, strict=True)
    ]
    return q, qd, t1


def period(
    q: list[Any], qd: list[Any], tau: list[Any], h: float, substeps: int, a: Arm, m: Any
) -> tuple[list[Any], list[Any]]:
    """`Plant::advance`: one control period from a fresh `Trig` (as `set_state` leaves it)."""
    t1 = trig_new(q, m)
    for _ in range(substeps):
        q, qd, t1 = substep(q, qd, t1, tau, h, a, m)
    return q, qd
