"""Audit of the PyBullet model of a spatial scene (`spatial_build`): what
the multibodies and user constraints hold, read back through PyBullet's
getters in the pose a run starts from, and set against the `SpatialSystem`
with the core audit's verdicts (`mechval.records.audit.audit`; the
expectations from the scene alone, `expected_spatial`).

PyBullet holds world poses, not the scene's body frames: each reading is
taken in world axes and expressed in the body's frame at the reference's
start pose, the pose the build placed the body in (a build that put a body
elsewhere shows as a wrong centre of mass or point). So:
- a body: `getDynamicsInfo` mass and inertia diagonal, about the inertial
  frame whose world pose `getLinkState[0:2]` (`getBasePositionAndOrientation`
  for a free base) reads; a body split in two halves welded at its centre
  of mass (`spatial_split`) is the halves' sum (mass, centre of mass,
  inertia about it).
- a tree joint: its chain of multibody joints (`getJointInfo` type, axis in
  the link frame, parent index; a cylindrical joint is a slide and a hinge,
  a planar two slides and a hinge, a universal two hinges, the chain's
  links before the last massless); the point is the link frame's origin
  o = p_G − R_link·p_inertial, R_link = R_G·R_inertialᵀ (in double:
  `getLinkState[4]` is float32); an axis is `getJointInfo[13]` turned by
  R_G: PyBullet keeps a joint axis in the link's inertial (centre-of-mass)
  frame, not in the link frame `createMultiBody` takes it in (measured:
  read as a link-frame axis, the RSSR crank's is 0.88 off). A slide's
  point on the parent is the point of its guide line (plane) nearest the
  scene's. A universal joint's
  first hinge is the parent's pin, its second the child's; a cylindrical
  joint's slide the parent's axis, its hinge the child's. A weld holds no
  frame of its own: its child's frame is the scene's ("as set"), the
  parent's where the weld puts it (the child link's orientation).
- a loop joint: its point-to-point constraints' pivots (`getConstraintInfo`,
  in each side's centre-of-mass frame): a ball one, a revolute a second one
  along the axis, whose direction is the axis.
- damping and spring-dampers are not in the model (PyBullet has no spring
  element and keeps no load): the stepping loop applies them (`Loads`), so
  they are "as set", as are a weld's child frame.
- the scene: gravity (`getPhysicsEngineParameters`), collision shapes,
  creation limits (lower ≤ upper).
Notes: massless links (their mass and inertia read), split bodies' welds,
free bases, the constraints' force cap; any multibody, link or user
constraint no scene element accounts for is an "other elements" row.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
import pandas as pd

from mechval.model.mechanism import GROUND
from mechval.records.audit import SCENE, Reading, audit, body_item, joint_item
from mechval.records.spatial_audit import INERTIA, axis_columns, expected_spatial
from mechval.reference.spatial.rotation import quaternion_to_matrix
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.pybullet.audit import quaternion_matrix
from mechval.engines.pybullet.model import p
from mechval.engines.pybullet.spatial import Start, start_model
from mechval.engines.pybullet.spatial_reactions import Loads
from mechval.engines.pybullet.spatial_split import is_weld

REV, PRI, SPH, FIX = p.JOINT_REVOLUTE, p.JOINT_PRISMATIC, p.JOINT_SPHERICAL, p.JOINT_FIXED
#: A tree joint's kind from its chain's joint types.
KINDS = {(REV,): "revolute", (PRI,): "prismatic", (SPH,): "spherical", (FIX,): "fixed", (PRI, REV): "cylindrical",
         (PRI, PRI, REV): "planar", (REV, REV): "universal"}
STEPPED = "not in the model: the stepping loop applies it every step as external loads"


def nearest_in_span(point, through, directions) -> np.ndarray:
    """The point of the line (plane) through `through` spanned by
    `directions` nearest to `point`."""
    A = np.array(directions, dtype=float).T
    return through + A @ np.linalg.lstsq(A, np.asarray(point, float) - through, rcond=None)[0]


class Reader:
    """Readings of one built model (`Start`) in its start pose."""

    def __init__(self, system: SpatialSystem, start: Start):
        self.system, self.start, self.model, self.c = system, start, start.model, start.model.client
        self.scene_of = lambda body: start.twins.get(body, body)     # noqa: E731
        self.name = {h: self.scene_of(body) for body, h in self.model.handles.items()}
        self.pose = {GROUND: (np.zeros(3), np.eye(3))}
        for b in start.built.bodies:
            row = start.pose
            self.pose[b.name] = (row[[f"{b.name}.{c}" for c in "xyz"]].to_numpy()[0],
                                 quaternion_to_matrix(row[[f"{b.name}.q{c}" for c in "wxyz"]].to_numpy()[0]))
        self.loads = Loads(system)

    # -- frames --------------------------------------------------------------------------

    def com_frame(self, uid: int, link: int) -> tuple[np.ndarray, np.ndarray]:
        """World position and rotation of a link's (or base's) inertial frame."""
        if link < 0:
            position, orientation = p.getBasePositionAndOrientation(uid, physicsClientId=self.c)
        else:
            state = p.getLinkState(uid, link, computeForwardKinematics=1, physicsClientId=self.c)
            position, orientation = state[0], state[1]
        return np.array(position), quaternion_matrix(orientation)

    def link_frame(self, uid: int, link: int) -> tuple[np.ndarray, np.ndarray]:
        """World origin and rotation of a link frame, from its inertial frame."""
        com, R_G = self.com_frame(uid, link)
        info = p.getDynamicsInfo(uid, link, physicsClientId=self.c)
        R = R_G @ quaternion_matrix(info[4]).T
        return com - R @ np.array(info[3]), R

    def to_body(self, body: str, world) -> np.ndarray:
        origin, R = self.pose[body]
        return R.T @ (np.asarray(world, float) - origin)

    def to_axes(self, body: str, world) -> np.ndarray:
        return self.pose[body][1].T @ np.asarray(world, float)

    # -- bodies ------------------------------------------------------------------------

    def bodies(self) -> list[Reading]:
        out = []
        for b in self.system.bodies:
            halves = [h for body, h in self.model.handles.items() if self.scene_of(body) == b.name]
            parts = []
            for uid, link in halves:
                info = p.getDynamicsInfo(uid, link, physicsClientId=self.c)
                com, R = self.com_frame(uid, link)
                parts.append((float(info[0]), com, R @ np.diag(info[2]) @ R.T))
            m = sum(part[0] for part in parts)
            com = sum(part[0] * part[1] for part in parts) / m
            I = sum(I_h + m_h * ((com_h - com) @ (com_h - com) * np.eye(3) - np.outer(com_h - com, com_h - com))
                    for m_h, com_h, I_h in parts)
            R = self.pose[b.name][1]
            local, I_body = self.to_body(b.name, com), R.T @ I @ R
            note = "two halves welded at the centre of mass, summed" if len(parts) == 2 else ""
            item = body_item(b.name)
            out.append(Reading(item, "mass", m, note))
            out += [Reading(item, f"com {c}", float(local[k]), note) for k, c in enumerate("xyz")]
            out += [Reading(item, name, float(I_body[r, col]), note or "R_G·diag·R_Gᵀ in body axes")
                    for name, r, col in INERTIA]
        return out

    # -- joints ------------------------------------------------------------------------

    def joint_common(self, j, kind: str, pair: tuple[str, str], how: str) -> list[Reading]:
        item = joint_item(j.name)
        bodies = f"{j.body_i} → {j.body_j}" if set(pair) == {j.body_i, j.body_j} else " → ".join(pair)
        damped = sum(d.damping for d in self.loads.damped if d.name == j.name)
        return [Reading(item, "kind", kind, how), Reading(item, "bodies", bodies),
                Reading(item, "damping", float(damped), f"{STEPPED} (PyBullet's jointDamping is 0)", "set")]

    def tree_joint(self, tj) -> list[Reading]:
        j, uid, item = self.system.joint(tj.joint.name), tj.uid, joint_item(tj.joint.name)
        infos = [p.getJointInfo(uid, link, physicsClientId=self.c) for link in tj.links]
        kind = KINDS.get(tuple(info[2] for info in infos), "PyBullet types " + ", ".join(str(i[2]) for i in infos))
        if any(info[16] != link for info, link in zip(infos[1:], tj.links)):
            kind += " (not a chain)"
        parent, child = self.name[(uid, infos[0][16])], self.name[(uid, tj.links[-1])]
        frames = [self.link_frame(uid, link) for link in tj.links]
        # PyBullet keeps the axis in the link's inertial frame (module docstring).
        axes = [self.com_frame(uid, link)[1] @ np.array(info[13]) for link, info in zip(tj.links, infos)]
        how = {"cylindrical": "a slide to a massless link, then a hinge", "universal": "a hinge to a massless "
               "cross, then a hinge", "planar": "two slides to massless links, then a hinge"}.get(kind, "multibody joint")
        out = self.joint_common(j, kind, (parent, child), how)
        origin, R_child = frames[-1]
        slides = [a for a, info in zip(axes, infos) if info[2] == PRI]
        for side, body, point, frame in (("i", j.body_i, j.point_i, j.frame_i), ("j", j.body_j, j.point_j, j.frame_j)):
            on_parent = body == parent
            world, note = origin, "the child link frame's origin"
            if slides and on_parent:
                world = nearest_in_span(self.pose_point(body, point), origin, slides)
                note = "the point of the guide line (plane) nearest the scene's: any point of it serves"
            local = self.to_body(body, world)
            out += [Reading(item, f"point {side} {c}", float(local[k]), note) for k, c in enumerate("xyz")]
            for col in axis_columns(j.kind):
                if kind == "fixed":
                    # The weld's child frame is the scene's; the parent's is where the weld puts it.
                    child_frame = j.frame_j if child == j.body_j else j.frame_i
                    value = self.to_axes(body, R_child @ child_frame[:, col]) if on_parent else child_frame[:, col]
                    source, note = ("read", "the child's frame through the child link's orientation") if on_parent \
                        else ("set", "a weld holds no frame of its own: the child's is the scene's")
                else:
                    value, source, note = self.to_axes(body, self.tree_axis(kind, axes, on_parent)), "read", "getJointInfo axis"
                out += [Reading(item, f"axis {side} {'xyz'[col]}{c}", float(value[k]), note, source)
                        for k, c in enumerate("xyz")]
        for link in tj.links[:-1]:
            info = p.getDynamicsInfo(uid, link, physicsClientId=self.c)
            empty = info[0] == 0.0 and not any(info[2])
            out.append(Reading(item, f"massless link {link}", f"mass {info[0]:g}, inertia {tuple(info[2])}",
                               "the composite kind's link between its joints", "note" if empty else "read"))
        return out

    @staticmethod
    def tree_axis(kind: str, axes: list[np.ndarray], on_parent: bool) -> np.ndarray:
        """A chain's axis on one side (world): a universal joint's first
        hinge on the parent, its second on the child; a cylindrical joint's
        slide on the parent, its hinge on the child; else the last joint's."""
        if kind in ("universal", "cylindrical"):
            return axes[0] if on_parent else axes[1]
        return axes[-1]

    def pose_point(self, body: str, point) -> np.ndarray:
        origin, R = self.pose[body]
        return origin + R @ np.asarray(point, float)

    def loop_joint(self, loop) -> list[Reading]:
        j, item = self.system.joint(loop.joint.name), joint_item(loop.joint.name)
        infos = [p.getConstraintInfo(cid, physicsClientId=self.c) for cid in loop.cids]
        kind = {1: "spherical", 2: "revolute"}.get(len(infos), "?") if all(i[4] == p.JOINT_POINT2POINT for i in infos) \
            else "PyBullet constraint types " + ", ".join(str(i[4]) for i in infos)
        pivots: dict[str, list[np.ndarray]] = {}
        for info in infos:
            for uid, link, pivot in ((info[0], info[1], info[6]), (info[2], info[3], info[7])):
                com, R = self.com_frame(uid, link)
                pivots.setdefault(self.name[(uid, link)], []).append(com + R @ np.array(pivot))
        how = "a point-to-point constraint" if kind == "spherical" else "two point-to-point constraints along the axis"
        out = self.joint_common(j, kind, tuple(pivots), how)
        for side, body in (("i", j.body_i), ("j", j.body_j)):
            world = pivots.get(body)
            if not world:
                continue
            local = self.to_body(body, world[0])
            out += [Reading(item, f"point {side} {c}", float(local[k]), "the constraint's pivot")
                    for k, c in enumerate("xyz")]
            if kind == "revolute" and len(world) == 2:
                axis = self.to_axes(body, (world[1] - world[0]) / np.linalg.norm(world[1] - world[0]))
                out += [Reading(item, f"axis {side} z{c}", float(axis[k]), "from the first pivot to the second")
                        for k, c in enumerate("xyz")]
        caps = sorted({float(info[10]) for info in infos})
        out.append(Reading(item, "force cap", ", ".join(f"{c:g}" for c in caps),
                           "an impulse cap converted with the step: far above any reaction", "note"))
        return out

    def weld(self, loop) -> list[Reading]:
        info = p.getConstraintInfo(loop.cids[0], physicsClientId=self.c)
        body = self.scene_of(loop.joint.body_i)
        text = f"halves welded by a fixed constraint (type {info[4]}), pivots {tuple(info[6])}, {tuple(info[7])}"
        return [Reading(body_item(body), "split", text, "a loop closed inside the body (spatial_split): its second "
                                                       "half carries the joint the loop could not close at", "note")]

    # -- springs, scene, notes ------------------------------------------------------------

    def springs(self) -> list[Reading]:
        out = []
        for s in self.loads.system.springs:
            item = f"spring {s.name}"
            out += [Reading(item, "bodies", f"{s.body_a} → {s.body_b}", STEPPED, "set"),
                    Reading(item, "stiffness", float(s.stiffness), STEPPED, "set"),
                    Reading(item, "free length", float(s.free_length), STEPPED, "set"),
                    Reading(item, "damping", float(s.damping), STEPPED, "set")]
            for end, point in (("a", s.point_a), ("b", s.point_b)):
                out += [Reading(item, f"point {end} {c}", float(point[k]), STEPPED, "set") for k, c in enumerate("xyz")]
        return out

    def scene(self) -> list[Reading]:
        c = self.c
        params = p.getPhysicsEngineParameters(physicsClientId=c)
        links = [(uid, link) for uid in range(p.getNumBodies(physicsClientId=c))
                 for link in range(-1, p.getNumJoints(uid, physicsClientId=c))]
        shapes = sum(len(p.getCollisionShapeData(uid, link, physicsClientId=c)) for uid, link in links)
        limits = sum(1 for uid, link in links if link >= 0
                     and (lambda info: info[8] <= info[9] and info[2] != FIX)(p.getJointInfo(uid, link, physicsClientId=c)))
        out = [Reading(SCENE, f"gravity {a}", float(params[f"gravityAcceleration{a.upper()}"]), "getPhysicsEngineParameters")
               for a in "xyz"]
        return out + [Reading(SCENE, "contacts", "off" if shapes == 0 else f"{shapes} collision shapes"),
                      Reading(SCENE, "joint limits", "none" if not limits else f"{limits} limited joints",
                              "creation limits (lower ≤ upper)")]

    def notes(self) -> list[Reading]:
        free = [self.scene_of(body) for body, (_, link) in self.model.handles.items() if link < 0 and body != GROUND]
        return [Reading("pybullet", "free bases", ", ".join(free) or "none",
                        "bodies that are a multibody's free base", "note")]

    def others(self) -> list[Reading]:
        """Multibodies, links and user constraints the scene's elements do
        not account for: a reading with no expectation (it differs), only
        when there are any."""
        c, model = self.c, self.model
        uids = {uid for uid, _ in model.handles.values()}
        links = {(tj.uid, link) for tj in model.tree.values() for link in tj.links}
        cids = {cid for loop in model.loops.values() for cid in loop.cids}
        extra = [f"multibody {uid}" for uid in range(p.getNumBodies(physicsClientId=c)) if uid not in uids]
        extra += [f"link {link} of multibody {uid}" for uid in sorted(uids)
                  for link in range(p.getNumJoints(uid, physicsClientId=c)) if (uid, link) not in links]
        extra += [f"constraint {cid}" for cid in (p.getConstraintUniqueId(i, physicsClientId=c)
                                                  for i in range(p.getNumConstraints(physicsClientId=c)))
                  if cid not in cids]
        return [Reading(SCENE, "other elements", "; ".join(extra))] if extra else []

    def readings(self) -> list[Reading]:
        out = self.bodies()
        for tj in self.model.tree.values():
            out += self.tree_joint(tj)
        for loop in self.model.loops.values():
            out += self.weld(loop) if is_weld(loop.joint) else self.loop_joint(loop)
        return out + self.springs() + self.scene() + self.notes() + self.others()


def read_spatial(system: SpatialSystem, start: Start) -> list[Reading]:
    return Reader(system, start).readings()


def audit_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the PyBullet model the adapter builds for `system`."""
    start = start_model(system, times, settings)
    try:
        return audit(expected_spatial(system), read_spatial(system, start))
    finally:
        p.disconnect(start.model.client)
