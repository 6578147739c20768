"""Cross-check of the arm's rigid-body dynamics (SPEC §1) against Pinocchio.

The same 3-joint arm is built independently in Pinocchio, its kinematics is first checked
against the closed-form tip formula, and then D, C, G, J, J̇q̇, the tip position, the friction
torque and forward dynamics of ``admit_rs`` are compared to Pinocchio's CRBA, RNEA, frame
Jacobian, frame acceleration and ABA at random states for both mass models.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import admit_rs as ar
import numpy as np
import pinocchio as pin
import pytest

MASS_MODELS = ["rod", "point"]
N_STATES = 120
ATOL = 1e-9


def build_pinocchio_arm(robot: ar.Robot) -> tuple[pin.Model, int]:
    """Build ``robot`` as a Pinocchio model; return it with the tip frame's id.

    Frame choice: every joint frame has the world's orientation at q = 0. Joint 1 is a
    revolute-Z joint at the origin; link 1 lies along its +z. Joint 2 sits at (0, 0, l1) and
    joint 3 at (l2, 0, 0) in joint 2's frame; both turn about -y, and links 2 and 3 lie along
    their joint frame's +x, so a positive angle raises the link: R_{-y}(θ) x̂ = (cos θ, 0,
    sin θ). The tip frame sits at (l3, 0, 0) in joint 3's frame. A "rod" link is a uniform thin
    rod (centre at l/2, transverse inertia m l²/12, axial inertia 0); a "point" link is a point
    mass at its distal end.
    """
    lengths, masses = robot.lengths, robot.masses
    model = pin.Model()
    model.gravity.linear = np.array([0.0, 0.0, -robot.gravity])

    def link_inertia(mass: float, length: float, axis: int) -> pin.Inertia:
        lever = np.zeros(3)
        rotational = np.zeros((3, 3))
        if robot.mass_model == "rod":
            lever[axis] = length / 2.0
            transverse = mass * length**2 / 12.0
            rotational = np.diag([0.0 if k == axis else transverse for k in range(3)])
        else:
            lever[axis] = length
        return pin.Inertia(mass, lever, rotational)

    def translation(x: float, y: float, z: float) -> pin.SE3:
        return pin.SE3(np.eye(3), np.array([x, y, z]))

    pitch_axis = np.array([0.0, -1.0, 0.0])
    yaw = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "yaw")
    model.appendBodyToJoint(yaw, link_inertia(masses[0], lengths[0], 2), pin.SE3.Identity())
    shoulder = model.addJoint(
        yaw, pin.JointModelRevoluteUnaligned(pitch_axis), translation(0, 0, lengths[0]), "q2"
    )
    model.appendBodyToJoint(shoulder, link_inertia(masses[1], lengths[1], 0), pin.SE3.Identity())
    elbow = model.addJoint(
        shoulder, pin.JointModelRevoluteUnaligned(pitch_axis), translation(lengths[1], 0, 0), "q3"
    )
    model.appendBodyToJoint(elbow, link_inertia(masses[2], lengths[2], 0), pin.SE3.Identity())
    tip = model.addFrame(
        pin.Frame("tip", elbow, translation(lengths[2], 0, 0), pin.FrameType.OP_FRAME)
    )
    return model, tip


def pinocchio_reference(
    model: pin.Model, tip: int, q: np.ndarray, qd: np.ndarray
) -> dict[str, np.ndarray]:
    """D, C, G, J, J̇q̇ and the tip position from Pinocchio, keyed like ``Robot.dynamics``."""
    data = model.createData()
    zero = np.zeros(model.nv)
    inertia = pin.crba(model, data, q).copy()
    inertia = np.triu(inertia) + np.triu(inertia, 1).T
    gravity = pin.computeGeneralizedGravity(model, data, q).copy()
    coriolis = pin.rnea(model, data, q, qd, zero) - gravity
    jacobian = pin.computeFrameJacobian(model, data, q, tip, pin.LOCAL_WORLD_ALIGNED)[:3].copy()
    pin.forwardKinematics(model, data, q, qd, zero)
    pin.updateFramePlacements(model, data)
    accel = pin.getFrameClassicalAcceleration(model, data, tip, pin.LOCAL_WORLD_ALIGNED)
    return {
        "inertia": inertia,
        "coriolis": coriolis,
        "gravity": gravity,
        "jacobian": jacobian,
        "jdot_qd": accel.linear.copy(),
        "position": data.oMf[tip].translation.copy(),
    }


def tip_formula(lengths: tuple[float, float, float], q: np.ndarray) -> np.ndarray:
    """SPEC §1 closed-form tip position."""
    l1, l2, l3 = lengths
    r = l2 * math.cos(q[1]) + l3 * math.cos(q[1] + q[2])
    z = l1 + l2 * math.sin(q[1]) + l3 * math.sin(q[1] + q[2])
    return np.array([math.cos(q[0]) * r, math.sin(q[0]) * r, z])


def spec_friction(
    qd: np.ndarray, fv: float | np.ndarray = 3.0, fc: float | np.ndarray = 5.0, eps: float = 0.01
) -> np.ndarray:
    """τ_f = Fv q̇ + Fc tanh(q̇/ε); exact sign (sign(0) = 0) when ε ≤ 0."""
    sign = np.tanh(qd / eps) if eps > 0 else np.sign(qd)
    return fv * qd + fc * sign


def random_states(
    n: int, seed: int
) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """(q, q̇, τ, F_tip) away from singularities: q3 ∈ ±[0.2, 2.5], |q2| ≤ 1.2."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        q3 = rng.choice([-1.0, 1.0]) * rng.uniform(0.2, 2.5)
        q = np.array([rng.uniform(-math.pi, math.pi), rng.uniform(-1.2, 1.2), q3])
        qd = rng.uniform(-2.0, 2.0, 3)
        tau = rng.uniform(-80.0, 80.0, 3)
        force = rng.uniform(-60.0, 60.0, 3)
        yield q, qd, tau, force


def assert_close(actual: np.ndarray, expected: np.ndarray, msg: str) -> None:
    """Absolute tolerance 1e-9, scaled by the reference's magnitude when that exceeds 1."""
    expected = np.asarray(expected)
    scale = max(1.0, float(np.max(np.abs(expected))))
    np.testing.assert_allclose(actual, expected, rtol=0, atol=ATOL * scale, err_msg=msg)


def check_against_pinocchio(robot: ar.Robot, n: int, seed: int) -> None:
    model, tip = build_pinocchio_arm(robot)
    data = model.createData()
    for q, qd, tau, force in random_states(n, seed):
        where = f"{robot.mass_model} at q={q.tolist()}, qd={qd.tolist()}"
        ours = robot.dynamics(q, qd)
        ref = pinocchio_reference(model, tip, q, qd)
        for key, expected in ref.items():
            assert ours[key].shape == expected.shape, key
            assert_close(ours[key], expected, f"{key} {where}")
        friction = spec_friction(
            qd,
            np.asarray(robot.viscous_friction),
            np.asarray(robot.coulomb_friction),
            robot.friction_smoothing,
        )
        assert_close(ours["friction"], friction, f"friction {where}")
        expected_qdd = pin.aba(model, data, q, qd, tau - friction + ref["jacobian"].T @ force)
        assert_close(
            robot.forward_dynamics(q, qd, tau, force),
            expected_qdd,
            f"forward dynamics {where}, tau={tau.tolist()}, F={force.tolist()}",
        )


@pytest.mark.parametrize("mass_model", MASS_MODELS)
def test_pinocchio_model_matches_tip_formula(mass_model):
    robot = ar.Robot(mass_model=mass_model)
    model, tip = build_pinocchio_arm(robot)
    data = model.createData()
    assert model.nq == model.nv == 3
    for q, _, _, _ in random_states(N_STATES, seed=11):
        pin.framesForwardKinematics(model, data, q)
        np.testing.assert_allclose(
            data.oMf[tip].translation, tip_formula(robot.lengths, q), rtol=0, atol=1e-12
        )
        np.testing.assert_allclose(
            robot.tip_position(q), tip_formula(robot.lengths, q), rtol=0, atol=1e-12
        )


@pytest.mark.parametrize("mass_model", MASS_MODELS)
def test_dynamics_terms_match_pinocchio(mass_model):
    robot = ar.Robot(mass_model=mass_model)
    model, tip = build_pinocchio_arm(robot)
    for q, qd, _, _ in random_states(N_STATES, seed=2024):
        ours = robot.dynamics(q, qd)
        ref = pinocchio_reference(model, tip, q, qd)
        where = f"{mass_model} at q={q.tolist()}, qd={qd.tolist()}"
        for key in ("inertia", "coriolis", "gravity", "jacobian", "jdot_qd", "position"):
            assert ours[key].shape == ref[key].shape, key
            assert_close(ours[key], ref[key], f"{key} {where}")


@pytest.mark.parametrize("mass_model", MASS_MODELS)
def test_friction_matches_spec_formula(mass_model):
    robot = ar.Robot(mass_model=mass_model)
    for q, qd, _, _ in random_states(N_STATES, seed=5):
        assert_close(robot.dynamics(q, qd)["friction"], spec_friction(qd), f"friction qd={qd}")
    slow = np.array([0.0, 1e-4, -3e-3])
    assert_close(robot.dynamics(robot.q0, slow)["friction"], spec_friction(slow), "near zero")


@pytest.mark.parametrize("mass_model", MASS_MODELS)
def test_forward_dynamics_matches_pinocchio_aba(mass_model):
    robot = ar.Robot(mass_model=mass_model)
    model, tip = build_pinocchio_arm(robot)
    data = model.createData()
    for q, qd, tau, force in random_states(N_STATES, seed=99):
        jacobian = pinocchio_reference(model, tip, q, qd)["jacobian"]
        expected = pin.aba(model, data, q, qd, tau - spec_friction(qd) + jacobian.T @ force)
        assert_close(
            robot.forward_dynamics(q, qd, tau, force),
            expected,
            f"{mass_model} at q={q.tolist()}, qd={qd.tolist()}, tau={tau}, F={force}",
        )


@pytest.mark.parametrize("mass_model", MASS_MODELS)
def test_non_default_parameters_match_pinocchio(mass_model):
    robot = ar.Robot(
        mass_model=mass_model,
        lengths=(0.8, 0.55, 0.31),
        masses=(7.0, 11.3, 2.6),
        gravity=3.71,
        viscous_friction=(1.5, 0.7, 2.2),
        coulomb_friction=(2.0, 4.0, 0.5),
        friction_smoothing=0.05,
    )
    check_against_pinocchio(robot, N_STATES, seed=31)


@pytest.mark.parametrize("mass_model", MASS_MODELS)
def test_exact_sign_friction_matches_pinocchio(mass_model):
    """ε ≤ 0 switches to the exact sign, with sign(0) = 0."""
    robot = ar.Robot(mass_model=mass_model, friction_smoothing=0.0)
    check_against_pinocchio(robot, 40, seed=8)
    qd = np.array([0.0, 0.2, -0.3])
    assert_close(robot.dynamics(robot.q0, qd)["friction"], [0.0, 5.6, -5.9], "exact sign")


@pytest.mark.parametrize("mass_model", MASS_MODELS)
def test_link1_mass_makes_no_difference(mass_model):
    """Link 1 lies on the yaw axis, so its mass enters neither D, C, G nor Pinocchio's."""
    q, qd = np.array([0.4, 0.3, -1.1]), np.array([1.2, -0.6, 0.9])
    light = ar.Robot(mass_model=mass_model, masses=(0.5, 17.4, 4.8))
    heavy = ar.Robot(mass_model=mass_model, masses=(250.0, 17.4, 4.8))
    ours_light, ours_heavy = light.dynamics(q, qd), heavy.dynamics(q, qd)
    ref_light = pinocchio_reference(*build_pinocchio_arm(light), q, qd)
    ref_heavy = pinocchio_reference(*build_pinocchio_arm(heavy), q, qd)
    for key in ("inertia", "coriolis", "gravity"):
        assert_close(ours_light[key], ours_heavy[key], f"admit_rs {key}")
        assert_close(ref_light[key], ref_heavy[key], f"pinocchio {key}")


def test_spec_check_values_at_q0_in_both_implementations():
    robot = ar.Robot()
    q0 = np.array([0.0, math.pi / 4, -math.pi / 4])
    np.testing.assert_allclose(robot.q0, q0, rtol=0, atol=1e-15)
    model, tip = build_pinocchio_arm(robot)
    implementations = {
        "admit_rs": robot.dynamics(q0, np.zeros(3)),
        "pinocchio": pinocchio_reference(model, tip, q0, np.zeros(3)),
    }
    d_spec = [[1.903, 0.0, 0.0], [0.0, 2.883, 0.610], [0.0, 0.610, 0.296]]
    for name, terms in implementations.items():
        np.testing.assert_allclose(terms["inertia"], d_spec, rtol=0, atol=5e-4, err_msg=name)
        np.testing.assert_allclose(
            terms["gravity"], [0.0, 50.39, 10.12], rtol=0, atol=5e-3, err_msg=name
        )
        np.testing.assert_allclose(
            terms["position"], [0.734056, 0.0, 0.964056], rtol=0, atol=1e-6, err_msg=name
        )
