"""Audit of the built PyBullet model (see `mechval.records.audit`).

The model is built by the adapter's own `model.build`, with the
step and start of `run.step_plan`, in the state a run starts from;
mechanism bodies, tree joints and loop constraints are found through the
model's own maps (`Model.bodies`, `tree_joints`, `constraints`).

What PyBullet 3.2.7 reads back and what it does not: masses, inertia
diagonals, inertial frames, joint types, axes, creation-time limits and
joint friction, constraints (pivots, caps), gravity, collision shapes, the
time step and sub-steps are read back. Linear/angular damping, jointDamping,
the joint speed clamp, the default velocity motors and activation states
have no getter (`getJointInfo` keeps the creation values, measured), so the
audit records the build's own `changeDynamics`/`setJointMotorControl2`
calls and reports those values as set ("as set"), with PyBullet's defaults
where the build makes no call. The drive law and the dampers are not in the
model at all: the adapter's stepping loop (`Stepper`) applies them every
step; the dampers it will apply are read from a `Stepper` of this model.

Conversion to the Mechanism's conventions: a body's centre of mass is its
inertial frame's world position (`getBasePositionAndOrientation`,
`getLinkState[0]`); a tree joint is at its child link's frame origin, o =
p_G − R_link·p_inertial with R_link = R_G·R_inertialᵀ (computed here in
double: `getLinkState[4]` rounds to float32, measured); a constraint's
pivot is relative to each side's centre-of-mass frame. World points are
expressed in the bodies' frames at the reference pose of the build's start
(`mechval.records.audit.to_body`); inertia is R_G·diag·R_Gᵀ.
"""

from __future__ import annotations

import contextlib
from typing import Any, Iterator, Mapping

import numpy as np
import pandas as pd

from mechval.records.audit import (ModelReader, Reading, SCENE, axis_readings, bodies_text, body_item, drive_item, force_item,
                           inertia_readings, joint_item, listing, point_readings, to_body, torque_law_item)
from mechval.model.kinematics import slide_motion
from mechval.model.mechanism import GROUND, Joint, Mechanism

from mechval.engines.pybullet.run import Stepper, step_plan
from mechval.engines.base import planned_motion
from mechval.engines.pybullet.model import BodyHandle, Model, build, p

ENGINE = "pybullet"
#: PyBullet's defaults for what has no getter (docs/engines.md, PyBullet 3.2.7).
DEFAULT_BODY_DAMPING = 0.04
DEFAULT_SPEED_CLAMP = 100.0
RECORDED_CALLS = ("changeDynamics", "setJointMotorControl2", "setPhysicsEngineParameter")
KINDS = {p.JOINT_REVOLUTE: "revolute", p.JOINT_PRISMATIC: "prismatic"}

Call = tuple[str, int, int, Mapping[str, Any]]     # function, body unique id, link index, keywords


def audit_model(mech: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the PyBullet model the adapter builds."""
    dt, per_sample, preroll = step_plan(times, settings)
    t_start = float(times[0]) - preroll * dt
    with recorded_calls() as calls:
        model = build(mech, dt, settings["layout"], t_start)
    try:
        stepper = Stepper(mech, model, times, per_sample, preroll)
        return Reader(mech, model, model.start, calls, stepper, peak_joint_rate(mech, times)).table()
    finally:
        p.disconnect(model.client)


@contextlib.contextmanager
def recorded_calls() -> Iterator[list[Call]]:
    """Record the `RECORDED_CALLS` the build makes (positional body id and
    link index, keywords) while passing them on to PyBullet."""
    calls: list[Call] = []
    originals = {name: getattr(p, name) for name in RECORDED_CALLS}

    def recorder(name: str, function):
        def call(*args, **kwargs):
            uid = args[0] if args else kwargs.get("bodyUniqueId", kwargs.get("bodyIndex", -1))
            link = args[1] if len(args) > 1 else kwargs.get("linkIndex", kwargs.get("jointIndex", -1))
            mode = args[2] if len(args) > 2 else kwargs.get("controlMode")
            calls.append((name, int(uid), int(link), {**kwargs, **({} if mode is None else {"mode": mode})}))
            return function(*args, **kwargs)
        return call

    for name, function in originals.items():
        setattr(p, name, recorder(name, function))
    try:
        yield calls
    finally:
        for name, function in originals.items():
            setattr(p, name, function)


def peak_joint_rate(mech: Mechanism, times: np.ndarray) -> float:
    """The largest |relative rate| of any joint over the run's samples
    (rad/s, or m/s for a slide: body_j's point relative to the point of
    body_i it passes, along the axis), from the reference motion (a
    torque-driven or free one's from the forward-dynamics reference)."""
    motion = planned_motion(mech).motion(np.asarray(times, dtype=float))
    zero = np.zeros(len(motion))
    col = lambda body, q: zero if body == GROUND else motion[f"{body}.{q}"].to_numpy()
    peak = 0.0
    for j in mech.joints:
        rate = col(j.body_j, "omega") - col(j.body_i, "omega")
        if j.kind == "prismatic":
            rate = slide_motion(motion, j)["v"]
        peak = max(peak, float(np.abs(rate).max()))
    return peak


def quaternion_matrix(q) -> np.ndarray:
    """Rotation matrix of a PyBullet quaternion (x, y, z, w)."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


class Reader(ModelReader):
    """Readings of one built model in its initial state."""

    def __init__(self, mech: Mechanism, model: Model, start: pd.DataFrame, calls: list[Call], stepper: Stepper,
                 peak_rate: float):
        self.mech, self.model, self.start, self.calls, self.stepper = mech, model, start, calls, stepper
        self.peak_rate = peak_rate      # of any joint over the run (`peak_joint_rate`)
        self.c = model.client
        self.name = {(h.uid, h.link): name for name, h in model.bodies.items()} | {(model.ground.uid, -1): GROUND}
        self.uids = sorted({h.uid for h in model.bodies.values()})

    def call(self, function: str, uid: int, link: int | None, key: str, default):
        """The last value the build passed for `key` (on that link, or on
        any link of the multibody when link is None), else `default`."""
        value = default
        for name, u, k, kwargs in self.calls:
            if name == function and u == uid and (link is None or k == link) and key in kwargs:
                value = kwargs[key]
        return value

    def links(self) -> list[tuple[int, int]]:
        return [(uid, link) for uid in range(p.getNumBodies(physicsClientId=self.c))
                for link in range(-1, p.getNumJoints(uid, physicsClientId=self.c))]

    def com_frame(self, handle: BodyHandle) -> tuple[np.ndarray, np.ndarray]:
        """World position and rotation of the body's inertial (COM) frame."""
        if handle.link < 0:
            position, orientation = p.getBasePositionAndOrientation(handle.uid, physicsClientId=self.c)
        else:
            state = p.getLinkState(handle.uid, handle.link, computeForwardKinematics=1, physicsClientId=self.c)
            position, orientation = state[0], state[1]
        return np.array(position), quaternion_matrix(orientation)

    def readings(self) -> list[Reading]:
        out = [r for b in self.mech.bodies for r in self.body(b.name)]
        out += [r for j in self.mech.joints for r in self.joint(j)]
        return out + self.drive() + self.prescribed_motion() + self.torque_laws() + self.forces() + self.scene() + self.notes()

    def body(self, name: str) -> list[Reading]:
        h = self.model.bodies[name]
        info = p.getDynamicsInfo(h.uid, h.link, physicsClientId=self.c)
        com, rotation = self.com_frame(h)
        local = to_body(self.start, name, com)
        item = body_item(name)
        return [Reading(item, "mass", float(info[0])), Reading(item, "com x", float(local[0])),
                Reading(item, "com y", float(local[1])),
                *inertia_readings(name, rotation @ np.diag(info[2]) @ rotation.T)]

    # -- joints -------------------------------------------------------------------

    def joint(self, joint: Joint) -> list[Reading]:
        if joint.name in self.model.tree_joints:
            return self.tree_joint(joint) + [self.damping(joint)]
        if joint.name in self.model.constraints:
            return self.constraint(joint) + [self.damping(joint)]
        return []

    def tree_joint(self, joint: Joint) -> list[Reading]:
        h = self.model.tree_joints[joint.name].handle
        info = p.getJointInfo(h.uid, h.link, physicsClientId=self.c)
        item = joint_item(joint.name)
        kind = KINDS.get(info[2], f"PyBullet joint type {info[2]}")
        pair = (self.name[(h.uid, info[16])], self.name[(h.uid, h.link)])
        com, rotation = self.com_frame(h)
        dynamics = p.getDynamicsInfo(h.uid, h.link, physicsClientId=self.c)
        link_rotation = rotation @ quaternion_matrix(dynamics[4]).T
        origin = com - link_rotation @ np.array(dynamics[3])
        readings = [Reading(item, "kind", kind, "multibody joint"), Reading(item, "bodies", bodies_text(joint, pair))]
        if kind == "prismatic":
            axis = link_rotation @ np.array(info[13])
            readings += point_readings(self.mech, self.start, joint.name, {b: origin for b in pair}, axis,
                                       "The point of the joint's line nearest to the Mechanism's point.")
            readings += axis_readings(self.mech, self.start, joint.name, axis)
            readings.append(Reading(item, "relative rotation", "locked", "A prismatic joint only translates."))
        else:
            readings += point_readings(self.mech, self.start, joint.name, {b: origin for b in pair})
        return readings

    def constraint(self, joint: Joint) -> list[Reading]:
        info = p.getConstraintInfo(self.model.constraints[joint.name].cid, physicsClientId=self.c)
        item = joint_item(joint.name)
        kind = "revolute" if info[4] == p.JOINT_POINT2POINT else f"PyBullet constraint type {info[4]}"
        anchors = {}
        for uid, link, pivot in ((info[0], info[1], info[6]), (info[2], info[3], info[7])):
            com, rotation = self.com_frame(BodyHandle(uid, link))
            anchors[self.name[(uid, link)]] = com + rotation @ np.array(pivot)
        note = ("point-to-point constraint (3-D): in the plane, the pin. A free base held by two of them keeps a "
                "spin about the line through its pins, which nothing excites (isotropic inertia, in-plane loads)")
        return [Reading(item, "kind", kind, note), Reading(item, "bodies", bodies_text(joint, tuple(anchors))),
                *point_readings(self.mech, self.start, joint.name, anchors)]

    def damping(self, joint: Joint) -> Reading:
        """The stepping loop's damper on this joint plus PyBullet's own
        jointDamping of its link (if it is a multibody joint)."""
        stepped = sum(j.damping for j in self.stepper.damped if j.name == joint.name)
        own = 0.0
        if joint.name in self.model.tree_joints:
            h = self.model.tree_joints[joint.name].handle
            created = p.getJointInfo(h.uid, h.link, physicsClientId=self.c)[6]
            own = float(self.call("changeDynamics", h.uid, h.link, "jointDamping", created))
        return Reading(joint_item(joint.name), "damping", stepped + own,
                       f"Applied every step by the stepping loop as equal and opposite loads ({stepped:g}), "
                       f"not part of the model; PyBullet's jointDamping {own:g}.", "set")

    # -- drive, scene, notes -----------------------------------------------------------

    def drive(self) -> list[Reading]:
        law = ("Not in the model: the stepping loop sets a position target from the Mechanism's φ(t) every step "
               "(POSITION_CONTROL, gains 1/1, force cap 1e12).")
        rows = []
        for k, motor in enumerate(self.stepper.motors):
            item = drive_item(self.mech, motor.drive)
            rows += [Reading(item, "joint", motor.joint.joint.name,
                             "The joint whose motor the stepping loop drives.", "set"),
                     *(Reading(item, q, "stepping loop", law, "note") for q in ("phi0", "omega0", "alpha"))]
        return rows

    def prescribed_motion(self) -> list[Reading]:
        """Per joint whose motion is integrated from an initial value, the
        position motors the stepping loop drives on it (none expected)."""
        motors = {motor.joint.joint.name for motor in self.stepper.motors}
        return [Reading(joint_item(v.joint), "prescribed motion", "position motor" if v.joint in motors else "none",
                        "position motors the stepping loop drives on the joint", "set")
                for v in self.mech.initial_values]

    def torque_laws(self) -> list[Reading]:
        """Each torque law as the stepping loop will apply it (not in the
        model: PyBullet keeps no torque beyond a step): the joint of the
        multibody link it sets under TORQUE_CONTROL, or the joint whose two
        bodies get equal and opposite external torques; the law's numbers."""
        rows = []
        for jt in self.stepper.joint_torques:
            item, law = torque_law_item(jt.law), jt.law
            if jt.joint is None:
                joint = self.mech.joint(law.joint)
                how = (f"Equal and opposite external torques every step: T on {joint.body_j}, −T on "
                       f"{joint.body_i} (its joint closes a loop or is already under control).")
                name = law.joint
            else:
                h = jt.joint.handle
                link = {(tj.handle.uid, tj.handle.link): n for n, tj in self.model.tree_joints.items()}
                name = link[(h.uid, h.link)]
                how = (f"TORQUE_CONTROL on link {h.link} of multibody {h.uid} every step, force "
                       f"{jt.sign:+g}·T(t_n) (its child is {jt.joint.child}).")
            value = "Not in the model: the stepping loop's law, T(t_n) over the step from t_n."
            rows += [Reading(item, "joint", name, how, "set"),
                     *(Reading(item, q, getattr(law, q), value, "set")
                       for q in ("torque", "amplitude", "frequency", "phase"))]
        return rows

    def forces(self) -> list[Reading]:
        """The spring-dampers and body torques the stepping loop will apply
        (PyBullet has no spring element and keeps no load: they are not in
        the model, so the values are those of a `Stepper` of it)."""
        applied = "Not in the model: applied every step by the stepping loop as external loads"
        rows = []
        for spring in self.stepper.springs:
            item = force_item(spring)
            rows.append(Reading(item, "bodies", f"{spring.body_a}–{spring.body_b}", applied, "set"))
            for end, point in (("a", spring.point_a), ("b", spring.point_b)):
                rows += [Reading(item, f"point {end} {axis}", value, applied, "set")
                         for axis, value in zip("xy", point)]
            rows += [Reading(item, "stiffness", spring.stiffness, applied, "set"),
                     Reading(item, "free length", spring.free_length, applied, "set"),
                     Reading(item, "damping", spring.damping,
                             f"{applied}; the rate of length is extrapolated to the step's start", "set")]
        for torque in self.stepper.torques:
            item = force_item(torque)
            rows += [Reading(item, "body", torque.body, applied, "set"),
                     Reading(item, "torque", torque.torque, applied, "set")]
        return rows

    def scene(self) -> list[Reading]:
        peak_rate = self.peak_rate
        c = self.c
        params = p.getPhysicsEngineParameters(physicsClientId=c)
        g = [params[f"gravityAcceleration{axis}"] for axis in "XYZ"]
        links = self.links()
        shapes = sum(len(p.getCollisionShapeData(uid, link, physicsClientId=c)) for uid, link in links)
        joints = [(uid, link, p.getJointInfo(uid, link, physicsClientId=c)) for uid, link in links if link >= 0]
        limits = [f"link {link} of multibody {uid}" for uid, link, info in joints if info[8] <= info[9]]
        limits += [f"{key} set on link {k} of multibody {u}" for f, u, k, kw in self.calls if f == "changeDynamics"
                   for key in ("jointLowerLimit", "jointUpperLimit", "jointLimitForce") if key in kw]
        friction = [f"jointFriction {info[7]:g} on link {link} of multibody {uid}" for uid, link, info in joints if info[7]]
        drives = {(m.joint.handle.uid, m.joint.handle.link) for m in self.stepper.motors}
        laws = {(jt.joint.handle.uid, jt.joint.handle.link) for jt in self.stepper.joint_torques if jt.joint}
        motors = []
        for uid, link, _ in joints:
            if (uid, link) in drives:
                continue
            if (uid, link) in laws:     # TORQUE_CONTROL sets the law's torque, nothing else
                continue
            mode = self.call("setJointMotorControl2", uid, link, "mode", None)
            force = self.call("setJointMotorControl2", uid, link, "force", None)
            if not (mode == p.VELOCITY_CONTROL and force == 0.0):
                motors.append(f"link {link} of multibody {uid}: "
                              + ("PyBullet's default velocity motor" if mode is None else f"mode {mode}, force {force}"))
        body_damping = []
        for uid in self.uids:
            values = [self.call("changeDynamics", uid, None, key, DEFAULT_BODY_DAMPING)
                      for key in ("linearDamping", "angularDamping")]
            if any(values):
                body_damping.append(f"multibody {uid}: linear {values[0]:g}, angular {values[1]:g}")
        clamp = min(self.call("changeDynamics", uid, None, "maxJointVelocity", DEFAULT_SPEED_CLAMP) for uid in self.uids)
        sleeping = [f"activationState on link {k} of multibody {u}" for f, u, k, kw in self.calls
                    if f == "changeDynamics" and "activationState" in kw]
        tree = {(h.handle.uid, h.handle.link) for h in self.model.tree_joints.values()}
        constraints = [f"multibody joint on link {link} of multibody {uid}" for uid, link, _ in joints
                       if (uid, link) not in tree]
        ours = {lc.cid for lc in self.model.constraints.values()}
        constraints += [f"constraint {cid}" for cid in (p.getConstraintUniqueId(i, physicsClientId=c)
                                                        for i in range(p.getNumConstraints(physicsClientId=c)))
                        if cid not in ours]
        no_getter = "No getter in PyBullet 3.2.7: the values the build set (recorded calls)"
        return [
            *(Reading(SCENE, f"gravity {axis}", float(v), "getPhysicsEngineParameters") for axis, v in zip("xyz", g)),
            Reading(SCENE, "contacts", "off" if shapes == 0 else "on",
                    f"{shapes} collision shapes on {len(links)} links and bases"),
            Reading(SCENE, "joint limits", listing(limits), "creation limits (lower ≤ upper) and any set later", "set"),
            Reading(SCENE, "joint friction", listing(friction), "getJointInfo jointFriction"),
            Reading(SCENE, "joint springs", "none", "PyBullet's multibody joints have no springs"),
            Reading(SCENE, "added inertia (armature)", "none", "not a feature of PyBullet"),
            Reading(SCENE, "motors other than the drive", listing(motors),
                    f"{no_getter}: a velocity motor with force 0 is released (the default one acts as friction); "
                    f"the stepping loop sets motors on the drives' joints only{self.free_joints()}", "set"),
            Reading(SCENE, "velocity damping of bodies", listing(body_damping),
                    f"{no_getter}; PyBullet's default is {DEFAULT_BODY_DAMPING} linear and angular", "set"),
            Reading(SCENE, "fluid forces", "none", "not a feature of PyBullet"),
            Reading(SCENE, "velocity clamps", "none" if clamp > peak_rate else f"{clamp:g} (the run reaches {peak_rate:.3g})",
                    f"{no_getter}: maxJointVelocity {clamp:g} (default {DEFAULT_SPEED_CLAMP:g}); the run's fastest "
                    f"joint rate {peak_rate:.3g} at the samples", "set"),
            Reading(SCENE, "sleeping (deactivation)", listing(sleeping),
                    f"{no_getter}: PyBullet puts a multibody to sleep only when asked (activationState, or the "
                    "URDF_ENABLE_SLEEPING flag of a URDF load)", "set"),
            Reading(SCENE, "other dampers", "none",
                    "The stepping loop damps only the Mechanism's damped joints (joint rows)", "set"),
            Reading(SCENE, "other loads", "not readable",
                    "PyBullet has no getter for loads: they are applied per step; the stepping loop applies the "
                    "dampers' loads, the spring-dampers, the body torques (force rows), the torque laws and the "
                    "drive motors only", "note"),
            Reading(SCENE, "other constraints", listing(constraints), "multibody joints and user constraints"),
        ]

    def free_joints(self) -> str:
        """The joints no drive prescribes (those of a free degree of
        freedom among them), for the motors row."""
        if not self.mech.forward_dynamics:
            return ""
        driven = {d.joint for d in self.mech.drives}
        free = [j.name for j in self.mech.joints if j.name not in driven]
        return f"; no motor on the joints no drive prescribes ({', '.join(free)})"

    def notes(self) -> list[Reading]:
        c = self.c
        params = p.getPhysicsEngineParameters(physicsClientId=c)
        solver = {k: v for f, _, _, kw in self.calls if f == "setPhysicsEngineParameter" for k, v in kw.items()
                  if k in ("constraintSolverType", "erp", "globalCFM", "solverResidualThreshold")}
        caps = sorted({p.getConstraintInfo(lc.cid, physicsClientId=c)[10] for lc in self.model.constraints.values()})
        free = [name for name, h in self.model.bodies.items() if h.link < 0]
        return [
            Reading(ENGINE, "time step", f"{params['fixedTimeStep']:.6g} s, {params['numSubSteps']} sub-steps",
                    "Numerical (read back).", "note"),
            Reading(ENGINE, "solver", ", ".join(f"{k} {v:g}" for k, v in solver.items()),
                    "Numerical; as set by the build (no getter).", "note"),
            Reading(ENGINE, "constraint force caps", ", ".join(f"{v:g}" for v in caps) or "no constraints",
                    "An impulse cap converted with the step; far above any reaction of the built-in scenes.", "note"),
            Reading(ENGINE, "free bases", ", ".join(free) or "none",
                    "Bodies that are the free base of a multibody, held to the rest by constraints (layout "
                    "'split': a reaction is read from a sensor only at a leaf hung from the ground, the others "
                    "are derived).", "note"),
        ]
