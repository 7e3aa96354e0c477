"""Audit of the Drake plant built for a spatial scene: what it holds, read
back through Drake's getters and set against the `SpatialSystem` with the
core audit's verdicts (`mechval.records.audit.audit`).

The expectations come from the scene alone
(`mechval.records.spatial_audit.expected_spatial`). Body loads and joint
torque laws are not audited yet (the applied-force system holds the
scene's own objects).

Readings: `default_mass`, `default_com` and `default_rotational_inertia`
(about the body origin; shifted to the centre of mass); a tree joint's
frames (`GetFixedPoseInBodyFrame`) and Drake's own axis in them
(`revolute_axis`, `translation_axis`; a universal joint's pins are its
frames' Fx and My, a planar joint's normal their z), its damping and
limits; `LinearSpringDamper`s' getters; the gravity field; the collision
geometries. Drake 1.51's Python
API has no getter for a constraint's points, so a cut joint's points and
axes are the values the build passed ("as set").
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
import pandas as pd

from pydrake.multibody.tree import ForceElementIndex, LinearSpringDamper

from mechval.records.audit import SCENE, Reading, audit, body_item, joint_item
from mechval.records.spatial_audit import INERTIA, axis_columns, expected_spatial, joint_sides
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.drake.spatial import built

def read_spatial(model) -> list[Reading]:
    plant, system, out = model.plant, model.system, []
    for b in system.bodies:
        body, item = model.bodies[b.name], body_item(b.name)
        m, c = body.default_mass(), np.asarray(body.default_com())
        I_origin = body.default_rotational_inertia().CopyToFullMatrix3()
        I = I_origin - m * (c @ c * np.eye(3) - np.outer(c, c))        # to the centre of mass
        out.append(Reading(item, "mass", float(m)))
        out += [Reading(item, f"com {n}", float(c[k])) for k, n in enumerate("xyz")]
        out += [Reading(item, name, float(I[r, col])) for name, r, col in INERTIA]
    limits = []
    for tj in model.topo.tree:
        j, item, joints = tj.joint, joint_item(tj.joint.name), model.joints[tj.joint.name]
        kind = "cylindrical" if len(joints) == 2 else {
            "revolute": "revolute", "prismatic": "prismatic", "ball_rpy": "spherical", "universal": "universal",
            "planar": "planar", "weld": "fixed"}.get(joints[0].type_name(), joints[0].type_name())
        parent, child = joints[0].frame_on_parent(), joints[-1].frame_on_child()
        ends = {tj.parent: parent.GetFixedPoseInBodyFrame(), tj.child: child.GetFixedPoseInBodyFrame()}
        damping = sum(float(np.sum(x.default_damping_vector())) for x in joints)
        out += [Reading(item, "kind", kind), Reading(item, "bodies", f"{j.body_i} → {j.body_j}"),
                Reading(item, "damping", damping)]
        for side, body, _, _ in joint_sides(j):
            X = ends[body]
            point, R = X.translation(), X.rotation().matrix()
            out += [Reading(item, f"point {side} {c}", float(point[k])) for k, c in enumerate("xyz")]
            for col in axis_columns(j.kind):
                axis = _drake_axis(joints, j.kind, body == tj.parent, R, col)
                out += [Reading(item, f"axis {side} {'xyz'[col]}{c}", float(axis[k])) for k, c in enumerate("xyz")]
        limits += [x.position_lower_limits() for x in joints] + [-x.position_upper_limits() for x in joints]
    for c in model.topo.cuts:
        item = joint_item(c.name)
        how = {"spherical": "a ball constraint", "revolute": "two ball constraints along the axis",
               "universal": "a ball and a distance constraint", "fixed": "a weld constraint"}[c.kind]
        out += [Reading(item, "kind", c.kind, f"closed by {how}", "set"),
                Reading(item, "bodies", f"{c.body_i} → {c.body_j}", "", "set"),
                Reading(item, "damping", float(c.damping), "", "set")]
        for side, _, point, frame in joint_sides(c):
            out += [Reading(item, f"point {side} {n}", float(point[k]), "", "set") for k, n in enumerate("xyz")]
            for col in axis_columns(c.kind):
                out += [Reading(item, f"axis {side} {'xyz'[col]}{n}", float(frame[k, col]), "", "set")
                        for k, n in enumerate("xyz")]
    names = {int(body.index()): name for name, body in model.bodies.items()}
    springs = [plant.get_force_element(ForceElementIndex(k)) for k in range(plant.num_force_elements())]
    springs = [f for f in springs if isinstance(f, LinearSpringDamper)]
    for spring, element in zip(system.springs, springs):        # added in the scene's order
        item = f"spring {spring.name}"
        out += [Reading(item, "bodies", f"{names[int(element.bodyA().index())]} → "
                                        f"{names[int(element.bodyB().index())]}"),
                Reading(item, "stiffness", float(element.stiffness())),
                Reading(item, "free length", float(element.free_length())),
                Reading(item, "damping", float(element.damping()))]
        for end, point in (("a", element.p_AP()), ("b", element.p_BQ())):
            out += [Reading(item, f"point {end} {c}", float(point[k])) for k, c in enumerate("xyz")]
    g = plant.gravity_field().gravity_vector()
    out += [Reading(SCENE, f"gravity {c}", float(g[k])) for k, c in enumerate("xyz")]
    out.append(Reading(SCENE, "contacts", "off" if plant.num_collision_geometries() == 0 else
                       f"{plant.num_collision_geometries()} collision geometries"))
    finite = [v for v in np.concatenate(limits) if np.isfinite(v)] if limits else []
    out.append(Reading(SCENE, "joint limits", "none" if not finite else f"{len(finite)} finite limits"))
    return out


def _drake_axis(joints, kind: str, on_parent: bool, R: np.ndarray, col: int) -> np.ndarray:
    """A joint frame's axis as Drake holds it, in the body's axes: a hinge
    or slide's own axis (`revolute_axis`, `translation_axis`, in its
    frames), a universal joint's pin (Fx on the parent, My on the child), a
    planar joint's normal and a weld's frame columns."""
    if kind == "universal":
        return R[:, 0] if on_parent else R[:, 1]
    if kind == "revolute":
        return R @ joints[0].revolute_axis()
    if kind == "prismatic":
        return R @ joints[0].translation_axis()
    if kind == "cylindrical":
        # the slide's axis on the parent, the turn's on the child (the massless body between)
        return R @ (joints[0].translation_axis() if on_parent else joints[1].revolute_axis())
    return R[:, col]


def audit_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the Drake plant the adapter builds for `system`."""
    model = built(system, times, settings)[0]
    return audit(expected_spatial(system), read_spatial(model))
