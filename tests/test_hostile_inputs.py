"""No input may hang, panic, kill the process or pass as a "stable" run full of NaN.

Every numeric field of two scenarios (TDC + Scheme 2 with a real sensor and actuator; CT with
the eq. 20 impedance reference) is set, one at a time, to each hostile value. Each case runs
in a worker subprocess under a per-case timeout: a hang or a dead worker fails the case and
the worker is restarted for the next. A case passes with a ``ParameterError`` or a result
whose "stable" runs are finite throughout.

Then the reproducers of issue #21 items 12, 14, 15 and 20, each with its exact message: a
URDF nested 20 000 deep (in a subprocess, so a crash fails the test instead of pytest),
unreadable TOML files, a checkpoint path that is a file, bools for numbers, a negative sine
frequency, a cut-off above Nyquist, values printed short, one Simulation on two threads.
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
import numpy as np
import pytest

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
        "first_contact": ar.paper.scenario("fig14").replace(
            wall=ar.Wall(gap=0.001, normal=(1, 0, 0.05)), wall_estimate=ar.Wall(),
            admittance=ar.AdmittanceFilter.adaptive(), approach=ar.GuardedApproach(),
            duration=0.3,
        ),
        "surfaces": ar.paper.scenario("fig14").replace(
            wall=ar.Sphere(radius=0.2, friction=0.3, damping=20.0, gap=0.001),
            wall_estimate=ar.Cylinder(radius=0.3, inside=True), duration=0.3,
        ),
        "height_field": ar.paper.scenario("fig14").replace(
            wall=ar.HeightField(heights=[[0.0, 0.001, 0.0], [0.0, -0.001, 0.002]],
                                friction=0.5, stiction_velocity=0.01),
            duration=0.3,
        ),
        "tool": ar.paper.scenario("fig14").replace(
            sensor=ar.ForceSensor(frame="tip", bias=(0.1, 0.0, -0.2), noise_std=0.1,
                                  cutoff=50.0, latency=1, tool_mass=0.5,
                                  tool_mass_estimate=0.6),
            wall=ar.Wall(normal=(0, 0, -1)), duration=0.3,
        ),
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
        if path in ar.config._UNIONS:
            continue  # a block slot left at None (wall_estimate, approach): not a number
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
        # Free space, a tilted true wall under the estimate, the adaptive filter (SPEC §16).
        "first_contact": ar.paper.scenario("fig14").replace(
            wall=ar.Wall(gap=0.001, normal=(1, 0, 0.05)), wall_estimate=ar.Wall(),
            admittance=ar.AdmittanceFilter.adaptive(), approach=ar.GuardedApproach(),
        ),
        # The surfaces of SPEC §15, with friction (a heights grid is covered below).
        "surfaces": ar.paper.scenario("fig14").replace(
            wall=ar.Sphere(radius=0.2, friction=0.3, damping=20.0, gap=0.001),
            wall_estimate=ar.Cylinder(radius=0.3, inside=True),
        ),
        "height_field": ar.paper.scenario("fig14").replace(
            wall=ar.HeightField(heights=[[0.0, 0.001, 0.0], [0.0, -0.001, 0.002]],
                                friction=0.5, stiction_velocity=0.01),
        ),
        # The 3-axis sensor with a tool on a table (SPEC §15).
        "tool": ar.paper.scenario("fig14").replace(
            sensor=ar.ForceSensor(frame="tip", bias=(0.1, 0.0, -0.2), noise_std=0.1,
                                  cutoff=50.0, latency=1, tool_mass=0.5,
                                  tool_mass_estimate=0.6),
            wall=ar.Wall(normal=(0, 0, -1)),
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
            "robot.coulomb_friction", "robot.q0", "wall.gap", "admittance.sigma",
            "wall_estimate.normal", "wall_estimate.position_error", "wall_estimate.gap",
            "approach.speed", "approach.contact_speed", "approach.slowdown_distance",
            "approach.threshold", "approach.acceleration", "wall.friction",
            "wall.stiction_velocity", "wall.radius",
            "wall_estimate.radius", "wall_estimate.axis", "wall.spacing", "sensor.bias",
            "sensor.tool_mass", "sensor.tool_mass_estimate"} <= paths
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


DEEP_URDF = ('<robot name="r"><link name="a">' + "<x>" * 20000 + "</x>" * 20000
             + "</link></robot>")  # fmt: skip
DEEP_MESSAGE = ("urdf = elements nested more than 100 deep is invalid: must be a URDF document "
                "nested at most 100 elements deep")  # fmt: skip


def run_python(code, *args, stdin=""):
    """``code`` in a fresh interpreter: a crash (stack overflow, SIGSEGV) fails the test
    with its exit code instead of killing pytest."""
    env = dict(os.environ, PYTHONFAULTHANDLER="1")
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          input=stdin, timeout=120, env=env)  # fmt: skip


def test_a_deeply_nested_urdf_is_a_parameter_error():
    # It used to overflow the stack inside urdf-rs's XML tree (exit 139, SIGSEGV).
    done = run_python(textwrap.dedent("""
        import sys
        import admit_rs as ar
        try:
            ar.UrdfArm(urdf=sys.stdin.read(), tip_link="a")
        except ar.ParameterError as e:
            print("ParameterError:", e, "|", e.field)
    """), stdin=DEEP_URDF)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert done.stdout.strip() == f"ParameterError: {DEEP_MESSAGE} | urdf"


def test_the_cli_on_a_deeply_nested_urdf_exits_2(tmp_path):
    (tmp_path / "deep.urdf").write_text(DEEP_URDF)
    (tmp_path / "sc.toml").write_text('[robot]\nkind = "urdf"\npath = "deep.urdf"\n'
                                      'tip_link = "a"\n')  # fmt: skip
    done = run_python("import sys; from admit_rs import cli; sys.exit(cli.main(sys.argv[1:]))",
                      "run", str(tmp_path / "sc.toml"))  # fmt: skip
    assert done.returncode == 2, (done.returncode, done.stderr[-2000:])
    assert done.stderr.strip() == f"admit-rs: error: {DEEP_MESSAGE}"


@pytest.mark.parametrize(
    ("content", "why"),
    [
        (b"[wall]\nstiffness = " + b"[" * 5000 + b"]" * 5000 + b"\n", "nested too deeply to read"),
        (b'label = "caf\xe9"\n', "not UTF-8 text"),
        (b"duration = = 1\n", "Invalid value (at line 1, column 12)"),
    ],
    ids=["nested-5000", "latin-1", "invalid"],
)
def test_an_unreadable_toml_exits_2_naming_the_file(tmp_path, content, why):
    # A TOML nested 5 000 arrays deep used to end in a RecursionError traceback (exit 1).
    path = tmp_path / "sc.toml"
    path.write_bytes(content)
    for command in (["run", str(path)], ["tune", str(path), "--vary", "admittance.b=100:200",
                                         "--over", "wall.stiffness=1e4:2e4"]):  # fmt: skip
        done = run_python("import sys; from admit_rs import cli; sys.exit(cli.main(sys.argv[1:]))",
                          *command)  # fmt: skip
        assert done.returncode == 2, (command, done.stderr[-2000:])
        assert done.stderr.strip() == (
            f"admit-rs: error: {path} is invalid: must be a TOML file ({why})"
        )
    from admit_rs import cli

    with pytest.raises(ar.ParameterError, match=r"must be a TOML file"):
        cli.load_sweep(path)


def test_a_checkpoint_path_that_is_a_file_is_a_parameter_error(tmp_path):
    # It used to raise FileExistsError from mkdir.
    path = tmp_path / "results.parquet"
    path.write_bytes(b"not a folder")
    sc = ar.paper.scenario("fig14").replace(duration=0.01)
    with pytest.raises(ar.ParameterError) as e:
        ar.sweep(sc, grid={"admittance.b": [400.0]}, checkpoint=path, progress=False)
    assert str(e.value) == (f"checkpoint = {str(path)!r} is invalid: must be a folder or a path "
                            "that does not exist yet (it is a file)")  # fmt: skip
    assert path.read_bytes() == b"not a folder"
    fresh = tmp_path / "new" / "ckpt"  # absent: created
    assert ar.sweep(sc, grid={"admittance.b": [400.0]}, checkpoint=fresh,
                    progress=False).height == 1  # fmt: skip


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: ar.paper.scenario("fig14").replace(**{"admittance.b": True}),
         "b must be a number, got a bool"),
        (lambda: ar.AdmittanceFilter.scheme2(ka=True), "ka must be a number, got a bool"),
        (lambda: ar.Wall(stiffness=True), "stiffness must be a number, got a bool"),
        (lambda: ar.Wall(normal=(True, 0.0, 0.0)),
         "normal must be a sequence of 3 numbers, got a bool"),
        (lambda: ar.ForceSensor(latency=False), "latency must be a number, got a bool"),
        (lambda: ar.Scenario(duration=True), "duration must be a number, got a bool"),
        (lambda: ar.UrdfArm(URDF_PATH, "tool0", coulomb_friction=True),
         "coulomb_friction must be a number or a sequence of numbers, got a bool"),
        (lambda: ar.Scenario.from_dict({"admittance": {"b": True}}),
         "b must be a number, got a bool"),
    ],
    ids=["replace", "scheme2", "wall", "normal", "latency", "duration", "urdf", "from_dict"],
)
def test_a_bool_is_not_a_number(make, message):
    # Python counts True as 1: admittance.b=True used to run as b = 1 without a word.
    with pytest.raises(TypeError) as e:
        make()
    assert str(e.value) == message
    assert ar.Wall(stiffness=3e4).stiffness == 3e4  # numbers still pass
    assert ar.ComputedTorque(contact_compensation=True).contact_compensation is True


def test_a_negative_sine_frequency_is_rejected():
    with pytest.raises(ar.ParameterError) as e:
        ar.Sine(omega=-1.0)
    assert str(e.value) == "omega = -1 is invalid: must be finite and >= 0"
    assert ar.Sine(omega=0.0)(1.0) == ar.Sine(omega=0.0)(0.0)  # a constant is allowed


def test_a_sensor_cutoff_above_nyquist_is_rejected():
    # A 5 kHz low-pass at a 1 kHz loop used to pass (the filter simply did nothing).
    sc = ar.paper.scenario("fig14")
    with pytest.raises(ar.ParameterError) as e:
        sc.replace(sensor=ar.ForceSensor(cutoff=5000.0))
    assert str(e.value) == ("sensor.cutoff = 5000 is invalid: must be at most the Nyquist "
                            "frequency 1/(2·period) = 500 Hz, or None for no filter")  # fmt: skip
    assert sc.replace(sensor=ar.ForceSensor(cutoff=500.0)).sensor.cutoff == 500.0
    # The limit follows the period: 5 kHz is fine at a 10 kHz loop.
    fast = sc.replace(period=1e-4, sensor=ar.ForceSensor(cutoff=5000.0))
    assert fast.sensor.cutoff == 5000.0
    with pytest.raises(ar.ParameterError, match=r"= 5000 Hz, or None"):
        fast.replace(sensor=ar.ForceSensor(cutoff=5000.5))


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: ar.Wall(stiffness=-1e300),
         "stiffness = -1e300 is invalid: must be finite and >= 0"),
        (lambda: ar.ForceSensor(latency=1e300),
         "latency = 1e300 is invalid: must be an integer from 0 to 100000"),
        (lambda: ar.paper.scenario("fig14").replace(duration=1e300),
         "duration = 1e300 is invalid: must be at most 9999999 periods of 0.001 s"),
        (lambda: ar.paper.scenario("fig14").replace(seed=10**400),
         "seed = ≈1.00000e+400 is invalid: must be an integer from 0 to 9007199254740992"),
        (lambda: ar.Sine(omega=-1e-300), "omega = -1e-300 is invalid: must be finite and >= 0"),
        (lambda: ar.ForceSensor(latency=10**20),
         "latency = ≈1.00000e+20 is invalid: must be a whole number of at most 64 bits "
         "(-2^63 to 2^64 - 1)"),
    ],
    ids=["wall", "latency", "duration", "seed", "omega", "latency beyond 64 bits"],
)
def test_error_messages_print_values_short(make, message):
    # -1e300 used to print as 301 digits (a 350-character message).
    with pytest.raises(ar.ParameterError) as e:
        make()
    assert str(e.value) == message


def test_a_simulation_shared_by_two_threads_says_so():
    # It used to raise pyo3's bare RuntimeError "Already borrowed".
    import threading

    sc = ar.paper.scenario("fig14").replace(duration=2.0)
    sim = ar.Simulation(sc)
    seen: list[BaseException] = []
    stop = threading.Event()

    def calls(*each):
        for call in each:
            try:
                call()
            except Exception as e:  # noqa: BLE001 - the test inspects what it gets
                seen.append(e)
                return

    def other_thread():
        while not stop.is_set() and not seen:
            assert repr(sim).startswith("<Simulation")  # a repr never raises
            calls(lambda: sim.step(1), lambda: sim.state, lambda: sim.trace)

    worker = threading.Thread(target=other_thread)
    worker.start()
    try:
        # Step whole runs until the two threads have met in one (a 2 s run steps for
        # milliseconds with the GIL released, so the first run usually does).
        for _ in range(200):
            if seen:
                break
            calls(sim.reset, lambda: sim.step(sc.samples))
    finally:
        stop.set()
        worker.join()
    assert seen, "the other thread never overlapped a step"
    err = seen[0]
    assert type(err) is ar.AdmitError, repr(err)
    assert str(err) == (
        "this Simulation is being stepped by another thread: one Simulation is one run, used "
        "by one thread at a time; give each thread its own ar.Simulation(scenario)"
    )
    # The refused calls changed nothing: the run still ends as simulate's, bit for bit.
    sim.reset()
    sim.step(sc.samples)
    assert sim.trace.equals(ar.simulate(sc).trace)
    assert repr(sim).endswith(": sample 2001 of 2001, done>")  # whatever the label


def test_a_divergence_cause_shows_the_velocity_that_tripped_the_limit():
    # `{:.2}` printed a 1e300 velocity as 303 characters and 0.00425 rad/s as "-0.00".
    import re

    limit = 1e-3
    r = ar.simulate(ar.paper.scenario("fig14").replace(velocity_limit=limit, duration=0.1))
    found = re.fullmatch(r"joint (\d) velocity (\S+) rad/s reached the velocity limit",
                         r.divergence_cause)  # fmt: skip
    assert found, r.divergence_cause
    velocity = float(found.group(2))
    assert limit <= abs(velocity) < 1.0, r.divergence_cause
    assert len(found.group(2).lstrip("-").replace(".", "").lstrip("0")) <= 6


def test_a_deeply_nested_value_is_a_type_error_not_a_recursion_error():
    deep: list = []
    for _ in range(5000):
        deep = [deep]
    with pytest.raises(TypeError, match=r"^stiffness must be a number, got list$"):
        ar.Wall(stiffness=deep)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: ar.AdmittanceFilter(b="800"), "b must be a number, got str"),
        (lambda: ar.TimeDelayControl(kp="100"), "kp must be a number, got str"),
        (lambda: ar.Step(value=None), "value must be a number, got None"),
        (lambda: ar.paper.scenario("fig14").replace(**{"admittance.b": "800"}),
         "b must be a number, got str"),
    ],
    ids=["filter", "controller", "signal", "replace"],
)
def test_a_wrong_type_below_a_tagged_block_names_its_field(make, message):
    # The core's decoder loses the field below a tagged block: "scenario must be a number".
    with pytest.raises(TypeError) as e:
        make()
    assert str(e.value) == message
    assert ar.Wall(position=None).position is None  # optional numbers may be None


def test_an_int_beyond_the_float_range_is_a_parameter_error() -> None:
    """``Wall(stiffness=10**400)`` raised a TypeError whose text was an OverflowError."""
    with pytest.raises(ar.ParameterError, match=r"^stiffness = ≈1\.00000e\+400 is invalid"):
        ar.Wall(stiffness=10**400)
    with pytest.raises(ar.ParameterError, match=r"^b = ≈-1\.00000e\+400 is invalid"):
        ar.AdmittanceFilter(b=-(10**400))


@pytest.mark.parametrize("value", HOSTILE)
def test_hostile_heights_are_an_error_or_a_finite_run(value):
    """A height-field grid is not a scalar path of `numeric_paths`: every hostile value in
    one node, and a grid of them, is a ParameterError naming the node or a finite run."""
    base = ar.paper.scenario("fig14").replace(duration=0.2)
    for heights in ([[0.0, value], [0.0, 0.0]], [[value] * 3] * 3):
        try:
            wall = ar.HeightField(heights=heights)
        except ar.ParameterError as e:
            assert str(e).startswith(("heights[0][1] = ", "heights[0][0] = ")), e
            assert abs(value) > 1e3 or math.isnan(value)
            continue
        r = ar.simulate(base.replace(wall=wall))
        assert all(np.isfinite(r.trace[c].to_numpy()).all() for c in ("f", "q1", "f_t"))


@pytest.mark.parametrize(
    "change", [{"wall.stiffness": 10**400}, {"sensor.noise_std": -(10**400)},
               {"admittance.b": 10**400}],
)  # fmt: skip
def test_an_int_beyond_the_float_range_is_a_parameter_error_naming_its_path(change):
    """Issue #53, item 13: replace() raised AttributeError ('ParameterError' object has no
    attribute 'field')."""
    (path,) = change
    with pytest.raises(ar.ParameterError) as info:
        ar.paper.scenario("fig14").replace(**change)
    assert info.value.field == path and info.value.allowed == "a finite number"


def test_height_field_heights_beyond_the_float_range_are_a_parameter_error():
    with pytest.raises(ar.ParameterError) as info:
        ar.HeightField(heights=[[0, 10**400], [0, 0]])
    assert info.value.field == "heights"
