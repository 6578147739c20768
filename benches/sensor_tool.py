"""The cost of the 3-axis sensor and a tool (issue #22 part 4, SPEC §15): a 10-s fig. 14 run
with the one-axis sensor, with a tool, with the tip-frame sensor (ideal, and noisy with a
low-pass and latency) and with both, scalar (``ar.simulate``, best of ``--repeat`` rounds) and in
lanes (``ar.sweep`` of ``--samples`` runs over the wall stiffness, no traces, one thread,
best of every fifth round).

    python benches/sensor_tool.py [--repeat 15] [--samples 64]

Prints each case's time and its ratio to the plain run (docs/performance-history.md §17).
"""

from __future__ import annotations

import admit_rs as ar
import ratios


def cases() -> dict[str, ar.Scenario]:
    fig14 = ar.paper.scenario("fig14")
    noisy = {"noise_std": 0.05, "cutoff": 100.0, "latency": 1}
    return {
        "plain fig. 14": fig14,
        "tool 1 kg (one axis)": fig14.replace(sensor=ar.ForceSensor(tool_mass=1.0)),
        "tip frame, ideal": fig14.replace(sensor=ar.ForceSensor(frame="tip")),
        "one axis, noisy": fig14.replace(sensor=ar.ForceSensor(**noisy)),
        "tip frame, noisy": fig14.replace(sensor=ar.ForceSensor(frame="tip", **noisy)),
        "tip frame, noisy, tool": fig14.replace(
            sensor=ar.ForceSensor(frame="tip", tool_mass=1.0, **noisy)),
    }


if __name__ == "__main__":
    ratios.main(cases())
