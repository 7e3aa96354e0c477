"""Audit of the Drake plant the adapter builds (see `mechval.records.audit`).

The plant is built by the adapter's own `run.Run` (the start state, the
tree, the drive gains) and read back through Drake's getters: bodies'
`default_mass`, `default_com` and `default_rotational_inertia` (about the
body origin, body axes; the audit shifts it to the centre of mass),
joints' frames posed in world at the start state (`CalcPoseInWorld`),
their axes, damping and limits, `LinearSpringDamper`s' getters, the
actuators and their gains, the gravity field, the force elements and the
collision geometries. Drake 1.51's Python API has no getter for a ball
constraint's points, so the cut pins' bodies and points are the values
the build passed ("as set"), as are body torques, torque laws and cut
dampers (applied by `model.AppliedForces`, which holds them). The drive
law is read from the desired-state source: q_d at Drake time c is
φ(t0 + c + dt), so three knots (the start, the middle and the end of the run) give φ0,
ω0, α.
World points are expressed in the bodies' frames at the reference pose
of the run's start (`mechval.records.audit.to_body`).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
import pandas as pd

from pydrake.multibody.tree import ForceElementIndex, LinearSpringDamper, UniformGravityFieldElement

from mechval.model.mechanism import GROUND, BodyTorque, Joint, Mechanism, SpringDamper
from mechval.records.audit import (SCENE, ModelReader, Reading, axis_readings, bodies_text, body_item, drive_item,
                                   force_item, joint_item, listing, point_readings, to_body, torque_law_item)

from mechval.engines.drake.model import set_position, set_rate
from mechval.engines.drake.run import Run
from mechval.engines.drake.topology import coordinates


def audit_model(mech: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the Drake plant the adapter builds."""
    return Reader(mech, Run(mech, times, settings)).table()


class Reader(ModelReader):
    """Readings of one built plant in its start state."""

    def __init__(self, mech: Mechanism, run: Run):
        self.mech, self.run, self.model, self.plant = mech, run, run.model, run.model.plant
        self.start = run.start.motion
        self.context = self.plant.CreateDefaultContext()
        for name, (q, v, _) in coordinates(run.topo, self.start).items():
            set_position(self.model.joints[name], self.context, float(q[0]))
            set_rate(self.model.joints[name], self.context, float(v[0]))
        self.name_of = {self.model.bodies[b.name].index(): b.name for b in mech.bodies}
        self.name_of[self.plant.world_body().index()] = GROUND

    def body(self, name: str) -> list[Reading]:
        body = self.model.bodies[name]
        mass, com = body.default_mass(), body.default_com()
        about_origin = body.default_rotational_inertia().CopyToFullMatrix3()
        # Shifted to the centre of mass (parallel axes): I_G = I_O − m·(|c|²·1 − c·cᵀ).
        central = about_origin - mass * (np.dot(com, com) * np.eye(3) - np.outer(com, com))
        item = body_item(name)
        return [Reading(item, "mass", float(mass)), Reading(item, "com x", float(com[0])),
                Reading(item, "com y", float(com[1])), Reading(item, "izz", float(central[2, 2])),
                Reading(item, "ixz", float(central[0, 2])), Reading(item, "iyz", float(central[1, 2]))]

    def joint(self, joint: Joint) -> list[Reading]:
        item = joint_item(joint.name)
        if joint in self.run.topo.cuts:
            note = "A ball constraint (AddBallConstraint); Drake 1.51 has no getter for its points: as built."
            return ([Reading(item, "kind", "revolute", note, "set"),
                     Reading(item, "bodies", f"{joint.body_i}–{joint.body_j}", note, "set")]
                    + [Reading(item, r.quantity, r.value, note, "set") for r in point_readings(
                        self.mech, self.start, joint.name, {b: self._world(b, p) for b, p in
                                                            ((joint.body_i, joint.point_i),
                                                             (joint.body_j, joint.point_j))})]
                    + [Reading(item, "damping", joint.damping, "Applied as torques each step (AppliedForces).",
                               "set")])
        drake_joint = self.model.joints[joint.name]
        kind = drake_joint.type_name()            # "revolute", "prismatic", or what else Drake built
        parent, child = (self.name_of[drake_joint.parent_body().index()], self.name_of[drake_joint.child_body().index()])
        anchors = {parent: self._frame_origin(drake_joint.frame_on_parent()),
                   child: self._frame_origin(drake_joint.frame_on_child())}
        axis_world = self._frame_rotation(drake_joint.frame_on_parent()) @ (
            drake_joint.revolute_axis() if kind == "revolute" else drake_joint.translation_axis())
        readings = [Reading(item, "kind", kind), Reading(item, "bodies", bodies_text(joint, (parent, child))),
                    Reading(item, "damping", float(drake_joint.default_damping()))]
        if kind == "prismatic":
            readings += point_readings(self.mech, self.start, joint.name, anchors, axis_world[:2])
            readings += axis_readings(self.mech, self.start, joint.name, axis_world[:2])
            readings.append(Reading(item, "relative rotation", "locked", "A PrismaticJoint only translates."))
        else:
            readings += point_readings(self.mech, self.start, joint.name, anchors)
            readings.append(Reading(item, "axis (world)", " ".join(f"{v:.6g}" for v in axis_world),
                                    "The pin's axis must be world z.", "note"))
        return readings

    def _frame_origin(self, frame) -> np.ndarray:
        return frame.CalcPoseInWorld(self.context).translation()

    def _frame_rotation(self, frame) -> np.ndarray:
        return frame.CalcPoseInWorld(self.context).rotation().matrix()

    def _world(self, body: str, point) -> np.ndarray:
        pose = self.plant.EvalBodyPoseInWorld(self.context, self.model.bodies[body])
        return pose.multiply(np.array([point[0], point[1], 0.0]))

    def drives(self) -> list[Reading]:
        out = []
        dt, t0 = self.model.dt, self.run.start.t0
        for k, (drive, actuator) in enumerate(zip(self.mech.drives, self.model.actuators)):
            item = drive_item(self.mech, drive)
            joint = next(name for name, j in self.model.joints.items() if j.index() == actuator.joint().index())
            sign = self.run.topo.of_joint(joint).sign
            # Knots spread over the run (exact there; a quadratic from three
            # neighbouring knots would amplify rounding by 1/dt²).
            last = self.model.desired.end_time() - dt
            clock = dt * np.round(np.array([0.0, 0.5, 1.0]) * last / dt)
            q = np.array([sign * self.model.desired.value(c)[k, 0] for c in clock])
            t = t0 + clock + dt
            mid = float(t[1])
            a, b, c = np.polyfit(t - mid, q, 2)          # φ = a·(t − mid)² + b·(t − mid) + c
            coef = (a, b - 2 * a * mid, a * mid * mid - b * mid + c)
            note = "Read from the desired-state source (φ(t + dt) at Drake time t − t0)."
            kp, kd = actuator.get_controller_gains().p, actuator.get_controller_gains().d
            out += [Reading(item, "joint", joint), Reading(item, "phi0", float(coef[2]), note),
                    Reading(item, "omega0", float(coef[1]), note), Reading(item, "alpha", float(2 * coef[0]), note),
                    Reading(item, "PD gains", f"Kp {kp:.6g}, Kd {kd:.6g}; effort limit {actuator.effort_limit():g}",
                            "A stiff PD-controlled actuator (implicit in SAP); lag T/Kp.", "note")]
        return out

    def forces(self) -> list[Reading]:
        out, springs = [], iter(self.model.springs)
        for force in self.mech.forces:
            item = force_item(force)
            if isinstance(force, BodyTorque):
                note = "Applied as a spatial torque each step (AppliedForces)."
                out += [Reading(item, "body", force.body, note, "set"),
                        Reading(item, "torque", force.torque, note, "set")]
                continue
            spring = next(springs)
            a, b = self.name_of[spring.bodyA().index()], self.name_of[spring.bodyB().index()]
            out += [Reading(item, "bodies", f"{a}–{b}"),
                    Reading(item, "point a x", float(spring.p_AP()[0])), Reading(item, "point a y", float(spring.p_AP()[1])),
                    Reading(item, "point b x", float(spring.p_BQ()[0])), Reading(item, "point b y", float(spring.p_BQ()[1])),
                    Reading(item, "stiffness", float(spring.stiffness())),
                    Reading(item, "free length", float(spring.free_length())),
                    Reading(item, "damping", float(spring.damping()))]
        for law in self.mech.torque_drives:
            item, note = torque_law_item(law), "Applied as spatial torques at each step's start (AppliedForces)."
            out += [Reading(item, q, getattr(law, q), note, "set")
                    for q in ("joint", "torque", "amplitude", "frequency", "phase")]
        driven = {self.model.joints[d.joint].index() for d in self.mech.drives}
        for value in self.mech.initial_values:
            on = self.model.joints.get(value.joint)
            out.append(Reading(joint_item(value.joint), "prescribed motion",
                               "actuator" if on is not None and on.index() in driven else "none"))
        return out

    def scene(self) -> list[Reading]:
        g = self.plant.gravity_field().gravity_vector()
        joints = list(self.model.joints.values())
        limited = [j.name() for j in joints if np.isfinite(j.position_lower_limits()).any()
                   or np.isfinite(j.position_upper_limits()).any()]
        clamped = [j.name() for j in joints if np.isfinite(j.velocity_lower_limits()).any()
                   or np.isfinite(j.velocity_upper_limits()).any()]
        reflected = [a.name() for a in self.model.actuators if a.default_reflected_inertia() != 0.0]
        elements = [type(e).__name__ for e in (self.plant.get_force_element(ForceElementIndex(k))
                                               for k in range(self.plant.num_force_elements()))
                    if not isinstance(e, (UniformGravityFieldElement, LinearSpringDamper))]
        extra_constraints = self.plant.num_constraints() - len(self.run.topo.cuts)
        other_motors = self.plant.num_actuators() - len(self.mech.drives)
        return [Reading(SCENE, "gravity x", float(g[0])), Reading(SCENE, "gravity y", float(g[1])),
                Reading(SCENE, "gravity z", float(g[2])),
                Reading(SCENE, "contacts", "off" if self.plant.num_collision_geometries() == 0 else "on",
                        "No geometry is registered."),
                Reading(SCENE, "joint limits", listing(limited)),
                Reading(SCENE, "joint friction", "none", "Drake's joints have no friction."),
                Reading(SCENE, "joint springs", listing([e for e in elements if "Spring" in e])),
                Reading(SCENE, "added inertia (armature)", listing(reflected)),
                Reading(SCENE, "motors other than the drive", "none" if other_motors == 0 else str(other_motors)),
                Reading(SCENE, "velocity damping of bodies", "none", "Drake has no body velocity damping."),
                Reading(SCENE, "fluid forces", "none", "Drake has no fluid forces."),
                Reading(SCENE, "velocity clamps", listing(clamped)),
                Reading(SCENE, "sleeping (deactivation)", "none", "Drake does not sleep bodies."),
                Reading(SCENE, "other dampers", listing([e for e in elements if "Spring" not in e])),
                Reading(SCENE, "other loads", "none", "Only AppliedForces' scene torques reach the plant's input."),
                Reading(SCENE, "other constraints", "none" if extra_constraints == 0 else str(extra_constraints))]

    def notes(self) -> list[Reading]:
        return [Reading(SCENE, "time step", f"{self.model.dt:.6g} s", "Discrete plant, SAP approximation.", "note"),
                Reading(SCENE, "output ports", "live", "Forces of the step from each sample (not sampled).", "note"),
                Reading(SCENE, "pre-roll", f"{self.run.start.steps} steps", "Along φ(t) before the first sample.",
                        "note")]

    def readings(self) -> list[Reading]:
        out = []
        for b in self.mech.bodies:
            out += self.body(b.name)
        for j in self.mech.joints:
            out += self.joint(j)
        return out + self.drives() + self.forces() + self.scene() + self.notes()
