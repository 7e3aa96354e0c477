"""The Pinocchio model of a generic planar mechanism: a spanning tree of
revolute (`JointModelRZ`) and prismatic (`JointModelPrismaticUnaligned`)
joints in minimal coordinates, and one `RigidConstraintModel` (CONTACT_3D)
per loop, closing it at a revolute pin (docs/engines.md, "Pinocchio").

Frames. Each moving body hangs on the Pinocchio joint of its tree joint;
that joint's frame has the body's axes and its origin at the body's point
of the tree joint, so the body's own frame is the joint frame shifted by
−point (`body_placement`), and a Pinocchio `Frame` named after the body
sits there. A revolute coordinate is q = θ_child − θ_parent; a prismatic
one the slide of the child's point along the axis, q = (P_child −
P_parent)·u. `TreeJoint.sign` is +1 when the child is the joint's body_j
(q is the Mechanism's relative angle or slide), −1 when reversed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pinocchio as pin

from mechval.model.mechanism import GROUND, Joint, Mechanism

from mechval.engines.base import Unrepresentable
from mechval.engines.spanning_tree import cut_joints


@dataclass(frozen=True)
class TreeJoint:
    """A mechanism joint as a Pinocchio tree joint from `parent` to `child`
    (Pinocchio joint id `index`, coordinate `index − 1`)."""

    joint: Joint
    parent: str
    child: str
    index: int

    @property
    def sign(self) -> float:
        return 1.0 if self.child == self.joint.body_j else -1.0

    @property
    def point_parent(self) -> tuple[float, float]:
        return self.joint.point_i if self.sign > 0 else self.joint.point_j

    @property
    def point_child(self) -> tuple[float, float]:
        return self.joint.point_j if self.sign > 0 else self.joint.point_i

    @property
    def coordinate(self) -> int:
        return self.index - 1

    @property
    def turn(self) -> float:
        """θ_child − θ_parent of a prismatic joint (it holds it)."""
        return self.sign * self.joint.held_angle


@dataclass(frozen=True)
class Loop:
    """A loop-closing pin: a CONTACT_3D constraint between `frame1` on the
    joint's body `first` and `frame2` on `second` (the ground is always
    second: Pinocchio anchors a one-joint constraint to the universe)."""

    joint: Joint
    first: str
    second: str

    @property
    def sign(self) -> float:
        """+1 when `first` is body_j: the constraint force on `first` is then Fij."""
        return 1.0 if self.first == self.joint.body_j else -1.0


@dataclass
class PinocchioModel:
    """The built model and what the run and the audit need to read it."""

    model: pin.Model
    data: pin.Data
    tree: tuple[TreeJoint, ...]
    loops: tuple[Loop, ...]
    constraints: pin.StdVec_RigidConstraintModel
    constraint_data: pin.StdVec_RigidConstraintData
    #: Mechanism body → Pinocchio joint id (the ground: 0) and frame id.
    joint_of: dict[str, int]
    frame_of: dict[str, int]
    #: Pinocchio joint id of a prismatic tree joint → its unit axis in that joint's frame.
    axes: dict[int, np.ndarray]

    def tree_joint(self, name: str) -> TreeJoint | None:
        return next((tj for tj in self.tree if tj.joint.name == name), None)

    def placement(self, body: str, point) -> pin.SE3:
        """A body-frame point as a placement in its Pinocchio joint's frame."""
        shift = self.model.frames[self.frame_of[body]].placement if body != GROUND else pin.SE3.Identity()
        return shift * pin.SE3(np.eye(3), np.array([point[0], point[1], 0.0]))


def topology(mech: Mechanism) -> tuple[list[tuple[Joint, str, str]], list[Joint]]:
    """A spanning tree (joint, parent, child; parents first, depth-first
    from the ground) and the loop-closing pins. Joints enter the tree
    greedily (Kruskal): the drives first (a drive is a coordinate of the
    tree), then the prismatic joints (a loop is closed by a point
    constraint, which only a pin is), then the pins in the file's order."""
    drives = {d.joint for d in mech.drives}
    rank = lambda j: 0 if j.name in drives else 1 if j.kind == "prismatic" else 2
    cuts = cut_joints(mech, rank)
    for j in cuts:
        if j.kind != "revolute" or j.name in drives:
            raise Unrepresentable(f"joint.{j.name}", "the Pinocchio adapter closes each loop at a revolute pin that "
                                                     "is not driven (a point constraint), and this loop has none")
    remaining = [j for j in mech.joints if j not in cuts]
    # Depth-first: Pinocchio's algorithms (crba, the constraint Cholesky)
    # take each joint's subtree to be the joints that follow it; a
    # breadth-first order silently drops mass-matrix couplings.
    reached, tree = {GROUND}, []

    def descend(body: str) -> None:
        for j in [j for j in remaining if body in (j.body_i, j.body_j)]:
            if j not in remaining:
                continue
            remaining.remove(j)
            child = j.body_j if j.body_i == body else j.body_i
            tree.append((j, body, child))
            reached.add(child)
            descend(child)
    descend(GROUND)
    if len(reached) != len(mech.bodies) + 1:
        loose = next(b.name for b in mech.bodies if b.name not in reached)
        raise Unrepresentable(f"body.{loose}", "the Pinocchio adapter needs every body joined to the ground")
    return tree, cuts


def vec3(p) -> np.ndarray:
    return np.array([float(p[0]), float(p[1]), 0.0])


def rot_z(angle: float) -> np.ndarray:
    return pin.utils.rotate("z", float(angle))


def body_placement(point_child) -> pin.SE3:
    """The body's frame in its Pinocchio joint's frame: same axes, origin at −point."""
    return pin.SE3(np.eye(3), -vec3(point_child))


def build_model(mech: Mechanism) -> PinocchioModel:
    """The tree, the bodies' inertias and frames, gravity, and one point
    constraint per loop; nothing else (no limits, friction, armature or
    damping in the model: dampers and the other effects are applied forces,
    `mechval.engines.pinocchio.forces`)."""
    edges, cuts = topology(mech)
    model = pin.Model()
    model.name = "mechval"
    joint_of, frame_of, tree, axes = {GROUND: 0}, {}, [], {}
    shift = {GROUND: pin.SE3.Identity()}        # body frame in its joint's frame
    for k, (joint, parent, child) in enumerate(edges):
        sign = 1.0 if child == joint.body_j else -1.0
        p_parent, p_child = (joint.point_i, joint.point_j) if sign > 0 else (joint.point_j, joint.point_i)
        if joint.kind == "revolute":
            native, turn = pin.JointModelRZ(), 0.0
        else:
            # The axis is fixed in body_i; expressed in the child's axes.
            turn = sign * joint.held_angle
            axis_i = vec3(joint.axis) / np.hypot(*joint.axis)
            axis = rot_z(-joint.held_angle) @ axis_i if sign > 0 else axis_i
            native = pin.JointModelPrismaticUnaligned(axis)
        placement = shift[parent] * pin.SE3(rot_z(turn), vec3(p_parent))
        index = model.addJoint(joint_of[parent], native, placement, f"j{k}")
        if joint.kind == "prismatic":
            axes[index] = axis / np.linalg.norm(axis)
        body = mech.body(child)
        shift[child] = body_placement(p_child)
        com = shift[child].act(vec3(body.com))
        model.appendBodyToJoint(index, pin.Inertia(body.mass, com, np.diag([0.0, 0.0, body.izz])), pin.SE3.Identity())
        joint_of[child] = index
        frame_of[child] = model.addFrame(pin.Frame(f"b{k}", index, shift[child], pin.FrameType.OP_FRAME))
        tree.append(TreeJoint(joint, parent, child, index))
    model.gravity = pin.Motion(vec3(mech.gravity), np.zeros(3))

    constraints = pin.StdVec_RigidConstraintModel()
    loops = []
    for joint in cuts:
        first, second = (joint.body_j, joint.body_i) if joint.body_i == GROUND else (joint.body_i, joint.body_j)
        points = {joint.body_i: joint.point_i, joint.body_j: joint.point_j}
        constraint = pin.RigidConstraintModel(
            pin.ContactType.CONTACT_3D, model,
            joint_of[first], shift[first] * pin.SE3(np.eye(3), vec3(points[first])),
            joint_of[second], shift[second] * pin.SE3(np.eye(3), vec3(points[second])),
            pin.ReferenceFrame.LOCAL)
        constraint.name = f"loop{len(loops)}"
        constraints.append(constraint)
        loops.append(Loop(joint, first, second))
    constraint_data = pin.StdVec_RigidConstraintData()
    for constraint in constraints:
        constraint_data.append(constraint.createData())
    data = model.createData()
    if not model.check(data):       # e.g. a subtree that is not contiguous (engines/pinocchio/findings.py)
        raise ValueError(f"pinocchio: Model.check refuses the model built for {mech.name!r}")
    pin.initConstraintDynamics(model, data, constraints, constraint_data)
    return PinocchioModel(model, data, tuple(tree), tuple(loops), constraints, constraint_data, joint_of, frame_of, axes)


def coordinates(pm: PinocchioModel, mech: Mechanism, motion: Mapping[str, np.ndarray], row: int = 0
                ) -> tuple[np.ndarray, np.ndarray]:
    """(q, v) of the tree from raw motion columns at one row: a revolute
    coordinate θ_child − θ_parent and its rate; a prismatic one the slide
    of the child's point from the parent's along the axis, and its rate."""
    def value(body: str, quantity: str) -> float:
        return 0.0 if body == GROUND else float(np.asarray(motion[f"{body}.{quantity}"])[row])

    def point(body: str, p) -> tuple[np.ndarray, np.ndarray]:
        theta, omega = value(body, "theta"), value(body, "omega")
        r = rot_z(theta)[:2, :2] @ np.asarray(p, dtype=float)
        origin = np.array([value(body, "x"), value(body, "y")])
        velocity = np.array([value(body, "vx"), value(body, "vy")]) + omega * np.array([-r[1], r[0]])
        return origin + r, velocity

    q, v = np.zeros(pm.model.nq), np.zeros(pm.model.nv)
    for tj in pm.tree:
        if tj.joint.kind == "revolute":
            q[tj.coordinate] = value(tj.child, "theta") - value(tj.parent, "theta")
            v[tj.coordinate] = value(tj.child, "omega") - value(tj.parent, "omega")
            continue
        theta = value(tj.parent, "theta")
        axis_i = np.asarray(tj.joint.axis, dtype=float) / np.hypot(*tj.joint.axis)
        axis_parent = axis_i if tj.sign > 0 else rot_z(-tj.joint.held_angle)[:2, :2] @ axis_i
        u = rot_z(theta)[:2, :2] @ axis_parent
        (pc, vc), (pp, vp) = point(tj.child, tj.point_child), point(tj.parent, tj.point_parent)
        omega = value(tj.parent, "omega")
        q[tj.coordinate] = float((pc - pp) @ u)
        # d/dt[(Pc − Pp)·u] = (vc − vp)·u + (Pc − Pp)·(ω ẑ × u)
        v[tj.coordinate] = float((vc - vp) @ u + (pc - pp) @ (omega * np.array([-u[1], u[0]])))
    return q, v
