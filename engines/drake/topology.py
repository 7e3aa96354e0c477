"""The tree Drake's MultibodyPlant is built on: a spanning tree of the
mechanism's joints from the ground (Drake's joints form a tree) and one
revolute pin per independent loop, closed by a ball constraint (`cuts`).

Joints enter the tree greedily (Kruskal): the drives first (a drive is a
PD-controlled actuator on a tree joint), then the prismatic joints (a cut
can only be a pin: a ball constraint), then the pins on the ground (Drake
1.51.1 crashes at the first step with a ball constraint on the world body:
`findings.py`), then the other pins, undamped before damped, each rank in
the mechanism's order, so that a loop is cut at an undamped pin between
two moving bodies where it has one (a tree joint's damper is Drake's own
implicit joint damping; a cut pin's is applied explicitly, `model`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from mechval.model.mechanism import GROUND, Joint, Mechanism

from mechval.engines.base import Unrepresentable
from mechval.engines.spanning_tree import TreeJoint, cut_joints


@dataclass(frozen=True)
class Topology:
    """The spanning tree (parents before children) and the cut pins."""

    tree: tuple[TreeJoint, ...]
    cuts: tuple[Joint, ...]

    def of_joint(self, name: str) -> TreeJoint:
        return next(tj for tj in self.tree if tj.joint.name == name)

    def of_child(self, body: str) -> TreeJoint:
        return next(tj for tj in self.tree if tj.child == body)

    def path(self, body: str) -> list[TreeJoint]:
        """Tree joints from the ground to `body`."""
        path = []
        while body != GROUND:
            tj = self.of_child(body)
            path.insert(0, tj)
            body = tj.parent
        return path

    def angle_coefficients(self, joint: Joint) -> dict[str, float]:
        """Tree-coordinate coefficients of a revolute joint's relative angle
        θj − θi (a body's angle is the sum of the hinge coordinates on its
        path, each signed by its orientation): a torque T on body_j and −T
        on body_i is the generalized force T times these (its Jacobian)."""
        coef: dict[str, float] = {}
        for body, sign in ((joint.body_j, 1.0), (joint.body_i, -1.0)):
            for name, c in self.body_angle_coefficients(body).items():
                coef[name] = coef.get(name, 0.0) + sign * c
        return {name: c for name, c in coef.items() if c != 0.0}

    def body_angle_coefficients(self, body: str) -> dict[str, float]:
        """Tree-coordinate coefficients of a body's angle θ (slides do not
        turn; a hinge's coordinate is θchild − θparent)."""
        if body == GROUND:
            return {}
        return {tj.joint.name: 1.0 for tj in self.path(body) if tj.joint.kind == "revolute"}


def topology(mech: Mechanism) -> Topology:
    """A spanning tree and one cut revolute pin per loop (module docstring).
    A loop that can be closed only at a slide or a drive is Unrepresentable
    naming the joint."""
    drives = {d.joint for d in mech.drives}
    rank = lambda j: (0 if j.name in drives else 1 if j.kind == "prismatic" else 2 if GROUND in (j.body_i, j.body_j)
                      else 3 if j.damping == 0.0 else 4)
    cuts = cut_joints(mech, rank)
    for j in cuts:
        if j.kind != "revolute" or j.name in drives or GROUND in (j.body_i, j.body_j):
            raise Unrepresentable(f"joint.{j.name}", "the Drake adapter closes each loop with a ball constraint at a "
                                                     "revolute pin between two moving bodies that is not driven, and "
                                                     "this loop has none (Drake 1.51.1 crashes with a ball constraint "
                                                     "on the world body)")
    cut_names = {j.name for j in cuts}
    tree = _spanning_tree(mech, [j for j in mech.joints if j.name not in cut_names])
    if tree is None:
        raise ValueError(f"{mech.name}: the Drake adapter found no spanning tree of the joints")
    return Topology(tree, tuple(j for j in mech.joints if j.name in cut_names))


def _spanning_tree(mech: Mechanism, joints: list[Joint]) -> tuple[TreeJoint, ...] | None:
    """The joints laid out breadth-first from the ground, in the
    mechanism's joint order; None if they do not form one tree over every
    body."""
    remaining = list(joints)
    reached, order, queue = {GROUND}, [], deque([GROUND])
    while queue:
        body = queue.popleft()
        for j in [j for j in remaining if body in (j.body_i, j.body_j)]:
            remaining.remove(j)
            child = j.body_j if j.body_i == body else j.body_i
            if child in reached:
                return None
            order.append(TreeJoint(j, body, child))
            reached.add(child)
            queue.append(child)
    return tuple(order) if not remaining and len(reached) == len(mech.bodies) + 1 else None


def coordinates(topo: Topology, motion: Mapping[str, np.ndarray]
                ) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per tree joint its Drake (q, v, v̇) from the reference body motion: a
    hinge's θchild − θparent, a slide's travel of the child's joint point
    from the parent's along the axis (sign·s, `slide_motion`)."""
    from mechval.model.kinematics import slide_motion
    zero = np.zeros(len(motion["t"]))
    of = lambda b, q: zero if b == GROUND else np.asarray(motion[f"{b}.{q}"], dtype=float)
    out = {}
    for tj in topo.tree:
        j = tj.joint
        if j.kind == "revolute":
            out[j.name] = tuple(tj.sign * (of(j.body_j, q) - of(j.body_i, q)) for q in ("theta", "omega", "alpha"))
        else:
            slide = slide_motion(motion, j)
            out[j.name] = tuple(tj.sign * np.asarray(slide[q]) for q in ("s", "v", "a"))
    return out
