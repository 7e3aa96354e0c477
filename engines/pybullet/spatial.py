"""One PyBullet 3.2.7 run of a spatial scene (`run_spatial`): start from
the reference, build (`spatial_build`), drive, load, step, read, and
convert to mechval's raw spatial columns (`SpatialSystem.motion_columns`,
`reaction_columns`).

Readings and their stamps (as for planar scenes, docs/engines.md):
- pose at t_n: each body's centre-of-mass frame before the step from t_n
  (PyBullet's URDF link frame is rounded to single precision); the frame
  origin and quaternion (w ≥ 0) follow;
- the origin's velocity and acceleration: central differences of its
  positions one step either side, and ω and α likewise from the attitudes
  (the turns over the steps before and after t_n): a velocity reading maps
  the mid-step joint rates through the Jacobian at the step's end, O(dt)
  off wherever the motion depends on the configuration (the planar
  adapter's lesson; for ω as soon as joint axes turn); a free run's first
  sample, with no step before it, keeps the readings (ω the mean of those
  either side of the step, α their difference);
- forces read after the step from t_n acted during it: stamped t_n.

Reactions: a loop joint's from its constraints' forces (on the child,
world axes; a revolute loop joint's moment from its second constraint at
`AXIS_ARM` along the axis). A tree joint's are derived from the
Newton–Euler balance of the bodies below it with PyBullet's own motion
and the loads applied (`spatial_reactions`), because PyBullet's joint
sensor misreads every joint but a leaf hung from the ground (planar
findings `pybullet.non-leaf-sensor`, `pybullet.slide-sensor-turning-parent`);
a drive's effort is its motor's applied torque or force as read.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from mechval.adapter import RawRun, RunInfo, Unrepresentable
from mechval.engines.pybullet.model import NO_CAP, p
from mechval.engines.pybullet.spatial_build import AXIS_ARM, SpatialModel, build_spatial, buildable, principal
from mechval.engines.pybullet.spatial_reactions import Loads, tree_reactions
from mechval.engines.pybullet.spatial_split import is_weld
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.mechanism import spatial_solution
from mechval.reference.spatial.rotation import matrix_to_quaternion, quaternion_to_matrix
from mechval.reference.spatial.system import SpatialSystem

FREE_PREROLL = ("a torque-driven or free run starts at the first instant from the reference's consistent "
                "initial state: there is no prescribed motion to pre-roll along (set 0)")

#: A body's reading: origin (3), rotation matrix (3×3), origin velocity (3), ω (3), world.
Reading = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _columns(frame: pd.DataFrame, body: str, names: str) -> np.ndarray:
    return frame[[f"{body}.{n}" for n in names.split()]].to_numpy(dtype=float)[0]


def start_state(system: SpatialSystem, t_start: float, dt: float, free: bool):
    """Poses at t_start and the mid-step rates of t_start − dt/2 (prescribed:
    the reference there; free: v − a·dt/2 from the consistent initial state)."""
    if free:
        # Two instants: the dynamics reference integrates over an interval (one instant fails).
        pose = spatial_solution(system, np.array([t_start, t_start + dt])).frame.iloc[:1]
        rates = pose.copy()
        for b in system.bodies:
            for v, a in zip(("vx", "vy", "vz", "wx", "wy", "wz"), ("ax", "ay", "az", "alphax", "alphay", "alphaz")):
                rates[f"{b.name}.{v}"] -= dt / 2 * pose[f"{b.name}.{a}"]
        return pose, rates
    both = spatial_solution(system, np.array([t_start - dt / 2, t_start])).frame
    return both.iloc[1:].reset_index(drop=True), both.iloc[:1].reset_index(drop=True)


def _with_twins(frame: pd.DataFrame, twins: dict[str, str]) -> pd.DataFrame:
    """The reference's columns with each split body's twin as the body."""
    extra = {f"{twin}.{c.split('.', 1)[1]}": frame[c] for twin, body in twins.items()
             for c in frame.columns if c.startswith(body + ".")}
    return frame.assign(**extra) if extra else frame


def set_rates(system: SpatialSystem, model: SpatialModel, pose: pd.DataFrame, rates: pd.DataFrame) -> None:
    """Joint rates (and free bases' velocities) from the reference's body
    rates: each tree joint's relative twist at its child's link origin on
    its PyBullet joints' axes (least squares; exact for a consistent state)."""
    c = model.client
    origin, rot, vel, omega = {GROUND: np.zeros(3)}, {GROUND: np.eye(3)}, {GROUND: np.zeros(3)}, {GROUND: np.zeros(3)}
    for b in system.bodies:
        origin[b.name] = _columns(pose, b.name, "x y z")
        rot[b.name] = quaternion_to_matrix(_columns(pose, b.name, "qw qx qy qz"))
        vel[b.name] = _columns(rates, b.name, "vx vy vz")
        omega[b.name] = _columns(rates, b.name, "wx wy wz")
    point_velocity = lambda body, x: vel[body] + np.cross(omega[body], x - origin[body])  # noqa: E731
    for b in system.bodies:
        if model.parent_joint[b.name] is None:
            com = origin[b.name] + rot[b.name] @ np.asarray(b.com, float)
            p.resetBaseVelocity(model.handles[b.name][0], tuple(point_velocity(b.name, com)),
                                tuple(omega[b.name]), physicsClientId=c)
    for tj in model.tree.values():
        x = origin[tj.child] + rot[tj.child] @ model.anchors[tj.child]
        twist = np.concatenate([omega[tj.child] - omega[tj.parent],
                                point_velocity(tj.child, x) - point_velocity(tj.parent, x)])
        columns = []
        for dof in tj.dofs:
            if dof.kind == p.JOINT_REVOLUTE:
                columns.append(np.concatenate([dof.axis, np.zeros(3)]))
            elif dof.kind == p.JOINT_PRISMATIC:
                columns.append(np.concatenate([np.zeros(3), dof.axis]))
            elif dof.kind == p.JOINT_SPHERICAL:
                # PyBullet's spherical joint rate: ω in the child link's axes.
                columns += [np.concatenate([rot[tj.child][:, k], np.zeros(3)]) for k in range(3)]
        if not columns:
            continue
        rate = np.linalg.lstsq(np.array(columns).T, twist, rcond=None)[0]
        k = 0
        for link, dof in zip(tj.links, tj.dofs):
            if dof.kind == p.JOINT_SPHERICAL:
                p.resetJointStateMultiDof(tj.uid, link, targetValue=(0.0, 0.0, 0.0, 1.0),
                                          targetVelocity=tuple(rate[k:k + 3]), physicsClientId=c)
                k += 3
            elif dof.kind != p.JOINT_FIXED:
                p.resetJointState(tj.uid, link, 0.0, float(rate[k]), physicsClientId=c)
                k += 1


class Reader:
    """Each body's pose and rates from PyBullet (see the module docstring)."""

    def __init__(self, system: SpatialSystem, model: SpatialModel):
        self.c = model.client
        self.bodies = []
        for b in system.bodies:
            uid, link = model.handles[b.name]
            self.bodies.append((b.name, uid, link, np.asarray(b.com, float), principal(b.inertia)[1].T))

    def read(self) -> dict[str, Reading]:
        out = {}
        for name, uid, link, com, to_body in self.bodies:
            if link < 0:
                x, q = p.getBasePositionAndOrientation(uid, physicsClientId=self.c)
                v, w = p.getBaseVelocity(uid, physicsClientId=self.c)
            else:
                # The centre-of-mass frame: PyBullet's URDF link frame (s[4], s[5]) is
                # rounded to single precision (measured: 3e-8 in a quaternion).
                x, q, _, _, _, _, v, w = p.getLinkState(uid, link, computeLinkVelocity=1,
                                                        computeForwardKinematics=1, physicsClientId=self.c)
            R = _matrix(q) @ to_body
            w = np.array(w)
            arm = R @ com
            out[name] = (np.array(x) - arm, R, np.array(v) - np.cross(w, arm), w)
        return out


def _matrix(q) -> np.ndarray:
    return np.array(p.getMatrixFromQuaternion(q)).reshape(3, 3)


@dataclass(frozen=True)
class Start:
    """A model built as a run starts it: the system PyBullet builds (split
    bodies' halves), {twin: body}, the model in the start pose, the
    reference's pose and mid-step rates there (twins included), the step
    and the samples' plan."""

    built: SpatialSystem
    twins: dict[str, str]
    model: SpatialModel
    pose: pd.DataFrame
    rates: pd.DataFrame
    dt: float
    per_sample: int
    preroll: int


def start_model(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> Start:
    """Build `system` in the pose a run of it at `times` starts from (its
    own DIRECT client: the caller disconnects it)."""
    from mechval.engines.pybullet.run import step_plan
    built, twins = buildable(system)    # refused before any solve
    dt, per_sample, preroll = step_plan(np.asarray(times, dtype=float), settings)
    free = system.forward_dynamics
    if preroll and free:
        raise Unrepresentable("engines.pybullet.preroll_steps", FREE_PREROLL)
    t_start = float(times[0]) - preroll * dt
    pose, rates = start_state(system, t_start, dt, free)
    pose, rates = _with_twins(pose, twins), _with_twins(rates, twins)
    pos = {b.name: _columns(pose, b.name, "x y z") for b in built.bodies}
    rot = {b.name: quaternion_to_matrix(_columns(pose, b.name, "qw qx qy qz")) for b in built.bodies}
    return Start(built, twins, build_spatial(built, dt, pos, rot), pose, rates, dt, per_sample, preroll)


def run_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
    """Build, step and read one run of `system` at instants `times` with the
    adapter's settings (timestep, preroll_steps); its own DIRECT client,
    always disconnected."""
    times = np.asarray(times, dtype=float)
    started = time.perf_counter()
    start = start_model(system, times, settings)
    built, twins, model = start.built, start.twins, start.model
    try:
        set_rates(built, model, start.pose, start.rates)
        ready = time.perf_counter()
        frame, steps, loads = Stepper(built, model, times, start.per_sample, start.preroll, system).run()
        wall = time.perf_counter() - ready
    finally:
        p.disconnect(model.client)
    frame = frame.assign(**tree_reactions(built, model, frame, loads))
    info = {"timestep_used": start.dt, "steps": steps, "build_time_s": ready - started, "wall_time_s": wall,
            "tree_joints": ", ".join(model.tree), "loop_joints": ", ".join(model.loops) or "none",
            "split_bodies": ", ".join(twins.values()) or "none",
            "reactions": "loop joints: their constraints' forces; tree joints: derived from the balance of the "
                         "bodies below them with PyBullet's motion and loads (its sensor misreads)"}
    columns = ["t", *system.motion_columns(), *system.reaction_columns()]
    return RawRun(frame[columns], {}, RunInfo.of(info))


class Stepper:
    """Drives, loads and readings of one run."""

    def __init__(self, system: SpatialSystem, model: SpatialModel, times: np.ndarray, per_sample: int, preroll: int,
                 scene: SpatialSystem | None = None):
        # `system` is what PyBullet builds (split bodies' halves); `scene`
        # the user's, whose loads apply (to a split body's first half).
        self.system, self.model, self.times = system, model, times
        self.per_sample, self.preroll, self.dt, self.c = per_sample, preroll, model.timestep, model.client
        self.reader = Reader(system, model)
        self.loads = Loads(scene or system)
        self.motors = []
        for d in system.drives:
            tj = model.tree[d.joint]
            sign = 1.0 if tj.child == tj.joint.body_j else -1.0
            self.motors.append((d, tj.uid, tj.links[-1], sign))

    def run(self) -> tuple[pd.DataFrame, int, list]:
        n_samples = len(self.times)
        total = self.preroll + (n_samples - 1) * self.per_sample + 1
        t_now = self.times[0] + (np.arange(total) - self.preroll) * self.dt
        t_next = t_now + self.dt
        t0 = t_now[0]
        # Each drive joint lands on φ(t_n+1) (unit-gain PD, as for planar scenes);
        # coordinates count from the start pose.
        targets = [(uid, link, sign * (d.law.angle(t_next) - self.dt * d.law.rate(t_next) - d.law.angle(t0)),
                    sign * d.law.rate(t_next)) for d, uid, link, sign in self.motors]
        sampled_at = lambda n: n >= self.preroll and (n - self.preroll) % self.per_sample == 0  # noqa: E731
        every = self.loads.needs_every_step
        before, after, earlier, reactions, applied = [], [], [], [], []
        state = previous = None
        for n in range(total):
            sampled = sampled_at(n)
            if sampled or every or sampled_at(n + 1) or state is None:
                previous, state = state, self.reader.read()
            if sampled:
                before.append(state)
                earlier.append(previous if n > 0 else None)
            step_loads = self.loads.apply(self.model, state, float(t_now[n]), self.dt)
            for uid, link, target_pos, target_vel in targets:
                p.setJointMotorControl2(uid, link, p.POSITION_CONTROL, targetPosition=target_pos[n],
                                        targetVelocity=target_vel[n], positionGain=1.0, velocityGain=1.0,
                                        force=NO_CAP, physicsClientId=self.c)
            p.stepSimulation(physicsClientId=self.c)
            if sampled:
                applied.append(step_loads)
                after.append(self.reader.read())
                reactions.append(self.read_reactions(before[-1]))
        return self.assemble(earlier, before, after, reactions), total, applied

    def read_reactions(self, state: dict[str, Reading]) -> dict[str, float]:
        out = {}
        for name, loop in self.model.loops.items():
            j = loop.joint
            if is_weld(j):
                # PyBullet reports a fixed constraint's load on its parent: the
                # force in world axes, the moment (about the pivot) in the
                # parent's centre-of-mass axes (measured: the delta's joint
                # moments off by 24× their bound read in world axes, 6e-4× so).
                load = -np.array(p.getConstraintState(loop.cids[0], physicsClientId=self.c))
                load[3:] = state[j.body_i][1] @ principal(self.system.body(j.body_i).inertia)[1] @ load[3:]
                for k, axis in enumerate("xyz"):
                    out[f"{name}.F{axis}"], out[f"{name}.M{axis}"] = load[k], load[3 + k]
                continue
            forces = [np.array(p.getConstraintState(cid, physicsClientId=self.c)[:3]) for cid in loop.cids]
            force = sum(forces)
            moment = np.zeros(3)
            if len(forces) == 2:
                zj = (state[j.body_j][1] if j.body_j != GROUND else np.eye(3)) @ j.frame_j[:, 2]
                moment = np.cross(AXIS_ARM * zj, forces[1])
            for k, axis in enumerate("xyz"):
                out[f"{name}.F{axis}"], out[f"{name}.M{axis}"] = force[k], moment[k]
        for d, uid, link, sign in self.motors:
            kind = self.system.joint(d.joint).kind
            out[f"{d.name}.{'T' if kind == 'revolute' else 'F'}"] = sign * p.getJointState(
                uid, link, physicsClientId=self.c)[3]
        for law, value in self.loads.torque_values.items():
            out[f"{law}.T"] = value
        return out

    def assemble(self, earlier, before, after, reactions) -> pd.DataFrame:
        columns: dict[str, np.ndarray] = {"t": self.times}
        back = [k for k, s in enumerate(earlier) if s is not None]
        for b in self.system.bodies:
            name = b.name
            x = np.array([s[name][0] for s in before])
            R = np.array([s[name][1] for s in before])
            v = 0.5 * (np.array([s[name][2] for s in before]) + np.array([s[name][2] for s in after]))
            a = (np.array([s[name][2] for s in after]) - np.array([s[name][2] for s in before])) / self.dt
            w_pre, w_post = np.array([s[name][3] for s in before]), np.array([s[name][3] for s in after])
            w, al = 0.5 * (w_pre + w_post), (w_post - w_pre) / self.dt
            if back:
                x_back = np.array([earlier[k][name][0] for k in back])
                x_after = np.array([after[k][name][0] for k in back])
                v[back] = (x_after - x_back) / (2 * self.dt)
                a[back] = (x_after - 2 * x[back] + x_back) / self.dt ** 2
                # The same for the attitude: the turns over the step before
                # and the step after t_n (a reading of ω maps mid-step joint
                # rates through the end of the step's axes, O(dt) off once
                # the axes turn).
                R_back = np.array([earlier[k][name][1] for k in back])
                R_after = np.array([after[k][name][1] for k in back])
                turn_in = Rotation.from_matrix(R[back] @ np.swapaxes(R_back, 1, 2)).as_rotvec() / self.dt
                turn_out = Rotation.from_matrix(R_after @ np.swapaxes(R[back], 1, 2)).as_rotvec() / self.dt
                w[back] = Rotation.from_matrix(R_after @ np.swapaxes(R_back, 1, 2)).as_rotvec() / (2 * self.dt)
                al[back] = (turn_out - turn_in) / self.dt
            q = matrix_to_quaternion(R)
            values = {"x": x[:, 0], "y": x[:, 1], "z": x[:, 2], "qw": q[:, 0], "qx": q[:, 1], "qy": q[:, 2],
                      "qz": q[:, 3]}
            for k, axis in enumerate("xyz"):
                values[f"v{axis}"], values[f"a{axis}"] = v[:, k], a[:, k]
                values[f"w{axis}"], values[f"alpha{axis}"] = w[:, k], al[:, k]
            columns.update({f"{name}.{q_}": val for q_, val in values.items()})
        for key in reactions[0]:
            columns[key] = np.array([r[key] for r in reactions])
        return pd.DataFrame(columns)
