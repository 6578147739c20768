"""The arm's dynamics against Pinocchio, an independent rigid-body implementation (SPEC §1).

D, C, G, J, J̇q̇, the tip position and forward dynamics agree to 1e-9 at 100+ random
states for both mass models, with default and with changed parameters.
"""

from __future__ import annotations

import math

import admit_rs as ar
import numpy as np
import pinocchio as pin
import pytest


def pinocchio_arm(robot: ar.Robot) -> tuple[pin.Model, int]:
    """The SPEC arm built joint by joint.

    Joint 1 turns about +z at the origin. Joints 2 and 3 turn about −y of a frame whose +x
    points along the link, so a positive angle raises the link: R_{−y}(θ) x̂ = (cos θ, 0,
    sin θ). Each link lies along its joint frame's +x (link 1 along +z) and carries a thin
    rod (centre at l/2, transverse inertia m l²/12, axial 0) or a point mass at its end.
    """
    (l1, l2, l3), (m1, m2, m3) = robot.lengths, robot.masses
    rod = robot.mass_model == "rod"
    model = pin.Model()
    model.gravity.linear = np.array([0.0, 0.0, -robot.gravity])

    def body(mass: float, length: float, axis: int) -> pin.Inertia:
        lever = np.zeros(3)
        lever[axis] = length / 2 if rod else length
        inertia = np.zeros((3, 3))
        if rod:
            i = mass * length**2 / 12
            inertia = np.diag([i if k != axis else 0.0 for k in range(3)])
        return pin.Inertia(mass, lever, inertia)

    pitch = np.array([0.0, -1.0, 0.0])
    j1 = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "q1")
    model.appendBodyToJoint(j1, body(m1, l1, 2), pin.SE3.Identity())
    shoulder = pin.SE3(np.eye(3), np.array([0.0, 0.0, l1]))
    j2 = model.addJoint(j1, pin.JointModelRevoluteUnaligned(pitch), shoulder, "q2")
    model.appendBodyToJoint(j2, body(m2, l2, 0), pin.SE3.Identity())
    elbow = pin.SE3(np.eye(3), np.array([l2, 0.0, 0.0]))
    j3 = model.addJoint(j2, pin.JointModelRevoluteUnaligned(pitch), elbow, "q3")
    model.appendBodyToJoint(j3, body(m3, l3, 0), pin.SE3.Identity())
    tip = pin.SE3(np.eye(3), np.array([l3, 0.0, 0.0]))
    frame = model.addFrame(pin.Frame("tip", j3, tip, pin.FrameType.OP_FRAME))
    return model, frame


def pinocchio_terms(model: pin.Model, frame: int, q, qd) -> dict[str, np.ndarray]:
    data = model.createData()
    zero = np.zeros(3)
    inertia = pin.crba(model, data, q)
    inertia = np.triu(inertia) + np.triu(inertia, 1).T
    gravity = pin.computeGeneralizedGravity(model, data, q).copy()
    coriolis = pin.rnea(model, data, q, qd, zero) - gravity
    pin.forwardKinematics(model, data, q, qd, zero)
    pin.updateFramePlacements(model, data)
    position = data.oMf[frame].translation.copy()
    jdot_qd = pin.getFrameClassicalAcceleration(
        model, data, frame, pin.LOCAL_WORLD_ALIGNED
    ).linear.copy()
    jacobian = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
    return {
        "inertia": inertia,
        "gravity": gravity,
        "coriolis": coriolis,
        "position": position,
        "jdot_qd": jdot_qd,
        "jacobian": jacobian,
    }


def friction(robot: ar.Robot, qd: np.ndarray) -> np.ndarray:
    eps = robot.friction_smoothing
    sign = np.tanh(qd / eps) if eps > 0 else np.sign(qd)
    return np.asarray(robot.viscous_friction) * qd + np.asarray(robot.coulomb_friction) * sign


def random_states(n: int, seed: int):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        q3 = rng.uniform(0.2, 2.5) * rng.choice([-1.0, 1.0])
        q = np.array([rng.uniform(-math.pi, math.pi), rng.uniform(-1.2, 1.2), q3])
        yield q, rng.uniform(-2.0, 2.0, 3), rng.uniform(-60.0, 60.0, 3), rng.uniform(-50, 50, 3)


ROBOTS = {
    "rod": ar.Robot(),
    "point": ar.Robot(mass_model="point"),
    "rod-custom": ar.Robot(lengths=(0.5, 0.35, 0.6), masses=(12.0, 8.0, 3.5), gravity=3.7,
                           viscous_friction=(1.0, 2.0, 0.5), friction_smoothing=0.05),
    "point-custom": ar.Robot(mass_model="point", lengths=(0.9, 0.5, 0.3),
                             masses=(5.0, 2.0, 9.0), gravity=9.81, friction_smoothing=0.0),
}  # fmt: skip


@pytest.mark.parametrize("name", list(ROBOTS))
def test_dynamics_terms_match_pinocchio(name):
    robot = ROBOTS[name]
    model, frame = pinocchio_arm(robot)
    n = 120 if name in ("rod", "point") else 40
    for q, qd, _, _ in random_states(n, seed=hash(name) % 2**32):
        ours = robot.dynamics(q, qd)
        ref = pinocchio_terms(model, frame, q, qd)
        for key, expected in ref.items():
            np.testing.assert_allclose(ours[key], expected, rtol=0, atol=1e-9,
                                       err_msg=f"{name} {key} at q={q}, qd={qd}")  # fmt: skip
        np.testing.assert_allclose(ours["friction"], friction(robot, qd), rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", list(ROBOTS))
def test_forward_dynamics_matches_pinocchio_aba(name):
    robot = ROBOTS[name]
    model, frame = pinocchio_arm(robot)
    data = model.createData()
    for q, qd, tau, tip_force in random_states(100, seed=7 + len(name)):
        jac = pinocchio_terms(model, frame, q, qd)["jacobian"]
        expected = pin.aba(model, data, q, qd, tau - friction(robot, qd) + jac.T @ tip_force)
        ours = robot.forward_dynamics(q, qd, tau, tip_force)
        scale = max(1.0, float(np.abs(expected).max()))
        np.testing.assert_allclose(ours, expected, rtol=0, atol=1e-9 * scale,
                                   err_msg=f"{name} at q={q}")  # fmt: skip


def test_spec_check_values_in_both_implementations():
    robot = ar.Robot()
    q0 = np.array(robot.q0)
    model, frame = pinocchio_arm(robot)
    for terms in (robot.dynamics(q0), pinocchio_terms(model, frame, q0, np.zeros(3))):
        np.testing.assert_allclose(terms["position"], [0.734056, 0.0, 0.964056], atol=1e-6)
        np.testing.assert_allclose(
            terms["inertia"], [[1.903, 0, 0], [0, 2.883, 0.610], [0, 0.610, 0.296]], atol=5e-4
        )
        np.testing.assert_allclose(terms["gravity"], [0.0, 50.39, 10.12], atol=5e-3)


def test_link1_mass_changes_nothing():
    """Link 1 lies on the yaw axis: its mass must not enter D, C or G."""
    q, qd = np.array([0.3, 0.4, -0.9]), np.array([0.5, -0.2, 0.7])
    light = ar.Robot(masses=(1.0, 17.4, 4.8)).dynamics(q, qd)
    heavy = ar.Robot(masses=(300.0, 17.4, 4.8)).dynamics(q, qd)
    for key in ("inertia", "coriolis", "gravity"):
        np.testing.assert_array_equal(light[key], heavy[key])
