"""Build the PyBullet 3.2.7 model of a generic `Mechanism` (headless client).

Layout ("split", the default): every body that has a joint to the ground is
a link of one fixed-base multibody whose base is the ground, so each of
those joints is a leaf with its own force/torque sensor; every other body is
a free multibody of its own, tied to its neighbours by user constraints
(`JOINT_POINT2POINT` for a revolute joint, `JOINT_PRISMATIC` for a slider).
PyBullet's joint sensor is wrong for a joint whose child carries further
moving links (ENGINE_NOTES: 40–80 % on F12/F32), hence no joint chains.
Layout "tree" is that naive spanning tree (a breadth-first tree of joints
from the ground, the remaining joint closing the loop); it exists only so a
regression test can show the sensor error.

Frames: a tree link's frame sits at its joint point with the body's
orientation; every PyBullet inertial frame is at the body's centre of mass
with the body's orientation, so readings (COM pose and velocity) convert to
the body frame origin with the body's `com`. Links have no collision or
visual shapes (no contacts); their inertia is set explicitly because
PyBullet gives shapeless links zero inertia. Every default that adds an
effect is disarmed here (see `disarm_defaults` and `configure_solver`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
import pandas as pd
import pybullet as p

from mechval.mechanism import GROUND, Joint, Mechanism, point_motion

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
    """A built PyBullet model in its own DIRECT client."""

    client: int
    timestep: float
    ground: BodyHandle
    bodies: dict[str, BodyHandle]
    tree_joints: dict[str, TreeJoint]
    constraints: dict[str, LoopConstraint]
    coms: dict[str, tuple[float, float]] = field(default_factory=dict)


def spanning_tree(mechanism: Mechanism, layout: str) -> list[tuple[Joint, str, str]]:
    """Tree joints as (joint, parent body, child body), parents first.

    "split": only the joints to the ground (every tree joint is a leaf);
    "tree": breadth-first from the ground over all joints.
    """
    if layout not in ("split", "tree"):
        raise ValueError(f"unknown layout {layout!r} (known: split, tree)")
    reached, order, queue = {GROUND}, [], deque([GROUND])
    while queue:
        parent = queue.popleft()
        for joint in mechanism.joints:
            if parent not in (joint.body_i, joint.body_j):
                continue
            child = joint.body_j if joint.body_i == parent else joint.body_i
            if child in reached or (layout == "split" and parent != GROUND):
                continue
            reached.add(child)
            order.append((joint, parent, child))
            queue.append(child)
    return order


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

    Dantzig LCP (exact) instead of PGS; `solverResidualThreshold=0` (the
    default 1e-7 stops iterating early: ~2e-2 force errors); no CFM and
    full error reduction; no sub-steps (they corrupt reported torques and
    constraint forces). Gravity is set explicitly (zero if none).
    """
    p.setPhysicsEngineParameter(
        fixedTimeStep=timestep, numSubSteps=0,
        constraintSolverType=p.CONSTRAINT_SOLVER_LCP_DANTZIG,
        solverResidualThreshold=0.0, globalCFM=0.0, erp=1.0,
        jointFeedbackMode=p.JOINT_FEEDBACK_IN_WORLD_SPACE | p.JOINT_FEEDBACK_IN_JOINT_FRAME,
        physicsClientId=client)
    p.setGravity(gravity[0], gravity[1], 0.0, physicsClientId=client)


def build(mechanism: Mechanism, timestep: float, layout: str, t_start: float) -> Model:
    """Connect a DIRECT client and build the model at the reference state of
    t_start (poses at t_start; velocities at t_start − dt/2, since the
    semi-implicit Euler velocity stands for the step's middle)."""
    client = p.connect(p.DIRECT)
    try:
        configure_solver(client, timestep, mechanism.gravity)
        pose = mechanism.motion(np.array([t_start]))
        rates = mechanism.motion(np.array([t_start - timestep / 2]))
        model = _build_tree(mechanism, client, timestep, layout, pose, rates)
        _build_free_bodies(mechanism, model, pose, rates)
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


def _build_tree(mechanism: Mechanism, client: int, timestep: float, layout: str, pose: pd.DataFrame,
                rates: pd.DataFrame) -> Model:
    """The ground as a fixed base with the tree joints' bodies as links."""
    tree = spanning_tree(mechanism, layout)
    index = {GROUND: 0}                       # createMultiBody: 0 = base
    origin = {GROUND: (0.0, 0.0)}             # link frame origin in body frame
    masses, inertial, positions, orientations, parents, types, axes = [], [], [], [], [], [], []
    for k, (joint, parent, child) in enumerate(tree):
        index[child] = k + 1
        origin[child] = side(joint, child)
        body = mechanism.body(child)
        masses.append(body.mass)
        inertial.append((body.com[0] - origin[child][0], body.com[1] - origin[child][1], 0.0))
        # Relative to the parent's inertial (COM) frame, as createMultiBody
        # expects; both frames have the parent body's orientation.
        parent_com = (0.0, 0.0) if parent == GROUND else mechanism.body(parent).com
        pj = side(joint, parent)
        positions.append((pj[0] - parent_com[0], pj[1] - parent_com[1], 0.0))
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
            ax = joint.axis if child == joint.body_i else _rotate(-rel, joint.axis)
            axes.append((ax[0], ax[1], 0.0))
    n = len(tree)
    uid = p.createMultiBody(
        baseMass=0.0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
        basePosition=(0, 0, 0), baseOrientation=quat_z(0.0),
        linkMasses=masses, linkCollisionShapeIndices=[-1] * n, linkVisualShapeIndices=[-1] * n,
        linkPositions=positions, linkOrientations=orientations,
        linkInertialFramePositions=inertial, linkInertialFrameOrientations=[quat_z(0.0)] * n,
        linkParentIndices=parents, linkJointTypes=types, linkJointAxis=axes,
        useMaximalCoordinates=False, physicsClientId=client)
    model = Model(client, timestep, BodyHandle(uid, -1), {}, {}, {},
                  {b.name: b.com for b in mechanism.bodies})
    for k, (joint, parent, child) in enumerate(tree):
        handle = BodyHandle(uid, k)
        model.bodies[child] = handle
        model.tree_joints[joint.name] = TreeJoint(joint, child, handle)
        q, qd = _joint_coordinate(mechanism, joint, parent, child, pose, rates)
        p.resetJointState(uid, k, q, qd, physicsClientId=model.client)
        p.enableJointForceTorqueSensor(uid, k, True, physicsClientId=model.client)
    return model


def _joint_coordinate(mechanism: Mechanism, joint: Joint, parent: str, child: str,
                      pose: pd.DataFrame, rates: pd.DataFrame) -> tuple[float, float]:
    """PyBullet joint position (at `pose`) and velocity (at `rates`)."""
    if joint.kind == "revolute":
        return (_angle(pose, child) - _angle(pose, parent), _omega(rates, child) - _omega(rates, parent))
    # Slide along the axis (fixed in body_i) of point_j relative to point_i;
    # the child's coordinate runs the other way when the child is body_i.
    sign = 1.0 if child == joint.body_j else -1.0
    ux, uy = _rotate(_angle(pose, joint.body_i), joint.axis)
    pi = point_motion(pose, joint.body_i, joint.point_i)
    pj = point_motion(pose, joint.body_j, joint.point_j)
    vi = point_motion(rates, joint.body_i, joint.point_i)
    vj = point_motion(rates, joint.body_j, joint.point_j)
    s = (pj["x"][0] - pi["x"][0]) * ux + (pj["y"][0] - pi["y"][0]) * uy
    v = (vj["vx"][0] - vi["vx"][0]) * ux + (vj["vy"][0] - vi["vy"][0]) * uy
    return sign * float(s), sign * float(v)


def _rotate(theta: float, v: tuple[float, float]) -> tuple[float, float]:
    c, s = np.cos(theta), np.sin(theta)
    return (float(c * v[0] - s * v[1]), float(s * v[0] + c * v[1]))


def _build_free_bodies(mechanism: Mechanism, model: Model, pose: pd.DataFrame,
                       rates: pd.DataFrame) -> None:
    """Every body not in the tree: its own multibody, base at the COM."""
    for body in mechanism.bodies:
        if body.name in model.bodies:
            continue
        com = point_motion(pose, body.name, body.com)
        vcom = point_motion(rates, body.name, body.com)
        uid = p.createMultiBody(
            baseMass=body.mass, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
            basePosition=(com["x"][0], com["y"][0], 0.0), baseOrientation=quat_z(_angle(pose, body.name)),
            physicsClientId=model.client)
        p.resetBaseVelocity(uid, (vcom["vx"][0], vcom["vy"][0], 0.0), (0.0, 0.0, _omega(rates, body.name)),
                            physicsClientId=model.client)
        model.bodies[body.name] = BodyHandle(uid, -1)


def _build_constraints(mechanism: Mechanism, model: Model) -> None:
    """Every joint not in the tree closes the loop as a user constraint
    (pivots relative to each side's COM frame; parent = body_i)."""
    for joint in mechanism.joints:
        if joint.name in model.tree_joints:
            continue
        parent, child = joint.body_i, joint.body_j
        pivots = []
        for body in (parent, child):
            com = (0.0, 0.0) if body == GROUND else model.coms[body]
            point = side(joint, body)
            pivots.append((point[0] - com[0], point[1] - com[1], 0.0))
        handles = {**model.bodies, GROUND: model.ground}
        pa, ch = handles[parent], handles[child]
        kind = p.JOINT_POINT2POINT if joint.kind == "revolute" else p.JOINT_PRISMATIC
        cid = p.createConstraint(pa.uid, pa.link, ch.uid, ch.link, kind, (joint.axis[0], joint.axis[1], 0.0),
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
