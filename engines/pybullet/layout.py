"""Where the PyBullet 3.2.7 model of a `Mechanism` puts each joint, and
which joint reactions are then read from a sensor and which are derived
(`plan_layout`).

What decides it (measured on 3.2.7, docs/engines.md):
- only a multibody joint has a motor, so every drive joint is one;
- PyBullet's slider user constraint has 5 rows, which over-constrain a
  planar loop closed by point-to-point constraints, so every prismatic
  joint is one too;
- a joint's force/torque sensor reads right only where the joint hangs
  from the fixed ground and its child link carries no further moving link
  (the engine findings `pybullet.non-leaf-sensor` and
  `pybullet.slide-sensor-turning-parent`); every other multibody joint's
  reaction is derived from its child body's balance (`slide`).

Layout "split" (the default): the drive and prismatic joints must not
close a loop among themselves (refused, naming the joint: PyBullet could
not build it). Each group of them joined through shared bodies is one
multibody, whose root is the ground (a fixed base) when the group reaches
it, else its central body (a free base: the fewest levels below it); a
revolute joint to the ground whose body no such group holds makes that
body a leaf of the ground; every body left over is a free base of its own,
and every joint not placed closes a loop as a point-to-point constraint.
In the usual mechanisms (drives and guides at the ground, a slide between
two moving bodies) every multibody is then a root with leaf links; a drive
beside a drive (a five-bar driven at O1 and at A) or a slide on a slide (a
Scotch yoke) hangs one link below another.

Layout "tree" is the naive spanning tree (breadth first from the ground,
the remaining joint closing the loop), reading every sensor but a slide's
between two moving bodies; it exists only so a regression test can show
the sensor error.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from mechval.model.mechanism import GROUND, Joint, Mechanism

from mechval.engines.base import Unrepresentable

Link = tuple[Joint, str, str]   # (joint, parent body, child body)

#: Why layout "tree" refuses a torque-driven or free closed loop (measured:
#: the free seed four-bar's loop, closed by a point-to-point constraint
#: between two links of one multibody, opened by 1 m within 0.2 s at a
#: 1e-4 s step, and at once at 1e-5 s; a drive's motor keeps it closed).
TREE_LOOP_UNSTABLE = ("layout 'tree' closes the loop inside one multibody, which PyBullet does not keep "
                      "closed without a drive's motor (the free seed four-bar's loop opened by 1 m within "
                      "0.2 s); use layout 'split'")


@dataclass(frozen=True)
class Layout:
    """The multibodies, {root body: its links (joint, parent, child),
    depth first}, and the multibody joints whose reactions are derived,
    each with the body whose balance gives it, listed so that every derived
    joint comes after those of its body's other joints."""

    multibodies: dict[str, list[Link]]
    derived: tuple[tuple[Joint, str], ...]


def plan_layout(mechanism: Mechanism, layout: str) -> Layout:
    """The layout (module docstring). Raises Unrepresentable for what
    PyBullet cannot build: a drive with no motor, a slide closing a loop."""
    if layout == "tree":
        return _naive_tree(mechanism)
    if layout != "split":
        raise ValueError(f"pybullet: unknown layout {layout!r} (known: split, tree)")
    drives = [mechanism.joint(d.joint) for d in mechanism.drives]
    bound = drives + [j for j in mechanism.joints if j.kind == "prismatic" and j not in drives]
    groups = _groups(bound, drives)
    parent_of: dict[str, Link] = {}
    roots: list[str] = [GROUND]
    for members in groups:
        root = GROUND if GROUND in members else _centre(members, bound)
        if root not in roots:
            roots.append(root)
        _hang(root, [j for j in bound if j.body_i in members], parent_of)
    held = {b for members in groups for b in members}
    for joint in mechanism.joints:
        if joint.kind == "revolute" and GROUND in (joint.body_i, joint.body_j):
            body = joint.body_j if joint.body_i == GROUND else joint.body_i
            if body not in held:
                held.add(body)
                parent_of[body] = (joint, GROUND, body)
    roots += [b.name for b in mechanism.bodies if b.name not in parent_of and b.name not in roots]
    # Links in the order their joints are placed: drives, slides, ground pins.
    placed = dict.fromkeys(j.name for j in bound + [link[0] for link in parent_of.values()])
    rank = {name: k for k, name in enumerate(placed)}
    kids: dict[str, list[Link]] = {}
    for link in sorted(parent_of.values(), key=lambda lk: rank[lk[0].name]):
        kids.setdefault(link[1], []).append(link)

    def depth_first(parent: str) -> list[Link]:
        return [item for link in kids.get(parent, []) for item in (link, *depth_first(link[2]))]

    multibodies = {root: depth_first(root) for root in roots}
    derived = [(joint, child) for links in multibodies.values() for joint, parent, child in reversed(links)
               if parent != GROUND or child in kids]
    return Layout(multibodies, tuple(derived))


def _groups(bound: list[Joint], drives: list[Joint]) -> list[set[str]]:
    """The bodies of each group of drive and prismatic joints joined through
    shared bodies (the ground included), in the order of their first joint;
    refuses a joint that closes a loop among them."""
    groups: list[set[str]] = []
    for joint in bound:
        ends = {joint.body_i, joint.body_j}
        touching = [g for g in groups if g & ends]
        if len(touching) == 1 and ends <= touching[0]:
            key, what = ("drive", "drive joint") if joint in drives else (f"joint.{joint.name}", "prismatic joint")
            raise Unrepresentable(key, f"the {what} {joint.name!r} closes a loop of drive and prismatic joints, "
                                       "which PyBullet cannot build (each must be a multibody joint: only those "
                                       "have motors, and its slider constraint over-constrains a planar loop)")
        merged = set(ends).union(*touching)
        first = min((groups.index(g) for g in touching), default=len(groups))
        groups = [g for g in groups if g not in touching]
        groups.insert(min(first, len(groups)), merged)
    return groups


def _neighbours(body: str, joints: list[Joint]) -> list[tuple[Joint, str]]:
    return [(j, j.body_j if j.body_i == body else j.body_i) for j in joints if body in (j.body_i, j.body_j)]


def _levels(root: str, joints: list[Joint]) -> int:
    """How many levels of links hang below `root` in the tree of `joints`."""
    depth, seen, queue = {root: 0}, {root}, deque([root])
    while queue:
        body = queue.popleft()
        for _, other in _neighbours(body, joints):
            if other not in seen:
                seen.add(other)
                depth[other] = depth[body] + 1
                queue.append(other)
    return max(depth.values())


def _centre(members: set[str], bound: list[Joint]) -> str:
    """The root of a group away from the ground: the body with the fewest
    levels below it; among equals, the first body_i of the group's joints
    in order (a lone slide or drive then hangs its body_j, as the reaction
    convention reads it)."""
    joints = [j for j in bound if j.body_i in members]
    candidates = list(dict.fromkeys(b for j in joints for b in (j.body_i, j.body_j)))
    return min(candidates, key=lambda b: _levels(b, joints))


def _hang(root: str, joints: list[Joint], parent_of: dict[str, Link]) -> None:
    """Each body of the group below its parent, breadth first from root."""
    queue = deque([root])
    while queue:
        body = queue.popleft()
        for joint, other in _neighbours(body, joints):
            if other != root and other not in parent_of:
                parent_of[other] = (joint, body, other)
                queue.append(other)


def _naive_tree(mechanism: Mechanism) -> Layout:
    links = _breadth_first(mechanism)
    in_tree = {joint.name for joint, _, _ in links}
    for joint in (mechanism.joint(d.joint) for d in mechanism.drives):
        if joint.name not in in_tree:
            raise Unrepresentable("drive", f"layout 'tree' closes a loop at the drive joint {joint.name!r}, "
                                           "which then has no motor; use layout 'split'")
    for joint in mechanism.joints:
        if joint.kind == "prismatic" and joint.name not in in_tree:
            # A point-to-point constraint there would pin the slide (found by the model audit).
            raise ValueError(f"pybullet: layout 'tree' would close the loop at the prismatic joint "
                             f"{joint.name!r} with a point-to-point constraint (a pin, not a slide); "
                             "use layout 'split'")
    if mechanism.forward_dynamics and len(links) < len(mechanism.joints):
        raise Unrepresentable("engines.pybullet.layout", TREE_LOOP_UNSTABLE)
    slides = tuple((j, j.body_j) for j in mechanism.joints
                   if j.kind == "prismatic" and GROUND not in (j.body_i, j.body_j))
    return Layout({GROUND: links}, slides)


def _breadth_first(mechanism: Mechanism) -> list[Link]:
    """A breadth-first spanning tree from the ground, listed depth first
    (createMultiBody renumbers links depth first; this keeps our indices)."""
    reached, kids, queue = {GROUND}, {}, deque([GROUND])
    while queue:
        parent = queue.popleft()
        for joint in mechanism.joints:
            if parent in (joint.body_i, joint.body_j):
                child = joint.body_j if joint.body_i == parent else joint.body_i
                if child not in reached:
                    reached.add(child)
                    kids.setdefault(parent, []).append((joint, parent, child))
                    queue.append(child)

    def depth_first(parent: str) -> list[Link]:
        return [item for link in kids.get(parent, []) for item in (link, *depth_first(link[2]))]

    return depth_first(GROUND)
