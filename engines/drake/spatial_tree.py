"""The tree Drake's MultibodyPlant is built on for a spatial scene: a
spanning tree of the scene's joints from the ground (Drake's joints form
a tree; a body no joint reaches is free, on Drake's own quaternion
floating joint) and one cut joint per independent loop, closed by
constraints (`spatial_model`).

Joints enter the tree greedily (Kruskal, `spanning_tree.cut_joints`), so
the cut falls on the last-ranked joint of its loop: the drives first (a
drive is a PD-controlled actuator on a tree joint), then damped joints (a
damper is Drake's implicit joint damping), then the kinds no constraint
of Drake 1.51 closes (prismatic, cylindrical, planar), then joints on the
ground (Drake 1.51.1 crashes at the first step with a ball constraint on
the world body: `findings.py`), then fixed, revolute, universal and last
spherical joints (the fewest constraint rows: a spherical cut is one ball
constraint, and it keeps Drake's BallRpyJoint, singular at a pitch of
±90°, out of the tree).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from mechval.model.mechanism import GROUND
from mechval.reference.spatial.system import SpatialJoint, SpatialSystem

from mechval.engines.base import Unrepresentable
from mechval.engines.spanning_tree import TreeJoint, cut_joints

#: Cut joints' kinds and how `spatial_model` closes them.
CUT_KINDS = ("spherical", "universal", "revolute", "fixed")
_RANK = {"fixed": 4, "revolute": 5, "universal": 6, "spherical": 7}


@dataclass(frozen=True)
class SpatialTopology:
    tree: tuple[TreeJoint, ...]          # parents before children
    cuts: tuple[SpatialJoint, ...]
    free: tuple[str, ...]                # bodies no joint reaches: Drake's floating bodies

    def of_joint(self, name: str) -> TreeJoint:
        return next(tj for tj in self.tree if tj.joint.name == name)


def spatial_topology(system: SpatialSystem) -> SpatialTopology:
    """A spanning tree and the cut joints (module docstring); a loop that
    can only be cut where no Drake constraint closes it is Unrepresentable
    naming the joint."""
    drives = {d.joint for d in system.drives}

    def rank(j: SpatialJoint) -> int:
        if j.name in drives:
            return 0
        if j.damping:
            return 1
        if j.kind not in CUT_KINDS:
            return 2
        return 3 if GROUND in (j.body_i, j.body_j) else _RANK[j.kind]

    cuts = cut_joints(system, rank)
    for j in cuts:
        if rank(j) < 4:
            raise Unrepresentable(f"joint.{j.name}", "the Drake adapter closes a loop with constraints at an "
                                                     "undriven, undamped spherical, universal, revolute or fixed "
                                                     "joint between two moving bodies, and this loop has none "
                                                     "(Drake 1.51.1 crashes with a ball constraint on the world "
                                                     "body)")
    names = {j.name for j in cuts}
    tree = _breadth_first([j for j in system.joints if j.name not in names])
    children = {tj.child for tj in tree}
    free = tuple(b.name for b in system.bodies if b.name not in children)
    return SpatialTopology(tree, tuple(j for j in system.joints if j.name in names), free)


def _breadth_first(joints: list[SpatialJoint]) -> tuple[TreeJoint, ...]:
    """The tree joints from the ground breadth-first, then those of
    groups of bodies not joined to the ground (each rooted at a body of
    its first joint, which floats)."""
    remaining, order = list(joints), []

    def grow(root: str) -> set[str]:
        reached, queue = {root}, deque([root])
        while queue:
            body = queue.popleft()
            for j in [j for j in remaining if body in (j.body_i, j.body_j)]:
                remaining.remove(j)
                child = j.body_j if j.body_i == body else j.body_i
                order.append(TreeJoint(j, body, child))
                reached.add(child)
                queue.append(child)
        return reached

    grow(GROUND)
    while remaining:
        grow(remaining[0].body_i)
    return tuple(order)
