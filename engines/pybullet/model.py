"""Build the PyBullet 3.2.7 model of a generic `Mechanism` (headless client).

Where each joint goes (multibody joint or loop constraint, which
multibodies, which reactions are read and which derived) is planned in
`layout`; layout "split" (the default) hangs every joint whose
sensor is read from the fixed ground as a leaf.

Frames: a tree link's frame sits at its joint point with the body's
orientation; every PyBullet inertial frame is at the body's centre of mass
with the body's orientation, so readings (COM pose and velocity) convert to
the body frame origin with the body's `com`. Links have no collision or
visual shapes (no contacts); their inertia is set explicitly because
PyBullet gives shapeless links zero inertia. Every default that adds an
effect is disarmed here (see `disarm_defaults` and `configure_solver`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from mechval.engines.base import native_output_silenced, reference_motion
from mechval.engines.pybullet.layout import Link, plan_layout

with native_output_silenced():      # PyBullet prints its build time on import
    import pybullet as p

from mechval.model.kinematics import point_motion, point_position, rotate_scalar, separation, slide_axis, slide_motion
from mechval.model.mechanism import GROUND, Joint, Mechanism

#: Force/impulse caps meant as "no cap": far above any kN-scale reaction,
#: far below overflow.
NO_CAP = 1e12
#: Joint speed limit meant as "no limit" (PyBullet clamps at 100 rad/s).
NO_SPEED_LIMIT = 1e9


@dataclass(frozen=True)
class BodyHandle:
    """Where a mechanism body lives in PyBullet: multibody id and link index
    (−1: the multibody's base)."""

    uid: int
    link: int


@dataclass(frozen=True)
class TreeJoint:
    """A mechanism joint modelled as a multibody joint; `child` is the body
    on the link side (the sensor reports the force by parent on child)."""

    joint: Joint
    child: str
    handle: BodyHandle


@dataclass(frozen=True)
class LoopConstraint:
    """A mechanism joint modelled as a user constraint; `child` is the body
    on the constraint's child side (getConstraintState: force on child)."""

    joint: Joint
    child: str
    cid: int


@dataclass
class Model:
    """A built PyBullet model in its own DIRECT client, in the state of
    `start` (raw motion columns, one row: see `start_state`)."""

    client: int
    timestep: float
    ground: BodyHandle
    bodies: dict[str, BodyHandle]
    tree_joints: dict[str, TreeJoint]
    constraints: dict[str, LoopConstraint]
    coms: dict[str, tuple[float, float]]
    start: pd.DataFrame
    #: The multibody joints whose reactions are derived, each with the body
    #: whose balance gives them (`layout.Layout.derived`).
    derived: tuple[tuple[Joint, str], ...] = ()


def side(joint: Joint, body: str) -> tuple[float, float]:
    """The joint's point in `body`'s frame."""
    return joint.point_i if body == joint.body_i else joint.point_j


def quat_z(theta: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, float(np.sin(theta / 2)), float(np.cos(theta / 2)))


def _inertia(mechanism: Mechanism, body: str) -> list[float]:
    # Out-of-plane principal moments never act (ω stays along z, a principal
    # axis); izz is used for all three so the 3D solver sees a regular body.
    izz = mechanism.body(body).izz
    return [izz, izz, izz]


def configure_solver(client: int, timestep: float, gravity: tuple[float, float]) -> None:
    """Time step and solver settings that add no effect and stop no early.

    Dantzig LCP (exact) instead of PGS; `solverResidualThreshold=0`
    (Dantzig ignores it, but PGS, its fallback, stops early at the default);
    no CFM and full error reduction; no sub-steps (they corrupt reported
    torques and constraint forces). Gravity is set explicitly (zero if
    none). tests/test_pybullet.py re-arms each default and measures what it
    costs (figures: docs/engines.md).
    """
    p.setPhysicsEngineParameter(
        fixedTimeStep=timestep, numSubSteps=0,
        constraintSolverType=p.CONSTRAINT_SOLVER_LCP_DANTZIG,
        solverResidualThreshold=0.0, globalCFM=0.0, erp=1.0,
        jointFeedbackMode=p.JOINT_FEEDBACK_IN_WORLD_SPACE | p.JOINT_FEEDBACK_IN_JOINT_FRAME,
        physicsClientId=client)
    p.setGravity(gravity[0], gravity[1], 0.0, physicsClientId=client)


def start_state(mechanism: Mechanism, t_start: float, timestep: float) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The reference state a run starts from: (poses at t_start, rates at
    t_start − dt/2, since the semi-implicit Euler velocity stands for the
    step's middle), raw motion columns, one row each.

    A prescribed motion: the reference motion (`mechanism.motion`) at both
    instants. A torque-driven or free one (`Mechanism.forward_dynamics`),
    which starts at the first instant with no pre-roll: the consistent
    initial state the forward-dynamics reference integrates from
    (`raw_dynamics` at t_start, the state every adapter starts from), its
    rates taken half a step back along its accelerations, v − a·dt/2
    (O(dt²), like the velocities the engine's steps then carry)."""
    if not mechanism.forward_dynamics:
        return mechanism.motion(np.array([t_start])), mechanism.motion(np.array([t_start - timestep / 2]))
    pose = reference_motion(mechanism, np.array([t_start]))
    rates = pose.copy()
    for body in mechanism.bodies:
        for rate, accel in (("vx", "ax"), ("vy", "ay"), ("omega", "alpha")):
            rates[f"{body.name}.{rate}"] -= timestep / 2 * pose[f"{body.name}.{accel}"]
    return pose, rates


def build(mechanism: Mechanism, timestep: float, layout: str, t_start: float,
          state: tuple[pd.DataFrame, pd.DataFrame] | None = None) -> Model:
    """Connect a DIRECT client and build the model in the reference state of
    t_start (`start_state`), or in `state` (poses, rates) when given."""
    client = p.connect(p.DIRECT)
    try:
        with native_output_silenced():      # "switched solver" notices from C
            configure_solver(client, timestep, mechanism.gravity)
        pose, rates = state if state is not None else start_state(mechanism, t_start, timestep)
        plan = plan_layout(mechanism, layout)
        model = Model(client, timestep, BodyHandle(-1, -1), {}, {}, {},
                      {b.name: b.com for b in mechanism.bodies}, pose, plan.derived)
        for root, links in plan.multibodies.items():
            _build_multibody(mechanism, model, root, links, pose, rates)
        _build_constraints(mechanism, model)
        disarm_defaults(mechanism, model)
        return model
    except BaseException:
        p.disconnect(client)
        raise


def _angle(motion: pd.DataFrame, body: str) -> float:
    return 0.0 if body == GROUND else float(motion[f"{body}.theta"].iloc[0])


def _omega(motion: pd.DataFrame, body: str) -> float:
    return 0.0 if body == GROUND else float(motion[f"{body}.omega"].iloc[0])


def _com(model: Model, body: str) -> tuple[float, float]:
    return (0.0, 0.0) if body == GROUND else model.coms[body]


def _build_multibody(mechanism: Mechanism, model: Model, root: str, links: list[Link],
                     pose: pd.DataFrame, rates: pd.DataFrame) -> None:
    """One multibody: the root as base (the ground: fixed, mass 0; a body:
    base frame at its COM) and the given joints' children as links."""
    index = {root: 0}                         # createMultiBody: 0 = base
    # Link frame origin in each body's frame: the base frame is at the COM.
    origin = {root: _com(model, root)}
    masses, inertial, positions, orientations, parents, types, axes = [], [], [], [], [], [], []
    for k, (joint, parent, child) in enumerate(links):
        index[child] = k + 1
        origin[child] = side(joint, child)
        body = mechanism.body(child)
        masses.append(body.mass)
        inertial.append((body.com[0] - origin[child][0], body.com[1] - origin[child][1], 0.0))
        # Relative to the parent's link frame (URDF semantics, measured);
        # both frames have the parent body's orientation.
        pj = side(joint, parent)
        positions.append((pj[0] - origin[parent][0], pj[1] - origin[parent][1], 0.0))
        parents.append(index[parent])
        if joint.kind == "revolute":
            orientations.append(quat_z(0.0))
            types.append(p.JOINT_REVOLUTE)
            axes.append((0.0, 0.0, 1.0))
        else:
            rel = _angle(pose, child) - _angle(pose, parent)
            orientations.append(quat_z(rel))
            types.append(p.JOINT_PRISMATIC)
            # The axis is fixed in body_i; the joint axis is in the child frame.
            ax = joint.axis if child == joint.body_i else rotate_scalar(-rel, joint.axis)
            axes.append((ax[0], ax[1], 0.0))
    n = len(links)
    if root == GROUND:
        base = dict(baseMass=0.0, basePosition=(0, 0, 0), baseOrientation=quat_z(0.0))
    else:
        com = point_position(pose, root, _com(model, root))
        base = dict(baseMass=mechanism.body(root).mass, basePosition=(com["x"][0], com["y"][0], 0.0),
                    baseOrientation=quat_z(_angle(pose, root)))
    uid = p.createMultiBody(
        **base, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
        linkMasses=masses, linkCollisionShapeIndices=[-1] * n, linkVisualShapeIndices=[-1] * n,
        linkPositions=positions, linkOrientations=orientations,
        linkInertialFramePositions=inertial, linkInertialFrameOrientations=[quat_z(0.0)] * n,
        linkParentIndices=parents, linkJointTypes=types, linkJointAxis=axes,
        useMaximalCoordinates=False, physicsClientId=model.client)
    if root == GROUND:
        model.ground = BodyHandle(uid, -1)
    else:
        model.bodies[root] = BodyHandle(uid, -1)
        vcom = point_motion(rates, root, _com(model, root))
        p.resetBaseVelocity(uid, (vcom["vx"][0], vcom["vy"][0], 0.0), (0.0, 0.0, _omega(rates, root)),
                            physicsClientId=model.client)
    for k, (joint, parent, child) in enumerate(links):
        handle = BodyHandle(uid, k)
        model.bodies[child] = handle
        model.tree_joints[joint.name] = TreeJoint(joint, child, handle)
        q, qd = _joint_coordinate(mechanism, joint, parent, child, pose, rates)
        p.resetJointState(uid, k, q, qd, physicsClientId=model.client)
        p.enableJointForceTorqueSensor(uid, k, True, physicsClientId=model.client)


def drive_force_arm(mechanism: Mechanism, joint: Joint) -> float:
    """(G − P)×u of a prismatic joint, G body_j's centre of mass, P the
    joint's point on it, u the axis (in body_j's frame: a constant, as the
    slide holds the relative angle).

    Why: PyBullet's motor force on a slide acts along the axis through the
    link's centre of mass, and the joint's sensor leaves it out there; the
    reference's drive force F acts at P. So where the link is body_j, the
    sensor's couple about P is the reference's M less the moment of F
    about G, (G − P)×u·F (measured: that difference to 1e-8 N·m on the
    slider-driven slider-crank with its centre of mass off the pin); the
    adapter adds it back."""
    com = mechanism.body(joint.body_j).com
    ux, uy = rotate_scalar(-joint.held_angle, joint.axis)
    rx, ry = com[0] - joint.point_j[0], com[1] - joint.point_j[1]
    return rx * uy - ry * ux


def _joint_coordinate(mechanism: Mechanism, joint: Joint, parent: str, child: str,
                      pose: pd.DataFrame, rates: pd.DataFrame) -> tuple[float, float]:
    """PyBullet joint position (at `pose`) and velocity (at `rates`)."""
    if joint.kind == "revolute":
        return (_angle(pose, child) - _angle(pose, parent), _omega(rates, child) - _omega(rates, parent))
    # Slide along the axis (fixed in body_i) of point_j relative to point_i;
    # the child's coordinate runs the other way when the child is body_i.
    # The rate: the joint points' relative velocity at `rates` along the
    # axis as it stands at `pose`, where the model is built.
    sign = 1.0 if child == joint.body_j else -1.0
    ux, uy = slide_axis(pose, joint)
    d = separation(rates, joint)
    s = slide_motion(pose, joint)["s"]
    v = d["vx"] * ux + d["vy"] * uy
    return sign * float(s[0]), sign * float(v[0])


def _build_constraints(mechanism: Mechanism, model: Model) -> None:
    """Every joint not in a multibody closes the loop as a point-to-point
    constraint (pivots relative to each side's COM frame; parent = body_i);
    plan_layout keeps prismatic joints out of this list."""
    for joint in mechanism.joints:
        if joint.name in model.tree_joints:
            continue
        parent, child = joint.body_i, joint.body_j
        pivots = []
        for body in (parent, child):
            point, com = side(joint, body), _com(model, body)
            pivots.append((point[0] - com[0], point[1] - com[1], 0.0))
        handles = {**model.bodies, GROUND: model.ground}
        pa, ch = handles[parent], handles[child]
        cid = p.createConstraint(pa.uid, pa.link, ch.uid, ch.link, p.JOINT_POINT2POINT, (0.0, 0.0, 1.0),
                                 pivots[0], pivots[1], physicsClientId=model.client)
        # The cap is an impulse converted with the time step current at
        # this call: configure_solver has already set it.
        p.changeConstraint(cid, maxForce=NO_CAP, physicsClientId=model.client)
        model.constraints[joint.name] = LoopConstraint(joint, child, cid)


def disarm_defaults(mechanism: Mechanism, model: Model) -> None:
    """Switch off every PyBullet default that adds an effect.

    Per multibody: linear/angular damping 0.04 → 0, in a call of its own
    (mixed with per-link keys the whole call lands on the base only), and
    the 100 rad/s joint speed clamp lifted. Per link: explicit inertia,
    no joint damping, the default velocity motor (friction) released.
    """
    c = model.client
    for uid in {h.uid for h in model.bodies.values()}:
        p.changeDynamics(uid, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=c)
        p.changeDynamics(uid, -1, maxJointVelocity=NO_SPEED_LIMIT, physicsClientId=c)
    for name, h in model.bodies.items():
        p.changeDynamics(h.uid, h.link, localInertiaDiagonal=_inertia(mechanism, name), physicsClientId=c)
        if h.link >= 0:
            p.changeDynamics(h.uid, h.link, jointDamping=0.0, physicsClientId=c)
            p.setJointMotorControl2(h.uid, h.link, p.VELOCITY_CONTROL, force=0.0, physicsClientId=c)
