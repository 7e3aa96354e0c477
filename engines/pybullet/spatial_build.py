"""Build the PyBullet 3.2.7 model of a spatial scene (`SpatialSystem`).

Where each joint goes: a spanning tree of joints (`spanning_tree`'s
Kruskal, drives and the kinds only a multibody joint can make ranked
first, spherical joints last) makes one multibody per connected group of
bodies, rooted at the ground (a fixed base) or, for a group that does not
reach it, at its first body (a free base). The joints the tree leaves out
close their loops as user constraints: a spherical joint as one
point-to-point constraint, a revolute joint as two, at its point and one
`AXIS_ARM` along its axis (PyBullet 3.2.7 has no revolute user constraint
for multibodies: fixed, point-to-point, slider and gear only); any other
kind there is refused before anything runs.

Tree joints (PyBullet's link frame sits at the joint, with the body's
orientation; every joint coordinate is 0 in the start pose):
- revolute, prismatic, spherical, fixed: PyBullet's own joint types;
- cylindrical: a prismatic joint along the axis to a massless link, then a
  revolute joint about it; planar: prismatic joints along the parent's
  joint x and y to two massless links, then a revolute joint about z;
  universal: a revolute joint about the parent's pin to a massless cross,
  then a revolute joint about the child's pin. The massless links carry
  no mass and no inertia (PyBullet's articulated-body solver accepts them
  where a massive link hangs below; measured in tests/test_spatial_pybullet.py).

Every default that adds an effect is switched off (`disarm`): linear and
angular damping (0.04), joint damping, the default velocity motors (which
act as friction), the 100 rad/s joint speed clamp; no collision shapes, so
no contacts; the solver as for planar scenes (`model.configure_solver`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mechval.engines.base import Unrepresentable
from mechval.engines.pybullet.model import NO_CAP, NO_SPEED_LIMIT, configure_solver, p
from mechval.engines.pybullet.spatial_split import is_weld, plan
from mechval.engines.base import native_output_silenced
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.rotation import matrix_to_quaternion
from mechval.reference.spatial.system import SpatialJoint, SpatialSystem
from mechval.engines import spanning_tree

#: Lever (m) of a revolute loop joint's second point-to-point constraint
#: along the axis: any length works; its moment arm turns the second
#: constraint's force into the joint's moment.
AXIS_ARM = 0.1
#: PyBullet's sequential-impulse solver (its default), run to this many
#: iterations (no early stop: `configure_solver` sets the residual
#: threshold 0). Its LCP solvers (Dantzig, which planar scenes use, and PGS)
#: blow up as soon as a user constraint closes a loop inside one multibody
#: (measured: the RSSR's velocities reach 1e9 within 0.2 s). A driven loop
#: converges within 50 iterations; Bricard's free, overconstrained one
#: needs more (its worst angular acceleration error 20× the bound at 200,
#: 0.1× at 2000, at the same CPU time).
SOLVER_ITERATIONS = 2000
SOLVER = p.CONSTRAINT_SOLVER_LCP_SI
#: Kinds a multibody joint (or a chain of them) builds; kinds a loop's
#: user constraint closes.
TREE_KINDS = frozenset({"revolute", "prismatic", "spherical", "fixed", "cylindrical", "planar", "universal"})
LOOP_KINDS = frozenset({"spherical", "revolute"})
LOOP_REFUSED = ("closes a loop, and PyBullet 3.2.7's user constraints between multibodies are fixed, "
                "point-to-point, slider and gear only: a loop closes at a spherical or revolute joint here "
                "(rank the scene's joints so that one closes each loop)")


@dataclass(frozen=True)
class Dof:
    """One PyBullet joint of a tree joint's chain: type, axis (world, start
    pose), and whether its link is the massless link of a composite kind."""

    kind: int
    axis: np.ndarray
    massless: bool


@dataclass
class TreeJoint:
    """A scene joint built as multibody joints: parent and child body, the
    chain of PyBullet joints (`Dof`) and their link indices (the last one
    is the child body's link)."""

    joint: SpatialJoint
    parent: str
    child: str
    dofs: list[Dof]
    links: list[int] = field(default_factory=list)
    uid: int = -1


@dataclass(frozen=True)
class LoopJoint:
    """A scene joint closing a loop: its constraint ids (the second one a
    revolute joint's along the axis) and the constraint's child body."""

    joint: SpatialJoint
    child: str
    cids: tuple[int, ...]


@dataclass
class SpatialModel:
    """A built model in its own DIRECT client, in the start pose."""

    client: int
    timestep: float
    #: Per body: (multibody id, link index; −1 for a free base).
    handles: dict[str, tuple[int, int]]
    #: Per body: its link frame's origin in body axes (the point of the
    #: joint it hangs on; its centre of mass for a free base).
    anchors: dict[str, np.ndarray]
    tree: dict[str, TreeJoint]
    loops: dict[str, LoopJoint]
    #: Per body: the tree joint it hangs on (None: a free base).
    parent_joint: dict[str, str | None]


def tree_rank(system: SpatialSystem):
    """Kruskal's order: drives and the kinds no user constraint closes
    first, then revolute joints, then spherical ones (a loop closes at the
    last joint of its loop in this order)."""
    driven = {d.joint for d in system.drives} | {t.joint for t in system.torques}
    order = {"revolute": 1, "spherical": 2}
    return lambda j: 3 if is_weld(j) else (0 if j.name in driven else order.get(j.kind, 0))


def cut_joints(system: SpatialSystem) -> list[SpatialJoint]:
    """The joints a spanning tree (Kruskal in `tree_rank` order) leaves out."""
    return spanning_tree.cut_joints(system, tree_rank(system))


def closable(system: SpatialSystem, joint: SpatialJoint) -> bool:
    """Whether a user constraint closes a loop at `joint` (not driven)."""
    driven = any(d.joint == joint.name for d in system.drives) or any(t.joint == joint.name for t in system.torques)
    return not driven and (joint.kind in LOOP_KINDS or is_weld(joint))


def buildable(system: SpatialSystem) -> tuple[SpatialSystem, dict[str, str]]:
    """The system built (`spatial_split.plan`: bodies split where a loop
    cannot close at a joint) and its {twin: body}; Unrepresentable naming
    the joint where neither works."""
    return plan(system, closable, cut_joints)


def world_axes(joint: SpatialJoint, side: str, rotation: np.ndarray) -> np.ndarray:
    """The joint frame of `side` ("i" or "j") in world axes."""
    return rotation @ (joint.frame_i if side == "i" else joint.frame_j)


def chain(joint: SpatialJoint, parent_is_i: bool, rot: dict[str, np.ndarray]) -> list[Dof]:
    """The PyBullet joints of a tree joint, parent side first (world axes)."""
    own = "i" if parent_is_i else "j"
    other = "j" if parent_is_i else "i"
    frame = world_axes(joint, own, rot[joint.body_i if parent_is_i else joint.body_j])
    x, y, z = frame[:, 0], frame[:, 1], frame[:, 2]
    kind = joint.kind
    if kind == "revolute":
        return [Dof(p.JOINT_REVOLUTE, z, False)]
    if kind == "prismatic":
        return [Dof(p.JOINT_PRISMATIC, z, False)]
    if kind == "spherical":
        return [Dof(p.JOINT_SPHERICAL, z, False)]
    if kind == "fixed":
        return [Dof(p.JOINT_FIXED, z, False)]
    if kind == "cylindrical":
        return [Dof(p.JOINT_PRISMATIC, z, True), Dof(p.JOINT_REVOLUTE, z, False)]
    if kind == "planar":
        return [Dof(p.JOINT_PRISMATIC, x, True), Dof(p.JOINT_PRISMATIC, y, True), Dof(p.JOINT_REVOLUTE, z, False)]
    if kind == "universal":
        pin = world_axes(joint, other, rot[joint.body_j if parent_is_i else joint.body_i])[:, 2]
        return [Dof(p.JOINT_REVOLUTE, z, True), Dof(p.JOINT_REVOLUTE, pin, False)]
    raise Unrepresentable(f"joint.{joint.name}.kind", f"no PyBullet joint for kind {kind!r}")


def _quat(R: np.ndarray) -> tuple[float, float, float, float]:
    """PyBullet's (x, y, z, w) of a rotation matrix."""
    w, x, y, z = matrix_to_quaternion(R)
    return (float(x), float(y), float(z), float(w))


def principal(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments and the right-handed rotation to their axes
    (PyBullet takes an inertia diagonal in an inertial frame)."""
    moments, axes = np.linalg.eigh(np.asarray(inertia, dtype=float))
    if np.linalg.det(axes) < 0:
        axes[:, 0] *= -1
    return moments, axes


def build_spatial(system: SpatialSystem, timestep: float, pos: dict[str, np.ndarray],
                  rot: dict[str, np.ndarray]) -> SpatialModel:
    """A DIRECT client with the scene built in the start pose (per body:
    frame origin `pos`, rotation `rot`; the ground at the identity)."""
    cuts = {j.name for j in cut_joints(system)}
    client = p.connect(p.DIRECT)
    try:
        with native_output_silenced():
            configure_solver(client, timestep, (0.0, 0.0))
            p.setPhysicsEngineParameter(constraintSolverType=SOLVER,
                                        numSolverIterations=SOLVER_ITERATIONS, physicsClientId=client)
        p.setGravity(*system.gravity, physicsClientId=client)
        model = SpatialModel(client, timestep, {}, {}, {}, {}, {})
        pos = {**pos, GROUND: np.zeros(3)}
        rot = {**rot, GROUND: np.eye(3)}
        for root, links in _multibodies(system, cuts).items():
            _build_multibody(system, model, root, links, pos, rot)
        for j in system.joints:
            if j.name in cuts:
                _close_loop(system, model, j)
        disarm(model)
        return model
    except BaseException:
        p.disconnect(client)
        raise


def _multibodies(system: SpatialSystem, cuts: set[str]) -> dict[str, list[tuple[SpatialJoint, str, str]]]:
    """{root: [(joint, parent, child)] depth first}: the ground's group,
    then each group of moving bodies not joined to it, rooted at its first
    body. Depth first because PyBullet numbers a multibody's links so
    (measured: links given breadth first came back renumbered, and every
    index read the wrong link)."""
    tree = [j for j in system.joints if j.name not in cuts]
    placed, groups = set(), {}

    def visit(body: str, links: list) -> None:
        children = []
        for j in tree:
            for parent, child in ((j.body_i, j.body_j), (j.body_j, j.body_i)):
                if parent == body and child not in placed:
                    placed.add(child)
                    children.append((j, parent, child))
        for link in children:
            links.append(link)
            visit(link[2], links)

    for root in [GROUND] + [b.name for b in system.bodies]:
        if root in placed:
            continue
        placed.add(root)
        links: list = []
        visit(root, links)
        if root != GROUND or links:
            groups[root] = links
    return groups


def _build_multibody(system: SpatialSystem, model: SpatialModel, root: str, links, pos, rot) -> None:
    masses, inertias, inertial_pos, inertial_orn = [], [], [], []
    positions, orientations, parents, types, axes = [], [], [], [], []
    link_of = {root: 0}                     # PyBullet's parent index: 0 = the base
    # Each link frame: origin (world, start pose) and rotation.
    frames = {root: (pos[root] + rot[root] @ _anchor(system, root), rot[root])}
    model.anchors[root] = _anchor(system, root)
    model.parent_joint[root] = None
    pending = []
    for joint, parent, child in links:
        point = np.asarray(joint.point_j if child == joint.body_j else joint.point_i, dtype=float)
        model.anchors[child] = point
        model.parent_joint[child] = joint.name
        origin = pos[child] + rot[child] @ point
        dofs = chain(joint, parent == joint.body_i, rot)
        tj = TreeJoint(joint, parent, child, dofs)
        above, (o_parent, r_parent) = link_of[parent], frames[parent]
        for k, dof in enumerate(dofs):
            last = k == len(dofs) - 1
            r_link = rot[child] if last else rot[parent]
            masses.append(0.0 if dof.massless else system.body(child).mass)
            if dof.massless:
                inertias.append((0.0, 0.0, 0.0))
                inertial_pos.append((0.0, 0.0, 0.0))
                inertial_orn.append((0.0, 0.0, 0.0, 1.0))
            else:
                moments, paxes = principal(system.body(child).inertia)
                inertias.append(tuple(moments))
                inertial_pos.append(tuple(np.asarray(system.body(child).com, float) - point))
                inertial_orn.append(_quat(paxes))
            positions.append(tuple(r_parent.T @ (origin - o_parent)))
            orientations.append(_quat(r_parent.T @ r_link))
            parents.append(above)
            types.append(dof.kind)
            axes.append(tuple(r_link.T @ dof.axis))
            above = len(masses)
            o_parent, r_parent = origin, r_link
            tj.links.append(above - 1)
        link_of[child], frames[child] = above, (origin, rot[child])
        pending.append(tj)
    n = len(masses)
    if root == GROUND:
        base = dict(baseMass=0.0, basePosition=(0.0, 0.0, 0.0), baseOrientation=(0.0, 0.0, 0.0, 1.0))
    else:
        moments, paxes = principal(system.body(root).inertia)
        base = dict(baseMass=system.body(root).mass, basePosition=tuple(frames[root][0]),
                    baseOrientation=_quat(rot[root]), baseInertialFramePosition=(0.0, 0.0, 0.0),
                    baseInertialFrameOrientation=_quat(paxes))
    uid = p.createMultiBody(
        **base, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
        linkMasses=masses, linkCollisionShapeIndices=[-1] * n, linkVisualShapeIndices=[-1] * n,
        linkPositions=positions, linkOrientations=orientations, linkInertialFramePositions=inertial_pos,
        linkInertialFrameOrientations=inertial_orn, linkParentIndices=parents, linkJointTypes=types,
        linkJointAxis=axes, useMaximalCoordinates=False, physicsClientId=model.client)
    model.handles[root] = (uid, -1)
    if root != GROUND:
        p.changeDynamics(uid, -1, localInertiaDiagonal=tuple(principal(system.body(root).inertia)[0]),
                         physicsClientId=model.client)
    for tj in pending:
        tj.uid = uid
        model.tree[tj.joint.name] = tj
        model.handles[tj.child] = (uid, tj.links[-1])
    for k in range(n):
        # Explicit inertia: PyBullet gives shapeless links zero (the massless ones keep it).
        p.changeDynamics(uid, k, localInertiaDiagonal=inertias[k], physicsClientId=model.client)


def _anchor(system: SpatialSystem, body: str) -> np.ndarray:
    """A root's link frame origin in body axes: the ground's origin, or a
    free base's centre of mass (PyBullet's base frame reads as it)."""
    return np.zeros(3) if body == GROUND else np.asarray(system.body(body).com, dtype=float)


def _close_loop(system: SpatialSystem, model: SpatialModel, joint: SpatialJoint) -> None:
    """Point-to-point constraint(s) at the joint, body_i the constraint's
    parent; each pivot in its body's centre-of-mass frame (principal axes
    at the centre of mass: PyBullet's frame of a user constraint's pivot)."""
    points = [(np.asarray(joint.point_i, float), np.asarray(joint.point_j, float))]
    if is_weld(joint):
        (ui, li), (uj, lj) = _handle(model, joint.body_i), _handle(model, joint.body_j)
        cid = p.createConstraint(ui, li, uj, lj, p.JOINT_FIXED, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                                 physicsClientId=model.client)        # both pivots at the centre of mass
        p.changeConstraint(cid, maxForce=NO_CAP, physicsClientId=model.client)
        model.loops[joint.name] = LoopJoint(joint, joint.body_j, (cid,))
        return
    if joint.kind == "revolute":
        points.append((points[0][0] + AXIS_ARM * joint.frame_i[:, 2], points[0][1] + AXIS_ARM * joint.frame_j[:, 2]))
    cids = []
    for point_i, point_j in points:
        (ui, li), (uj, lj) = _handle(model, joint.body_i), _handle(model, joint.body_j)
        cid = p.createConstraint(ui, li, uj, lj, p.JOINT_POINT2POINT, (0.0, 0.0, 1.0),
                                 tuple(com_frame_pivot(system, joint.body_i, point_i)),
                                 tuple(com_frame_pivot(system, joint.body_j, point_j)),
                                 physicsClientId=model.client)
        # An impulse cap converted at the current step: configure_solver set it.
        p.changeConstraint(cid, maxForce=NO_CAP, physicsClientId=model.client)
        cids.append(cid)
    model.loops[joint.name] = LoopJoint(joint, joint.body_j, tuple(cids))


def _handle(model: SpatialModel, body: str) -> tuple[int, int]:
    """A body's (multibody, link); the ground's fixed base, made if no tree
    joint hangs on the ground."""
    if body == GROUND and GROUND not in model.handles:
        uid = p.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
                                physicsClientId=model.client)
        model.handles[GROUND] = (uid, -1)
    return model.handles[body]


def com_frame_pivot(system: SpatialSystem, body: str, point: np.ndarray) -> np.ndarray:
    """A body point in its centre-of-mass frame (principal axes); world
    coordinates for the ground."""
    if body == GROUND:
        return np.asarray(point, dtype=float)
    b = system.body(body)
    return principal(b.inertia)[1].T @ (np.asarray(point, float) - np.asarray(b.com, float))


def disarm(model: SpatialModel) -> None:
    """Switch off every PyBullet default that adds an effect (module docstring)."""
    c = model.client
    for uid in {h[0] for body, h in model.handles.items() if body != GROUND}:
        p.changeDynamics(uid, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=c)
        p.changeDynamics(uid, -1, maxJointVelocity=NO_SPEED_LIMIT, physicsClientId=c)
    for tj in model.tree.values():
        for k, dof in zip(tj.links, tj.dofs):
            p.changeDynamics(tj.uid, k, jointDamping=0.0, physicsClientId=c)
            if dof.kind == p.JOINT_SPHERICAL:
                p.setJointMotorControlMultiDof(tj.uid, k, p.POSITION_CONTROL, targetPosition=(0, 0, 0, 1),
                                               positionGain=0.0, velocityGain=0.0, force=(0.0, 0.0, 0.0),
                                               physicsClientId=c)
            elif dof.kind != p.JOINT_FIXED:
                p.setJointMotorControl2(tj.uid, k, p.VELOCITY_CONTROL, force=0.0, physicsClientId=c)
