"""Audit of the OpenSim model the adapter builds (see
`mechval.records.audit`).

The model is built and put in its start state by the adapter's own
`run.prepare`, then read back from OpenSim's component sets: bodies
(`BodySet`: mass, mass centre, inertia about it), joints (`JointSet`: the
class, the two offset frames' base bodies, translations and orientations,
each coordinate's prescribed function), constraints (`ConstraintSet`: each
`PointConstraint`'s bodies and locations), forces (`ForceSet`) and
controllers (`ControllerSet`), and the gravity. Every component of every
set is accounted for or listed.

Conventions: an OpenSim body's frame is the mechanism body's, so points
and mass centres are read in body frames as they are. A joint is
identified by its two bodies and points, never by the adapter's names; its
coordinate is reversed when the joint's parent is the Mechanism's body_j,
so a prescribed law or an actuator on it is read with the sign turned.
The drive law is read by evaluating the prescribed function (a quadratic:
three points determine it, a fourth checks it).
"""

from __future__ import annotations

import math
import re
from typing import Any, Mapping

import numpy as np
import opensim as osim
import pandas as pd

from mechval.model.kinematics import rotate
from mechval.model.mechanism import GROUND, BodyTorque, Drive, Joint, Mechanism, SpringDamper, TorqueLaw
from mechval.records.audit import (SCENE, ModelReader, Reading, body_item, drive_item, force_item, joint_item,
                                   listing, point_quantity, torque_law_item)

from mechval.engines.opensim.run import prepare

ENGINE = "opensim"
#: Relative agreement for the laws read back by evaluation (rounding only).
ROUNDING = 1e-12
#: The spring-damper expression the adapter writes (`model.spring_expression`).
SPRING = re.compile(r"^(?P<k>[^*]+)\*\(d-\((?P<l0>[^)]+)\)\)\+(?P<c>[^*]+)\*ddot$")
JOINT_KINDS = {"PinJoint": "revolute", "SliderJoint": "prismatic"}


def audit_model(mech: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the OpenSim model the adapter builds."""
    prepared = prepare(mech, times, settings)
    return Reader(mech, prepared.built.model, {b.getName(): n for n, b in prepared.built.bodies.items()},
                  np.asarray(times, dtype=float), settings).table()


def _double(component, name: str) -> float:
    return float(osim.PropertyHelper.getValueDouble(component.getPropertyByName(name)))


def _vec(v) -> np.ndarray:
    return np.array([v[0], v[1], v[2]])


class Reader(ModelReader):
    """Readings of one OpenSim model (its default state: nothing in it
    depends on the state but the coordinates' values)."""

    def __init__(self, mech: Mechanism, model: osim.Model, names: Mapping[str, str], times: np.ndarray,
                 settings: Mapping[str, Any]):
        self.mech, self.model, self.times, self.settings = mech, model, times, settings
        self.names = dict(names) | {"ground": GROUND}
        self.used: set[str] = set()         # absolute paths of components accounted for
        self.joints = {}        # mechanism joint → (OpenSim joint or constraint, reversed)
        self.points: dict[str, dict[str, tuple[float, float]]] = {}     # mechanism joint → body → point
        for joint in model.getJointSet():
            self._place(joint, self._joint_side(joint.getParentFrame()), self._joint_side(joint.getChildFrame()))
        for constraint in model.getConstraintSet():
            if constraint.getConcreteClassName() == "PointConstraint":
                sides = [(self.names.get(constraint.getConnectee(f"body_{k}").getName(), "?"),
                          tuple(_vec(osim.PointConstraint.safeDownCast(constraint).get_location_body_1()
                                     if k == 1 else osim.PointConstraint.safeDownCast(constraint)
                                     .get_location_body_2())[:2])) for k in (1, 2)]
                self._place(constraint, *sides)

    # -- identification -------------------------------------------------------------

    def _joint_side(self, frame) -> tuple[str, tuple[float, float]]:
        offset = osim.PhysicalOffsetFrame.safeDownCast(frame)
        point = _vec(offset.get_translation())[:2] if offset else np.zeros(2)
        return self.names.get(frame.findBaseFrame().getName(), "?"), tuple(point)

    def _place(self, component, first, second) -> None:
        """Records the component as the Mechanism joint it joins (if any;
        components that match none stay unaccounted)."""
        joint, reversed_ = self._match(first, second)
        if joint is not None:
            self.joints[joint] = (component, reversed_)
            self.points[joint] = dict((first, second))
            self.used.add(component.getAbsolutePathString())

    def _match(self, first, second) -> tuple[str | None, bool]:
        """The Mechanism joint between these (body, point) sides, either
        order (reversed: `first` is body_j), points within rounding."""
        size = max(1.0, *(abs(v) for j in self.mech.joints for v in j.point_i + j.point_j))
        for j in self.mech.joints:
            for (a, pa), (b, pb), reversed_ in ((first, second, False), (second, first, True)):
                if (a, b) == (j.body_i, j.body_j) and max(np.hypot(*np.subtract(pa, j.point_i)),
                                                          np.hypot(*np.subtract(pb, j.point_j))) <= ROUNDING * size:
                    return j.name, reversed_
        return None, False

    def _coordinate(self, joint: str):
        component, _ = self.joints.get(joint, (None, False))
        if component is None or component.getConcreteClassName() not in JOINT_KINDS:
            return None
        return osim.Joint.safeDownCast(component).get_coordinates(0)

    def _sign(self, joint: str) -> float:
        return -1.0 if self.joints.get(joint, (None, False))[1] else 1.0

    def _joint_of_coordinate(self, coordinate: str) -> str | None:
        return next((name for name in self.joints if (c := self._coordinate(name)) is not None
                     and c.getName() == coordinate), None)

    # -- readings -------------------------------------------------------------------

    def readings(self) -> list[Reading]:
        out = [r for body in self.mech.bodies for r in self.body(body.name)]
        out += [r for joint in self.mech.joints for r in self.joint(joint)]
        out += [r for drive in self.mech.drives for r in self.drive(drive)]
        out += [self.prescribed(value.joint) for value in self.mech.initial_values]
        out += [r for force in self.mech.forces for r in self.force(force)]
        out += [r for law in self.mech.torque_drives for r in self.torque_law(law)]
        out += self.dampings()
        return out + self.scene() + self.notes()

    def body(self, name: str) -> list[Reading]:
        item = body_item(name)
        found = [b for b in self.model.getBodySet() if self.names.get(b.getName()) == name]
        if len(found) != 1:
            return [Reading(item, "mass", f"{len(found)} bodies")]
        b = found[0]
        self.used.add(b.getAbsolutePathString())
        vec6 = b.get_inertia()        # about the mass centre: xx yy zz xy xz yz
        com, inertia = _vec(b.getMassCenter()), [vec6.get(k) for k in range(6)]
        note = "Body inertia about its mass centre, body axes (= world z)"
        return [Reading(item, "mass", b.getMass()), Reading(item, "com x", float(com[0])),
                Reading(item, "com y", float(com[1])), Reading(item, "izz", float(inertia[2]), note),
                Reading(item, "ixz", float(inertia[4]), note), Reading(item, "iyz", float(inertia[5]), note)]

    def joint(self, joint: Joint) -> list[Reading]:
        item = joint_item(joint.name)
        component, reversed_ = self.joints.get(joint.name, (None, False))
        if component is None:
            return [Reading(item, "kind", "no OpenSim joint or constraint between its bodies at its points")]
        kind = component.getConcreteClassName()
        points = [Reading(item, point_quantity(body, axis), float(v), "the offset frame's or location's point")
                  for body in (joint.body_i, joint.body_j) for axis, v in zip("xy", self.points[joint.name][body])]
        bodies = f"{joint.body_i}–{joint.body_j}"
        if kind == "PointConstraint":
            return [Reading(item, "kind", "revolute", "PointConstraint closing the loop (pin: rotation free)"),
                    Reading(item, "bodies", bodies)] + points
        readings = [Reading(item, "kind", JOINT_KINDS.get(kind, kind), kind + (", reversed" if reversed_ else "")),
                    Reading(item, "bodies", bodies)] + points
        if kind != "SliderJoint":
            return readings
        j = osim.Joint.safeDownCast(component)
        frames = {True: j.getParentFrame(), False: j.getChildFrame()}
        on_i = frames[not reversed_]
        on_j = frames[reversed_]
        angle_i = float(_vec(osim.PhysicalOffsetFrame.safeDownCast(on_i).get_orientation())[2])
        angle_j = float(_vec(osim.PhysicalOffsetFrame.safeDownCast(on_j).get_orientation())[2])
        axis = rotate(angle_i, (1.0, 0.0))
        held = angle_i - angle_j
        locked = "locked" if abs(held - joint.held_angle) <= ROUNDING else f"locked at θj − θi = {held:.6g}"
        note = "SliderJoint: translation along the x axis of its offset frame on body_i"
        return readings + [Reading(item, "axis x", float(axis[0]), note), Reading(item, "axis y", float(axis[1]), note),
                           Reading(item, "relative rotation", locked, "the offset frames' orientations")]

    def drive(self, drive: Drive) -> list[Reading]:
        item = drive_item(self.mech, drive)
        prescribed = [name for name in self.joints if (c := self._coordinate(name)) is not None
                      and c.getDefaultIsPrescribed() and name not in self._claimed]
        if drive.joint in prescribed:
            prescribed = [drive.joint]
        if not prescribed:
            return [Reading(item, "joint", "no prescribed coordinate")]
        joint = prescribed[0]
        self._claimed.add(joint)
        function = self._coordinate(joint).getPrescribedFunction()
        sign = self._sign(joint)
        f = lambda t: sign * function.calcValue(osim.Vector(1, float(t)))   # noqa: E731
        c0, c1, c2 = f(0.0), (f(1.0) - f(-1.0)) / 2, (f(1.0) - 2 * f(0.0) + f(-1.0)) / 2
        note = "the coordinate's prescribed function, evaluated"
        readings = [Reading(item, "joint", joint, "setPrescribedFunction + setDefaultIsPrescribed"),
                    Reading(item, "phi0", c0, note), Reading(item, "omega0", c1, note),
                    Reading(item, "alpha", 2 * c2, note)]
        if abs(f(2.0) - (c0 + 2 * c1 + 4 * c2)) > ROUNDING * max(abs(c0), abs(c1), abs(c2), 1.0):
            readings.append(Reading(item, "law", "not quadratic in t"))
        return readings

    @property
    def _claimed(self) -> set[str]:
        if not hasattr(self, "_claimed_joints"):
            self._claimed_joints: set[str] = set()
        return self._claimed_joints

    def prescribed(self, joint: str) -> Reading:
        coordinate = self._coordinate(joint)
        held = "none" if coordinate is None or not coordinate.getDefaultIsPrescribed() else "prescribed coordinate"
        return Reading(joint_item(joint), "prescribed motion", held, "the joint's coordinate (a constraint: none)")

    def torque_law(self, law: TorqueLaw) -> list[Reading]:
        """The CoordinateActuator on the law's joint and the Sine its
        PrescribedController gives it (read with the coordinate's sign),
        checked by evaluation at the run's output instants."""
        item = torque_law_item(law)
        for controller in self.model.getControllerSet():
            pc = osim.PrescribedController.safeDownCast(controller)
            for k in range(pc.getNumActuators() if pc else 0):
                actuator = osim.CoordinateActuator.safeDownCast(pc.getSocket("actuators").getConnecteeAsObject(k))
                joint = self._joint_of_coordinate(actuator.get_coordinate()) if actuator else None
                if joint != law.joint:
                    continue
                self.used |= {pc.getAbsolutePathString(), actuator.getAbsolutePathString()}
                sine, sign = pc.get_ControlFunctions().get(k), self._sign(joint) * actuator.getOptimalForce()
                values = np.array([sign * sine.calcValue(osim.Vector(1, float(t))) for t in self.times])
                held = {"torque": sign * _double(sine, "offset"), "amplitude": sign * _double(sine, "amplitude"),
                        "frequency": _double(sine, "omega") / (2 * math.pi), "phase": _double(sine, "phase")}
                off = float(np.max(np.abs(values - law.value(self.times))))
                note = f"Sine control × optimal force, {sine.getConcreteClassName()}; within {off:.1g} N·m at the samples"
                return [Reading(item, "joint", joint, "CoordinateActuator + PrescribedController")] + [
                    Reading(item, q, v, note) for q, v in held.items()]
        return [Reading(item, "joint", "no actuator")]

    def force(self, force: SpringDamper | BodyTorque) -> list[Reading]:
        item = force_item(force)
        kind = "PrescribedForce" if isinstance(force, BodyTorque) else "ExpressionBasedPointToPointForce"
        candidates = [f for f in self.model.getForceSet() if f.getConcreteClassName() == kind
                      and f.getAbsolutePathString() not in self.used]
        for f in candidates:
            readings = self._body_torque(item, f) if kind == "PrescribedForce" else self._spring(item, f)
            if readings[0].value == (force.body if isinstance(force, BodyTorque) else
                                     f"{force.body_a}–{force.body_b}"):
                self.used.add(f.getAbsolutePathString())
                return readings
        return [Reading(item, "body" if isinstance(force, BodyTorque) else "bodies", f"no {kind}")]

    def _body_torque(self, item: str, f) -> list[Reading]:
        pf = osim.PrescribedForce.safeDownCast(f)
        torques = pf.get_torqueFunctions()
        z = torques.get(2).calcValue(osim.Vector(1, 0.0)) if torques.getSize() == 3 else math.nan
        extras = [f"torque function {k}" for k in (0, 1) if torques.getSize() == 3
                  and torques.get(k).calcValue(osim.Vector(1, 0.0)) != 0.0]
        extras += ["forces"] * (pf.get_forceFunctions().getSize() > 0)
        body = self.names.get(pf.getConnectee("frame").getName(), "?")
        return [Reading(item, "body", body if not extras else f"{body} ({listing(extras)})", "PrescribedForce frame"),
                Reading(item, "torque", float(z), "torque function z (global frame)")]

    def _spring(self, item: str, f) -> list[Reading]:
        e = osim.ExpressionBasedPointToPointForce.safeDownCast(f)
        sides = [(self.names.get(e.get_body1(), "?"), _vec(e.get_point1())),
                 (self.names.get(e.get_body2(), "?"), _vec(e.get_point2()))]
        readings = [Reading(item, "bodies", f"{sides[0][0]}–{sides[1][0]}", "ExpressionBasedPointToPointForce")]
        for end, (_, point) in zip("ab", sides):
            readings += [Reading(item, f"point {end} x", float(point[0])), Reading(item, f"point {end} y", float(point[1]))]
        match = SPRING.match(e.get_expression().replace(" ", ""))
        if match is None:
            return readings + [Reading(item, "stiffness", f"expression {e.get_expression()!r}")]
        return readings + [Reading(item, "stiffness", float(match["k"]), "from the expression k*(d-(l0))+c*ddot"),
                           Reading(item, "free length", float(match["l0"]), "from the expression"),
                           Reading(item, "damping", float(match["c"]), "from the expression")]

    def dampings(self) -> list[Reading]:
        """Each joint's damper: a SpringGeneralizedForce of stiffness 0 on
        its coordinate, or a BushingForce between its pin's frames with
        rotational damping about z alone."""
        found: dict[str, float] = {}
        for f in self.model.getForceSet():
            name = f.getConcreteClassName()
            if name == "SpringGeneralizedForce":
                g = osim.SpringGeneralizedForce.safeDownCast(f)
                joint = self._joint_of_coordinate(g.get_coordinate())
                if joint is not None and g.getStiffness() == 0.0:
                    found[joint] = found.get(joint, 0.0) + g.getViscosity()
                    self.used.add(f.getAbsolutePathString())
            elif name == "BushingForce":
                b = osim.BushingForce.safeDownCast(f)
                joint, _ = self._match(*(self._joint_side(osim.PhysicalFrame.safeDownCast(b.getConnectee(socket)))
                                         for socket in ("frame1", "frame2")))
                rest = np.concatenate([_vec(b.get_rotational_stiffness()), _vec(b.get_translational_stiffness()),
                                       _vec(b.get_translational_damping()), _vec(b.get_rotational_damping())[:2]])
                if joint is not None and not rest.any():
                    found[joint] = found.get(joint, 0.0) + float(_vec(b.get_rotational_damping())[2])
                    self.used.add(f.getAbsolutePathString())
        return [Reading(joint_item(j.name), "damping", found.get(j.name, 0.0),
                        "SpringGeneralizedForce viscosity or BushingForce rotational damping z"
                        if j.name in found else "no damper on this joint") for j in self.mech.joints]

    def scene(self) -> list[Reading]:
        gravity = _vec(self.model.getGravity())
        others = [f"{f.getConcreteClassName()} {f.getName()}" for f in self.model.getForceSet()
                  if f.getAbsolutePathString() not in self.used]
        springs = [s for s in others if s.startswith("SpringGeneralizedForce")]
        limits = [f"{c.getName()} clamped" for c in self.model.getCoordinateSet() if c.getDefaultClamped()]
        limits += [s for s in others if "LimitForce" in s]
        contacts = self.model.getContactGeometrySet().getSize()
        constraints = [f"{c.getConcreteClassName()} {c.getName()}" for c in self.model.getConstraintSet()
                       if c.getAbsolutePathString() not in self.used]
        controllers = [f"{c.getConcreteClassName()} {c.getName()}" for c in self.model.getControllerSet()
                       if c.getAbsolutePathString() not in self.used]
        motors = [s for s in others if "Actuator" in s] + controllers
        loads = [s for s in others if s not in springs and s not in motors and "LimitForce" not in s]
        absent = "not in the model (every force, constraint and controller is listed)"
        note = "Model gravity"
        return [
            Reading(SCENE, "gravity x", float(gravity[0]), note), Reading(SCENE, "gravity y", float(gravity[1]), note),
            Reading(SCENE, "gravity z", float(gravity[2]), note),
            Reading(SCENE, "contacts", "off" if contacts == 0 and not any("Contact" in s for s in others)
                    else f"{contacts} contact geometries", "ContactGeometrySet and contact forces"),
            Reading(SCENE, "joint limits", listing(limits), "clamped coordinates, limit forces"),
            Reading(SCENE, "joint friction", "none", absent),
            Reading(SCENE, "joint springs", listing(springs), "SpringGeneralizedForce with stiffness"),
            Reading(SCENE, "added inertia (armature)", "none", absent),
            Reading(SCENE, "motors other than the drive", listing(motors), "actuators and controllers"),
            Reading(SCENE, "velocity damping of bodies", "none", absent),
            Reading(SCENE, "fluid forces", "none", absent),
            Reading(SCENE, "velocity clamps", "none", absent),
            Reading(SCENE, "sleeping (deactivation)", "none", "Simbody has none"),
            Reading(SCENE, "other dampers", "none", "dampers on no joint are among the other loads"),
            Reading(SCENE, "other loads", listing(loads), "every force of the ForceSet is accounted for"),
            Reading(SCENE, "other constraints", listing(constraints), "every constraint is accounted for"),
        ]

    def notes(self) -> list[Reading]:
        s = self.settings
        return [Reading(ENGINE, "integrator", f"{s['integrator']}, accuracy {s['accuracy']:g}, constraint tolerance "
                                              f"{s['constraint_tolerance']:g}, max step {s['max_step']:.6g} s",
                        "Simbody's error-controlled integration with constraint projection", "note")]
