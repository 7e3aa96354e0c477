"""Audit of the Pinocchio model built for a spatial scene
(`spatial_model.build_spatial_model`): what it holds, read back from the
`pin.Model` and its `RigidConstraintModel`s and set against the scene's
expectations (`mechval.records.spatial_audit.expected_spatial`) with the
core audit's verdicts (`mechval.records.audit.audit`).

Conversions to the scene's conventions:
- A body is a frame carrying its inertia (`Frame.inertia`, about the
  centre of mass in the frame's axes: the scene's terms as they are); the
  frames' inertias, moved to their joint, must sum to the joint's
  `model.inertias` (bodies welded in the tree share one joint), or a row
  says where they do not.
- A tree joint's frame on its parent body is the parent's frame placement
  inverted times `model.jointPlacements`, on its child the child's frame
  placement inverted; its axes are Pinocchio's own (z of RZ, PZ and a
  planar joint's normal; a universal joint's `axis1` in the parent's frame
  and `axis2` in the child's), the child's negated where the adapter
  turned its frame by π about x (zj against zi, `TreeJoint.flipped`).
- A loop cut at a spherical, revolute or fixed joint is one or two
  constraints: its points are the constraints' placements in the bodies'
  frames, a revolute cut's axis the direction from its first constraint
  point to its second (a flipped cut's on body_j negated), a fixed cut's
  frame the CONTACT_6D placement's. A cut of another kind is that joint
  from body_i to a near-massless carrier welded to body_j (its mass is
  listed as a note).
- A weld in the tree is no Pinocchio joint (both bodies' frames on one
  joint): only the bodies' relative pose is held, so its points and axes
  are "as set", and a row says if the relative pose the model holds is not
  the one they make.

"As set": joint dampers and spring-dampers are wrenches the adapter's
dynamics applies from the scene (`spatial_dynamics.applied_wrenches`):
Pinocchio has no element for them. Drives, torque laws and body loads are
not audited yet.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
import pandas as pd
import pinocchio as pin

from mechval.model.mechanism import GROUND
from mechval.records.audit import AUDIT_RTOL, SCENE, Reading, audit, body_item, joint_item
from mechval.records.spatial_audit import INERTIA, axis_columns, expected_spatial, joint_sides
from mechval.reference.spatial.system import SpatialJoint, SpatialSystem

from mechval.engines.pinocchio.spatial_model import Cut, SpatialModel, TreeJoint, build_spatial_model, flipped

KINDS = {"JointModelRZ": "revolute", "JointModelPZ": "prismatic", "JointModelUniversal": "universal",
         "JointModelPlanar": "planar", "JointModelSpherical": "spherical"}
FLIP = np.diag([1.0, -1.0, -1.0])
APPLIED = "applied by the adapter's dynamics from the scene (Pinocchio has no such element)"
#: Pinocchio's default position limits (±DBL_MAX): no limit.
NO_LIMIT = 1e308


def audit_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the Pinocchio model the adapter builds for `system`."""
    return audit(expected_spatial(system), read_spatial(build_spatial_model(system), system))


def kind_of(jm) -> str:
    name = jm.shortname()
    if name == "JointModelComposite":
        parts = [j.shortname() for j in jm.extract().joints]
        return "cylindrical" if parts == ["JointModelPZ", "JointModelRZ"] else f"composite {parts}"
    return KINDS.get(name, name)


def pinocchio_axis(jm, on_parent: bool) -> np.ndarray:
    """The joint's axis in its parent (or child) joint frame."""
    if jm.shortname() == "JointModelUniversal":
        u = jm.extract()
        return np.asarray(u.axis1 if on_parent else u.axis2, float)
    return np.array([0.0, 0.0, 1.0])


def read_spatial(sm: SpatialModel, system: SpatialSystem) -> list[Reading]:
    model, out = sm.model, []
    for b in system.bodies:
        I, item = model.frames[sm.frame_of[b.name]].inertia, body_item(b.name)
        c, rot = np.asarray(I.lever, float), np.asarray(I.inertia, float)
        out.append(Reading(item, "mass", float(I.mass), f"Frame.inertia on joint {sm.joint_of[b.name]}"))
        out += [Reading(item, f"com {n}", float(c[k])) for k, n in enumerate("xyz")]
        out += [Reading(item, name, float(rot[r, col])) for name, r, col in INERTIA]
    out += _joint_sums(sm)
    for tj in sm.tree:
        out += _fixed(sm, tj) if tj.joint.kind == "fixed" else _tree_joint(sm, tj)
    for cut in sm.cuts:
        out += _carried(sm, cut, system) if cut.carrier is not None else _cut(sm, cut, system)
    for index, body in sm.free.items():
        out.append(Reading(body_item(body), "free flyer", f"JointModelFreeFlyer {index}",
                           "a body with no joint to the ground hangs on a free flyer", "note"))
    for j in system.joints:
        out.append(Reading(joint_item(j.name), "damping", float(j.damping), APPLIED, "set"))
    for s in system.springs:
        item = f"spring {s.name}"
        out += [Reading(item, "bodies", f"{s.body_a} → {s.body_b}", APPLIED, "set"),
                Reading(item, "stiffness", float(s.stiffness), "", "set"),
                Reading(item, "free length", float(s.free_length), "", "set"),
                Reading(item, "damping", float(s.damping), "", "set")]
        for end, point in (("a", s.point_a), ("b", s.point_b)):
            out += [Reading(item, f"point {end} {c}", float(point[k]), "", "set") for k, c in enumerate("xyz")]
    return out + _scene(sm)


def _body_frame(sm: SpatialModel, body: str) -> tuple[int, pin.SE3]:
    """(joint, placement in it) of a body's frame; the ground's: the universe."""
    if body == GROUND:
        return 0, pin.SE3.Identity()
    f = sm.model.frames[sm.frame_of[body]]
    return int(f.parentJoint), f.placement


def _joint_sums(sm: SpatialModel) -> list[Reading]:
    """A row for each joint whose inertia is not the sum of its frames'."""
    model, out = sm.model, []
    for index in range(1, model.njoints):
        total = pin.Inertia.Zero()
        for f in model.frames:
            if int(f.parentJoint) == index and f.inertia.mass > 0:
                total = total + f.placement.act(f.inertia)
        held = model.inertias[index]
        gap = float(np.abs(held.toDynamicParameters() - total.toDynamicParameters()).max())
        scale = float(np.abs(held.toDynamicParameters()).max())
        if gap > AUDIT_RTOL * max(scale, 1e-300):
            out.append(Reading(f"pinocchio joint {index}", "inertia", f"off its frames' sum by {gap:.3g}"))
    return out


def _sides(j: SpatialJoint, frames: dict[str, pin.SE3], axes: dict[str, np.ndarray], item: str,
           source: str = "read", note: str = "") -> list[Reading]:
    """Point and axis readings of both sides from each body's joint frame
    (body axes) and its axis (body axes)."""
    out = []
    for side, body, _, _ in joint_sides(j):
        X = frames[body]
        out += [Reading(item, f"point {side} {c}", float(X.translation[k]), note, source) for k, c in enumerate("xyz")]
        for col in axis_columns(j.kind):
            a = axes[body] if col == 2 and body in axes else X.rotation[:, col]
            out += [Reading(item, f"axis {side} {'xyz'[col]}{c}", float(a[k]), note, source)
                    for k, c in enumerate("xyz")]
    return out


def _bodies(sm: SpatialModel, j: SpatialJoint, joints: dict[str, int]) -> str:
    """body_i → body_j when each body's frame sits on the model joint the
    connection needs (`joints`: body → joint index), else what is there."""
    names = [b if _body_frame(sm, b)[0] == joints[b] else f"joint {joints[b]}" for b in (j.body_i, j.body_j)]
    return " → ".join(names)


def _tree_joint(sm: SpatialModel, tj: TreeJoint) -> list[Reading]:
    model, j, item = sm.model, tj.joint, joint_item(tj.joint.name)
    jm = model.joints[tj.index]
    parent_joint, on_parent = _body_frame(sm, tj.parent)
    frames = {tj.parent: on_parent.inverse() * model.jointPlacements[tj.index],
              tj.child: _body_frame(sm, tj.child)[1].inverse()}
    axes = {tj.parent: frames[tj.parent].rotation @ pinocchio_axis(jm, True),
            tj.child: frames[tj.child].rotation @ pinocchio_axis(jm, False)}
    note = ""
    if tj.flipped:          # the child's frame turned by π about x: back to the scene's
        frames[tj.child] = frames[tj.child] * pin.SE3(FLIP, np.zeros(3))
        axes[tj.child] = -axes[tj.child]
        note = "the child's frame turned back by π about x (zj against zi)"
    joints = {tj.parent: int(model.parents[tj.index]), tj.child: tj.index}
    return [Reading(item, "kind", kind_of(jm), f"{jm.shortname()} {tj.index}"),
            Reading(item, "bodies", _bodies(sm, j, joints))] + _sides(j, frames, axes, item, note=note)


def _fixed(sm: SpatialModel, tj: TreeJoint) -> list[Reading]:
    """A weld in the tree: both frames on one joint; points and axes as set."""
    j, item = tj.joint, joint_item(tj.joint.name)
    (pj, parent), (cj, child) = _body_frame(sm, tj.parent), _body_frame(sm, tj.child)
    out = [Reading(item, "kind", "fixed" if pj == cj else f"joints {pj}, {cj}",
                   f"no Pinocchio joint: both bodies' frames on joint {pj}"),
           Reading(item, "bodies", _bodies(sm, j, {tj.parent: pj, tj.child: pj}))]
    sides = {tj.parent: tj.side(tj.parent), tj.child: tj.side(tj.child)}
    held = parent.inverse() * child
    made = sides[tj.parent] * sides[tj.child].inverse()
    gap = float(np.abs(held.homogeneous - made.homogeneous).max())
    if gap > AUDIT_RTOL * max(1.0, float(np.abs(made.translation).max())):
        out.append(Reading(item, "relative pose", f"off the joint frames' by {gap:.3g}"))
    note = "a weld in the tree holds only the bodies' relative pose (checked)"
    return out + _sides(j, sides, {}, item, "set", note)


def _carried(sm: SpatialModel, cut: Cut, system: SpatialSystem) -> list[Reading]:
    """A cut joint built as itself, from body_i to a carrier welded to body_j."""
    model, tj, j, item = sm.model, cut.carrier, cut.joint, joint_item(cut.joint.name)
    jm, weld = model.joints[tj.index], sm.constraints[cut.constraints[0]]
    frames = {j.body_i: _body_frame(sm, j.body_i)[1].inverse() * model.jointPlacements[tj.index],
              j.body_j: _body_frame(sm, j.body_j)[1].inverse() * weld.joint2_placement * weld.joint1_placement.inverse()}
    axes = {j.body_i: frames[j.body_i].rotation @ pinocchio_axis(jm, True),
            j.body_j: frames[j.body_j].rotation @ pinocchio_axis(jm, False)}
    if tj.flipped:
        frames[j.body_j] = frames[j.body_j] * pin.SE3(FLIP, np.zeros(3))
        axes[j.body_j] = -axes[j.body_j]
    carrier = sum(model.frames[f].inertia.mass for f, t in sm.carrier_frames.items() if t.index == tj.index)
    joints = {j.body_i: int(model.parents[tj.index]), j.body_j: int(weld.joint2_id)}
    return [Reading(item, "kind", kind_of(jm), f"{jm.shortname()} {tj.index} to a carrier welded to "
                                               f"{j.body_j} ({weld.type})"),
            Reading(item, "bodies", _bodies(sm, j, joints)),
            Reading(item, "carrier", f"{carrier:.3g} kg", "the carrier's mass: not in the scene", "note")] + \
        _sides(j, frames, axes, item)


def _cut(sm: SpatialModel, cut: Cut, system: SpatialSystem) -> list[Reading]:
    """A loop closed by point constraints (spherical, revolute: two along
    the axis) or a weld (fixed)."""
    j, item = cut.joint, joint_item(cut.joint.name)
    constraints = [sm.constraints[k] for k in cut.constraints]
    types = [str(c.type).rsplit(".", 1)[-1] for c in constraints]
    kind = {("CONTACT_3D",): "spherical", ("CONTACT_3D", "CONTACT_3D"): "revolute",
            ("CONTACT_6D",): "fixed"}.get(tuple(types), f"constraints {types}")

    def placed(c, body: str) -> pin.SE3:
        return _body_frame(sm, body)[1].inverse() * (c.joint1_placement if body == cut.first else c.joint2_placement)

    frames = {b: placed(constraints[0], b) for b in (j.body_i, j.body_j)}
    axes = {}
    if kind == "revolute":
        for b in (j.body_i, j.body_j):
            d = placed(constraints[1], b).translation - frames[b].translation
            axes[b] = d / np.linalg.norm(d) * (-1.0 if b == j.body_j and flipped(system, j) else 1.0)
    joints = {cut.first: int(constraints[0].joint1_id), cut.second: int(constraints[0].joint2_id)}
    note = "a revolute cut's axis: from its first constraint point to its second" if kind == "revolute" else ""
    return [Reading(item, "kind", kind, f"closed by {' + '.join(types)}"),
            Reading(item, "bodies", _bodies(sm, j, joints))] + _sides(j, frames, axes, item, note=note)


def _scene(sm: SpatialModel) -> list[Reading]:
    model = sm.model
    g = np.asarray(model.gravity.linear, float)
    out = [Reading(SCENE, f"gravity {c}", float(g[k]), "model.gravity") for k, c in enumerate("xyz")]
    used = sum(len(c.constraints) for c in sm.cuts)
    out.append(Reading(SCENE, "contacts", "off", "no geometry model; constraintDynamics takes the loop closures only"))
    if len(sm.constraints) != used:
        out.append(Reading(SCENE, "other constraints", f"{len(sm.constraints) - used}"))
    limits = np.concatenate([np.asarray(model.lowerPositionLimit), np.asarray(model.upperPositionLimit)])
    finite = int(np.sum(np.abs(limits) < NO_LIMIT))
    out.append(Reading(SCENE, "joint limits", "none" if not finite else f"{finite} finite limits",
                       "the model's position limits are ±DBL_MAX, and constraintDynamics applies none"))
    effects = [name for name in ("friction", "damping", "armature", "rotorInertia")
               if np.any(np.asarray(getattr(model, name)))]
    if effects:
        out.append(Reading(SCENE, "joint effects", ", ".join(f"model.{e}" for e in effects)))
    return out
