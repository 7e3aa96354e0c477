"""Audit of the Exudyn system built for a spatial scene: what it holds, read
back through Exudyn's getters (`GetObject`, `GetMarker`, `GetLoad`, and the
assembled markers' and nodes' outputs) and set against the scene's
expectations (`mechval.records.spatial_audit.expected_spatial`) with the
core audit's verdicts (`mechval.records.audit.audit`).

Conversions to the scene's conventions: an `ObjectRigidBody`'s inertia is
about its node, the body frame's origin: Steiner back to the centre of
mass. A joint marker's point and frame are its world `Position` and
`RotationMatrix` outputs in the assembled start state, taken into its
body's axes with the body node's pose, p_B = Rᵀ·(p_W − o), A_B = Rᵀ·A_W
(read so, not from `localHT`: Exudyn 1.13.6's `GetMarker` reports a
marker given by `localHT` with `localPosition` 0 beside it). A joint's kind
is its `constrainedAxes`; its axes are the ones Exudyn leaves free: z of
both marker frames, or for the universal joint the y of marker 0's frame
and the z of marker 1's (its constraint y0·z1 = 0). A joint's damping is
the `ObjectConnectorCoordinateSpringDamper` whose relative coordinate
marker joins its bodies about or along its axis. Gravity is each body's
m·g load (at its centre of mass) over its mass.

Drives and torque laws, body loads and the solver's settings are not
audited yet.
"""

from __future__ import annotations

from typing import Any, Mapping

import exudyn as exu
import numpy as np
import pandas as pd

from mechval.model.mechanism import GROUND
from mechval.records.audit import AUDIT_RTOL, SCENE, Reading, audit, body_item, joint_item
from mechval.records.spatial_audit import INERTIA, axis_columns, expected_spatial, joint_sides
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.exudyn.spatial import prepare_spatial
from mechval.engines.exudyn.spatial_model import CONSTRAINED_AXES, SpatialModel

OUTPUT = exu.OutputVariableType
KINDS = {axes: kind for kind, axes in CONSTRAINED_AXES.items()}
#: Per kind, the marker frames' columns that carry the scene's axis z (or
#: x) on body_i (marker 0) and body_j (marker 1).
AXIS_COLUMN = {"universal": ({2: 1}, {2: 2})}
#: Item types a spatial model is made of: anything else is listed as such.
KNOWN = {"Ground", "RigidBody", "JointGeneric", "ConnectorCoordinate", "ConnectorCoordinateSpringDamper",
         "ConnectorSpringDamper"}


def audit_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the Exudyn system the adapter builds for `system`."""
    return audit(expected_spatial(system), read_spatial(prepare_spatial(system, times, settings)[0], system))


class _Poses:
    """Each object's body frame in the assembled start state (node output)."""

    def __init__(self, model: SpatialModel):
        self.mbs = model.mbs
        self.name = {int(number): name for name, number in model.objects.items()}

    def pose(self, body_number: int) -> tuple[np.ndarray, np.ndarray]:
        item = self.mbs.GetObject(body_number)
        if item["objectType"] == "Ground":
            return np.zeros(3), np.eye(3)
        node = int(item["nodeNumber"])
        return (np.asarray(self.mbs.GetNodeOutput(node, OUTPUT.Position), float),
                np.asarray(self.mbs.GetNodeOutput(node, OUTPUT.RotationMatrix), float).reshape(3, 3))

    def point(self, marker: int) -> tuple[str, np.ndarray]:
        """(body, the marker's point in the body's axes)."""
        number = int(self.mbs.GetMarker(marker)["bodyNumber"])
        origin, R = self.pose(number)
        return self.name[number], R.T @ (np.asarray(self.mbs.GetMarkerOutput(marker, OUTPUT.Position), float) - origin)

    def frame(self, marker: int) -> np.ndarray:
        """The marker's frame in its body's axes."""
        R = self.pose(int(self.mbs.GetMarker(marker)["bodyNumber"]))[1]
        return R.T @ np.asarray(self.mbs.GetMarkerOutput(marker, OUTPUT.RotationMatrix), float).reshape(3, 3)


def read_spatial(model: SpatialModel, system: SpatialSystem) -> list[Reading]:
    mbs, poses, out = model.mbs, _Poses(model), []
    objects = [mbs.GetObject(k) for k in range(mbs.systemData.NumberOfObjects())]
    for name, number in model.objects.items():
        if name == GROUND:
            continue
        item, body = objects[number], body_item(name)
        m, c = float(item["mass"]), np.asarray(item["centerOfMass"], float)
        xx, yy, zz, yz, xz, xy = np.asarray(item["inertia"], float)
        I = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) - m * ((c @ c) * np.eye(3) - np.outer(c, c))
        note = f"ObjectRigidBody on a {mbs.GetNode(int(item['nodeNumber']))['nodeType']} node at the body origin"
        out.append(Reading(body, "mass", m, note))
        out += [Reading(body, f"com {n}", float(c[k])) for k, n in enumerate("xyz")]
        out += [Reading(body, q, float(I[r, col]), "Steiner from the node") for q, r, col in INERTIA]
    axes_of = {}
    for joint in system.joints:
        number = model.joint_objects[joint.name]
        item, name = objects[number], joint_item(joint.name)
        kind = KINDS.get(tuple(int(a) for a in item["constrainedAxes"]), str(item["constrainedAxes"]))
        markers = [int(k) for k in item["markerNumbers"]]
        ends = [poses.point(k) for k in markers]
        out += [Reading(name, "kind", kind, f"ObjectJointGeneric, constrainedAxes {list(item['constrainedAxes'])}"),
                Reading(name, "bodies", f"{ends[0][0]} → {ends[1][0]}")]
        columns = AXIS_COLUMN.get(kind, ({}, {}))
        for (side, _, _, _), marker, (_, point), turn in zip(joint_sides(joint), markers, ends, columns):
            frame = poses.frame(marker)
            out += [Reading(name, f"point {side} {n}", float(point[k])) for k, n in enumerate("xyz")]
            for col in axis_columns(kind):
                axis = frame[:, turn.get(col, col)]
                out += [Reading(name, f"axis {side} {'xyz'[col]}{n}", float(axis[k])) for k, n in enumerate("xyz")]
        axes_of[joint.name] = (ends[0][0], ends[1][0], poses.frame(markers[0])[:, 2], kind)
    out += _dampers(model, system, objects, axes_of)
    out += _springs(model, system, objects, poses)
    out += _scene(model, system, objects, poses)
    return out


def _dampers(model: SpatialModel, system: SpatialSystem, objects: list, axes_of: dict) -> list[Reading]:
    """Each joint's damping: the coordinate spring-dampers on a relative
    coordinate of its two bodies about (revolute) or along (prismatic)
    its axis; one that fits no joint is listed as another damper."""
    mbs, found, stray = model.mbs, {j.name: [] for j in system.joints}, []
    for k, item in enumerate(objects):
        if item["objectType"] != "ConnectorCoordinateSpringDamper":
            continue
        marker = mbs.GetMarker(int(item["markerNumbers"][1]))
        # Exudyn 1.13.6's GetMarker names a MarkerBodiesRelativeRotationCoordinate
        # "BodiesRelativeTranslationCoordinate"; only the rotation one has an unwrapping node.
        turns = "nodeNumber" in marker
        bodies = tuple(model_name(model, int(b)) for b in marker.get("bodyNumbers", ()))
        axis = np.asarray(marker.get("axis0", np.zeros(3)), float)
        joint = next((name for name, (bi, bj, zi, kind) in axes_of.items()
                      if (bi, bj) == bodies and kind == ("revolute" if turns else "prismatic")
                      and np.allclose(axis, zi, rtol=0, atol=AUDIT_RTOL)), None)
        if joint is None or float(item["stiffness"]) != 0.0:
            stray.append(f"object {k} (stiffness {item['stiffness']}, damping {item['damping']})")
        else:
            found[joint].append(float(item["damping"]))
    out = [Reading(joint_item(name), "damping", float(sum(values)),
                   "ObjectConnectorCoordinateSpringDamper on the joint's coordinate" if values else "")
           for name, values in found.items()]
    if stray:
        out.append(Reading(SCENE, "other dampers", "; ".join(stray)))
    return out


def model_name(model: SpatialModel, number: int) -> str:
    return next((name for name, k in model.objects.items() if int(k) == number), f"object {number}")


def _springs(model: SpatialModel, system: SpatialSystem, objects: list, poses: _Poses) -> list[Reading]:
    """`ObjectConnectorSpringDamper`s, in the scene's order (the build's)."""
    elements = [item for item in objects if item["objectType"] == "ConnectorSpringDamper"]
    out = []
    for k, item in enumerate(elements):
        name = f"spring {system.springs[k].name}" if k < len(system.springs) else f"spring object {k}"
        (a, pa), (b, pb) = (poses.point(int(m)) for m in item["markerNumbers"])
        out += [Reading(name, "bodies", f"{a} → {b}"), Reading(name, "stiffness", float(item["stiffness"])),
                Reading(name, "free length", float(item["referenceLength"]), "referenceLength"),
                Reading(name, "damping", float(item["damping"]))]
        for end, point in (("a", pa), ("b", pb)):
            out += [Reading(name, f"point {end} {c}", float(point[i])) for i, c in enumerate("xyz")]
    return out


def _scene(model: SpatialModel, system: SpatialSystem, objects: list, poses: _Poses) -> list[Reading]:
    """Gravity from the bodies' m·g loads (the first massive body's; any
    body whose load gives another field, or sits off its centre of mass,
    is listed), contacts and limits (no such items)."""
    mbs, fields, out = model.mbs, {}, []
    for body in system.bodies:
        if body.mass <= 0:
            continue
        load = model.gravity_loads.get(body.name)
        if load is None:
            fields[body.name] = np.zeros(3)
            continue
        item = mbs.GetLoad(load)
        fields[body.name] = np.asarray(item["loadVector"], float) / float(objects[model.objects[body.name]]["mass"])
        at = poses.point(int(item["markerNumber"]))[1]
        if not np.allclose(at, body.com, rtol=0, atol=AUDIT_RTOL * max(1.0, float(np.linalg.norm(body.com)))):
            out.append(Reading(body_item(body.name), "gravity load point", str(at.tolist())))
    g = next(iter(fields.values()), np.zeros(3))
    out += [Reading(SCENE, f"gravity {c}", float(g[k]), "each body's m·g load over its mass")
            for k, c in enumerate("xyz")]
    out += [Reading(body_item(name), "gravity", str(v.tolist())) for name, v in fields.items()
            if not np.allclose(v, g, rtol=0, atol=AUDIT_RTOL * 9.81)]
    kinds = [item["objectType"] for item in objects]
    contacts = [k for k in kinds if "Contact" in k]
    out.append(Reading(SCENE, "contacts", "off" if not contacts else "; ".join(contacts),
                       f"no contact objects ({len(kinds)} objects)"))
    out.append(Reading(SCENE, "joint limits", "none", "ObjectJointGeneric has no limits, and no other joint items"))
    others = sorted({k for k in kinds if k not in KNOWN})
    if others:
        out.append(Reading(SCENE, "other items", "; ".join(others)))
    return out
