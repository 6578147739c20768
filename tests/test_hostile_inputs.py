"""No input may hang, panic, kill the process or pass as a "stable" run full of NaN.

Every numeric field of two scenarios (TDC + Scheme 2 with a real sensor and actuator; CT with
the eq. 20 impedance reference) is set, one at a time, to each hostile value. Each case runs
in a worker subprocess under a per-case timeout: a hang or a dead worker fails the case and
the worker is restarted for the next. A case passes with a ``ParameterError`` or a result
whose "stable" runs are finite throughout.
"""

import json
import math
import os
import select
import subprocess
import sys
import textwrap
from pathlib import Path

import admit_rs as ar

HOSTILE = [0.0, -1.0, 1e300, -1e300, 1e100, 1e-300, math.nan, math.inf, -math.inf]
TIMEOUT_S = 10.0

URDF_PATH = str(Path(__file__).resolve().parent.parent / "examples" / "data" / "ur5.urdf")

WORKER = f"URDF_PATH = {URDF_PATH!r}\n" + textwrap.dedent(
    """
    import json, math, sys
    import numpy as np
    import admit_rs as ar

    UR5 = ar.UrdfArm(URDF_PATH, "tool0", q0=(0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0),
                     viscous_friction=1.0, coulomb_friction=2.0)

    BASES = {
        "tdc": ar.paper.scenario("fig14").replace(
            sensor=ar.ForceSensor(noise_std=0.1, cutoff=30.0, latency=2, resolution=0.01),
            actuator=ar.Actuator(torque_limit=(60.0, 40.0, 20.0), rate_limit=1e4, delay=1),
            wall=ar.Wall(damping=20.0, model="hunt_crossley", exponent=1.5, stiffness=3e6),
            duration=0.3,
        ),
        "ct": ar.paper.scenario("fig8").replace(
            admittance=ar.ImpedanceReference(), duration=0.3
        ),
        "urdf": ar.paper.scenario("fig14").replace(robot=UR5, duration=0.3),
    }

    def apply(sc, path, value):
        node = sc
        for part in path.split("."):
            node = getattr(node, part)
        if isinstance(node, tuple):  # a vector: the hostile value in its first element
            value = (value, *node[1:])
        return sc.replace(**{path: value})

    for line in sys.stdin:
        base, path, value = json.loads(line)
        try:
            r = ar.simulate(apply(BASES[base], path, value))
        except ar.ParameterError as e:
            out = "error: " + str(e)[:80]
        else:
            tr = r.trace
            finite = all(np.isfinite(tr[c].to_numpy()).all()
                         for c in ("q1", "q2", "q3", "qd1", "f", "f_measured", "tau1"))
            if r.stable and not finite:
                out = "FAIL: stable run with non-finite trace"
            elif r.stable and any(isinstance(v, float) and math.isinf(v)
                                  for v in r.metrics.values()):
                out = "FAIL: stable run with infinite metrics"
            else:
                out = "result: " + ("stable" if r.stable else r.verdict[:60])
        print(json.dumps(out), flush=True)
    """
)


def numeric_paths(sc):
    out = []
    for path in ar.parameter_paths(sc):
        node = sc
        for part in path.split("."):
            node = getattr(node, part)
        if isinstance(node, bool) or isinstance(node, str):
            continue
        if node is None or isinstance(node, int | float) or (
            isinstance(node, tuple) and all(isinstance(v, int | float) for v in node)
        ):
            out.append(path)
    return out


class Worker:
    def __init__(self):
        env = dict(os.environ, PYTHONFAULTHANDLER="1")
        self.proc = subprocess.Popen(
            [sys.executable, "-c", WORKER],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            env=env,
        )

    def ask(self, case):
        """The worker's answer, or a failure text for a hang or a dead worker."""
        assert self.proc.stdin and self.proc.stdout
        try:
            self.proc.stdin.write(json.dumps(case) + "\n")
            self.proc.stdin.flush()
        except BrokenPipeError:
            return "FAIL: worker died before the case"
        ready, _, _ = select.select([self.proc.stdout], [], [], TIMEOUT_S + 20.0)
        if not ready:
            return f"FAIL: no answer within {TIMEOUT_S} s (hang)"
        line = self.proc.stdout.readline()
        if not line:
            return f"FAIL: worker died (exit {self.proc.wait()})"
        return json.loads(line)

    def close(self):
        self.proc.kill()
        self.proc.wait()
        for pipe in (self.proc.stdin, self.proc.stdout):
            if pipe:
                pipe.close()


def test_every_numeric_field_survives_hostile_values():
    import time

    scenarios = {
        "tdc": ar.paper.scenario("fig14").replace(
            sensor=ar.ForceSensor(cutoff=30.0), actuator=ar.Actuator(torque_limit=60.0)
        ),
        "ct": ar.paper.scenario("fig8").replace(admittance=ar.ImpedanceReference()),
        "urdf": ar.paper.scenario("fig14").replace(
            robot=ar.UrdfArm(URDF_PATH, "tool0", q0=(0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0),
                             viscous_friction=1.0, coulomb_friction=2.0)
        ),
    }
    cases = [
        (base, path, value)
        for base, sc in scenarios.items()
        for path in numeric_paths(sc)
        for value in HOSTILE
    ]
    paths = {p for _, p, _ in cases}
    # The new stages' fields are covered.
    assert {"sensor.noise_std", "sensor.latency", "actuator.rate_limit", "actuator.delay",
            "wall.damping", "wall.exponent", "wall.normal", "seed",
            "admittance.assumed_stiffness", "robot.gravity", "robot.friction_smoothing",
            "robot.coulomb_friction", "robot.q0"} <= paths
    failures = []
    worker = Worker()
    warmed = False
    try:
        for case in cases:
            start = time.monotonic()
            answer = worker.ask(case)
            # The first case also pays the worker's import.
            limit = TIMEOUT_S + (0 if warmed else 20.0)
            warmed = True
            if time.monotonic() - start > limit and not answer.startswith("FAIL"):
                answer = f"FAIL: took {time.monotonic() - start:.1f} s"
            if answer.startswith("FAIL"):
                failures.append((case, answer))
                worker.close()
                worker = Worker()
                warmed = False
    finally:
        worker.close()
    assert not failures, failures
    assert len(cases) > 500
