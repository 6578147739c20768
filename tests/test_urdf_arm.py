"""ar.UrdfArm as a block of the simulator (SPEC §11): the three-link URDF reproduces the
closed-form arm, the UR5 and the Panda track force against a wall with TDC + Scheme 2, the
block works in pickles, sweeps, TOML and model errors, and every loader error names its
element."""

import math
import pickle
import subprocess
import sys
from pathlib import Path

import admit_rs as ar
import numpy as np
import pinocchio as pin
import pytest

DATA = Path(__file__).resolve().parent.parent / "examples" / "data"
UR5_Q0 = (0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0)
PANDA_Q0 = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)


def three_link():
    return ar.UrdfArm(
        DATA / "three_link.urdf", "tip", viscous_friction=3.0, coulomb_friction=5.0,
        q0=(0.0, math.pi / 4, -math.pi / 4),
    )  # fmt: skip


def ur5(**kw):
    return ar.UrdfArm(DATA / "ur5.urdf", "tool0", q0=UR5_Q0, **kw)


def panda(**kw):
    return ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp", q0=PANDA_Q0, **kw)


def test_three_link_urdf_reproduces_fig14():
    sc = ar.paper.scenario("fig14")
    closed = ar.simulate(sc)
    chain = ar.simulate(sc.replace(robot=three_link()))
    assert closed.trace.columns == chain.trace.columns
    worst = 0.0
    for c in closed.trace.columns:
        a, b = closed.trace[c].to_numpy(), chain.trace[c].to_numpy()
        both = np.isfinite(a)
        assert (both == np.isfinite(b)).all(), c
        scale = max(np.abs(a[both]).max(initial=0.0), 1e-300)
        worst = max(worst, np.abs(a[both] - b[both]).max(initial=0.0) / scale)
    assert worst < 1e-9, worst
    assert chain.metrics["joint_limit_violation"] == 0.0


def orientation_error(arm, result, every=10):
    r0 = arm.dynamics(arm.initial_position)["rotation"]
    qs = result.trace.select([f"q{i + 1}" for i in range(arm.dof)]).to_numpy()[::every]
    return max(np.linalg.norm(pin.log3(r0 @ arm.dynamics(q)["rotation"].T)) for q in qs)


@pytest.mark.parametrize("make", [ur5, panda], ids=["ur5", "panda"])
@pytest.mark.parametrize("wall_error", [0.0, 0.01])
def test_tdc_scheme2_tracks_force_on_real_arms(make, wall_error):
    arm = make()
    sc = ar.paper.scenario("fig14").replace(
        robot=arm, controller=ar.TimeDelayControl.for_arm(arm),
        **{"wall.position_error": wall_error},
    )  # fmt: skip
    r = ar.simulate(sc)
    m = r.metrics
    assert m["stable"], r.verdict
    assert abs(m["force_ss_error"]) < 0.05, m["force_ss_error"]
    assert orientation_error(arm, r) < 1e-3
    assert m["joint_limit_violation"] == 0.0
    assert f"q{arm.dof}" in r.trace.columns and f"tau{arm.dof}" in r.trace.columns


def test_pose_is_the_default_task_from_six_joints():
    assert ur5().task_kind == "pose" and panda().task_kind == "pose"
    assert three_link().task_kind == "position"
    assert panda(task="position").task_kind == "position"
    assert ur5().dof == 6 and panda().dof == 7
    assert panda().joint_names[0] == "panda_joint1"


def test_q0_defaults_to_zero_clipped_into_the_limits():
    arm = ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp")
    lower, upper = arm.position_limits
    assert np.allclose(arm.initial_position, np.clip(0.0, lower, upper))
    assert arm.initial_position[3] == pytest.approx(-0.0698)


def test_joint_limit_violation_measures_the_excursion():
    q0 = list(PANDA_Q0)
    q0[3] = -0.0698 + 0.05  # joint 4 starts 0.05 rad past its upper limit
    arm = ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp", q0=tuple(q0))
    sc = ar.paper.scenario("fig14").replace(
        robot=arm, controller=ar.TimeDelayControl.for_arm(arm), duration=0.05
    )
    m = ar.simulate(sc).metrics
    assert m["joint_limit_violation"] == pytest.approx(0.05, abs=0.01)


def test_actuator_from_urdf_uses_the_effort_limits():
    act = ar.Actuator.from_urdf(panda())
    assert act.torque_limit == (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
    sc = ar.paper.scenario("fig14").replace(
        robot=panda(), controller=ar.TimeDelayControl.for_arm(panda()), actuator=act,
        duration=1.0,
    )  # fmt: skip
    assert ar.simulate(sc).metrics["torque_saturation"] < 0.01
    with pytest.raises(ar.ParameterError, match="one per joint"):
        ar.simulate(ar.paper.scenario("fig14").replace(actuator=act))


def test_arm_pickles_with_its_text_and_runs_anywhere(tmp_path):
    src = tmp_path / "arm.urdf"
    src.write_text((DATA / "ur5.urdf").read_text())
    arm = ar.UrdfArm(src, "tool0", q0=UR5_Q0)
    src.unlink()  # the block carries the document, not the file
    back = pickle.loads(pickle.dumps(arm))
    assert back == arm
    sc = ar.paper.scenario("fig14").replace(
        robot=back, controller=ar.TimeDelayControl.for_arm(back), duration=0.2
    )
    res = ar.simulate(sc)  # 0.2 s: runs, too short to assess
    assert not res.diverged and res.verdict.startswith("not assessed")


def test_dotted_paths_sweeps_and_model_errors():
    arm = panda()
    base = ar.paper.scenario("fig14").replace(
        robot=arm, controller=ar.TimeDelayControl.for_arm(arm), duration=0.5
    )
    sc = base.replace(**{"robot.coulomb_friction": 0.5, "robot.viscous_friction": 0.2})
    assert sc.robot.coulomb_friction == 0.5
    q0 = list(PANDA_Q0)
    q0[0] = 0.1
    assert base.replace(**{"robot.q0": tuple(q0)}).robot.q0[0] == 0.1
    table = ar.sweep(
        sc, vary={"robot.coulomb_friction": ar.Uniform(0.0, 1.0),
                  "controller.model.mass_scale": ar.Uniform(0.8, 1.2)},
        samples=3, seed=0, progress=False,
    )  # fmt: skip
    assert table.height == 3
    assert "joint_limit_violation" in table.columns
    assert table["stable"].all()


def test_toml_round_trip(tmp_path):
    import tomllib

    arm = ur5()
    sc = ar.paper.scenario("fig14").replace(robot=arm, controller=ar.TimeDelayControl.for_arm(arm))
    back = ar.Scenario.from_dict(sc.to_dict())
    assert back == sc
    toml = tmp_path / "ur5.toml"
    toml.write_text(
        f'[robot]\nkind = "urdf"\npath = "{DATA / "ur5.urdf"}"\ntip_link = "tool0"\n'
        f"q0 = {list(UR5_Q0)}\n"
    )
    with open(toml, "rb") as f:
        loaded = ar.Scenario.from_dict(tomllib.load(f))
    assert isinstance(loaded.robot, ar.UrdfArm) and loaded.robot.dof == 6


def test_dynamics_and_forward_dynamics_like_robot():
    arm = panda(viscous_friction=0.5)
    q, qd = np.array(PANDA_Q0), np.full(7, 0.3)
    t = arm.dynamics(q, qd)
    assert t["inertia"].shape == (7, 7) and t["jacobian"].shape == (6, 7)
    tau = np.arange(7.0)
    force = np.array([1.0, -2.0, 3.0])
    rhs = tau + t["jacobian"][:3].T @ force - t["coriolis"] - t["gravity"] - t["friction"]
    assert np.allclose(arm.forward_dynamics(q, qd, tau, force), np.linalg.solve(t["inertia"], rhs))


URDF_HEAD = '<?xml version="1.0"?><robot name="r"><link name="a"/>'
JOINT = ('<joint name="{n}" type="{t}"><parent link="{p}"/><child link="{c}"/>'
         '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>')
GOOD_LINK = ('<link name="{n}"><inertial><mass value="1"/>'
             '<inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>')


def urdf(*parts):
    return URDF_HEAD + "".join(parts) + "</robot>"


@pytest.mark.parametrize(
    ("text", "tip", "match"),
    [
        (urdf(GOOD_LINK.format(n="b"), JOINT.format(n="j1", t="floating", p="a", c="b")), "b",
         r"urdf joint 'j1' = type floating is invalid: must be a revolute, continuous"),
        (urdf(JOINT.format(n="j1", t="revolute", p="a", c="ghost")), "a",
         r"urdf joint 'j1' = child link 'ghost' is invalid: must be a link defined"),
        (urdf(GOOD_LINK.format(n="b"), GOOD_LINK.format(n="c"),
              JOINT.format(n="j1", t="revolute", p="a", c="b"),
              JOINT.format(n="j2", t="revolute", p="a", c="c")), "b",
         None),
        (urdf(GOOD_LINK.format(n="b"), GOOD_LINK.format(n="c"),
              JOINT.format(n="j1", t="revolute", p="a", c="b"),
              JOINT.format(n="j2", t="revolute", p="b", c="c"),
              JOINT.format(n="j3", t="revolute", p="c", c="b")), "c",
         r"urdf link 'b' = the child of joints 'j1' and 'j3' .*closed chains"),
        (urdf('<link name="b"><inertial><mass value="1"/><inertia ixx="-0.1" ixy="0" ixz="0" '
              'iyy="0.1" iyz="0" izz="0.1"/></inertial></link>',
              JOINT.format(n="j1", t="revolute", p="a", c="b")), "b",
         r"urdf link 'b' inertial = mass 1, inertia \[ixx -0.1.* positive"),
        ("<robot", "b", r"urdf = .* must be a valid URDF document"),
        (urdf(GOOD_LINK.format(n="b"), JOINT.format(n="j1", t="revolute", p="a", c="b")),
         "nowhere", r"tip_link = 'nowhere' is invalid: must be a link of the URDF"),
    ],
    ids=["joint-type", "missing-link", "valid", "closed-chain", "bad-inertia", "not-xml",
         "no-tip"],
)
def test_loader_errors_name_the_element(text, tip, match):
    if match is None:
        assert ar.UrdfArm(urdf=text, tip_link=tip).dof == 1
        return
    with pytest.raises(ar.ParameterError, match=match):
        ar.UrdfArm(urdf=text, tip_link=tip)


def test_tip_not_below_base_and_wrong_q0_are_errors():
    text = (DATA / "panda.urdf").read_text()
    with pytest.raises(ar.ParameterError, match=r"tip_link = 'panda_link3' is invalid: must be a "
                       r"link below base_link 'panda_link5'"):  # fmt: skip
        ar.UrdfArm(urdf=text, tip_link="panda_link3", base_link="panda_link5")
    with pytest.raises(ar.ParameterError, match=r"q0 = 3 values is invalid: must be 7 values"):
        ar.UrdfArm(urdf=text, tip_link="panda_hand_tcp", q0=(0.0, 0.0, 0.0))
    with pytest.raises(ar.ParameterError, match=r"path = .* readable URDF file"):
        ar.UrdfArm("/nonexistent/arm.urdf", "tip")
    with pytest.raises(ar.ParameterError, match=r"inertia = .* one number, 7 numbers"):
        ar.simulate(ar.paper.scenario("fig14").replace(
            robot=panda(), controller=ar.TimeDelayControl(inertia=(0.1, 0.2))))


def test_orientation_gains_and_damping_are_used():
    def run(**kw):
        arm = panda(**kw)
        sc = ar.paper.scenario("fig14").replace(
            robot=arm, controller=ar.TimeDelayControl.for_arm(arm), duration=2.0
        )
        return arm, ar.simulate(sc)

    arm, own = run()  # the controller's K_P = 600, K_D = 50
    soft_arm, soft = run(orientation_gains=(100.0, 20.0))
    assert own.stable and soft.stable
    assert orientation_error(soft_arm, soft) > 2 * orientation_error(arm, own)
    # Same gains given explicitly: the same run.
    same_arm, same = run(orientation_gains=(600.0, 50.0))
    assert same.trace.equals(own.trace)
    # λ of J⁺ = Jᵀ(J Jᵀ + λ² I)⁻¹ changes an eq. 17 run.
    a = panda()
    law17 = ar.TimeDelayControl.for_arm(a, law="inverse_jacobian")
    base = ar.paper.scenario("fig14").replace(robot=a, controller=law17, duration=0.5)
    r1 = ar.simulate(base)
    r2 = ar.simulate(base.replace(**{"robot.damping": 0.05}))
    assert not r1.trace["f"].equals(r2.trace["f"])
    with pytest.raises(ar.ParameterError, match="orientation_gains"):
        panda(orientation_gains=(1.0, 2.0, 3.0))
    with pytest.raises(ar.ParameterError, match="damping = -1"):
        panda(damping=-1.0)


def test_a_seven_link_robot_points_to_urdf_arm():
    with pytest.raises(TypeError, match=r"lengths must have 3 elements, got 7 .*ar.UrdfArm"):
        ar.Robot(lengths=[0.4] * 7)


TWO_LINKS = urdf(GOOD_LINK.format(n="b"), JOINT.format(n="j1", t="revolute", p="a", c="b"))


@pytest.mark.parametrize(
    ("text", "match"),
    [
        # A second <link name="b"> with 100 times the mass: urdf-rs keeps both and the last
        # one used to win silently.
        (TWO_LINKS.replace("</robot>", GOOD_LINK.format(n="b").replace('"1"', '"100"')
                           + "</robot>"),
         "urdf link 'b' = defined twice is invalid: must be one <link> per name"),
        (TWO_LINKS.replace("</robot>", GOOD_LINK.format(n="c")
                           + JOINT.format(n="j1", t="revolute", p="b", c="c") + "</robot>"),
         "urdf joint 'j1' = defined twice is invalid: must be one <joint> per name"),
    ],
    ids=["link", "joint"],
)
def test_duplicate_names_are_rejected(text, match):
    assert ar.UrdfArm(urdf=TWO_LINKS, tip_link="b").dof == 1
    with pytest.raises(ar.ParameterError) as e:
        ar.UrdfArm(urdf=text, tip_link="b")
    assert str(e.value) == match


@pytest.mark.parametrize("where", ["xyz", "rpy"])
@pytest.mark.parametrize(
    ("value", "shown"), [("nan", "NaN"), ("inf", "inf"), ("-1e300", "-1e300")]
)
def test_joint_origins_must_be_finite_and_in_range(where, value, shown):
    unit, bound = {"xyz": ("m", "1000"), "rpy": ("rad", "1000")}[where]
    good = TWO_LINKS.replace('<axis', '<origin xyz="0 0 0.5" rpy="0 0 0"/><axis')
    assert ar.UrdfArm(urdf=good, tip_link="b").dof == 1
    old = {"xyz": 'xyz="0 0 0.5"', "rpy": 'rpy="0 0 0"'}[where]
    new = old.replace("0 0 ", f"0 {value} ", 1) if where == "xyz" else f'rpy="0 {value} 0"'
    numbers = {"xyz": f"0, {shown}, 0.5", "rpy": f"0, {shown}, 0"}[where]
    with pytest.raises(ar.ParameterError) as e:
        ar.UrdfArm(urdf=good.replace(old, new), tip_link="b")
    assert str(e.value) == (
        f"urdf joint 'j1' origin {where} = [{numbers}] is invalid: must be three finite "
        f"numbers within ±{bound} {unit}"
    )


def test_inertial_origins_masses_and_limits_are_checked():
    big = TWO_LINKS.replace('<mass value="1"/>', '<mass value="1e300"/>')
    with pytest.raises(ar.ParameterError, match=r"^urdf link 'b' inertial = mass 1e300, inertia "
                       r"\[ixx 0.1, .* must be finite, with mass from 0 to 1e9 kg"):  # fmt: skip
        ar.UrdfArm(urdf=big, tip_link="b")
    far = TWO_LINKS.replace('<mass value="1"/>', '<mass value="1"/><origin xyz="1e300 0 0"/>')
    with pytest.raises(ar.ParameterError, match=r"^urdf link 'b' inertial origin xyz = "
                       r"\[1e300, 0, 0\] is invalid"):  # fmt: skip
        ar.UrdfArm(urdf=far, tip_link="b")
    nan = TWO_LINKS.replace('upper="1"', 'upper="nan"')
    with pytest.raises(ar.ParameterError, match=r"^urdf joint 'j1' limit upper = NaN is invalid"):
        ar.UrdfArm(urdf=nan, tip_link="b")


def test_a_bad_origin_in_a_toml_run_exits_2_naming_the_joint(tmp_path):
    # It used to load, then end as "inertia = NaN" or a singular Jacobian, exit 3.
    text = (DATA / "three_link.urdf").read_text()
    assert text.count('<origin xyz="0 0 0.66"') == 1
    (tmp_path / "arm.urdf").write_text(text.replace('<origin xyz="0 0 0.66"',
                                                    '<origin xyz="0 0 1e300"'))
    (tmp_path / "sc.toml").write_text(
        'duration = 0.1\n[robot]\nkind = "urdf"\npath = "arm.urdf"\ntip_link = "tip"\n'
    )
    done = subprocess.run([sys.executable, "-m", "admit_rs.cli", "run", str(tmp_path / "sc.toml")],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert "origin xyz = [0, 0, 1e300] is invalid: must be three finite numbers" in done.stderr
    assert "Traceback" not in done.stderr


def test_a_urdf_file_that_is_not_utf8_names_the_file(tmp_path):
    path = tmp_path / "latin1.urdf"
    raw = TWO_LINKS.replace('name="r"', 'name="r\xe9"').encode("latin-1")
    path.write_bytes(raw)
    at = raw.index(b"\xe9")
    with pytest.raises(ar.ParameterError) as e:
        ar.UrdfArm(path, "b")
    assert str(e.value) == (
        f"path = {str(path)!r} is invalid: must be a URDF file in UTF-8 (byte {at} is not UTF-8)"
    )
    assert e.value.field == "path"
