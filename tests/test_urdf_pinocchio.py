"""URDF arms against Pinocchio (SPEC §11): D, C q̇ + G, J, J̇q̇, the tip pose and forward
dynamics with a tip force agree to 1e-9 at 50 random states each, on random chains (1 to 8
joints: tilted and non-unit axes, random origins and rpy, full inertia tensors, prismatic,
continuous and fixed joints) and on the UR5 and Panda files."""

from pathlib import Path

import admit_rs as ar
import numpy as np
import pinocchio as pin
import pytest

DATA = Path(__file__).resolve().parent.parent / "examples" / "data"
TOL = 1e-9
STATES = 50


def vec(v):
    """Three numbers as URDF text, exactly."""
    return " ".join(repr(float(x)) for x in v)


def _inertia_xml(rng):
    """A physically valid random inertial: a point cloud's moments, rotated."""
    mass = rng.uniform(0.2, 5.0)
    second = rng.uniform(0.001, 0.05, 3) * mass  # Σ m x², Σ m y², Σ m z² about the COM
    moments = np.array([second[1] + second[2], second[0] + second[2], second[0] + second[1]])
    rot = pin.rpy.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3))
    tensor = rot @ np.diag(moments) @ rot.T
    com = rng.uniform(-0.2, 0.2, 3)
    rpy = rng.uniform(-np.pi, np.pi, 3)
    # The tensor is given in the inertial frame (rotated by rpy): undo that rotation.
    r_in = pin.rpy.rpyToMatrix(*rpy)
    t = r_in.T @ tensor @ r_in
    return (
        f'<inertial><origin xyz="{vec(com)}" '
        f'rpy="{vec(rpy)}"/><mass value="{float(mass)!r}"/>'
        f'<inertia ixx="{float(t[0, 0])!r}" ixy="{float(t[0, 1])!r}" ixz="{float(t[0, 2])!r}" '
        f'iyy="{float(t[1, 1])!r}" iyz="{float(t[1, 2])!r}" izz="{float(t[2, 2])!r}"/></inertial>'
    )


def random_chain(n, seed):
    """URDF text for us (raw, non-unit axes) and for Pinocchio (unit axes), and the tip."""
    rng = np.random.default_rng(seed)
    links = ['<link name="base"/>']
    ours, theirs = [], []
    parent, moving = "base", 0
    k = 0
    while moving < n:
        k += 1
        kinds = ["revolute", "continuous", "prismatic", "fixed"]
        kind = rng.choice(kinds, p=[0.45, 0.15, 0.2, 0.2])
        if kind != "fixed":
            moving += 1
        child = f"l{k}"
        xyz = rng.uniform(-0.4, 0.4, 3)
        rpy = rng.uniform(-np.pi, np.pi, 3)
        axis = rng.normal(size=3)
        if rng.random() < 0.3:  # an aligned axis now and then, scaled
            axis = np.eye(3)[rng.integers(3)] * rng.uniform(0.5, 3.0)
        unit = axis / np.linalg.norm(axis)
        head = (
            f'<joint name="j{k}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{vec(xyz)}" '
            f'rpy="{vec(rpy)}"/>'
        )
        limit = '<limit lower="-3" upper="3" effort="50" velocity="5"/>'
        ours.append(head + f'<axis xyz="{vec(axis)}"/>{limit}</joint>')
        theirs.append(head + f'<axis xyz="{vec(unit)}"/>{limit}</joint>')
        links.append(f'<link name="{child}">{_inertia_xml(rng)}</link>')
        parent = child
    # A fixed tool frame at the end.
    k += 1
    tail = (
        f'<joint name="j{k}" type="fixed"><parent link="{parent}"/><child link="tool"/>'
        '<origin xyz="0.05 -0.1 0.2" rpy="0.3 -0.2 0.1"/></joint>'
    )
    links.append(f'<link name="tool">{_inertia_xml(rng)}</link>')
    wrap = '<?xml version="1.0"?><robot name="r">{}</robot>'
    return (
        wrap.format("".join(links + ours) + tail),
        wrap.format("".join(links + theirs) + tail),
        "tool",
    )


def pin_configuration(model, q):
    """Our joint angles as Pinocchio's q (continuous joints are (cos, sin) pairs)."""
    out = []
    for i, joint in enumerate(model.joints[1:]):
        out += [np.cos(q[i]), np.sin(q[i])] if joint.nq == 2 else [q[i]]
    return np.array(out)


def compare(urdf_ours, urdf_pin, tip, seed):
    """Worst absolute difference per quantity over STATES random states."""
    arm = ar.UrdfArm(urdf=urdf_ours, tip_link=tip)
    model = pin.buildModelFromXML(urdf_pin)
    data = model.createData()
    frame = model.getFrameId(tip)
    n = arm.dof
    assert model.nv == n
    rng = np.random.default_rng(seed)
    worst: dict[str, float] = {}

    def note(name, ours, theirs):
        worst[name] = max(worst.get(name, 0.0), float(np.max(np.abs(np.asarray(ours) - theirs))))

    for _ in range(STATES):
        q = rng.uniform(-2.5, 2.5, n)
        v = rng.uniform(-2.0, 2.0, n)
        tau = rng.uniform(-20.0, 20.0, n)
        force = rng.uniform(-30.0, 30.0, 3)
        qp = pin_configuration(model, q)
        terms = arm.dynamics(q, v)
        d = pin.crba(model, data, qp)
        d = np.triu(d) + np.triu(d, 1).T
        note("D", terms["inertia"], d)
        note("Cqd+G", terms["coriolis"] + terms["gravity"], pin.rnea(model, data, qp, v, 0 * v))
        note("G", terms["gravity"], pin.computeGeneralizedGravity(model, data, qp))
        jac = pin.computeFrameJacobian(model, data, qp, frame, pin.LOCAL_WORLD_ALIGNED)
        note("J", terms["jacobian"], np.reshape(jac, (6, n)))
        pin.forwardKinematics(model, data, qp, v, 0 * v)
        pin.updateFramePlacements(model, data)
        acc = pin.getFrameClassicalAcceleration(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        note("Jdot_qd", terms["jdot_qd"], np.r_[acc.linear, acc.angular])
        tip_pose = data.oMf[frame]
        note("tip position", terms["position"], tip_pose.translation)
        note("tip rotation", terms["rotation"], tip_pose.rotation)
        # ABA with the tip force as an external wrench on the last joint (its local frame).
        last = model.frames[frame].parentJoint
        wrench = pin.Force(force, np.cross(tip_pose.translation, force))
        fext = [pin.Force.Zero() for _ in range(model.njoints)]
        fext[last] = data.oMi[last].actInv(wrench)
        qdd_pin = pin.aba(model, data, qp, v, tau, fext)
        note("forward dynamics", arm.forward_dynamics(q, v, tau, force), qdd_pin)
    return worst


@pytest.mark.parametrize("n", range(1, 9))
def test_random_chains_agree_with_pinocchio(n):
    for seed in (n, 100 + n):
        ours, theirs, tip = random_chain(n, seed)
        worst = compare(ours, theirs, tip, seed)
        assert max(worst.values()) < TOL, worst


@pytest.mark.parametrize(
    ("name", "tip"), [("ur5.urdf", "tool0"), ("panda.urdf", "panda_hand_tcp")]
)
def test_real_arms_agree_with_pinocchio(name, tip):
    text = (DATA / name).read_text()
    worst = compare(text, text, tip, 7)
    assert max(worst.values()) < TOL, worst


def test_random_chains_have_every_joint_kind():
    kinds = set()
    for n in range(1, 9):
        for seed in (n, 100 + n):
            ours, _, _ = random_chain(n, seed)
            kinds |= {k for k in ("revolute", "continuous", "prismatic", "fixed")
                      if f'type="{k}"' in ours}  # fmt: skip
    assert kinds == {"revolute", "continuous", "prismatic", "fixed"}
