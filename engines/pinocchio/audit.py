"""Audit of the Pinocchio model the adapter builds (see `mechval.records.audit`).

The model, its constraints and the dynamics' applied effects are built by
the adapter's own functions (`model.build_model`, `dynamics.Dynamics`) and
read back in the state a run starts from (`forwardKinematics` at the start
coordinates): a body's mass, centre of mass and inertia from
`model.inertias` (about its Pinocchio joint's frame, turned into the body's
frame through the body's `Frame`); a tree joint's kind from its joint model,
its bodies from `model.parents`, its point from `oMi` (world) and a slide's
axis from its motion subspace; a loop's pin from its `RigidConstraintModel`
(type, joints, placements → world points); gravity from `model.gravity`;
friction, damping, armature and rotor inertia from the model's vectors. The
dampers, drives, torque laws, springs and body torques are not elements of
a Pinocchio model: the adapter's dynamics apply them, so their rows are the
values it applies ("as set").
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
import pandas as pd
import pinocchio as pin

from mechval.model.mechanism import GROUND, BodyTorque, Joint, Mechanism
from mechval.records.audit import (ModelReader, Reading, SCENE, axis_readings, bodies_text, body_item, drive_item,
                                   force_item, inertia_readings, joint_item, listing, point_readings, to_body,
                                   torque_law_item)

from mechval.engines.base import reference_motion
from mechval.engines.pinocchio.dynamics import Dynamics
from mechval.engines.pinocchio.model import PinocchioModel, build_model, coordinates

ENGINE = "pinocchio"
KINDS = {"JointModelRZ": "revolute", "JointModelPrismaticUnaligned": "prismatic"}
APPLIED = "applied by the adapter's dynamics (Pinocchio models no such element)"


def audit_model(mech: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the Pinocchio model the adapter builds."""
    pm = build_model(mech)
    dynamics = Dynamics(pm, mech, settings)
    start = reference_motion(mech, np.asarray(times[:1], dtype=float))
    return Reader(mech, pm, dynamics, start, settings).table()


class Reader(ModelReader):
    """Readings of one built model at the run's start state."""

    def __init__(self, mech: Mechanism, pm: PinocchioModel, dynamics: Dynamics, start: pd.DataFrame,
                 settings: Mapping[str, Any]):
        self.mech, self.pm, self.dynamics, self.settings = mech, pm, dynamics, settings
        self.start = {c: start[c].to_numpy() for c in start.columns}
        self.q, self.v = coordinates(pm, mech, self.start)
        self.model, self.data = pm.model, pm.data
        pin.forwardKinematics(self.model, self.data, self.q, self.v)
        pin.updateFramePlacements(self.model, self.data)
        self.body_of = {index: body for body, index in pm.joint_of.items()}

    def readings(self) -> list[Reading]:
        out = [r for body in self.mech.bodies for r in self.body(body.name)]
        out += [r for joint in self.mech.joints for r in self.joint(joint)]
        out += [self.damping(joint) for joint in self.mech.joints]
        out += [r for k, drive in enumerate(self.mech.drives) for r in self.drive(k, drive)]
        out += [self.prescribed(value.joint) for value in self.mech.initial_values]
        out += [r for force in self.mech.forces for r in self.force(force)]
        out += [r for law in self.mech.torque_drives for r in self.torque_law(law)]
        return out + self.scene() + self.notes()

    def body(self, name: str) -> list[Reading]:
        index = self.pm.joint_of[name]
        inertia = self.model.inertias[index]
        frame = self.model.frames[self.pm.frame_of[name]]
        placement = self.data.oMi[index]
        com = to_body(self.start, name, placement.act(inertia.lever))
        world = placement.rotation @ inertia.inertia @ placement.rotation.T
        note = "model.inertias of the body's joint, about its centre of mass"
        readings = [Reading(body_item(name), "mass", float(inertia.mass), note),
                    Reading(body_item(name), "com x", float(com[0]), note),
                    Reading(body_item(name), "com y", float(com[1]), note), *inertia_readings(name, world, note)]
        if frame.parentJoint != index:
            readings.append(Reading(body_item(name), "frame", f"on joint {frame.parentJoint}, not {index}"))
        return readings

    def joint(self, joint: Joint) -> list[Reading]:
        tj = self.pm.tree_joint(joint.name)
        if tj is None:
            return self.loop(joint)
        item, index = joint_item(joint.name), tj.index
        native = self.model.joints[index].shortname()
        kind = KINDS.get(native, native)
        pair = (self.body_of[int(self.model.parents[index])], self.body_of[index])
        readings = [Reading(item, "kind", kind, f"{native} of the spanning tree (minimal coordinates)"),
                    Reading(item, "bodies", bodies_text(joint, pair))]
        anchor = self.data.oMi[index].translation
        if kind != "prismatic":
            return readings + point_readings(self.mech, self.start, joint.name, {b: anchor for b in pair})
        subspace = self._subspace(index)
        axis = self.data.oMi[index].rotation @ subspace[:3]
        turning = float(np.abs(subspace[3:]).max())
        return readings + point_readings(
            self.mech, self.start, joint.name, {b: anchor for b in pair}, axis,
            "The point of the slide's line nearest to the Mechanism's point.") + axis_readings(
            self.mech, self.start, joint.name, axis, "The joint's motion subspace.") + [
            Reading(item, "relative rotation", "locked" if turning == 0.0 else f"turns ({turning:g})",
                    "The joint's motion subspace has no angular part.")]

    def _subspace(self, index: int) -> np.ndarray:
        """The joint's motion subspace S (6-vector: linear, angular) in its frame."""
        q = self.q
        data = self.model.createData()
        pin.computeJointJacobians(self.model, data, q)
        jacobian = pin.getJointJacobian(self.model, data, index, pin.LOCAL)
        return np.asarray(jacobian[:, self.model.joints[index].idx_v])

    def loop(self, joint: Joint) -> list[Reading]:
        k = next(i for i, loop in enumerate(self.pm.loops) if loop.joint == joint)
        constraint, item = self.pm.constraints[k], joint_item(joint.name)
        kind = "revolute" if constraint.type == pin.ContactType.CONTACT_3D else str(constraint.type)
        anchors = {}
        for joint_id, placement in ((constraint.joint1_id, constraint.joint1_placement),
                                    (constraint.joint2_id, constraint.joint2_placement)):
            body = self.body_of.get(int(joint_id), f"joint {joint_id}")
            anchors[body] = (self.data.oMi[joint_id] * placement).translation
        note = ("RigidConstraintModel CONTACT_3D (a point constraint; its z row is redundant in the plane) "
                "closing the loop; the tree's joints hold the rotations about x and y")
        return [Reading(item, "kind", kind, note), Reading(item, "bodies", bodies_text(joint, tuple(anchors))),
                *point_readings(self.mech, self.start, joint.name, anchors)]

    def damping(self, joint: Joint) -> Reading:
        fx = self.dynamics.fx
        tj = self.pm.tree_joint(joint.name)
        if tj is not None:
            value = sum(c for k, c in fx.tree_dampers if k == tj.coordinate)
            where = "−c·q̇ on the joint's tree coordinate"
        else:
            value = sum(j.damping for j in fx.cut_dampers if j.name == joint.name)
            where = "−c·(ω_j − ω_i) on body_j and the opposite on body_i"
        return Reading(joint_item(joint.name), "damping", float(value), f"{where}, {APPLIED}", "set")

    def drive(self, k: int, drive) -> list[Reading]:
        item = drive_item(self.mech, drive)
        coordinate = int(self.dynamics.drive_coordinates[k])
        tj = next(tj for tj in self.pm.tree if tj.coordinate == coordinate)
        law = self.dynamics.laws[k]
        note = f"the computed effort on the tree coordinate gives sign·φ''(t) ({APPLIED}); from the start state"
        sign = float(self.dynamics.drive_signs[k])
        return [Reading(item, "joint", tj.joint.name, "the tree joint whose coordinate the drive prescribes", "set"),
                Reading(item, "phi0", float(sign * self.q[coordinate] - law.omega0 * self._t0()
                                            - 0.5 * law.alpha * self._t0() ** 2), note),
                Reading(item, "omega0", float(sign * self.v[coordinate] - law.alpha * self._t0()), note),
                Reading(item, "alpha", float(law.alpha), f"the acceleration the dynamics imposes ({APPLIED})", "set")]

    def _t0(self) -> float:
        return float(np.asarray(self.start["t"]).reshape(-1)[0])

    def prescribed(self, joint: str) -> Reading:
        tj = self.pm.tree_joint(joint)
        driven = tj is not None and tj.coordinate in set(self.dynamics.drive_coordinates.tolist())
        return Reading(joint_item(joint), "prescribed motion", "the drive" if driven else "none",
                       "drives on the joint's tree coordinate", "set")

    def force(self, force) -> list[Reading]:
        item, fx = force_item(force), self.dynamics.fx
        if isinstance(force, BodyTorque):
            held = next((t for t in fx.torques if t.name == force.name), None)
            if held is None:
                return [Reading(item, "body", "absent", APPLIED, "set")]
            return [Reading(item, "body", held.body, APPLIED, "set"), Reading(item, "torque", held.torque, APPLIED, "set")]
        held = next((s for s in fx.springs if s.name == force.name), None)
        if held is None:
            return [Reading(item, "bodies", "absent", APPLIED, "set")]
        rows = [Reading(item, "bodies", f"{held.body_a}–{held.body_b}", APPLIED, "set")]
        for end, point in (("a", held.point_a), ("b", held.point_b)):
            rows += [Reading(item, f"point {end} {axis}", float(v), APPLIED, "set") for axis, v in zip("xy", point)]
        return rows + [Reading(item, "stiffness", held.stiffness, APPLIED, "set"),
                       Reading(item, "free length", held.free_length, APPLIED, "set"),
                       Reading(item, "damping", held.damping, APPLIED, "set")]

    def torque_law(self, law) -> list[Reading]:
        item, fx = torque_law_item(law), self.dynamics.fx
        held = [held for _, _, held in fx.tree_laws] + [held for _, held in fx.cut_laws]
        found = next((h for h in held if h.name == law.name), None)
        if found is None:
            return [Reading(item, "joint", "absent", APPLIED, "set")]
        return [Reading(item, "joint", found.joint, APPLIED, "set")] + [
            Reading(item, quantity, float(getattr(found, quantity)), APPLIED, "set")
            for quantity in ("torque", "amplitude", "frequency", "phase")]

    def scene(self) -> list[Reading]:
        m = self.model
        g = np.asarray(m.gravity.linear)
        nonzero = lambda name: listing([f"{name}[{k}] = {v:g}" for k, v in enumerate(np.asarray(getattr(m, name)))
                                        if v != 0.0])
        extra = [c.name for c in self.pm.constraints][len(self.pm.loops):]
        applied = ("the adapter's dynamics apply only the Mechanism's dampers, drives, torque laws, spring-dampers "
                   "and body torques (their rows)")
        return [
            Reading(SCENE, "gravity x", float(g[0]), "model.gravity"),
            Reading(SCENE, "gravity y", float(g[1]), "model.gravity"),
            Reading(SCENE, "gravity z", float(g[2]), "model.gravity"),
            Reading(SCENE, "contacts", "off", "No geometry model is built: Pinocchio has no collisions without one",
                    "set"),
            Reading(SCENE, "joint limits", "none", "constraintDynamics enforces no position limits (no "
                    "JointLimitConstraintModel is built)", "set"),
            Reading(SCENE, "joint friction", nonzero("friction"), "model.friction"),
            Reading(SCENE, "joint springs", "none", "Pinocchio models no joint springs", "set"),
            Reading(SCENE, "added inertia (armature)",
                    listing([x for x in (nonzero("armature"), nonzero("rotorInertia")) if x != "none"]),
                    "model.armature, model.rotorInertia"),
            Reading(SCENE, "motors other than the drive", "none", applied, "set"),
            Reading(SCENE, "velocity damping of bodies", nonzero("damping"),
                    "model.damping (the joints' viscous damping vector; the adapter applies dampers itself)"),
            Reading(SCENE, "fluid forces", "none", "Pinocchio models none", "set"),
            Reading(SCENE, "velocity clamps", "none", "constraintDynamics enforces no velocity limits", "set"),
            Reading(SCENE, "sleeping (deactivation)", "none", "Pinocchio has no sleeping", "set"),
            Reading(SCENE, "other dampers", "none", applied, "set"),
            Reading(SCENE, "other loads", "none", applied, "set"),
            Reading(SCENE, "other constraints", listing(extra),
                    "RigidConstraintModels beyond one per loop"),
        ]

    def notes(self) -> list[Reading]:
        s = self.settings
        baumgarte = (f"time constant {s['baumgarte_steps']:g} steps" if s["baumgarte_steps"] else "off")
        return [
            Reading(ENGINE, "integrator", f"RK4 (the adapter's), dt {float(s['timestep']):.6g} s",
                    "Numerical: Pinocchio computes the dynamics, the adapter integrates them.", "note"),
            Reading(ENGINE, "proximal solver", f"accuracy {s['proximal_accuracy']:g}, mu {s['proximal_mu']:g}, "
                    f"at most {s['proximal_max_iterations']} iterations",
                    "Numerical: Pinocchio's proximal solve of the constrained dynamics.", "note"),
            Reading(ENGINE, "Baumgarte stabilisation", baumgarte,
                    "Numerical: pulls the loops' drift back; zero on an exactly closed loop.", "note"),
        ]
