"""Polishing a curved part: 10 N on a sphere and on a scanned height field while sliding.

fig. 14's task (10 N step, a 0.05 m sine along the part, TDC + Scheme 2) on the paper's arm
and on a Franka Panda, against

* a sphere of radius 0.3 m (the tool on its outside) and a scanned-looking height field
  (a gentle bulge with 0.3 mm bumps, 41×41 nodes at 5 mm),
* Coulomb friction μ = 0, 0.1, 0.3, 0.5, 1.0 (SPEC §15),
* the controller's belief about the shape: the true shape, a sphere with a 10 % larger
  radius, and a flat estimate (the tangent plane at the start).

    python examples/polishing.py [OUT_DIR]   # writes polishing.png and polishing.md

docs/surfaces.md shows and discusses the output.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import admit_rs as ar
import numpy as np
import polars as pl
from matplotlib.figure import Figure

DATA = Path(__file__).resolve().parent / "data"
PANDA = ar.UrdfArm(
    DATA / "panda.urdf", "panda_hand_tcp", q0=(0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
)
FRICTIONS = (0.0, 0.1, 0.3, 0.5, 1.0)
RADIUS = 0.3
METRICS = ["force_rms_error", "force_ss_error", "force_peak", "tangential_force_mean",
           "path_rms_error", "stable", "passed"]  # fmt: skip


def scanned_part(spacing: float = 0.005, nodes: int = 41, seed: int = 3) -> ar.HeightField:
    """A part as a scanner would give it: a gentle bulge (1/R = 2 /m across the sliding
    direction, 4 /m along it) with 0.3 mm bumps of a few centimetres, on a grid of heights."""
    rng = np.random.default_rng(seed)
    u = (np.arange(nodes) - (nodes - 1) / 2) * spacing
    uu, vv = np.meshgrid(u, u, indexing="ij")
    heights = 2.0 * uu**2 + 1.0 * vv**2  # receding from the tool's start: a bulge
    for _ in range(6):
        cu, cv, w = rng.uniform(-0.08, 0.08), rng.uniform(-0.08, 0.08), rng.uniform(0.01, 0.03)
        heights += 3e-4 * rng.uniform(-1, 1) * np.exp(-((uu - cu) ** 2 + (vv - cv) ** 2) / w**2)
    return ar.HeightField(heights=heights, spacing=(spacing, spacing))


def base(arm: str) -> ar.Scenario:
    sc = ar.paper.scenario("fig14")
    if arm == "Panda":
        sc = sc.replace(robot=PANDA, controller=ar.TimeDelayControl.for_arm(PANDA))
    return sc


def friction_table() -> tuple[pl.DataFrame, dict[tuple[str, str, float], ar.Result]]:
    """Each arm on each part at each μ, the controller believing the true shape."""
    rows, results = [], {}
    parts = {"sphere": ar.Sphere(radius=RADIUS), "scan": scanned_part()}
    for arm in ("paper arm", "Panda"):
        for part, wall in parts.items():
            for mu in FRICTIONS:
                sc = base(arm).replace(wall=dataclasses.replace(wall, friction=mu))
                r = ar.simulate(sc)
                results[(arm, part, mu)] = r
                rows.append({"arm": arm, "part": part, "μ": mu,
                             **{m: r.metrics[m] for m in METRICS}})  # fmt: skip
    return pl.DataFrame(rows), results


def estimate_table() -> tuple[pl.DataFrame, dict[str, ar.Result]]:
    """The paper's arm on the sphere at μ = 0.3 with three beliefs about its shape."""
    wall = ar.Sphere(radius=RADIUS, friction=0.3)
    beliefs = {
        "true shape": None,
        "radius +10 %": ar.Sphere(radius=1.1 * RADIUS),
        "flat (tangent plane)": ar.Wall(),
    }
    rows, results = [], {}
    for name, estimate in beliefs.items():
        r = ar.simulate(base("paper arm").replace(wall=wall, wall_estimate=estimate))
        results[name] = r
        rows.append({"belief": name, **{m: r.metrics[m] for m in METRICS}})
    scan = scanned_part()
    for name, estimate in {"scan, true shape": None, "scan, flat": ar.Wall()}.items():
        sc = base("paper arm").replace(wall=dataclasses.replace(scan, friction=0.3),
                                       wall_estimate=estimate)  # fmt: skip
        r = ar.simulate(sc)
        results[name] = r
        rows.append({"belief": name, **{m: r.metrics[m] for m in METRICS}})
    return pl.DataFrame(rows), results


def figure(by_mu: dict, by_belief: dict) -> Figure:
    fig = Figure(figsize=(12, 8), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True)
    for mu in FRICTIONS:
        tr = by_mu[("paper arm", "sphere", mu)].trace
        t = tr["t"].to_numpy()
        axes[0, 0].plot(t, tr["f"].to_numpy(), lw=1, label=f"μ = {mu:g}")
        axes[0, 1].plot(t, tr["f_t"].to_numpy(), lw=1, label=f"μ = {mu:g}")
    for name, r in by_belief.items():
        tr = r.trace
        axes[1, 0].plot(tr["t"].to_numpy(), tr["f"].to_numpy(), lw=1, label=name)
        ref = np.column_stack([tr[c].to_numpy() for c in ("x_ref", "y_ref", "z_ref")])
        pos = np.column_stack([tr[c].to_numpy() for c in ("x", "y", "z")])
        axes[1, 1].plot(tr["t"].to_numpy(), 1e3 * np.linalg.norm(ref - pos, axis=1), lw=1,
                        label=name)  # fmt: skip
    axes[0, 0].set_title("paper arm on a sphere (R = 0.3 m): normal force f")
    axes[0, 1].set_title("friction force f_t = |F_t| along the sphere")
    axes[1, 0].set_title("μ = 0.3: normal force for each belief about the shape")
    axes[1, 1].set_title("μ = 0.3: tracking error |X_d − X|")
    for ax, unit in zip(axes.flat, ["f [N]", "f_t [N]", "f [N]", "|X_d − X| [mm]"], strict=True):
        ax.set_ylabel(unit)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    axes[1, 0].set_ylim(0, 20)
    return fig


def main(out: Path) -> dict[str, pl.DataFrame]:
    out.mkdir(parents=True, exist_ok=True)
    frictions, by_mu = friction_table()
    beliefs, by_belief = estimate_table()
    figure(by_mu, by_belief).savefig(out / "polishing.png", dpi=110)
    with pl.Config(tbl_rows=40, tbl_cols=20, float_precision=4, tbl_width_chars=200):
        text = f"## Friction\n\n{frictions}\n\n## Beliefs about the shape\n\n{beliefs}\n"
    (out / "polishing.md").write_text(text, encoding="utf-8")
    print(text)
    return {"friction": frictions, "beliefs": beliefs}


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("polishing_out"))
