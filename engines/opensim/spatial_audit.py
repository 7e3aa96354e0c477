"""Audit of the OpenSim model built for a spatial scene (the run's own
`spatial_run.prepare`, charted at the start): what it holds, read back
through OpenSim's getters and set against the scene's expectations
(`mechval.records.spatial_audit.expected_spatial`) with the core audit's
verdicts (`mechval.records.audit.audit`).

Readings and their conversions to the scene's conventions:
- Bodies: `Body.getMass`, `getMassCenter`, `getInertia` (moments and
  products about the mass centre, body axes: the scene's terms).
- Tree joints: the class gives the kind (a `CustomJoint` with one
  rotation and one translation about the same axis is cylindrical); each
  side's `PhysicalOffsetFrame` its body (`getParentFrame`) and its point
  and axes (`getOffsetTransform`, in the body's axes), with OpenSim's own
  axis of the class: z of a `PinJoint` and a `PlanarJoint`'s normal, x of
  a `SliderJoint`, the parent frame's x and the child frame's y of a
  `UniversalJoint`, a `CustomJoint`'s rotation axis; a `WeldJoint`'s frame
  columns. A `BallJoint`'s frames are its chart (no axis).
- Loop closures: a `PointConstraint`'s locations are the joint points; a
  revolute closure's axis is the direction from its first point to its
  second, a universal closure's pins from its point to the
  `ConstantDistanceConstraint`'s locations (whose distance keeps them at
  right angles: a row says if it does not); a `WeldConstraint`'s frames'
  offsets are the joint frames.
- Dampers: the `SpringGeneralizedForce`s of zero stiffness on a joint's
  coordinate (rotational for a revolute joint, translational for a slide);
  one that fits no joint is listed. Spring-dampers: an
  `ExpressionBasedPointToPointForce`'s bodies and points, and k, ℓ0 and c
  parsed from its expression.
- Gravity (`getGravity`), contact geometry, clamped coordinates and
  force types beyond the build's are listed.

Drives, torque laws and body loads are not audited yet.
"""

from __future__ import annotations

import re
from typing import Any, Mapping

import numpy as np
import opensim as osim
import pandas as pd

from mechval.model.mechanism import GROUND
from mechval.records.audit import AUDIT_RTOL, SCENE, Reading, audit, body_item, joint_item
from mechval.records.spatial_audit import INERTIA, axis_columns, expected_spatial, joint_sides
from mechval.reference.spatial.system import SpatialJoint, SpatialSystem

from mechval.engines.opensim.spatial_model import DAMPED, SpatialModel
from mechval.engines.opensim.spatial_run import prepare, start_world
from mechval.engines.opensim.model import quiet

KINDS = {"PinJoint": "revolute", "SliderJoint": "prismatic", "UniversalJoint": "universal",
         "PlanarJoint": "planar", "WeldJoint": "fixed", "BallJoint": "spherical", "FreeJoint": "free"}
#: OpenSim's axis per class: its column in the (parent, child) frame.
AXIS = {"PinJoint": (2, 2), "PlanarJoint": (2, 2), "SliderJoint": (0, 0), "UniversalJoint": (0, 1)}
FORCES = {"SpringGeneralizedForce", "CoordinateActuator", "ExpressionBasedPointToPointForce", "PrescribedForce"}
#: The build's expression k*(d-(l0))+c*ddot (`spatial_model._add_spring`).
SPRING = re.compile(r"^(?P<k>[^*]+)\*\(d-\((?P<l0>[^)]+)\)\)\+(?P<c>[^*]+)\*ddot$")


def audit_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the OpenSim model the adapter builds for `system`."""
    times = np.asarray(times, dtype=float)
    built, _ = prepare(system, start_world(system, times), float(times[0]), settings, times)
    return audit(expected_spatial(system), read_spatial(built, system))


def vec(v) -> np.ndarray:
    return np.array([float(v[k]) for k in range(3)])


def matrix(R) -> np.ndarray:
    return np.array([[R.get(i, k) for k in range(3)] for i in range(3)])


class _Names:
    """OpenSim body names ↔ the scene's."""

    def __init__(self, built: SpatialModel):
        self.scene = {b.getName(): name for name, b in built.bodies.items()} | {"ground": GROUND}

    def __call__(self, name: str) -> str:
        return self.scene.get(name, f"opensim {name}")

    def offset(self, frame) -> tuple[str, np.ndarray, np.ndarray]:
        """(body, point, rotation in the body's axes) of an offset frame."""
        offset = osim.PhysicalOffsetFrame.safeDownCast(frame)
        if offset is None:          # the body itself
            return self(frame.getName()), np.zeros(3), np.eye(3)
        X = offset.getOffsetTransform()
        return self(offset.getParentFrame().getName()), vec(X.p()), matrix(X.R())


def read_spatial(built: SpatialModel, system: SpatialSystem) -> list[Reading]:
    model, names, out = built.model, _Names(built), []
    with quiet():
        for b in system.bodies:
            body, item = model.getBodySet().get(built.bodies[b.name].getName()), body_item(b.name)
            I = body.getInertia()
            (xx, yy, zz), (xy, xz, yz) = vec(I.getMoments()), vec(I.getProducts())
            tensor = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
            out.append(Reading(item, "mass", float(body.getMass()), f"Body {body.getName()}"))
            out += [Reading(item, f"com {n}", float(v)) for n, v in zip("xyz", vec(body.getMassCenter()))]
            out += [Reading(item, q, float(tensor[r, c])) for q, r, c in INERTIA]
        for joint in system.joints:
            if joint.name in built.tree:
                out += _tree_joint(model.getJointSet().get(built.tree[joint.name]), joint, names)
            else:
                out += _closure(model, built.closures[joint.name], joint, names)
        for name, mob in built.mobilizers.items():
            if mob.kind == "free":
                out.append(Reading(body_item(mob.child), "free joint", f"FreeJoint {name}",
                                   "a body with no joint to the ground hangs on a FreeJoint", "note"))
        out += _dampers(model, built, system)
        out += _springs(model, system, names)
        out += _scene(model)
    return out


def _sides(joint: SpatialJoint, frames: dict[str, tuple[np.ndarray, np.ndarray]], axes: dict[str, np.ndarray],
           item: str, note: str = "") -> list[Reading]:
    out = []
    for side, body, _, _ in joint_sides(joint):
        point, R = frames[body]
        out += [Reading(item, f"point {side} {c}", float(point[k]), note) for k, c in enumerate("xyz")]
        for col in axis_columns(joint.kind):
            a = axes[body] if col == 2 and body in axes else R[:, col]
            out += [Reading(item, f"axis {side} {'xyz'[col]}{c}", float(a[k]), note) for k, c in enumerate("xyz")]
    return out


def _bodies(joint: SpatialJoint, found: list[str]) -> str:
    """body_i → body_j when the two bodies found are the joint's."""
    if sorted(found) == sorted([joint.body_i, joint.body_j]):
        return f"{joint.body_i} → {joint.body_j}"
    return " → ".join(found)


def _custom_axis(osim_joint) -> tuple[str, np.ndarray | None]:
    """A CustomJoint's kind and rotation axis (parent frame): cylindrical
    when one rotation and one translation, with coordinates, share an axis."""
    transform = osim.CustomJoint.safeDownCast(osim_joint).getSpatialTransform()
    moving = [(k, vec(transform.getTransformAxis(k).getAxis())) for k in range(6)
              if transform.getTransformAxis(k).getCoordinateNamesInArray().getSize() > 0]
    turns, slides = [a for k, a in moving if k < 3], [a for k, a in moving if k >= 3]
    if len(turns) == 1 and len(slides) == 1 and np.allclose(turns[0], slides[0], rtol=0, atol=AUDIT_RTOL):
        return "cylindrical", turns[0]
    return f"CustomJoint ({len(turns)} rotations, {len(slides)} translations)", None


def _tree_joint(osim_joint, joint: SpatialJoint, names: _Names) -> list[Reading]:
    item, cls = joint_item(joint.name), osim_joint.getConcreteClassName()
    (parent, pp, pR), (child, cp, cR) = names.offset(osim_joint.getParentFrame()), names.offset(osim_joint.getChildFrame())
    frames, axes = {parent: (pp, pR), child: (cp, cR)}, {}
    kind = KINDS.get(cls, cls)
    if cls == "CustomJoint":
        kind, axis = _custom_axis(osim_joint)
        if axis is not None:
            axes = {parent: pR @ axis, child: cR @ axis}
    elif cls in AXIS:
        axes = {parent: pR[:, AXIS[cls][0]], child: cR[:, AXIS[cls][1]]}
    out = [Reading(item, "kind", kind, f"{cls} {osim_joint.getName()}"),
           Reading(item, "bodies", _bodies(joint, [parent, child]))]
    if set(frames) != {joint.body_i, joint.body_j}:
        return out
    note = "a BallJoint's frames are its chart" if cls == "BallJoint" else ""
    return out + _sides(joint, frames, axes, item, note)


def _closure(model, parts: list, joint: SpatialJoint, names: _Names) -> list[Reading]:
    item = joint_item(joint.name)
    held = [model.getConstraintSet().get(p.getName()) for p in parts]
    classes = [c.getConcreteClassName() for c in held]
    if classes == ["WeldConstraint"]:
        weld = osim.WeldConstraint.safeDownCast(held[0])
        ends = [names.offset(weld.getFrame1()), names.offset(weld.getFrame2())]
        frames = {body: (p, R) for body, p, R in ends}
        return [Reading(item, "kind", "fixed", "closed by a WeldConstraint"),
                Reading(item, "bodies", _bodies(joint, [e[0] for e in ends]))] + \
            _sides(joint, frames, {}, item, "the WeldConstraint's frames")
    points = []
    for c in held:
        typed = osim.PointConstraint.safeDownCast(c) or osim.ConstantDistanceConstraint.safeDownCast(c)
        points.append([(names(typed.getConnectee(s).getName()), vec(loc))
                       for s, loc in (("body_1", typed.get_location_body_1()), ("body_2", typed.get_location_body_2()))])
    kind = {("PointConstraint",): "spherical", ("PointConstraint", "PointConstraint"): "revolute",
            ("PointConstraint", "ConstantDistanceConstraint"): "universal"}.get(tuple(classes), " + ".join(classes))
    frames = {body: (p, np.eye(3)) for body, p in points[0]}
    out = [Reading(item, "kind", kind, f"closed by {' + '.join(classes)}"),
           Reading(item, "bodies", _bodies(joint, [b for b, _ in points[0]]))]
    axes = {}
    if len(points) == 2:
        for (body, p), (other, q) in zip(points[0], points[1]):
            axes[body] = (q - p) / np.linalg.norm(q - p) if body == other else np.full(3, np.nan)
    if kind == "universal":
        arms = [np.linalg.norm(q - p) for (_, p), (_, q) in zip(points[0], points[1])]
        distance = float(osim.ConstantDistanceConstraint.safeDownCast(held[1]).get_constant_distance())
        if abs(distance - np.hypot(*arms)) > AUDIT_RTOL * distance:
            out.append(Reading(item, "pins at right angles", f"distance {distance!r} for arms {arms}"))
    if set(frames) != {joint.body_i, joint.body_j}:
        return out
    note = "the axis from the first constraint point to the second" if axes else ""
    return out + _sides(joint, frames, axes, item, note)


def _dampers(model, built: SpatialModel, system: SpatialSystem) -> list[Reading]:
    """Each joint's damping from the zero-stiffness SpringGeneralizedForces
    on its coordinate of the right motion; others listed."""
    scene_of = {osim_name: scene for scene, osim_name in built.tree.items()}
    found, stray = {j.name: 0.0 for j in system.joints}, []
    forces = model.getForceSet()
    for k in range(forces.getSize()):
        damper = osim.SpringGeneralizedForce.safeDownCast(forces.get(k))
        if damper is None:
            continue
        coordinate = model.getCoordinateSet().get(damper.get_coordinate())
        joint = scene_of.get(coordinate.getJoint().getName())
        motion = {1: "revolute", 2: "slide"}.get(int(coordinate.getMotionType()))
        fits = joint is not None and motion == ("revolute" if system.joint(joint).kind == "revolute" else "slide")
        if fits and damper.getStiffness() == 0.0:
            found[joint] += float(damper.getViscosity())
        else:
            stray.append(f"{damper.getName()} on {damper.get_coordinate()}")
    out = []
    for joint in system.joints:
        value = found[joint.name]
        if not value and joint.damping and joint.kind not in DAMPED:
            out.append(Reading(joint_item(joint.name), "damping", "none built",
                               f"the scene's damper along zi meets no slide at a {joint.kind} joint: no effect", "note"))
        else:
            out.append(Reading(joint_item(joint.name), "damping", value,
                               "SpringGeneralizedForce on its coordinate" if value else ""))
    return out + ([Reading(SCENE, "other dampers", "; ".join(stray))] if stray else [])


def _springs(model, system: SpatialSystem, names: _Names) -> list[Reading]:
    """ExpressionBasedPointToPointForces, in the scene's order (the build's)."""
    forces = model.getForceSet()
    springs = [f for f in (osim.ExpressionBasedPointToPointForce.safeDownCast(forces.get(k))
                           for k in range(forces.getSize())) if f is not None]
    out = []
    for k, force in enumerate(springs):
        item = f"spring {system.springs[k].name}" if k < len(system.springs) else f"spring {force.getName()}"
        parsed = SPRING.match(force.get_expression())
        out.append(Reading(item, "bodies", f"{names(force.get_body1())} → {names(force.get_body2())}",
                           f"expression {force.get_expression()}"))
        for quantity, key in (("stiffness", "k"), ("free length", "l0"), ("damping", "c")):
            out.append(Reading(item, quantity, float(parsed[key]) if parsed else "not k*(d-(l0))+c*ddot",
                               "parsed from the expression"))
        for end, point in (("a", force.get_point1()), ("b", force.get_point2())):
            out += [Reading(item, f"point {end} {c}", float(v)) for c, v in zip("xyz", vec(point))]
    return out


def _scene(model) -> list[Reading]:
    g = vec(model.getGravity())
    out = [Reading(SCENE, f"gravity {c}", float(g[k]), "Model.getGravity") for k, c in enumerate("xyz")]
    forces = model.getForceSet()
    classes = [forces.get(k).getConcreteClassName() for k in range(forces.getSize())]
    contacts = model.getContactGeometrySet().getSize()
    out.append(Reading(SCENE, "contacts", "off" if contacts == 0 else f"{contacts} contact geometries",
                       "no contact geometry"))
    coordinates = model.getCoordinateSet()
    clamped = [coordinates.get(k).getName() for k in range(coordinates.getSize())
               if coordinates.get(k).getDefaultClamped()]
    clamped += [c for c in classes if "Limit" in c]
    out.append(Reading(SCENE, "joint limits", "none" if not clamped else "; ".join(clamped),
                       "no coordinate clamped to its range, no limit force"))
    others = sorted({c for c in classes if c not in FORCES})
    if others:
        out.append(Reading(SCENE, "other forces", "; ".join(others)))
    return out
