"""One PyBullet run of a generic planar mechanism: build (`model`),
drive, step and read, converted to the Fij convention (see
`mechval.engines.pybullet.adapter` for the conversions). The adapter (`pybullet`)
and the model audit (`audit`) both build on this module.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import ChainMap
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np
import pandas as pd

from mechval.model.kinematics import joint_gaps, rigid_velocity, rotate_scalar, slide_motion
from mechval.model.mechanism import GROUND, MOTION_QUANTITIES, BodyTorque, Drive, Mechanism, SpringDamper, TorqueLaw

from mechval.engines.base import RawRun, RunInfo, Unrepresentable
from mechval.engines.pybullet.model import (NO_CAP, Model, TreeJoint, build, drive_force_arm, p,  # p: pybullet, imported quietly there
                             start_state)
from mechval.engines.pybullet.slide import NO_EARLIER_STEP, BodyTrack, derived_note, derived_quantities, derived_reaction

#: A body's reading: origin x, y (m), wrapped angle (rad), origin vx, vy
#: (m/s), ω (rad/s), world axes. The ground is always at rest.
BodyState = tuple[float, float, float, float, float, float]
AT_REST: BodyState = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
PREROLL = "preroll_steps"
#: The largest rate (rad/s, m/s) of `steady_start`'s probe: small enough
#: that the engine's velocity-product terms (∝ rate²·dt) are negligible.
PROBE_RATE = 1e-3
#: Why a torque-driven or free run refuses a pre-roll, and what it does instead.
FREE_PREROLL = ("a torque-driven or free run starts at the first instant from the reference's consistent "
                "initial state: there is no prescribed motion to pre-roll along (set 0)")
FREE_START = ("forward dynamics: poses at the first instant from the reference's consistent initial state, "
              "velocities half a step back along its accelerations; no pre-roll")


def run_model(mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any],
              prepare: Callable[[Model], None] | None = None) -> RawRun:
    """Build, step and read one run in its own DIRECT client (always
    disconnected). `prepare(model)` runs on the built model before stepping:
    tests use it to re-arm one PyBullet default and show its effect."""
    dt, per_sample, preroll = step_plan(times, settings)
    if preroll and mechanism.forward_dynamics:
        raise Unrepresentable(f"engines.pybullet.{PREROLL}", FREE_PREROLL)
    started = time.perf_counter()
    t_start = float(times[0]) - preroll * dt
    state = steady_start(mechanism, dt, settings["layout"], t_start) if mechanism.forward_dynamics else None
    model = build(mechanism, dt, settings["layout"], t_start, state)
    try:
        if prepare:
            prepare(model)
        built = time.perf_counter()
        stepper = Stepper(mechanism, model, times, per_sample, preroll)
        frame, steps = stepper.run()
        wall = time.perf_counter() - built
    finally:
        p.disconnect(model.client)
    info = {
        "timestep_used": dt, "steps": steps,
        "closure_gap_max": float(joint_gaps(mechanism, frame).max()),
        "build_time_s": built - started, "wall_time_s": wall,
    }
    if mechanism.drives:
        info["drive_error_max"] = max(
            float(np.abs(drive_coordinate(mechanism, d, frame) - d.law.angle(times)).max()) for d in mechanism.drives)
    if mechanism.forward_dynamics:
        info["start"] = FREE_START
    if stepper.joint_torques:
        info["torque_laws"] = "; ".join(t.describe() for t in stepper.joint_torques)
    missing = {}
    derived = {joint.name for joint, _ in model.derived}
    for name, tree_joint in model.tree_joints.items():
        if (tree_joint.joint.kind == "prismatic" and tree_joint.child != tree_joint.joint.body_j
                and name not in derived):
            frame[f"{name}.M"] = np.nan
            missing[f"{name}.M"] = "the slide's sensor is on body_i: its couple is about body_i's point, not converted"
    if model.derived:
        info["derived_reactions"] = "; ".join(derived_note(joint, body) for joint, body in model.derived)
    if model.derived and preroll == 0:
        missing.update({f"{j.name}.{q}": NO_EARLIER_STEP for j, _ in model.derived for q in derived_quantities(j)})
    return RawRun(frame, missing, RunInfo.of(info))


def steady_start(mechanism: Mechanism, dt: float, layout: str, t0: float) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The reference's initial state (`start_state`) with the mid-step
    rates PyBullet's step carries there, so that its first step's
    constraint forces are not a start-up transient.

    Why: PyBullet makes each step's new velocity v_n+½ satisfy the
    constraints at the step's start (J(q_n)·v_n+½ = −C(q_n)/dt, erp 1),
    so its closed loops ride with a steady gap C ≈ ½·dt²·J̇·v. Built on the
    exact pose (C = 0) with v(t0 − dt/2), the first step misses half the
    J̇·v term of the loop forces, an error that does not shrink with dt
    (measured: the motored slider-crank's B.Fy 0.30 N of its 43.8 N peak
    at t0 at any step, 1e-4 N after; 9e-3 N with these rates). The rates
    that give the first step the steady state's forces: v0 − dt/2·a0 −
    dt/2·Pn·a0, with Pn·a0 the part of the initial accelerations along
    the constraint forces (the kinetic-energy projection, which the
    engine's own solver does): PyBullet finds it in a throw-away copy of
    the model started at rates ε·a0 with no loads, whose step keeps the
    tangential part Pt·(ε·a0) (drives held at ε·φ̈). Not explained: two
    free bases pinned to each other (the five-bars) keep a transient in
    their first two steps (docs/engines.md).
    """
    pose, rates = start_state(mechanism, t0, dt)
    accel = {b.name: tuple(float(pose[f"{b.name}.{q}"].iloc[0]) for q in ("ax", "ay", "alpha"))
             for b in mechanism.bodies}
    size = max(max(abs(a) for a in values) for values in accel.values())
    if size == 0.0:
        return pose, rates
    eps = PROBE_RATE / size
    probe = pose.copy()
    for body, values in accel.items():
        for q, a in zip(("vx", "vy", "omega"), values):
            probe[f"{body}.{q}"] = eps * a
    quiet = dataclasses.replace(mechanism, gravity=(0.0, 0.0))
    model = build(quiet, dt, layout, t0, (pose, probe))
    try:
        stepper = Stepper(quiet, model, np.array([t0]), 1, 0)
        if not model.constraints and not stepper.motors:
            return pose, rates
        for motor in stepper.motors:
            h = motor.joint.handle
            q = p.getJointState(h.uid, h.link, physicsClientId=model.client)[0]
            p.setJointMotorControl2(h.uid, h.link, p.POSITION_CONTROL, targetPosition=q,
                                    targetVelocity=motor.sign * eps * motor.drive.law.alpha, positionGain=1.0,
                                    velocityGain=1.0, force=NO_CAP, physicsClientId=model.client)
        p.stepSimulation(physicsClientId=model.client)
        kept = stepper.read_bodies()
    finally:
        p.disconnect(model.client)
    for body, values in accel.items():
        for k, (q, a) in enumerate(zip(("vx", "vy", "omega"), values)):
            rates[f"{body}.{q}"] -= dt / 2 * (a - kept[body][3 + k] / eps)
    return pose, rates


def drive_coordinate(mechanism: Mechanism, drive: Drive, frame: pd.DataFrame) -> np.ndarray:
    """What `drive` prescribes, from the run's motion: θj − θi of a revolute
    joint, the slide s of a prismatic one."""
    joint = mechanism.joint(drive.joint)
    if joint.kind == "prismatic":
        return np.asarray(slide_motion(frame, joint)["s"], dtype=float)
    angle = lambda body: 0.0 if body == GROUND else frame[f"{body}.theta"]   # noqa: E731 (either may be the ground)
    return np.asarray(angle(joint.body_j) - angle(joint.body_i), dtype=float)


def step_plan(times: np.ndarray, settings: Mapping[str, Any]) -> tuple[float, int, int]:
    """The step dt (the setting, shortened so that a sample interval holds a
    whole number of steps), steps per sample interval, pre-roll steps.
    A single instant has no sample interval: the pre-roll steps at the set step."""
    interval = float(times[1] - times[0]) if len(times) > 1 else settings["timestep"]
    per_sample = max(1, int(np.ceil(interval / settings["timestep"] - 1e-9)))
    return interval / per_sample, per_sample, int(settings["preroll_steps"])


@dataclass(frozen=True)
class Motor:
    """One drive as PyBullet runs it: the position-controlled multibody joint
    of its joint, and the sign of its coordinate (+1 when the link is the
    joint's body_j: q = θj − θi or s; −1 when it is body_i). `arm`: a
    slide drive's `drive_force_arm` where its link is body_j, else 0."""

    drive: Drive
    joint: TreeJoint
    sign: float
    column: str
    arm: float = 0.0


@dataclass(frozen=True)
class JointTorque:
    """One torque law as PyBullet applies it: under TORQUE_CONTROL on the
    multibody joint of its joint (`joint`; `sign` as a Motor's), or, where
    its joint closes a loop as a user constraint or is already under
    control (a drive's motor, another law), as equal and opposite
    external torques, T on body_j and −T on body_i (`joint` None)."""

    law: TorqueLaw
    joint: TreeJoint | None
    sign: float

    @property
    def column(self) -> str:
        return f"{self.law.name}.T"

    def describe(self) -> str:
        how = ("TORQUE_CONTROL on its multibody joint, read back from the joint's sensor (z moment)"
               if self.joint else "equal and opposite external torques on its two bodies, as applied")
        return f"{self.law.name} at {self.law.joint}: {how}"


class Stepper:
    """The stepping loop of one run: drive targets, torque laws, dampers,
    spring-dampers, body torques, readings.

    PyBullet has no spring element between bodies and keeps no load from
    one step to the next, so the Mechanism's dampers, spring-dampers and
    body torques are external loads (`applyExternalForce`/`Torque`) set
    before every step; what was applied in a sampled step is kept for the
    derived slide reactions (`loads`)."""

    def __init__(self, mechanism: Mechanism, model: Model, times: np.ndarray, per_sample: int, preroll: int):
        self.mech, self.model, self.times = mechanism, model, np.asarray(times, dtype=float)
        self.per_sample, self.preroll, self.c = per_sample, preroll, model.client
        self.dt = model.timestep
        self.motors = []
        for d in mechanism.drives:
            joint = mechanism.joint(d.joint)
            tree_joint = model.tree_joints[joint.name]
            on_body_j = tree_joint.child == joint.body_j
            arm = drive_force_arm(mechanism, joint) if joint.kind == "prismatic" and on_body_j else 0.0
            self.motors.append(Motor(d, tree_joint, 1.0 if on_body_j else -1.0, d.effort_column(joint.kind), arm))
        self.joint_torques: list[JointTorque] = []
        controlled = {m.joint.joint.name for m in self.motors}
        for law in mechanism.torque_drives:
            joint = mechanism.joint(law.joint)
            tree_joint = model.tree_joints.get(joint.name) if joint.name not in controlled else None
            controlled.add(joint.name)
            self.joint_torques.append(JointTorque(
                law, tree_joint, 1.0 if tree_joint is None or tree_joint.child == joint.body_j else -1.0))
        #: The external torque-law values applied in the current step.
        self.applied: dict[str, float] = {}
        self.damped = mechanism.damped_joints
        self.springs = tuple(f for f in mechanism.forces if isinstance(f, SpringDamper))
        self.torques = tuple(f for f in mechanism.forces if isinstance(f, BodyTorque))
        #: External loads applied in the current step, per body: force x, y
        #: and its moment about the world origin.
        self.loads: dict[str, list[float]] = {}
        #: Per spring-damper: its length at the last step and its mid-step
        #: rate of length over the last step (None before the first step).
        self.spring_history: dict[str, tuple[float, float | None]] = {}

    def run(self) -> tuple[pd.DataFrame, int]:
        n_samples = len(self.times)
        total = self.preroll + (n_samples - 1) * self.per_sample + 1
        t_next = self.times[0] + (np.arange(total) - self.preroll + 1) * self.dt
        # Lands each drive joint exactly on φ(t_n+1) (motor PD with unit gains).
        targets = [(m, m.sign * (m.drive.law.angle(t_next) - self.dt * m.drive.law.rate(t_next)),
                    m.sign * m.drive.law.rate(t_next)) for m in self.motors]
        # Each law's torque over the step from t_n is T(t_n), as every
        # other load of the step (semi-implicit Euler takes the forces at
        # the step's start).
        laws = [(jt, jt.law.value(t_next - self.dt)) for jt in self.joint_torques]
        before, after, reactions, earlier, loads = [], [], [], [], []
        previous_rates = state = None
        every_step = bool(self.damped or self.springs)
        sampled_at = lambda n: n >= self.preroll and (n - self.preroll) % self.per_sample == 0  # noqa: E731
        for n in range(total):
            sampled = sampled_at(n)
            # The positions one step before each sample: the linear rates
            # at a sample are central differences (`assemble`), and a
            # derived reaction (slide) needs them too.
            if sampled or every_step or sampled_at(n + 1):
                previous, state = state, self.read_bodies()
            if sampled:
                before.append(state)
                earlier.append(previous if n > 0 else None)
            self.loads = {}
            if self.damped:
                previous_rates = self.apply_dampers(state, previous_rates)
            if self.springs:
                self.apply_springs(state)
            if self.torques:
                self.apply_torques()
            if sampled:
                loads.append(self.loads)
            for jt, torque in laws:
                self.apply_torque_law(jt, float(torque[n]))
            for motor, target_pos, target_vel in targets:
                h = motor.joint.handle
                p.setJointMotorControl2(h.uid, h.link, p.POSITION_CONTROL, targetPosition=target_pos[n],
                                        targetVelocity=target_vel[n], positionGain=1.0, velocityGain=1.0,
                                        force=NO_CAP, physicsClientId=self.c)
            p.stepSimulation(physicsClientId=self.c)
            if sampled:
                after.append(self.read_bodies())
                reactions.append(self.read_reactions())
        frame = self.assemble(earlier, before, after, reactions)
        if self.model.derived:
            frame = frame.assign(**self.derived_reactions(frame, earlier, before, after, loads))
        return frame, total

    def read_bodies(self) -> dict[str, BodyState]:
        """Per body: frame origin x, y, wrapped angle, origin vx, vy, ω.
        Scalar `math` throughout: this runs every step in damped scenes."""
        state = {}
        for body in self.mech.bodies:
            h = self.model.bodies[body.name]
            if h.link < 0:
                pos, orn = p.getBasePositionAndOrientation(h.uid, physicsClientId=self.c)
                vel, ang = p.getBaseVelocity(h.uid, physicsClientId=self.c)
            else:
                s = p.getLinkState(h.uid, h.link, computeLinkVelocity=1, computeForwardKinematics=1,
                                   physicsClientId=self.c)
                pos, orn, vel, ang = s[0], s[1], s[6], s[7]
            x, y, z, w = orn
            theta = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
            # PyBullet reports the COM; shift to the body frame origin.
            r = rotate_scalar(theta, (-body.com[0], -body.com[1]))
            vx, vy = rigid_velocity(vel[0], vel[1], ang[2], r)
            state[body.name] = (pos[0] + r[0], pos[1] + r[1], theta, vx, vy, ang[2])
        return state

    def joint_rates(self, state: dict[str, BodyState]) -> dict[str, float]:
        """Relative rate of every damped joint: ω_j − ω_i, or the slide speed
        of point_j relative to point_i along the axis (fixed in body_i)."""
        rates = {}
        for joint in self.damped:
            si, sj = state.get(joint.body_i, AT_REST), state.get(joint.body_j, AT_REST)
            if joint.kind == "revolute":
                rates[joint.name] = sj[5] - si[5]
                continue
            ux, uy = rotate_scalar(si[2], joint.axis)
            vi = _point_velocity(si, joint.point_i)
            vj = _point_velocity(sj, joint.point_j)
            rates[joint.name] = (vj[0] - vi[0]) * ux + (vj[1] - vi[1]) * uy
        return rates

    def apply_dampers(self, state: dict[str, BodyState], previous: dict[str, float] | None) -> dict[str, float]:
        """Equal and opposite damper loads for the coming step, with rates
        extrapolated to t_n (1.5·v_n − 0.5·v_n−1: the readings are mid-step
        values; plain v_n is O(dt), docs/engines.md). Returns this step's rates."""
        rates = self.joint_rates(state)
        previous = previous or rates
        for joint in self.damped:
            load = -joint.damping * (1.5 * rates[joint.name] - 0.5 * previous[joint.name])
            for body, sign in ((joint.body_j, 1.0), (joint.body_i, -1.0)):
                if body == GROUND:
                    continue
                h = self.model.bodies[body]
                on_body = self.loads.setdefault(body, [0.0, 0.0, 0.0])
                if joint.kind == "revolute":
                    p.applyExternalTorque(h.uid, h.link, (0.0, 0.0, sign * load), p.WORLD_FRAME,
                                          physicsClientId=self.c)
                    on_body[2] += sign * load
                    continue
                ux, uy = rotate_scalar(state.get(joint.body_i, AT_REST)[2], joint.axis)
                sj = state[joint.body_j]
                px, py = rotate_scalar(sj[2], joint.point_j)
                fx, fy, x, y = sign * load * ux, sign * load * uy, sj[0] + px, sj[1] + py
                p.applyExternalForce(h.uid, h.link, (fx, fy, 0.0), (x, y, 0.0), p.WORLD_FRAME,
                                     physicsClientId=self.c)
                on_body[0] += fx
                on_body[1] += fy
                on_body[2] += x * fy - y * fx
        return rates

    def push(self, body: str, force: tuple[float, float], at: tuple[float, float], torque: float = 0.0) -> None:
        """Apply a load on a moving body for the coming step (world axes,
        force at a world point, plus a couple) and record it in `loads`."""
        h = self.model.bodies[body]
        on_body = self.loads.setdefault(body, [0.0, 0.0, 0.0])
        if force != (0.0, 0.0):
            p.applyExternalForce(h.uid, h.link, (force[0], force[1], 0.0), (at[0], at[1], 0.0), p.WORLD_FRAME,
                                 physicsClientId=self.c)
            on_body[0] += force[0]
            on_body[1] += force[1]
            on_body[2] += at[0] * force[1] - at[1] * force[0]
        if torque:
            p.applyExternalTorque(h.uid, h.link, (0.0, 0.0, torque), p.WORLD_FRAME, physicsClientId=self.c)
            on_body[2] += torque

    def apply_springs(self, state: dict[str, BodyState]) -> None:
        """Each spring-damper's tension k·(ℓ − ℓ0) + c·ℓ̇ along the line of
        its points, pulling them together, for the coming step. ℓ is read
        at t_n; ℓ̇ at t_n is the mid-step rate (ℓ_n − ℓ_n−1)/dt extrapolated,
        1.5·v_n − 0.5·v_n−1 (as the joint dampers' rates; i.e. the
        second-order backward difference of ℓ). The first step, with no
        earlier length, takes the rate of the point velocities as read."""
        for spring in self.springs:
            sa, sb = state.get(spring.body_a, AT_REST), state.get(spring.body_b, AT_REST)
            ra, rb = rotate_scalar(sa[2], spring.point_a), rotate_scalar(sb[2], spring.point_b)
            pa, pb = (sa[0] + ra[0], sa[1] + ra[1]), (sb[0] + rb[0], sb[1] + rb[1])
            dx, dy = pb[0] - pa[0], pb[1] - pa[1]
            length = math.hypot(dx, dy)
            ex, ey = dx / length, dy / length
            last = self.spring_history.get(spring.name)
            if last is None:
                va, vb = _point_velocity(sa, spring.point_a), _point_velocity(sb, spring.point_b)
                mid = (vb[0] - va[0]) * ex + (vb[1] - va[1]) * ey
            else:
                mid = (length - last[0]) / self.dt
            previous_mid = mid if last is None or last[1] is None else last[1]
            self.spring_history[spring.name] = (length, mid)
            tension = (spring.stiffness * (length - spring.free_length)
                       + spring.damping * (1.5 * mid - 0.5 * previous_mid))
            for body, point, sign in ((spring.body_a, pa, 1.0), (spring.body_b, pb, -1.0)):
                if body != GROUND:
                    self.push(body, (sign * tension * ex, sign * tension * ey), point)

    def apply_torque_law(self, jt: JointTorque, torque: float) -> None:
        """A torque law's T for the coming step. PyBullet keeps neither a
        TORQUE_CONTROL torque nor an external load beyond one step (measured),
        so it is set before every step. Not in `loads`: the derived slide
        reactions count a torque law by its column, as a drive's effort."""
        if jt.joint is not None:
            h = jt.joint.handle
            p.setJointMotorControl2(h.uid, h.link, p.TORQUE_CONTROL, force=jt.sign * torque, physicsClientId=self.c)
            return
        self.applied[jt.column] = torque
        joint = self.mech.joint(jt.law.joint)
        for body, sign in ((joint.body_j, 1.0), (joint.body_i, -1.0)):
            if body != GROUND:
                h = self.model.bodies[body]
                p.applyExternalTorque(h.uid, h.link, (0.0, 0.0, sign * torque), p.WORLD_FRAME, physicsClientId=self.c)

    def apply_torques(self) -> None:
        """Every constant body torque, for the coming step."""
        for torque in self.torques:
            if torque.body != GROUND:
                self.push(torque.body, (0.0, 0.0), (0.0, 0.0), torque.torque)

    def read_reactions(self) -> dict[str, float]:
        """Fij of every joint and the drive torque, from the step just taken."""
        out = {}
        for name, tj in self.model.tree_joints.items():
            force = p.getJointState(tj.handle.uid, tj.handle.link, physicsClientId=self.c)[2]
            sign = 1.0 if tj.child == tj.joint.body_j else -1.0
            out[f"{name}.Fx"], out[f"{name}.Fy"] = sign * force[0], sign * force[1]
            if tj.joint.kind == "prismatic" and sign > 0:
                # Couple about the child's link origin, point_j (measured).
                out[f"{name}.M"] = force[5]
        for name, lc in self.model.constraints.items():
            force = p.getConstraintState(lc.cid, physicsClientId=self.c)
            sign = 1.0 if lc.child == lc.joint.body_j else -1.0
            out[f"{name}.Fx"], out[f"{name}.Fy"] = sign * force[0], sign * force[1]
        for motor in self.motors:
            h = motor.joint.handle
            out[motor.column] = motor.sign * p.getJointState(h.uid, h.link, physicsClientId=self.c)[3]
            if motor.arm:
                out[f"{motor.drive.joint}.M"] += motor.arm * out[motor.column]
        for jt in self.joint_torques:
            if jt.joint is None:
                out[jt.column] = self.applied[jt.column]
                continue
            # Under TORQUE_CONTROL getJointState's applied torque reads 0;
            # the sensor's z moment at the joint point is the joint torque.
            h = jt.joint.handle
            out[jt.column] = jt.sign * p.getJointState(h.uid, h.link, physicsClientId=self.c)[2][5]
        return out

    def derived_reactions(self, frame: pd.DataFrame, earlier: list, before: list, after: list,
                          loads: list) -> dict[str, np.ndarray]:
        """Every derived joint's reaction (slide), replacing the
        sensor's reading; each sees those derived before it."""
        tracks = {b: BodyTrack(np.array([s[b] if s else (np.nan,) * 6 for s in earlier]),
                               np.array([s[b] for s in before]), np.array([s[b] for s in after]))
                  for b in (body.name for body in self.mech.bodies)}
        columns: dict[str, np.ndarray] = {}
        for joint, body in self.model.derived:
            applied = np.array([step.get(body, (0.0, 0.0, 0.0)) for step in loads])
            columns.update(derived_reaction(self.mech, joint, body, tracks, ChainMap(columns, frame),
                                            applied, self.dt))
        return columns

    def assemble(self, earlier: list, before: list, after: list, reactions: list) -> pd.DataFrame:
        """Raw columns at the samples (see the module docstring for stamps)."""
        columns: dict[str, np.ndarray] = {"t": self.times}
        t_start = self.times[0] - self.preroll * self.dt
        start = self.model.start
        for body in self.mech.bodies:
            b = body.name
            pre = np.array([s[b] for s in before])
            post = np.array([s[b] for s in after])
            vel = 0.5 * (pre[:, 3:] + post[:, 3:])
            acc = (post[:, 3:] - pre[:, 3:]) / self.dt
            # The frame origin's velocity and acceleration from its
            # positions one step either side (O(dt²) about t_n): each
            # velocity reading maps the mid-step joint rates through the
            # Jacobian at the step's end, so their mean and difference are
            # O(dt) off wherever the origin's motion depends on the
            # configuration (ω·α·r·dt in a coupler's acceleration). Angular
            # rates are sums of joint rates, exact as read. A sample with
            # no step before it (a free run's first) keeps the readings.
            back = [k for k, s in enumerate(earlier) if s is not None]
            if back:
                x_back = np.array([earlier[k][b][:2] for k in back])
                vel[back, :2] = (post[back, :2] - x_back) / (2 * self.dt)
                acc[back, :2] = (post[back, :2] - 2 * pre[back, :2] + x_back) / self.dt ** 2
            theta = _unwrap(pre[:, 2], vel[:, 2], self.times,
                            float(start[f"{b}.theta"].iloc[0]), float(start[f"{b}.omega"].iloc[0]), t_start)
            values = (pre[:, 0], pre[:, 1], theta, vel[:, 0], vel[:, 1], vel[:, 2], acc[:, 0], acc[:, 1], acc[:, 2])
            columns.update({f"{b}.{q}": v for q, v in zip(MOTION_QUANTITIES, values)})
        for key in reactions[0]:
            columns[key] = np.array([r[key] for r in reactions])
        return pd.DataFrame(columns)


def _point_velocity(s: BodyState, point: tuple[float, float]) -> tuple[float, float]:
    """World velocity of a body-fixed point from the body's reading."""
    return rigid_velocity(s[3], s[4], s[5], rotate_scalar(s[2], point))


def _unwrap(wrapped: np.ndarray, omega: np.ndarray, t: np.ndarray, theta0: float, omega0: float,
            t0: float) -> np.ndarray:
    """Continuous angles anchored at the reference start: each sample takes
    the 2π branch nearest the angle predicted from the previous one with the
    mean rate (robust however far a body turns between samples)."""
    out = np.empty_like(wrapped)
    prev, prev_w, prev_t = theta0, omega0, t0
    for k, (a, w) in enumerate(zip(wrapped, omega)):
        guess = prev + 0.5 * (prev_w + w) * (t[k] - prev_t)
        out[k] = a + 2 * np.pi * np.round((guess - a) / (2 * np.pi))
        prev, prev_w, prev_t = out[k], w, t[k]
    return out
