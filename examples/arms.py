"""The paper's task on real arms: a UR5 and a Franka Panda from their URDF files.

10 N against a wall (step f_d), a 0.05 m sine along it, TDC (eq. 18) + Scheme 2
(b = 800, k_a = 1), with and without a 0.01 m error in the wall's estimated position; then
a short wall-stiffness sweep on the Panda.

    python examples/arms.py [OUT_DIR]     # writes arms.png, arms.md (the tables) into OUT_DIR

docs/arms.md shows and discusses the output.
"""

from __future__ import annotations

import sys
from pathlib import Path

import admit_rs as ar
import numpy as np
import polars as pl
from matplotlib.figure import Figure

DATA = Path(__file__).resolve().parent / "data"
ARMS = {
    "UR5": ar.UrdfArm(DATA / "ur5.urdf", "tool0", q0=(0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0)),
    "Panda": ar.UrdfArm(
        DATA / "panda.urdf", "panda_hand_tcp", q0=(0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
    ),
}
"""Elbow-up poses with the tool pointing down; the task holds that orientation (pose task)."""
METRICS = ["force_peak", "overshoot_pct", "force_ss_error", "force_rms_error", "z_rms_error",
           "joint_limit_violation", "stable"]  # fmt: skip


def scenario(arm: ar.UrdfArm, wall_error: float = 0.0, stiffness: float = 30_000.0) -> ar.Scenario:
    """fig. 14's task and loop on `arm`, with TDC tuned for it (TimeDelayControl.for_arm)."""
    return ar.paper.scenario("fig14").replace(
        robot=arm,
        controller=ar.TimeDelayControl.for_arm(arm),
        wall=ar.Wall(stiffness=stiffness, position_error=wall_error),
        label=f"wall error {wall_error * 1000:.0f} mm",
    )


def orientation_error(arm: ar.UrdfArm, result: ar.Result, every: int = 10) -> float:
    """Largest rotation angle of the tip away from its start orientation [rad]."""
    r0 = arm.dynamics(arm.initial_position)["rotation"]
    qs = result.trace.select([f"q{i + 1}" for i in range(arm.dof)]).to_numpy()[::every]
    worst = 0.0
    for q in qs:
        r = r0 @ arm.dynamics(q)["rotation"].T
        worst = max(worst, float(np.arccos(np.clip((np.trace(r) - 1) / 2, -1.0, 1.0))))
    return worst


def runs() -> tuple[pl.DataFrame, dict[str, dict[float, ar.Result]]]:
    rows, results = [], {}
    for name, arm in ARMS.items():
        results[name] = {}
        for err in (0.0, 0.01):
            r = ar.simulate(scenario(arm, err))
            results[name][err] = r
            rows.append({"arm": name, "wall error [m]": err,
                         **{m: r.metrics[m] for m in METRICS},
                         "orientation_error [rad]": orientation_error(arm, r)})  # fmt: skip
    return pl.DataFrame(rows), results


def stiffness_sweep() -> pl.DataFrame:
    """The Panda against walls of 10 000 … 100 000 N/m (the paper's k_e values)."""
    table = ar.sweep(
        scenario(ARMS["Panda"]),
        grid={"wall.stiffness": [1e4, 3e4, 5e4, 1e5]},
        progress=False,
    )
    return table.select("wall.stiffness", *[m for m in METRICS if m != "joint_limit_violation"])


def figure(results: dict[str, dict[float, ar.Result]]) -> Figure:
    fig = Figure(figsize=(10, 6), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True)
    for row, (name, by_error) in enumerate(results.items()):
        for err, r in by_error.items():
            t = r.trace["t"].to_numpy()
            label = f"wall error {err * 1000:.0f} mm"
            axes[row, 0].plot(t, r.trace["f"].to_numpy(), lw=0.8, label=label)
            axes[row, 1].plot(t, (r.trace["z"] - r.trace["z_ref"]).to_numpy() * 1e3, lw=0.8,
                              label=label)  # fmt: skip
        axes[row, 0].plot(t, r.trace["f_d"].to_numpy(), "k--", lw=0.6, label="f_d")
        axes[row, 0].set_ylabel(f"{name}: f [N]")
        axes[row, 1].set_ylabel(f"{name}: z − z_d [mm]")
        axes[row, 0].legend(fontsize=7)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    fig.suptitle("TDC + Scheme 2 (b = 800, k_a = 1) on the UR5 and the Panda, 10 N against "
                 "a 30 000 N/m wall")  # fmt: skip
    return fig


def markdown(table: pl.DataFrame) -> str:
    head = "| " + " | ".join(table.columns) + " |\n|" + "---|" * table.width + "\n"

    def cell(v: object) -> str:
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    return head + "".join(
        "| " + " | ".join(cell(v) for v in row) + " |\n" for row in table.iter_rows()
    )


def main(out: Path) -> dict[str, pl.DataFrame]:
    out.mkdir(parents=True, exist_ok=True)
    table, results = runs()
    sweep = stiffness_sweep()
    figure(results).savefig(out / "arms.png", dpi=120)
    (out / "arms.md").write_text(
        "## The paper's task on the UR5 and the Panda\n\n" + markdown(table)
        + "\n## Panda: wall stiffness sweep (no wall error)\n\n" + markdown(sweep)
    )  # fmt: skip
    return {"runs": table, "sweep": sweep}


if __name__ == "__main__":
    tables = main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("."))
    for t in tables.values():
        print(t)
