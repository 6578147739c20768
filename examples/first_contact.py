"""First contact (issue #23, docs/first_contact.md): what a user decides with it.

    python examples/first_contact.py [--out DIR] [--quick]

1. The trade-off between approach speed and impact peak, over wall stiffness k_e = 1e4 … 1e6
   N/m and over sensor latency 0–5 samples: a guarded approach (no slowdown, so the tool
   meets the wall at the approach speed v) through 5 mm of free space under fig. 14's TDC
   (4-s runs, the motion along the wall held: the slowest, 2 mm/s, touches at 2.5 s), with
   the energy bound v·√(k_e·m_eff) drawn for comparison (m_eff: the arm's mass along n at q0,
   1 / (n·J D⁻¹ Jᵀ·n)).
2. fig. 19 (the estimate 1 cm beyond the wall) without an approach, with a guarded approach,
   with and without re-anchoring.
3. Scheme 2 against the adaptive filter sliding over a plane tilted 3° from the estimate,
   and over a ball and a shaft believed flat or believed right.

Writes first_contact.png, first_contact.md (the tables) and the sweep tables (Parquet).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import admit_rs as ar
import matplotlib
import numpy as np
import polars as pl

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

GAP = 0.005


def effective_mass(scenario: ar.Scenario) -> float:
    """m_eff = 1 / (n·J D⁻¹ Jᵀ·n) at q0 along the wall normal n."""
    robot = scenario.robot
    terms = robot.dynamics(robot.q0)
    j, d = terms["jacobian"][:3], terms["inertia"]
    n, _ = scenario.wall.directions()
    return float(1.0 / (n @ j @ np.linalg.solve(d, j.T) @ n))


def approach(speed: float) -> ar.GuardedApproach:
    """No slowdown and velocity steps: the tool meets the wall at ``speed``."""
    return ar.GuardedApproach(speed=speed, contact_speed=speed, slowdown_distance=0.0,
                              acceleration=None)


def trade_off(speeds: list[float], stiffness: list[float], latency: list[int]) -> dict:
    base = ar.paper.scenario("fig14").replace(
        wall=ar.Wall(gap=GAP), approach=approach(0.05), duration=4.0, label="",
        # The motion held: its friction reversal (fig. 14's 12.6 N bump at 1.7 s) would
        # fall into the impact window of the slow approaches.
        z_reference=ar.Step(value=0.0))
    by_stiffness, by_latency = [], []
    for v in speeds:
        sc = base.replace(approach=approach(v))
        for table, path, values in ((by_stiffness, "wall.stiffness", stiffness),
                                    (by_latency, "sensor.latency", latency)):
            t = ar.sweep(sc, grid={path: values}, progress=False)
            table.append(t.with_columns(pl.lit(v).alias("approach.speed")))
    return {"base": base, "stiffness": pl.concat(by_stiffness, how="diagonal"),
            "latency": pl.concat(by_latency, how="diagonal")}


def fig19_cases() -> pl.DataFrame:
    fig19 = ar.paper.scenario("fig19")
    fig14 = ar.paper.scenario("fig14")
    cases = {
        "fig. 14 (estimate right)": fig14,
        "fig. 19, no approach": fig19,
        "fig. 19, GuardedApproach(reanchor=True)": fig19.replace(
            approach=ar.GuardedApproach(reanchor=True)),
        "fig. 19, GuardedApproach(acceleration=None)": fig19.replace(
            approach=ar.GuardedApproach(acceleration=None)),
        "fig. 19, GuardedApproach(reanchor=False)": fig19.replace(
            approach=ar.GuardedApproach(reanchor=False)),
        "fig. 19 Scheme 1, GuardedApproach(reanchor=True)": fig19.replace(
            admittance=ar.AdmittanceFilter.scheme1(), approach=ar.GuardedApproach(reanchor=True)),
        "fig. 19 Scheme 1, GuardedApproach(reanchor=False)": fig19.replace(
            admittance=ar.AdmittanceFilter.scheme1(),
            approach=ar.GuardedApproach(reanchor=False)),
    }
    rows = []
    for name, sc in cases.items():
        res = ar.simulate(sc)
        m = res.metrics
        rows.append({"case": name, "impact_peak": m["impact_peak"],
                     "settling_time": m["settling_time"], "force_ss_error": m["force_ss_error"],
                     "first_contact_time": m["first_contact_time"], "verdict": res.verdict})
    return pl.DataFrame(rows)


def tilted_cases() -> pl.DataFrame:
    theta = math.radians(3.0)
    base = ar.paper.scenario("fig8").replace(
        controller=ar.ComputedTorque(command_divisor=1.0, kd=200.0, kp=1e4,
                                     contact_compensation=True),
        wall=ar.Wall(normal=(math.cos(theta), 0.0, -math.sin(theta))),
        wall_estimate=ar.Wall(),
        z_reference=ar.Sampled(times=(0.0, 10.0), values=(0.0, 0.1)),
    )
    tdc = ar.paper.scenario("fig14").replace(
        wall=base.wall, wall_estimate=base.wall_estimate, z_reference=base.z_reference)
    rows = []
    for loop, sc in (("CT, contact compensation", base), ("TDC (fig. 14)", tdc)):
        for name, filt in (("Scheme 2", ar.AdmittanceFilter.scheme2(b=800.0, ka=1.0)),
                           ("adaptive σ = 0.005", ar.AdmittanceFilter.adaptive(sigma=0.005))):
            res = ar.simulate(sc.replace(admittance=filt))
            fm = res.trace["f_measured"].to_numpy()
            rows.append({"inner loop": loop, "filter": name,
                         "e_f last 2 s [N]": float(10.0 - fm[-2001:].mean()),
                         "verdict": res.verdict})
    rows.append({"inner loop": "closed form", "filter": "Scheme 2: b v tan θ / k_a",
                 "e_f last 2 s [N]": 800 * 0.01 * math.tan(theta), "verdict": ""})
    return pl.DataFrame(rows)


def curved_cases() -> pl.DataFrame:
    """Scheme 2 and the adaptive filter sliding 0.1 m at 0.01 m/s over a ball (R = 0.3 m) and
    along a shaft (a cylinder of R = 0.3 m whose axis is the motion's direction), believed
    flat or believed right. (A shaft slid across its axis in this plane is the ball.)"""
    rows = []
    parts = {"ball R = 0.3 m": ar.Sphere(radius=0.3),
             "shaft R = 0.3 m, along its axis": ar.Cylinder(radius=0.3, axis=(0.0, 0.0, 1.0))}
    for part, wall in parts.items():
        for belief_name, belief in (("flat", ar.Wall()), ("right shape", wall)):
            sc = ar.paper.scenario("fig8").replace(
                controller=ar.ComputedTorque(command_divisor=1.0, kd=200.0, kp=1e4,
                                             contact_compensation=True),
                wall=wall, wall_estimate=belief,
                z_reference=ar.Sampled(times=(0.0, 10.0), values=(0.0, 0.1)),
            )
            for name, filt in (("Scheme 2", ar.AdmittanceFilter.scheme2(b=800.0, ka=1.0)),
                               ("adaptive σ = 0.005", ar.AdmittanceFilter.adaptive(sigma=0.005))):
                res = ar.simulate(sc.replace(admittance=filt))
                fm = res.trace["f_measured"].to_numpy()
                rows.append({"part": part, "belief": belief_name, "filter": name,
                             "e_f at s = 0.1 m [N]": float(10.0 - fm[-1]),
                             "force_rms_error": res.metrics["force_rms_error"],
                             "verdict": res.verdict})
    return pl.DataFrame(rows)


def main(out: Path, quick: bool = False) -> dict[str, pl.DataFrame]:
    out.mkdir(parents=True, exist_ok=True)
    speeds = [0.005, 0.01, 0.02, 0.05, 0.1] if quick else list(np.geomspace(0.002, 0.2, 11))
    stiffness = [1e4, 1e5, 1e6] if quick else list(np.geomspace(1e4, 1e6, 9))
    latency = [0, 2, 5] if quick else [0, 1, 2, 3, 4, 5]
    maps = trade_off(speeds, stiffness, latency)
    m_eff = effective_mass(maps["base"])
    fig19 = fig19_cases()
    tilted = tilted_cases()
    curved = curved_cases()

    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    ax = axes[0]
    cmap = plt.get_cmap("viridis")
    for i, ke in enumerate(stiffness):
        rows = maps["stiffness"].filter(pl.col("wall.stiffness") == ke).sort("approach.speed")
        colour = cmap(i / max(1, len(stiffness) - 1))
        v = rows["approach.speed"].to_numpy()
        ax.loglog(v, rows["impact_peak"].to_numpy(), "o-", color=colour,
                  label=f"k_e = {ke:.0e}")
        ax.loglog(v, v * math.sqrt(ke * m_eff), ":", color=colour)
    ax.axhline(10.0, color="k", lw=0.8)
    ax.set_xlabel("approach speed v [m/s]")
    ax.set_ylabel("impact_peak [N]")
    ax.set_title(f"impact vs speed (dotted: v·√(k_e·m_eff), m_eff = {m_eff:.2f} kg)")
    ax.legend(fontsize=7)
    ax = axes[1]
    for i, lat in enumerate(latency):
        rows = maps["latency"].filter(pl.col("sensor.latency") == lat).sort("approach.speed")
        ax.loglog(rows["approach.speed"].to_numpy(), rows["impact_peak"].to_numpy(), "o-",
                  color=cmap(i / max(1, len(latency) - 1)), label=f"latency {lat} samples")
    ax.axhline(10.0, color="k", lw=0.8)
    ax.set_xlabel("approach speed v [m/s]")
    ax.set_ylabel("impact_peak [N]")
    ax.set_title("impact vs speed, k_e = 3e4, sensor latency")
    ax.legend(fontsize=7)
    ax = axes[2]
    for name, sc in (("no approach", ar.paper.scenario("fig19")),
                     ("GuardedApproach(acceleration=None)", ar.paper.scenario("fig19").replace(
                         approach=ar.GuardedApproach(acceleration=None))),
                     ("GuardedApproach()", ar.paper.scenario("fig19").replace(
                         approach=ar.GuardedApproach()))):
        tr = ar.simulate(sc.replace(duration=2.0)).trace
        ax.plot(tr["t"], tr["f"], label=f"fig. 19, {name}")
    tr = ar.simulate(ar.paper.scenario("fig14").replace(duration=2.0)).trace
    ax.plot(tr["t"], tr["f"], "--", label="fig. 14")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("f [N]")
    ax.set_title("fig. 19: the estimate 1 cm beyond the wall")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "first_contact.png", dpi=90)
    plt.close(fig)

    maps["stiffness"].write_parquet(out / "speed_by_stiffness.parquet")
    maps["latency"].write_parquet(out / "speed_by_latency.parquet")
    text = ["# first_contact.py tables", "", f"m_eff = {m_eff:.3f} kg along n at q0", ""]
    for title, table in (("fig. 19", fig19), ("tilted plane, v = 0.01 m/s, θ = 3°", tilted),
                         ("curved parts, v = 0.01 m/s", curved)):
        text += [f"## {title}", "", _markdown(table), ""]
    (out / "first_contact.md").write_text("\n".join(text))
    return {"stiffness": maps["stiffness"], "latency": maps["latency"], "fig19": fig19,
            "tilted": tilted, "curved": curved, "m_eff": pl.DataFrame({"m_eff": [m_eff]})}


def _markdown(table: pl.DataFrame) -> str:
    def cell(v: object) -> str:
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    lines = ["| " + " | ".join(table.columns) + " |", "|" + "---|" * len(table.columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in table.iter_rows()]
    return "\n".join(lines)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=Path("first-contact"))
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    tables = main(args.out, args.quick)
    print(tables["fig19"])
    print(tables["tilted"])
    print(tables["curved"])
    print(f"wrote {args.out}/first_contact.png and first_contact.md")
