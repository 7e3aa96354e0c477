"""Audit of the assembled Exudyn model (see `mechval.records.audit`).

The model and the solver settings are built by the adapter's own
`run.prepare` (`model.build_model`, `simulation_settings`) and
read back with `GetNode`/`GetObject`/`GetMarker`/`GetLoad`. Mechanism bodies
are found through the model's sensors (`ExudynModel.body_sensors` → node →
the rigid body on it), joints through `joint_sensors`, the drive through
`drive_sensor`; every other item is accounted for by its type.

Conversion to the Mechanism's conventions: a body's pose at the start is its
node's reference coordinates plus initial displacements (x, y, θ of the
reference point); the centre of mass is that point plus R(θ)·centerOfMass,
and izz is `inertia` (about the reference point) minus m·|centerOfMass|²;
a marker's world point is the same transform of its localPosition (the
ground's: its reference position and rotation). World points are expressed
in the bodies' frames at the reference pose of the model's start t0
(`mechval.records.audit.to_body`). A coordinate spring-damper is matched to the
joint whose relative coordinate it acts on: the rotation coordinates of the
joint's two bodies (revolute), or their relative translation along the
joint's axis (prismatic). The drive law is read by evaluating the drive
constraint's offset user function (a quadratic: three points determine it,
a fourth checks it) and its time derivative. A torque law is read from its
two loads (see `Reader.torque_law`), and a joint integrated from an initial
value from the coordinate constraints on its coordinate (there must be none).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
import pandas as pd

from mechval.records.audit import (ModelReader, Reading, SCENE, axis_readings, bodies_text, body_item, drive_item, force_item,
                           joint_item, listing, point_readings, to_body, torque_law_item)
from mechval.model.kinematics import rotate
from mechval.model.mechanism import GROUND, BodyTorque, Drive, Joint, Mechanism, SpringDamper, TorqueLaw

from mechval.engines.exudyn.run import prepare
from mechval.engines.exudyn.model import ExudynModel, TorqueLawLoad, torque_law_load_names

ENGINE = "exudyn"
#: Item types the adapter's model is made of; anything else is listed.
KNOWN_OBJECTS = {"Ground", "RigidBody2D", "JointRevolute2D", "JointPrismatic2D", "ConnectorCoordinate",
                 "ConnectorCoordinateSpringDamper", "ConnectorSpringDamper"}
#: Relative agreement for the drive's consistency checks (rounding only).
ROUNDING = 1e-12


def audit_model(mech: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the Exudyn model the adapter builds."""
    model, simulation, t0 = prepare(mech, times, settings)
    return Reader(mech, model, t0, np.asarray(times, dtype=float), settings, simulation).table()


class Reader(ModelReader):
    """Readings of one assembled system in its initial state."""

    def __init__(self, mech: Mechanism, model: ExudynModel, t0: float, times: np.ndarray,
                 settings: Mapping[str, Any], simulation):
        self.mech, self.model, self.mbs, self.start, self.t0 = mech, model, model.mbs, model.start, t0
        self.settings, self.simulation = settings, simulation     # the solver's, for the notes
        self.times = times      # the run's output instants
        data = model.mbs.systemData
        self.objects = [self.mbs.GetObject(i) for i in range(data.NumberOfObjects())]
        self.markers = [self.mbs.GetMarker(i) for i in range(data.NumberOfMarkers())]
        self.loads = [self.mbs.GetLoad(i) for i in range(data.NumberOfLoads())]
        node_body = {int(self.mbs.GetSensor(sensors["q"])["nodeNumber"]): body
                     for body, sensors in model.body_sensors.items()}
        self.node_body = node_body | {i: GROUND for i in range(data.NumberOfNodes())
                                      if self.mbs.GetNode(i)["nodeType"] == "PointGround"}
        self.object_body = {i: node_body[int(o["nodeNumber"])] for i, o in enumerate(self.objects)
                            if o["objectType"] == "RigidBody2D" and int(o["nodeNumber"]) in node_body}
        self.object_body |= {i: GROUND for i, o in enumerate(self.objects) if o["objectType"] == "Ground"}
        self.used: set[int] = set()     # objects accounted for
        self.used_loads: set[int] = set()

    def readings(self) -> list[Reading]:
        out = [r for body in self.mech.bodies for r in self.body(body.name)]
        out += [r for joint in self.mech.joints for r in self.joint(joint)]
        dampers = self.dampers()[0]
        out += [Reading(joint_item(j.name), "damping", dampers.get(j.name, 0.0),
                        "ConnectorCoordinateSpringDamper on the joint's relative coordinate"
                        if j.name in dampers else "no spring-damper on this joint's coordinate")
                for j in self.mech.joints]
        out += [r for drive in self.mech.drives for r in self.drive(drive)]
        out += [self.prescribed(value.joint) for value in self.mech.initial_values]
        out += [r for force in self.mech.forces for r in self.force(force)]
        out += [r for law in self.mech.torque_drives for r in self.torque_law(law)]
        return out + self.scene() + self.notes()

    # -- bodies and points --------------------------------------------------------------

    def frame(self, number: int) -> tuple[np.ndarray, float]:
        """World position and angle of an object's reference point."""
        o = self.objects[number]
        if o["objectType"] == "Ground":
            rotation = np.asarray(o["referenceRotation"])
            return np.asarray(o["referencePosition"], dtype=float)[:2], float(np.arctan2(rotation[1, 0], rotation[0, 0]))
        node = self.mbs.GetNode(int(o["nodeNumber"]))
        q = np.asarray(node["referenceCoordinates"]) + np.asarray(node["initialCoordinates"])
        return q[:2], float(q[2])

    def world(self, number: int, local) -> np.ndarray:
        origin, theta = self.frame(number)
        return origin + np.array(rotate(theta, np.asarray(local, dtype=float)[:2]))

    def body(self, name: str) -> list[Reading]:
        number = next(i for i, b in self.object_body.items()
                      if b == name and self.objects[i]["objectType"] == "RigidBody2D")
        self.used.add(number)
        o, item = self.objects[number], body_item(name)
        offset = np.asarray(o["centerOfMass"], dtype=float)
        com = to_body(self.start, name, self.world(number, offset))
        planar = "2-D rigid body: no out-of-plane inertia"
        return [Reading(item, "mass", float(o["mass"])),
                Reading(item, "com x", float(com[0])), Reading(item, "com y", float(com[1])),
                Reading(item, "izz", float(o["inertia"] - o["mass"] * offset @ offset),
                        "inertia about the reference point − m·|centerOfMass|²"),
                Reading(item, "ixz", 0.0, planar), Reading(item, "iyz", 0.0, planar)]

    def marker_point(self, number: int) -> tuple[str, np.ndarray]:
        m = self.markers[number]
        number = int(m["bodyNumber"])
        return self.object_body.get(number, f"object {number}"), self.world(number, m["localPosition"])

    def rotation_of(self, marker: int) -> str | None:
        """The body whose rotation a coordinate marker measures (None if it
        measures anything else)."""
        m = self.markers[marker]
        if m["markerType"] != "NodeCoordinate":
            return None
        body = self.node_body.get(int(m["nodeNumber"]))
        return body if body == GROUND or (body is not None and m["coordinate"] == 2) else None

    # -- joints -------------------------------------------------------------------

    def joint(self, joint: Joint) -> list[Reading]:
        number = int(self.mbs.GetSensor(self.model.joint_sensors[joint.name])["objectNumber"])
        self.used.add(number)
        o, item = self.objects[number], joint_item(joint.name)
        kind = {"JointRevolute2D": "revolute", "JointPrismatic2D": "prismatic"}.get(o["objectType"], o["objectType"])
        if not o["activeConnector"]:
            kind += " (inactive)"
        sides = [self.marker_point(int(k)) for k in o["markerNumbers"]]
        anchors = dict(sides)
        readings = [Reading(item, "kind", kind, o["objectType"]),
                    Reading(item, "bodies", bodies_text(joint, tuple(anchors)))]
        if o["objectType"] != "JointPrismatic2D":
            return readings + point_readings(self.mech, self.start, joint.name, anchors)
        # Marker 0 holds the axis; the translation constraint keeps marker 1
        # on the line through marker 0 normal to normalMarker1 (in marker 1's body).
        (body0, _), (body1, _) = sides
        normal = self.direction(body1, o["normalMarker1"])
        axis = self.direction(body0, o["axisMarker0"])
        line = np.array([-normal[1], normal[0]])
        crossing = abs(float(axis @ normal)) / (np.hypot(*axis) * np.hypot(*normal))
        rotation = ("locked" if o["constrainRotation"] and crossing <= ROUNDING else
                    "free" if not o["constrainRotation"] else f"locked with axis·normal = {crossing:.3g}")
        return readings + point_readings(
            self.mech, self.start, joint.name, anchors, line,
            "The point of the line (through marker 0, normal to normalMarker1) nearest to the Mechanism's point."
        ) + axis_readings(self.mech, self.start, joint.name, axis, "axisMarker0") + [
            Reading(item, "relative rotation", rotation, "constrainRotation, and axisMarker0 ⟂ normalMarker1 at the start")]

    def direction(self, body: str, local) -> np.ndarray:
        number = next((i for i, b in self.object_body.items() if b == body), None)
        if number is None:
            return np.asarray(local, dtype=float)[:2]
        return self.world(number, local) - self.world(number, (0.0, 0.0))

    # -- dampers ------------------------------------------------------------------

    def dampers(self) -> tuple[dict[str, float], list[str], list[str]]:
        """Damping per joint; spring-dampers that act on no joint's relative
        coordinate; and springs (any stiffness or spring user function)."""
        damping: dict[str, float] = {}
        other, springs = [], []
        for number, o in enumerate(self.objects):
            if o["objectType"] != "ConnectorCoordinateSpringDamper":
                continue
            self.used.add(number)
            if o["stiffness"] or o["springForceUserFunction"]:
                springs.append(f"object {number}: stiffness {o['stiffness']:g}"
                               + (", spring force user function" if o["springForceUserFunction"] else ""))
            if not o["activeConnector"] or not o["damping"]:
                continue
            joint, factor = self.damped_joint([int(k) for k in o["markerNumbers"]])
            if joint is None:
                other.append(f"object {number}: damping {o['damping']:g}")
            else:
                damping[joint] = damping.get(joint, 0.0) + o["damping"] * factor
        return damping, other, springs

    def damped_joint(self, markers: list[int]) -> tuple[str | None, float]:
        """(joint, factor) whose relative rate the coordinate pair measures:
        rotations of its two bodies, or the relative translation marker of
        a prismatic joint (factor |axis0|², the rate being axis0·Δv)."""
        rotations = [self.rotation_of(k) for k in markers]
        if None not in rotations:
            for j in self.mech.joints:
                if j.kind == "revolute" and set(rotations) == {j.body_i, j.body_j}:
                    return j.name, 1.0
            return None, 0.0
        relative = [self.markers[k] for k in markers if self.markers[k]["markerType"] == "BodiesRelativeTranslationCoordinate"]
        others = [k for k in markers if self.markers[k]["markerType"] != "BodiesRelativeTranslationCoordinate"]
        if len(relative) != 1 or [self.rotation_of(k) for k in others] != [GROUND]:
            return None, 0.0
        m = relative[0]
        bodies = [self.object_body.get(int(b)) for b in m["bodyNumbers"]]
        axis = np.asarray(m["axis0"], dtype=float)[:2]
        for j in self.mech.joints:
            if j.kind == "prismatic" and bodies == [j.body_i, j.body_j]:
                unit = np.asarray(j.axis) / np.hypot(*j.axis)
                if abs(axis[0] * unit[1] - axis[1] * unit[0]) <= ROUNDING * np.hypot(*axis):
                    return j.name, float(axis @ axis)
        return None, 0.0

    # -- drives -------------------------------------------------------------------

    def drive(self, drive: Drive) -> list[Reading]:
        """φ(t) from the coordinate constraint factor1·q1 − q0 = offset(t − t0):
        on the rotation displacements, θj − θi = offset + θj_ref − θi_ref
        when marker 0 measures body_i and marker 1 body_j; on a ground
        coordinate (0) and a relative translation marker along a prismatic
        joint's axis between its points (the slide itself), s = offset."""
        item = drive_item(self.mech, drive)
        number = int(self.mbs.GetSensor(self.model.drive_sensors[drive.name])["objectNumber"])
        self.used.add(number)
        o = self.objects[number]
        markers = [int(k) for k in o["markerNumbers"]]
        bodies = [self.rotation_of(k) for k in markers]
        if None in bodies:
            joint, base = self.slide_of(markers), 0.0
            what = "ObjectConnectorCoordinate on a ground coordinate and the slide along the joint's axis"
        else:
            pair = [j.name for j in self.mech.joints if j.kind == "revolute" and [j.body_i, j.body_j] == bodies]
            joint = pair[0] if pair else None
            what = "ObjectConnectorCoordinate on the two bodies' rotation coordinates"
            if joint is not None:
                j = self.mech.joint(joint)
                base = self.reference_angle(j.body_j) - self.reference_angle(j.body_i)
        label = joint if joint is not None else f"coordinates of markers {markers}"
        readings = [Reading(item, "joint", label if o["activeConnector"] else f"{label} (inactive)", what)]
        if joint is None or o["velocityLevel"]:
            return readings + ([Reading(item, "velocity level", "yes")] if o["velocityLevel"] else [])
        offset = o["offsetUserFunction"]["function"] if o["offsetUserFunction"] else (lambda *a: o["offset"])
        rate = o["offsetUserFunction_t"]["function"] if o["offsetUserFunction_t"] else None
        f = lambda tau: float(offset(self.mbs, tau, number, o["offset"]))
        c0, c1, c2 = f(0.0), (f(1.0) - f(-1.0)) / 2, (f(1.0) - 2 * f(0.0) + f(-1.0)) / 2
        t0, note = self.t0, "From the drive constraint's offset user function."
        readings += [Reading(item, "phi0", c0 - c1 * t0 + c2 * t0 * t0 + base, note),
                     Reading(item, "omega0", c1 - 2 * c2 * t0, note),
                     Reading(item, "alpha", 2 * c2, note)]
        size = max(abs(c0), abs(c1), abs(c2), 1.0)
        if abs(f(2.0) - (c0 + 2 * c1 + 4 * c2)) > ROUNDING * 4 * size:
            readings.append(Reading(item, "law", "not quadratic in t"))
        if rate is None or abs(float(rate(self.mbs, 0.0, number, o["offset"])) - c1) > ROUNDING * size:
            readings.append(Reading(item, "offset rate", "missing or not d/dt of the offset",
                                    "index-2 uses offsetUserFunction_t (without it the crank is held still)"))
        if o["factor1"] != 1.0:
            readings.append(Reading(item, "ratio", float(o["factor1"])))
        return readings

    def prescribed(self, joint: str) -> Reading:
        """The coordinate constraints on a joint's relative coordinate (its
        two bodies' rotations, in either order, or its slide)."""
        found = []
        for number, o in enumerate(self.objects):
            if o["objectType"] != "ConnectorCoordinate":
                continue
            markers = [int(k) for k in o["markerNumbers"]]
            bodies = [self.rotation_of(k) for k in markers]
            on = self.slide_of(markers) if None in bodies else next(
                (j.name for j in self.mech.joints if j.kind == "revolute" and {j.body_i, j.body_j} == set(bodies)), None)
            if on == joint:
                found.append(f"object {number} (ConnectorCoordinate)")
        return Reading(joint_item(joint), "prescribed motion", listing(found),
                       "coordinate constraints on the joint's relative coordinate")

    def slide_of(self, markers: list[int]) -> str | None:
        """The prismatic joint whose slide s the pair (a ground coordinate,
        then a relative translation marker: q1 − q0 = s) measures: the marker joins the
        joint's bodies at its points (at the start, within rounding of the
        mechanism's size) along its unit axis; None if no joint's."""
        if (len(markers) != 2 or self.rotation_of(markers[0]) != GROUND
                or self.markers[markers[1]]["markerType"] != "BodiesRelativeTranslationCoordinate"):
            return None
        m = self.markers[markers[1]]
        numbers = [int(b) for b in m["bodyNumbers"]]
        bodies = [self.object_body.get(b) for b in numbers]
        axis = np.asarray(m["axis0"], dtype=float)[:2]
        size = max(1.0, *(abs(v) for j in self.mech.joints for v in j.point_i + j.point_j))
        for j in self.mech.joints:
            if j.kind != "prismatic" or bodies != [j.body_i, j.body_j]:
                continue
            points = [to_body(self.start, body, self.world(number, m[f"localPosition{k}"]))
                      for k, (body, number) in enumerate(zip(bodies, numbers))]
            off = max(float(np.hypot(*(points[0] - j.point_i))), float(np.hypot(*(points[1] - j.point_j))))
            if off <= ROUNDING * size and float(np.hypot(*(axis - np.asarray(j.axis)))) <= ROUNDING:
                return j.name
        return None

    # -- force elements ----------------------------------------------------------

    def force(self, force: SpringDamper | BodyTorque) -> list[Reading]:
        """The engine element named after the force (`model`), read
        back: a spring-damper's markers, stiffness, free length and damping
        (any force offset, velocity offset or user function is listed); a
        torque load's body and vector."""
        item = force_item(force)
        if isinstance(force, BodyTorque):
            found = [i for i, load in enumerate(self.loads) if load["name"] == item]
            if len(found) != 1:
                return [Reading(item, "body", f"{len(found)} loads named {item!r}")]
            self.used_loads.add(found[0])
            load = self.loads[found[0]]
            vector = np.asarray(load["loadVector"], dtype=float)
            marker = self.markers[int(load["markerNumber"])]
            body = self.object_body.get(int(marker.get("bodyNumber", -1)), f"marker type {marker['markerType']}")
            readings = [Reading(item, "body", body if load["loadType"] == "TorqueVector" else
                                f"{body} ({load['loadType']})", "LoadTorqueVector on a MarkerBodyRigid"),
                        Reading(item, "torque", float(vector[2]), "loadVector z")]
            if vector[0] or vector[1] or load["loadVectorUserFunction"]:
                readings.append(Reading(item, "out of plane or user function", f"{vector.tolist()}"))
            return readings
        found = [i for i, o in enumerate(self.objects) if o["name"] == item]
        if len(found) != 1:
            return [Reading(item, "bodies", f"{len(found)} objects named {item!r}")]
        self.used.add(found[0])
        o = self.objects[found[0]]
        sides = [self.marker_point(int(k)) for k in o["markerNumbers"]]
        kind = "" if o["objectType"] == "ConnectorSpringDamper" else f" ({o['objectType']})"
        readings = [Reading(item, "bodies", "–".join(b for b, _ in sides) + kind, "ObjectConnectorSpringDamper")]
        for end, (body, point) in zip("ab", sides):
            local = to_body(self.start, body, point) if body in (GROUND, *self.node_body.values()) else point
            readings += [Reading(item, f"point {end} x", float(local[0])), Reading(item, f"point {end} y", float(local[1]))]
        readings += [Reading(item, "stiffness", float(o["stiffness"])),
                     Reading(item, "free length", float(o["referenceLength"]), "referenceLength"),
                     Reading(item, "damping", float(o["damping"]))]
        extras = [f"{key} {o[key]:g}" for key in ("force", "velocityOffset") if o[key]]
        extras += ["spring force user function"] * bool(o["springForceUserFunction"])
        extras += ["inactive"] * (not o["activeConnector"])
        if extras:
            readings.append(Reading(item, "extras", listing(extras)))
        return readings

    def torque_law(self, law: TorqueLaw) -> list[Reading]:
        """The `LoadTorqueVector`s named after the law (one name per side,
        `torque_law_load_names`): the joint whose bodies carry them (body_j
        +T, body_i −T, none on the ground), and the law's parameters as
        held by their user function (Exudyn reports the function, not what
        it computes), checked by evaluating both loads' functions at the
        run's output instants."""
        item, names = torque_law_item(law), set(torque_law_load_names(law).values())
        found = [i for i, load in enumerate(self.loads) if load["name"] in names]
        self.used_loads.update(found)
        carried, functions = {}, []
        for number in found:
            load = self.loads[number]
            marker = self.markers[int(load["markerNumber"])]
            body = self.object_body.get(int(marker.get("bodyNumber", -1)), f"marker type {marker['markerType']}")
            function = load["loadVectorUserFunction"]
            function = function["function"] if isinstance(function, dict) else None
            if load["loadType"] != "TorqueVector" or not isinstance(function, TorqueLawLoad):
                return [Reading(item, "joint", f"load {number} ({load['loadType']}) without a torque law function")]
            carried[body] = function.sign
            functions.append(function)
        joints = [j.name for j in self.mech.joints if j.kind == "revolute" and carried == {
            b: s for b, s in ((j.body_j, 1.0), (j.body_i, -1.0)) if b != GROUND}]
        if not joints or not functions:
            return [Reading(item, "joint", f"loads on {carried or 'no body'}", "body: sign of T")]
        held = functions[0].law
        solver_times = self.times - self.t0
        values = np.array([[f(self.mbs, t, 0)[2] * f.sign for t in solver_times] for f in functions])
        off = float(np.max(np.abs(values - held.value(self.times))))
        size = max(abs(held.torque), abs(held.amplitude)) or 1.0
        note = "The load user function's law, T on body_j and −T on body_i"
        if off > ROUNDING * size:
            return [Reading(item, "joint", f"{joints[0]}, but the loads depart from their law by {off:.3g} N·m")]
        return [Reading(item, "joint", joints[0], f"{note}, at every output instant within {off:.1g} N·m")] + [
            Reading(item, quantity, float(getattr(held, quantity)), note, "set")
            for quantity in ("torque", "amplitude", "frequency", "phase")]

    # -- scene ------------------------------------------------------------------

    def reference_angle(self, body: str) -> float:
        if body == GROUND:
            return 0.0
        number = next(i for i, b in self.object_body.items()
                      if b == body and self.objects[i]["objectType"] == "RigidBody2D")
        return float(self.mbs.GetNode(int(self.objects[number]["nodeNumber"]))["referenceCoordinates"][2])

    def scene(self) -> list[Reading]:
        _, other_dampers, springs = self.dampers()
        gravity, other_loads = self.gravity()
        unknown = [f"object {i} ({o['objectType']})" for i, o in enumerate(self.objects)
                   if i not in self.used and o["objectType"] not in ("Ground", "RigidBody2D")]
        unknown += [f"object {i} ({o['objectType']})" for i, o in enumerate(self.objects)
                    if o["objectType"] not in KNOWN_OBJECTS]
        absent = "not a feature of Exudyn's 2-D rigid bodies and joints"
        note = "from the load vectors (2-D model: z has no effect)"
        return [
            Reading(SCENE, "gravity x", gravity[0], note), Reading(SCENE, "gravity y", gravity[1], note),
            Reading(SCENE, "gravity z", gravity[2], note),
            Reading(SCENE, "contacts", "off", f"no contact objects ({len(self.objects)} objects, all listed)"),
            Reading(SCENE, "joint limits", "none", absent),
            Reading(SCENE, "joint friction", "none", absent),
            Reading(SCENE, "joint springs", listing(springs), "stiffness of the coordinate spring-dampers"),
            Reading(SCENE, "added inertia (armature)", "none", absent),
            Reading(SCENE, "motors other than the drive", listing(
                [f"object {i}" for i, o in enumerate(self.objects)
                 if o["objectType"] == "ConnectorCoordinate" and i not in self.used]), "coordinate constraints"),
            Reading(SCENE, "velocity damping of bodies", "none", absent),
            Reading(SCENE, "fluid forces", "none", absent),
            Reading(SCENE, "velocity clamps", "none", absent),
            Reading(SCENE, "sleeping (deactivation)", "none", absent),
            Reading(SCENE, "other dampers", listing(other_dampers), "spring-dampers on no joint's coordinate"),
            Reading(SCENE, "other loads", listing(other_loads), "every load is listed"),
            Reading(SCENE, "other constraints", listing(sorted(set(unknown))), "every object is accounted for"),
        ]

    def gravity(self) -> tuple[list[float], list[str]]:
        """The gravity vector if every body carries the same mass-proportional
        load (zero if none does), and the loads that are not that."""
        vectors: dict[str, list[np.ndarray]] = {b.name: [] for b in self.mech.bodies}
        other = []
        for number, load in enumerate(self.loads):
            marker = self.markers[int(load["markerNumber"])]
            body = self.object_body.get(int(marker["bodyNumber"])) if "bodyNumber" in marker else None
            if number in self.used_loads:
                continue
            if load["loadType"] != "MassProportional" or body not in vectors or load["loadVectorUserFunction"]:
                other.append(f"load {number} ({load['loadType']})")
                continue
            vectors[body].append(np.asarray(load["loadVector"], dtype=float))
        if all(not v for v in vectors.values()):
            return [0.0, 0.0, 0.0], other
        first = next(v[0] for v in vectors.values() if v)
        uneven = [b for b, v in vectors.items() if len(v) != 1 or not np.array_equal(v[0], first)]
        other += [f"weight of {b} differs from the others" for b in uneven]
        return [float(v) for v in first], other

    def notes(self) -> list[Reading]:
        settings, ti = self.settings, self.simulation.timeIntegration
        radius = ti.generalizedAlpha.spectralRadius
        solver = settings["solver"]
        damping = (f"generalized-α, spectral radius {radius:g}: numerical dissipation of high frequencies, "
                   "not a physical damper" if solver == "index3" else
                   "trapezoidal (Newmark γ ½, β ¼): no numerical dissipation; the spectral radius setting is unused")
        return [
            Reading(ENGINE, "solver", f"{solver}, dt {settings['timestep']:.6g} s, {int(ti.numberOfSteps)} steps, "
                                      f"adaptive step {'on' if ti.adaptiveStep else 'off'}", damping, "note"),
            Reading(ENGINE, "Newton", f"{'modified' if ti.newton.useModifiedNewton else 'full'}, relative "
                                      f"{ti.newton.relativeTolerance:g}, absolute {ti.newton.absoluteTolerance:.3g}",
                    "Numerical.", "note"),
            Reading(ENGINE, "initial accelerations",
                    "computed by Exudyn" if ti.generalizedAlpha.computeInitialAccelerations else "the reference's",
                    "Exudyn's own solve ignores φ'' of the drive (docs/engines.md).", "note"),
        ]
