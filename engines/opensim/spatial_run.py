"""One OpenSim run of a spatial scene: the start state from the spatial
reference, Simbody's error-controlled integration to each sample, and the
read-out in mechval's conventions (`run_spatial`).

Read-out:
- Body motion: each OpenSim body's frame is the scene body's frame, so
  `getTransformInGround`, `getVelocityInGround`, `getAccelerationInGround`
  (spatial vectors, angular first, ground axes, of the frame origin) are
  the raw columns; the quaternion from the rotation matrix (w ≥ 0).
- Tree joint: `calcReactionOnChildExpressedInGround` is the load on the
  child at its joint point, ground axes, including the mobility forces
  applied across the joint (damper, torque law), which come out first.
  Child body_j: Fij as is; child body_i (a reversed joint): body_j gets the
  opposite, moved to Pj. A drive's effort is Fij's component along zi (T
  of the moment, F of the force), taken out of the reaction as the
  reference does.
- Loop closure: each constraint's forces on body_j (`calcConstraintForces`,
  spatial forces at the body origins, ground axes, with Simbody's sign of
  the term on the left of M·u̇ + Gᵀ·λ = f: negated), summed and moved to Pj.
- A run re-anchors a Ball or Free joint's Euler chart when its second
  angle passes RECHART_ANGLE: the model is built again with the chart at
  the state reached, and the integration goes on from that state.
"""

from __future__ import annotations

import math
import time
from typing import Any, Mapping

import numpy as np
import opensim as osim
import pandas as pd

from mechval.model.mechanism import GROUND
from mechval.reference.spatial.dynamics import SpatialDynamics
from mechval.reference.spatial.mechanism import spatial_solution
from mechval.reference.spatial.rotation import matrix_to_quaternion, quaternion_to_matrix
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.base import RawRun, RunInfo
from mechval.engines.opensim.model import quiet
from mechval.engines.opensim.run import INTEGRATORS, MIN_STEP_FRACTION, step_limit
from mechval.engines.opensim.spatial_model import CHARTED, DAMPED, SpatialModel, build_spatial_model, cut_joints, euler_xyz

#: Re-anchor a Ball or Free joint's Euler chart past this second angle (rad):
#: the kinematic map q̇ = N(q)·u grows as 1/cos of it (singular at π/2).
#: Simbody's error control copes with a near pass, at a cost in accuracy:
#: a body spun about a principal axis with a 1e-5 wobble passes 0.012 rad
#: from the singularity, and without re-anchoring its quaternions are 7.5e-11
#: off the reference (7.5e-12 with it), accelerations 5.4e-6 of their peak
#: (7.3e-7).
RECHART_ANGLE = 1.0

World = dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]   # body → R, origin, v, ω


def start_world(system: SpatialSystem, times: np.ndarray) -> World:
    """The reference's state at times[0] (the only read of the reference):
    a prescribed scene solved there, a forward-dynamics one's consistent
    initial state (`SpatialDynamics`: centres of mass and their velocities,
    moved here to the body origins)."""
    if not system.forward_dynamics:
        return world_from_frame(system, spatial_solution(system, times[:1]).frame)
    dynamics = SpatialDynamics(system, system.velocities, t0=float(times[0]))
    pose, w = dynamics.pose0, dynamics.w0[0]
    out = {}
    for k, body in enumerate(system.bodies):
        R = pose.A[0, k]
        arm = R @ np.asarray(body.com, dtype=float)
        omega = w[k, 3:]
        out[body.name] = (R, pose.G[0, k] - arm, w[k, :3] - np.cross(omega, arm), omega)
    return out


def world_from_frame(system: SpatialSystem, frame: pd.DataFrame, row: int = 0) -> World:
    """Every body's pose and velocity in one row of raw columns."""
    out = {}
    for body in system.bodies:
        get = lambda qs: np.array([float(frame[f"{body.name}.{q}"].iloc[row]) for q in qs])   # noqa: E731
        out[body.name] = (quaternion_to_matrix(get(("qw", "qx", "qy", "qz"))), get(("x", "y", "z")),
                          get(("vx", "vy", "vz")), get(("wx", "wy", "wz")))
    return out


def scene_length(system: SpatialSystem) -> float:
    """A length of the scene's size: the largest joint point or centre of
    mass from its body's origin, at least 0.1 m."""
    sizes = [np.linalg.norm(p) for j in system.joints for p in (j.point_i, j.point_j)]
    sizes += [np.linalg.norm(b.com) for b in system.bodies]
    return max([0.1, *sizes])


def _frame_motion(world: World, body: str, point: np.ndarray, frame: np.ndarray):
    """World rotation, origin, origin's velocity and ω of a frame fixed in
    `body` at `point` (body axes)."""
    if body == GROUND:
        return frame, point, np.zeros(3), np.zeros(3)
    R, o, v, w = world[body]
    arm = R @ point
    return R @ frame, o + arm, v + np.cross(w, arm), w


def coordinate_values(built: SpatialModel, world: World, t: float) -> dict[str, list[tuple[float, float]]]:
    """(q, u) of every OpenSim coordinate from the bodies' world state: the
    child frame M relative to the parent frame F (R_FM, p_FM, ω and v of M
    in F, F's axes) in each joint's own coordinates."""
    values = {}
    for name, mob in built.mobilizers.items():
        RF, oF, vF, wF = _frame_motion(world, mob.parent, mob.parent_point, mob.parent_frame)
        RM, oM, vM, wM = _frame_motion(world, mob.child, mob.child_point, mob.child_frame)
        R = RF.T @ RM
        p = RF.T @ (oM - oF)
        w = RF.T @ (wM - wF)
        v = RF.T @ (vM - vF - np.cross(wF, oM - oF))
        kind = mob.kind
        if kind == "revolute":
            values[name] = [(math.atan2(R[1, 0], R[0, 0]), w[2])]
        elif kind == "prismatic":
            values[name] = [(p[0], v[0])]
        elif kind == "cylindrical":
            values[name] = [(math.atan2(R[1, 0], R[0, 0]), w[2]), (p[2], v[2])]
        elif kind == "planar":
            values[name] = [(math.atan2(R[1, 0], R[0, 0]), w[2]), (p[0], v[0]), (p[1], v[1])]
        elif kind == "universal":
            # R = Rx(a)·Ry(b); ω = ȧ·x̂ + ḃ·Rx(a)·ŷ
            a, b = math.atan2(R[2, 1], R[1, 1]), math.atan2(R[0, 2], R[0, 0])
            values[name] = [(a, w[0]), (b, w[1] * math.cos(a) + w[2] * math.sin(a))]
        elif kind == "spherical":
            values[name] = list(zip(euler_xyz(R), w))
        elif kind == "free":
            values[name] = list(zip((*euler_xyz(R), *p), (*w, *v)))
        else:
            values[name] = []
    return values


def prepare(system: SpatialSystem, world: World, t0: float, settings: Mapping[str, Any], times: np.ndarray):
    """The model charted at `world`, its state there at t0, and a Manager
    set up with the settings (no analyses, no storage: nothing written)."""
    method = INTEGRATORS.get(settings["integrator"])
    if method is None:
        raise ValueError(f"opensim: integrator must be one of {tuple(INTEGRATORS)}, got {settings['integrator']!r}")
    with quiet():
        built = build_spatial_model(system, world, scene_length(system))
        state = built.model.initSystem()
        state.setTime(t0)
        for name, values in coordinate_values(built, world, t0).items():
            for coordinate, (q, u) in zip(built.coordinates(name), values):
                coordinate.setValue(state, float(q), False)
                coordinate.setSpeedValue(state, float(u))
        for drive in system.drives:        # a prescribed coordinate: the law's value, not modulo a turn
            mob = built.mobilizers[built.tree[drive.joint]]
            built.coordinates(mob.name)[0].setValue(state, mob.sign * float(drive.law.angle(t0)), False)
        max_step = float(settings["max_step"])
        manager = osim.Manager(built.model)
        manager.setIntegratorMethod(method)
        manager.setIntegratorAccuracy(float(settings["accuracy"]))
        manager.setIntegratorConstraintTolerance(float(settings["constraint_tolerance"]))
        manager.setIntegratorMaximumStepSize(max_step)
        manager.setIntegratorInternalStepLimit(step_limit(times, max_step))
        manager.setIntegratorMinimumStepSize(MIN_STEP_FRACTION * max_step)
        manager.setPerformAnalyses(False)
        manager.setWriteToStorage(False)
        manager.setRecordStatesTrajectory(False)
        manager.initialize(state)
    return built, manager


def needs_rechart(built: SpatialModel, state: osim.State) -> bool:
    return any(abs(built.coordinates(name)[1].getValue(state)) > RECHART_ANGLE
               for name, mob in built.mobilizers.items() if mob.kind in CHARTED)


def run_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
    """The raw frame at `times` from the reference's state at times[0]."""
    times = np.asarray(times, dtype=float)
    cut_joints(system)          # what the adapter cannot build is refused before the reference is read
    clock = time.perf_counter()
    built, manager = prepare(system, start_world(system, times), float(times[0]), settings, times)
    build_time = time.perf_counter() - clock
    clock = time.perf_counter()
    rows, recharts = [], 0
    with quiet():
        for k, t in enumerate(times):
            state = manager.getState() if k == 0 else manager.integrate(float(t))
            if abs(state.getTime() - t) > 1e-9 * max(1.0, abs(t)):
                raise RuntimeError(f"opensim: Simbody stopped at t = {state.getTime():.9g} s, before the sample at "
                                   f"{t:.9g} s (more than its internal step limit per sample interval)")
            built.model.realizeAcceleration(state)
            rows.append(sample(system, built, state))
            if k + 1 < len(times) and needs_rechart(built, state):
                world = world_from_frame(system, pd.DataFrame([rows[-1]]))
                built, manager = prepare(system, world, float(t), settings, times)
                recharts += 1
    frame = pd.DataFrame(rows)
    frame["t"] = times
    frame = frame[["t", *system.motion_columns(), *system.reaction_columns()]]
    info = {"build_time_s": build_time, "wall_time_s": time.perf_counter() - clock, "recharts": recharts}
    return RawRun(frame, {}, RunInfo.of(info))


def _vec(v) -> np.ndarray:
    return np.array([v[0], v[1], v[2]])


def _mat(R) -> np.ndarray:
    return np.array([[R.get(i, k) for k in range(3)] for i in range(3)])


def sample(system: SpatialSystem, built: SpatialModel, state: osim.State) -> dict[str, float]:
    """Every raw column at one realised state, in mechval's conventions."""
    row: dict[str, float] = {}
    poses = {}
    for body in system.bodies:
        b = built.bodies[body.name]
        pose, velocity, acceleration = (b.getTransformInGround(state), b.getVelocityInGround(state),
                                        b.getAccelerationInGround(state))
        R, origin = _mat(pose.R()), _vec(pose.p())
        poses[body.name] = (R, origin)
        values = (*origin, *matrix_to_quaternion(R), *_vec(velocity.get(1)), *_vec(velocity.get(0)),
                  *_vec(acceleration.get(1)), *_vec(acceleration.get(0)))
        row |= {f"{body.name}.{q}": float(v) for q, v in zip(
            ("x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz",
             "ax", "ay", "az", "alphax", "alphay", "alphaz"), values)}
    point = lambda body, p: (np.asarray(p, float) if body == GROUND else    # noqa: E731
                             poses[body][0] @ np.asarray(p, float) + poses[body][1])
    axis = lambda body, frame: (np.asarray(frame, float)[:, 2] if body == GROUND else   # noqa: E731
                                poses[body][0] @ np.asarray(frame, float)[:, 2])
    efforts = {d.joint: d for d in system.drives}
    for joint in system.joints:
        Pi, Pj = point(joint.body_i, joint.point_i), point(joint.body_j, joint.point_j)
        if joint.name in built.tree:
            F, M = _tree_load(built, state, built.tree[joint.name], Pi, Pj)
        else:
            F, M = _closure_load(built, state, joint, Pi, Pj, poses)
        drive = efforts.get(joint.name)
        if drive is not None:
            zi = axis(joint.body_i, joint.frame_i)
            if joint.kind == "revolute":
                row[f"{drive.name}.T"] = float(M @ zi)
                M = M - (M @ zi) * zi
            else:
                row[f"{drive.name}.F"] = float(F @ zi)
                F = F - (F @ zi) * zi
        row |= {f"{joint.name}.{q}": float(v) for q, v in zip(("Fx", "Fy", "Fz", "Mx", "My", "Mz"), (*F, *M))}
    for torque in system.torques:
        mob = built.mobilizers[built.tree[torque.joint]]
        row[f"{torque.name}.T"] = mob.sign * built.actuators[torque.name].getActuation(state)
    return row


def _tree_load(built: SpatialModel, state: osim.State, name: str, Pi: np.ndarray, Pj: np.ndarray):
    """A mobilizer's reaction as Fij (force, moment about Pj), less the
    mobility forces applied across it."""
    mob = built.mobilizers[name]
    reaction = built.joints[name].calcReactionOnChildExpressedInGround(state)
    moment, force = _vec(reaction.get(0)), _vec(reaction.get(1))
    applied = _mobility_force(built, state, name)
    if applied:
        axes = _mat(built.joints[name].getParentFrame().getTransformInGround(state).R())
        if mob.kind == "revolute":
            moment = moment - applied * axes[:, 2]
        elif mob.kind == "prismatic":        # along the slider's x
            force = force - applied * axes[:, 0]
        else:                                # cylindrical: along z
            force = force - applied * axes[:, 2]
    if mob.reversed:
        return -force, -moment - np.cross(Pi - Pj, force)
    return force, moment


def _mobility_force(built: SpatialModel, state: osim.State, name: str) -> float:
    """The generalised force the joint's damper and torque law apply on its
    damped or driven coordinate: −c·q̇ and the actuation."""
    mob = built.mobilizers[name]
    if mob.joint is None or mob.kind not in DAMPED:
        return 0.0
    coordinate = built.coordinates(name)[DAMPED[mob.kind]]
    total = 0.0
    damper = built.dampers.get(mob.joint.name)
    if damper is not None:
        total -= damper.getViscosity() * coordinate.getSpeedValue(state)
    for actuator in built.actuators.values():
        if actuator.get_coordinate() == coordinate.getName():
            total += actuator.getActuation(state)
    return total


def _closure_load(built: SpatialModel, state: osim.State, joint, Pi, Pj, poses) -> tuple[np.ndarray, np.ndarray]:
    """A cut joint's Fij: its constraints' forces on body_j (or the opposite
    of those on body_i where body_j is the ground), moved to Pj."""
    on_j = joint.body_j != GROUND
    body = joint.body_j if on_j else joint.body_i
    origin = poses[body][1]
    force, moment = np.zeros(3), np.zeros(3)
    for constraint in built.closures[joint.name]:
        forces = osim.VectorOfSpatialVec()
        constraint.calcConstraintForces(state, forces, osim.Vector())
        # One spatial force per constrained body, in the constraint's order
        # (body_i's frame first); Simbody's sign is the opposite.
        k = 1 if on_j else 0
        f, m = -_vec(forces.get(k).get(1)), -_vec(forces.get(k).get(0))
        force += f
        moment += m + np.cross(origin - Pj, f)
    if on_j:
        return force, moment
    return -force, -moment
