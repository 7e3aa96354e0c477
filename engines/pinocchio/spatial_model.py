"""The Pinocchio model of a spatial scene (`SpatialSystem`): a spanning
tree of Pinocchio joints in minimal coordinates, the loops closed by
`RigidConstraintModel`s (docs/engines.md, "Pinocchio", "Spatial scenes").

Tree joints, per kind, between the parent's joint frame (frame_i at Pi
when the parent is body_i) and the child's (frame_j at Pj): revolute
`JointModelRZ`, prismatic `JointModelPZ` (both along z of the joint
frame, so q is the scene's angle or slide, times `TreeJoint.sign`),
cylindrical a `JointModelComposite` of PZ and RZ, universal
`JointModelUniversal(z, x)` (the child's frame turned so that its pin zj
is the joint's x), planar `JointModelPlanar` (x, y, cos, sin of the frame
plane), spherical `JointModelSpherical`; a body joined to nothing that
leads to the ground hangs on a `JointModelFreeFlyer` at its own frame.
A fixed joint in the tree is no Pinocchio joint: the child's inertia and
frame are appended to the parent's joint (a rigid frame).

Loops: each cut joint becomes constraints between its two bodies'
Pinocchio joints: spherical one CONTACT_3D at the joint point; revolute
two CONTACT_3D, at the point and one `axis_length` along the axis (six
rows for five: the one along the axis is redundant, and the proximal
solver copes); fixed one CONTACT_6D. Any other kind is the joint itself,
from body_i to a near-massless carrier welded to body_j (CONTACT_6D,
`CARRIER_FRACTION`). A driven joint must be a tree coordinate
(`Unrepresentable` otherwise). The tree is added depth-first and
`Model.check` is asked (engines/pinocchio/findings.py: a breadth-first
tree silently loses mass-matrix couplings).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from mechval.model.mechanism import GROUND
from mechval.reference.spatial.system import SpatialJoint, SpatialSystem

from mechval.engines.base import Unrepresentable
from mechval.engines.spanning_tree import cut_joints

#: What a loop can be cut at (a point or weld constraint) and what must
#: be a tree coordinate; within those, the rank `cut_joints` sorts by.
CUTTABLE = ("spherical", "revolute", "fixed")
TREE_RANK = {"fixed": 1, "prismatic": 2, "cylindrical": 2, "universal": 2, "planar": 2, "revolute": 3, "spherical": 4}
#: The child's joint frame of a universal joint: its pin zj as x.
UNIVERSAL_TURN = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def frame_jacobian(model: pin.Model, data: pin.Data, frame_id: int, reference) -> np.ndarray:
    """A frame's 6 × nv Jacobian (Pinocchio's Python returns a flat 6-vector when nv = 1)."""
    return np.asarray(pin.getFrameJacobian(model, data, frame_id, reference)).reshape(6, model.nv)


def frame(rotation, point) -> pin.SE3:
    return pin.SE3(np.asarray(rotation, dtype=float), np.asarray(point, dtype=float))


@dataclass(frozen=True)
class TreeJoint:
    """A scene joint as a tree joint from `parent` to `child`: Pinocchio
    joint `index` (0 for a fixed joint, which has none). `flipped`: zj
    points against zi (a revolute, cylindrical or planar joint allows it),
    so the child's joint frame is turned by π about its x."""

    joint: SpatialJoint
    parent: str
    child: str
    index: int
    flipped: bool = False

    @property
    def sign(self) -> float:
        """q over the scene's angle or slide: +1 when the child is body_j,
        or when the frames are flipped (q is then measured about zj = −zi
        from xj to xi: the same angle)."""
        return 1.0 if self.child == self.joint.body_j or self.flipped else -1.0

    def side(self, body: str) -> pin.SE3:
        """The joint frame on `body` (one of its two bodies), body axes;
        a universal joint's child's turned so that its pin is x, a flipped
        one's so that its z is the parent's."""
        j = self.joint
        placed = frame(j.frame_i, j.point_i) if body == j.body_i else frame(j.frame_j, j.point_j)
        if j.kind == "universal" and body == self.child:
            placed = placed * frame(UNIVERSAL_TURN, np.zeros(3))
        if self.flipped and body == self.child:
            placed = placed * frame(np.diag([1.0, -1.0, -1.0]), np.zeros(3))
        return placed


@dataclass(frozen=True)
class Cut:
    """A loop-closing joint: its constraints (indices into the model's
    list), each between a frame on `first` and one on `second` (the ground
    always second: Pinocchio anchors a one-joint constraint to the universe)."""

    joint: SpatialJoint
    first: str
    second: str
    constraints: tuple[int, ...]
    #: A cut no point or weld constraint closes: the joint itself as a
    #: Pinocchio joint from body_i to a massless carrier, welded by
    #: CONTACT_6D to body_j (`first` is then body_i, to which the carrier
    #: passes the weld's load on it).
    carrier: TreeJoint | None = None


@dataclass
class SpatialModel:
    model: pin.Model
    data: pin.Data
    tree: tuple[TreeJoint, ...]
    cuts: tuple[Cut, ...]
    constraints: pin.StdVec_RigidConstraintModel
    constraint_data: pin.StdVec_RigidConstraintData
    #: Scene body → its Pinocchio joint (the ground: 0), frame id, and the
    #: body frame's placement in that joint's frame.
    joint_of: dict[str, int] = field(default_factory=dict)
    frame_of: dict[str, int] = field(default_factory=dict)
    shift: dict[str, pin.SE3] = field(default_factory=dict)
    #: Body → the bodies of its subtree (itself included), for the reactions.
    subtree: dict[str, list[str]] = field(default_factory=dict)
    #: Free-flyer joint → the body on it (its frame is the joint's).
    free: dict[int, str] = field(default_factory=dict)
    #: A carrier's frame (its joint's) → its joint.
    carrier_frames: dict[int, TreeJoint] = field(default_factory=dict)

    def tree_joint(self, name: str) -> TreeJoint | None:
        return next((tj for tj in self.tree if tj.joint.name == name), None)


def topology(system: SpatialSystem) -> tuple[list[tuple[str, SpatialJoint | None, str, str]], list[SpatialJoint]]:
    """The tree's edges (role: "joint", "free" for a free flyer or
    "carrier"; the scene joint; parent; child), depth-first from the
    ground, and the cut joints. A cut that no point or weld constraint
    closes gets a carrier, a leaf right after its body_i so that every
    subtree stays contiguous."""
    drives = {d.joint for d in system.drives}
    cuts = cut_joints(system, lambda j: 0 if j.name in drives else TREE_RANK[j.kind])
    for j in cuts:
        if j.name in drives:
            drive = next(d.name for d in system.drives if d.joint == j.name)
            raise Unrepresentable(f"drive.{drive}", f"the Pinocchio adapter drives a tree coordinate, and joint "
                                                    f"{j.name} closes a loop of other drives")
    carried = [j for j in cuts if j.kind not in CUTTABLE]
    remaining = [j for j in system.joints if j not in cuts]
    reached, edges = {GROUND}, []

    def descend(body: str) -> None:
        edges.extend(("carrier", j, body, f"{j.name}~carrier") for j in carried if j.body_i == body)
        for j in [j for j in remaining if body in (j.body_i, j.body_j)]:
            if j not in remaining:
                continue
            remaining.remove(j)
            child = j.body_j if j.body_i == body else j.body_i
            edges.append(("joint", j, body, child))
            reached.add(child)
            descend(child)
    descend(GROUND)
    for b in system.bodies:             # a free group: its first body on a free flyer
        if b.name not in reached:
            edges.append(("free", None, GROUND, b.name))
            reached.add(b.name)
            descend(b.name)
    return edges, cuts


def native_joint(kind: str):
    if kind == "revolute":
        return pin.JointModelRZ()
    if kind == "prismatic":
        return pin.JointModelPZ()
    if kind == "cylindrical":
        composite = pin.JointModelComposite(pin.JointModelPZ(), pin.SE3.Identity())
        composite.addJoint(pin.JointModelRZ(), pin.SE3.Identity())
        return composite
    if kind == "universal":
        return pin.JointModelUniversal(np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    if kind == "planar":
        return pin.JointModelPlanar()
    if kind == "spherical":
        return pin.JointModelSpherical()
    raise AssertionError(kind)


def axis_length(system: SpatialSystem) -> float:
    """The second point of a revolute cut this far along its axis: the
    scene's size (largest distance of a joint point or centre of mass from
    the first joint point), so that its forces are of the order of the first's."""
    points = [np.asarray(p, float) for j in system.joints for p in (j.point_i, j.point_j)]
    points += [np.asarray(b.com, float) for b in system.bodies]
    size = max(float(np.linalg.norm(p - points[0])) for p in points) if points else 0.0
    return size if size > 0 else 1.0


#: A carrier's mass and inertia, as fractions of the lightest body's (and
#: of its inertia's largest principal moment): Pinocchio's constraint
#: Cholesky needs every coordinate to carry inertia (a massless carrier
#: gives NaN); its inertia then changes the dynamics by about this much
#: (measured on the delta: 1e-9 meets the tolerances with 1e-3 of them
#: to spare, tests/test_spatial_pinocchio.py).
CARRIER_FRACTION = 1e-9


def carrier_inertia(system: SpatialSystem) -> pin.Inertia:
    """A carrier's (tiny) inertia: a point-like body at its joint point."""
    light = min(system.bodies, key=lambda b: b.mass)
    moment = max(float(np.linalg.eigvalsh(np.asarray(b.inertia, float)).max()) for b in system.bodies)
    return pin.Inertia(CARRIER_FRACTION * light.mass, np.zeros(3), CARRIER_FRACTION * moment * np.eye(3))


def axis(system: SpatialSystem, body: str, joint_frame: np.ndarray) -> np.ndarray:
    """A joint frame's z in world axes at the scene's stated (approximate) pose."""
    return (np.eye(3) if body == GROUND else system.body(body).rotation) @ joint_frame[:, 2]


def flipped(system: SpatialSystem, joint: SpatialJoint) -> bool:
    """zj against zi at the stated pose, on a joint that allows it."""
    return joint.kind in ("revolute", "cylindrical", "planar") and \
        float(axis(system, joint.body_i, joint.frame_i) @ axis(system, joint.body_j, joint.frame_j)) < 0


def build_spatial_model(system: SpatialSystem) -> SpatialModel:
    """The tree, inertias, frames, gravity and loop constraints; nothing
    else (no limits, friction, armature or damping in the model: joint
    dampers and every other effect are applied forces)."""
    edges, cuts = topology(system)
    model = pin.Model()
    model.name = "mechval"
    sm = SpatialModel(model, None, (), (), pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData())
    sm.joint_of[GROUND], sm.shift[GROUND] = 0, pin.SE3.Identity()
    tree, carriers = [], {}
    for k, (role, joint, parent, child) in enumerate(edges):
        if role == "carrier":           # the cut joint itself, from body_i to a massless stand-in for body_j
            tj = TreeJoint(joint, joint.body_i, joint.body_j, 0, flipped(system, joint))
            index = model.addJoint(sm.joint_of[parent], native_joint(joint.kind), sm.shift[parent] * tj.side(parent),
                                   f"carrier{k}")
            carriers[joint.name] = dataclasses.replace(tj, index=index)
            sm.carrier_frames[model.addFrame(pin.Frame(child, index, pin.SE3.Identity(), pin.FrameType.OP_FRAME,
                                                       carrier_inertia(system)))] = carriers[joint.name]
            continue
        if role == "free":
            index = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), f"free{k}")
            shift = pin.SE3.Identity()
            sm.free[index] = child
        else:
            tj = TreeJoint(joint, parent, child, 0, flipped(system, joint))
            on_parent = sm.shift[parent] * tj.side(parent)
            if joint.kind == "fixed":
                index, shift = sm.joint_of[parent], on_parent * tj.side(child).inverse()
            else:
                index = model.addJoint(sm.joint_of[parent], native_joint(joint.kind), on_parent, f"j{k}")
                shift = tj.side(child).inverse()
            tree.append(dataclasses.replace(tj, index=0 if joint.kind == "fixed" else index))
        body = system.body(child)
        inertia = pin.Inertia(float(body.mass), np.asarray(body.com, float), np.asarray(body.inertia, float))
        # the body's inertia in its own frame, added to its joint's (`append_inertia`): the audit reads it per body
        sm.frame_of[child] = model.addFrame(pin.Frame(f"body{k}", index, shift, pin.FrameType.OP_FRAME, inertia))
        sm.joint_of[child], sm.shift[child] = index, shift
    model.gravity = pin.Motion(np.asarray(system.gravity, float), np.zeros(3))
    sm.tree = tuple(tree)
    for b in system.bodies:
        sm.subtree[b.name] = [b.name]
    for role, _, parent, child in reversed(edges):        # children after parents: fold upwards
        if role != "carrier" and parent != GROUND:
            sm.subtree[parent] += sm.subtree[child]

    length, found = axis_length(system), []
    for joint in cuts:
        if joint.name in carriers:      # the carrier welded to body_j
            tj = carriers[joint.name]
            constraint = pin.RigidConstraintModel(pin.ContactType.CONTACT_6D, model, tj.index, pin.SE3.Identity(),
                                                  sm.joint_of[joint.body_j],
                                                  sm.shift[joint.body_j] * tj.side(joint.body_j),
                                                  pin.ReferenceFrame.LOCAL)
            constraint.name = f"{joint.name}.weld"
            found.append(Cut(joint, joint.body_i, joint.body_j, (len(sm.constraints),), tj))
            sm.constraints.append(constraint)
            continue
        first, second = (joint.body_j, joint.body_i) if joint.body_i == GROUND else (joint.body_i, joint.body_j)
        sides = {joint.body_i: frame(joint.frame_i, joint.point_i), joint.body_j: frame(joint.frame_j, joint.point_j)}
        # a revolute's second points, `length` along zi: on zj's negative side where zj points against zi
        along = {joint.body_i: length, joint.body_j: -length if flipped(system, joint) else length}
        offsets = [0.0] + ([1.0] if joint.kind == "revolute" else [])
        kind = pin.ContactType.CONTACT_6D if joint.kind == "fixed" else pin.ContactType.CONTACT_3D
        indices = []
        for offset in offsets:
            def at(body: str) -> pin.SE3:
                return sm.shift[body] * sides[body] * frame(np.eye(3), [0.0, 0.0, offset * along[body]])
            constraint = pin.RigidConstraintModel(kind, model, sm.joint_of[first], at(first),
                                                  sm.joint_of[second], at(second), pin.ReferenceFrame.LOCAL)
            constraint.name = f"{joint.name}.{len(indices)}"
            indices.append(len(sm.constraints))
            sm.constraints.append(constraint)
        found.append(Cut(joint, first, second, tuple(indices)))
    sm.cuts = tuple(found)
    for constraint in sm.constraints:
        sm.constraint_data.append(constraint.createData())
    sm.data = model.createData()
    if not model.check(sm.data):    # e.g. a subtree that is not contiguous (engines/pinocchio/findings.py)
        raise ValueError(f"pinocchio: Model.check refuses the model built for {system.name!r}")
    pin.initConstraintDynamics(model, sm.data, sm.constraints, sm.constraint_data)
    return sm


def start_state(sm: SpatialModel, system: SpatialSystem, poses: dict[str, pin.SE3],
                twists: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(q, v) from every body's pose (body frame → world) and (velocity of
    its origin, ω), world axes: q joint by joint from the relative pose of
    its two joint frames; v the least-squares fit of the bodies' frame
    Jacobians to their velocities (exact for consistent velocities)."""
    model = sm.model
    q = pin.neutral(model)
    world = lambda body: poses[body] if body != GROUND else pin.SE3.Identity()   # noqa: E731
    for k, jm in enumerate(model.joints[1:], start=1):
        tj = next((t for t in (*sm.tree, *sm.carrier_frames.values()) if t.index == k), None)
        if tj is None:                                  # a free flyer: the body's own pose
            rel = world(sm.free[k])
        else:
            rel = (world(tj.parent) * tj.side(tj.parent)).inverse() * (world(tj.child) * tj.side(tj.child))
        q[jm.idx_q:jm.idx_q + jm.nq] = joint_coordinates(model.names[k], jm, rel, tj)
    pin.framesForwardKinematics(model, sm.data, q)
    for b in system.bodies:
        placed = sm.data.oMf[sm.frame_of[b.name]]
        miss = max(np.abs(placed.translation - poses[b.name].translation).max(),
                   np.abs(placed.rotation - poses[b.name].rotation).max())
        if miss > 1e-8:
            raise ValueError(f"pinocchio: the start pose of body {b.name!r} is off by {miss:.3g} in the model")
    pin.computeJointJacobians(model, sm.data, q)
    rows = [frame_jacobian(model, sm.data, sm.frame_of[b.name], pin.LOCAL_WORLD_ALIGNED)
            for b in system.bodies]
    target = [twists[b.name] for b in system.bodies]
    for f, tj in sm.carrier_frames.items():     # a carrier moves with body_j's joint frame
        rows.append(frame_jacobian(model, sm.data, f, pin.LOCAL_WORLD_ALIGNED))
        if tj.child == GROUND:
            target.append(np.zeros(6))
        else:
            arm = poses[tj.child].rotation @ tj.side(tj.child).translation
            target.append(np.concatenate([twists[tj.child][:3] + np.cross(twists[tj.child][3:], arm),
                                          twists[tj.child][3:]]))
    target = np.concatenate(target)
    v = np.linalg.lstsq(np.vstack(rows), target, rcond=None)[0] if model.nv else np.zeros(0)
    return q, v


def joint_coordinates(name: str, jm, rel: pin.SE3, tj: TreeJoint | None) -> np.ndarray:
    """A joint's q from the child's joint frame in the parent's."""
    R, p = rel.rotation, rel.translation
    kind = "free" if tj is None else tj.joint.kind
    quat = lambda: pin.Quaternion(R).normalized().coeffs()   # noqa: E731 (x, y, z, w)
    if kind == "revolute":
        return np.array([np.arctan2(R[1, 0], R[0, 0])])
    if kind == "prismatic":
        return np.array([p[2]])
    if kind == "cylindrical":
        return np.array([p[2], np.arctan2(R[1, 0], R[0, 0])])
    if kind == "universal":                             # R = Rz(q1)·Rx(q2)
        return np.array([np.arctan2(R[1, 0], R[0, 0]), np.arctan2(R[2, 1], R[2, 2])])
    if kind == "planar":
        angle = np.arctan2(R[1, 0], R[0, 0])
        return np.array([p[0], p[1], np.cos(angle), np.sin(angle)])
    if kind == "spherical":
        return np.asarray(quat())
    return np.concatenate([p, quat()])
