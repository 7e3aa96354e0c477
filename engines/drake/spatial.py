"""One Drake run of a spatial scene (`run_spatial`): the start state from
the reference, the simulation, and the read-out at the samples in
mechval's raw columns (motion here, reactions in `spatial_reactions`;
the model: `spatial_model`; docs/engines.md, "Drake: spatial scenes")."""

from __future__ import annotations

import time
from typing import Any, Mapping

import numpy as np
import pandas as pd

from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.analysis import Simulator

from mechval.model.kinematics import STEP_RULE_GRID, dense_grid, spatial_peak_rate
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.mechanism import spatial_mechanism, spatial_solution
from mechval.reference.spatial.rotation import matrix_to_quaternion
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.base import RawRun, RunInfo, Unrepresentable, default_step
from mechval.engines.drake.adapter import sap_defaults
from mechval.engines.drake.run import STEP_MARGIN
from mechval.engines.drake.spatial_model import SpatialModel, build, joint_frames, world_pose
from mechval.engines.drake.spatial_reactions import Motion, Sample, reaction_columns
from mechval.engines.drake.spatial_tree import spatial_topology


def spatial_rate(system: SpatialSystem, times: np.ndarray, dense: int = STEP_RULE_GRID) -> float:
    """Ω of the shared step rule (`mechval.model.kinematics.spatial_peak_rate`)
    from the reference on `dense` instants of the run."""
    t = dense_grid(times, dense)
    mechanism = spatial_mechanism(system)
    return spatial_peak_rate(mechanism, mechanism.motion(t), t)


#: The continuous plant's target accuracy (Drake's integrator's
#: relative error measure): the heavy top at 200 rad/s keeps its
#: attitude within 6e-7 of the reference over 1 s with it, 6e-6 at 1e-4
#: (docs/engines.md, Drake, "Spatial scenes").
ACCURACY = 1e-6


def has_constraints(system: SpatialSystem) -> bool:
    """A prescribed drive or a loop: what only the discrete plant takes."""
    if system.drives:
        return True
    try:
        return bool(spatial_topology(system).cuts)
    except Unrepresentable:
        return True


def spatial_defaults(system: SpatialSystem, times: np.ndarray, rate: float | None = None) -> dict[str, Any]:
    """The planar defaults (the adapter's `default_settings`: the shared
    step rule with Ω = `rate`, else `spatial_rate`), and the integrator: a
    continuous plant with RK3 where the scene allows it (no loop, no
    prescribed drive), whose error control holds the gyroscopic motion of
    a free or spinning body that SAP's first-order step does not (the
    T-handle's attitude: 8e-3 off after 4 s at the rule's step with SAP,
    7e-7 with RK3: docs/engines.md); SAP otherwise."""
    rate = spatial_rate(system, times) if rate is None else rate
    return {**sap_defaults(default_step(None, times, rate=rate), system.forward_dynamics),
            "integrator": "sap" if has_constraints(system) else "rk3", "accuracy": ACCURACY}


def start_of(system: SpatialSystem, times: np.ndarray, steps: int, dt: float) -> tuple[float, int, dict]:
    """(t0, pre-roll steps, the reference's raw columns at t0): a prescribed
    scene starts `steps` steps before the first sample (SAP's start and the
    drives' PD lag settle), none if the reference cannot solve there or
    reaches the first sample on another branch than the run's own start; a
    torque-driven or free one at the first sample."""
    first = float(times[0])
    direct = spatial_solution(system, np.asarray(times[:2], float)).frame
    if steps and not system.forward_dynamics:
        try:
            frame = spatial_solution(system, np.array([first - steps * dt, first])).frame
        except ValueError:              # the reference cannot assemble there: no pre-roll
            frame = None
        # Assembled earlier, the reference must reach the run's own start
        # (not another branch of the loop) at the first sample.
        columns = system.motion_columns()
        if frame is not None and np.abs(frame[columns].to_numpy()[1, :] - direct[columns].to_numpy()[0, :]).max() \
                <= 1e-9 * max(1.0, float(np.abs(direct[columns].to_numpy()[0, :]).max())):
            return first - steps * dt, steps, {c: frame[c].to_numpy()[:1] for c in frame.columns}
    return first, 0, {c: direct[c].to_numpy()[:1] for c in direct.columns}


def set_start(model: SpatialModel, context, start: Mapping[str, np.ndarray], t0: float, dt: float) -> None:
    """Drake's state from the reference's at t0: each tree joint's
    coordinates from its frames' relative pose, each free body's pose, and
    the velocities v that reproduce the bodies' spatial velocities (least
    squares over the bodies' Jacobians; exact for a consistent state),
    less half a step of their rate: Drake's v_n is the mean rate of the step
    that ends at t_n (the planar `run` does the same)."""
    plant = model.plant
    for tj in model.topo.tree:
        (pb, pp, pf), (cb, cp, cf) = joint_frames(tj, start)
        (op, Rp), (oc, Rc) = world_pose(start, pb), world_pose(start, cb)
        RF, RM = Rp @ pf, Rc @ cf
        R = RF.T @ RM
        p = RF.T @ (oc + Rc @ cp - op - Rp @ pp)
        angle = float(np.arctan2(R[1, 0], R[0, 0]))
        joints, kind = model.joints[tj.joint.name], tj.joint.kind
        if kind == "revolute":
            drive = next((d for d in model.system.drives if d.joint == tj.joint.name), None)
            if drive is not None:         # the drive's desired angle is absolute: no turn of 2π off it
                target = tj.sign * float(drive.law.angle(np.array([t0]))[0])
                angle += 2 * np.pi * np.round((target - angle) / (2 * np.pi))
            joints[0].set_angle(context, angle)
        elif kind == "prismatic":
            joints[0].set_translation(context, float(p[2]))
        elif kind == "spherical":
            joints[0].set_angles(context, RollPitchYaw(RotationMatrix(R)).vector())
        elif kind == "universal":
            joints[0].set_angles(context, [np.arctan2(R[2, 1], R[1, 1]), np.arctan2(R[0, 2], R[0, 0])])
        elif kind == "planar":
            joints[0].set_pose(context, p[:2], angle)
        elif kind == "cylindrical":
            joints[0].set_translation(context, float(p[2]))
            joints[1].set_angle(context, angle)
    for name in model.topo.free:
        o, A = world_pose(start, name)
        plant.SetFreeBodyPose(context, model.bodies[name], RigidTransform(RotationMatrix(A), o))
    world = plant.world_frame()
    J, V, A = [], [], []
    for b in model.system.bodies:
        frame = model.bodies[b.name].body_frame()
        J.append(plant.CalcJacobianSpatialVelocity(context, JacobianWrtVariable.kV, frame, np.zeros(3), world, world))
        V.append([float(start[f"{b.name}.{c}"][0]) for c in ("wx", "wy", "wz", "vx", "vy", "vz")])
        A.append([float(start[f"{b.name}.{c}"][0]) for c in ("alphax", "alphay", "alphaz", "ax", "ay", "az")])
    J = np.vstack(J)
    v = np.linalg.lstsq(J, np.concatenate(V), rcond=None)[0]
    plant.SetVelocities(context, v)
    bias = np.concatenate([plant.CalcBiasSpatialAcceleration(context, JacobianWrtVariable.kV,
                                                             model.bodies[b.name].body_frame(), np.zeros(3), world,
                                                             world).get_coeffs() for b in model.system.bodies])
    vdot = np.linalg.lstsq(J, np.concatenate(A) - bias, rcond=None)[0]
    plant.SetVelocities(context, v - 0.5 * dt * vdot)


#: A ball constraint whose relative Jacobian is below this (m/s per unit
#: generalized speed, over the lever) at the start is switched off.
STILL = 1e-9


def switch_off_still_balls(model: SpatialModel, context, lever: float) -> list[int]:
    """Switch off each ball constraint whose two points the tree holds
    still (relative Jacobian zero at the start: the points lie on their
    bodies' fixed axes, as at the cross of Hooke's joint): wholly
    redundant, and SAP blows up on it (finding
    drake.ball-constraint-between-fixed-points). Their indices."""
    plant, world, off = model.plant, model.plant.world_frame(), []
    for k, (cid, bi, pi, bj, pj) in enumerate(model.balls):
        jac = lambda body, p: plant.CalcJacobianTranslationalVelocity(context, JacobianWrtVariable.kV,
                                                                      body.body_frame(), p, world, world)
        if np.abs(jac(bj, pj) - jac(bi, pi)).max() <= STILL * lever:
            plant.SetConstraintActiveStatus(context, cid, False)
            off.append(k)
    return off


def read(model: SpatialModel, context) -> Sample:
    """Everything at the current state x_n (ports live: the accelerations,
    reactions and actuation of the step from t_n)."""
    plant = model.plant
    poses, velocities = {}, {}
    for b in model.system.bodies:
        body = model.bodies[b.name]
        X = plant.EvalBodyPoseInWorld(context, body)
        V = plant.EvalBodySpatialVelocityInWorld(context, body)
        poses[b.name] = (X.translation().copy(), X.rotation().matrix().copy())
        velocities[b.name] = (V.rotational().copy(), V.translational().copy())
    accelerations = plant.get_body_spatial_accelerations_output_port().Eval(context)
    reactions = plant.get_reaction_forces_output_port().Eval(context)
    joints = {}
    for name, drake_joints in model.joints.items():
        last = drake_joints[-1]
        X = last.frame_on_child().CalcPoseInWorld(context)
        F = reactions[int(last.index())]
        R = X.rotation().matrix()
        joints[name] = (X.translation().copy(), R @ F.rotational(), R @ F.translational())
    return Sample(poses, velocities,
                  {b.name: (accelerations[int(model.bodies[b.name].index())].rotational().copy(),
                            accelerations[int(model.bodies[b.name].index())].translational().copy())
                   for b in model.system.bodies},
                  joints, plant.get_net_actuation_output_port().Eval(context).copy())


def built(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> tuple:
    """(model, t0, pre-roll steps, the reference's raw columns at t0, lever):
    the plant a run (and the audit) starts from."""
    dt = float(settings["timestep"]) / int(settings["refine"])
    topo = spatial_topology(system)
    t0, preroll, start = start_of(system, np.asarray(times, dtype=float), int(settings["preroll_steps"]), dt)
    arm = lever(system)
    return build(system, topo, settings, t0, float(times[-1]), start, arm), t0, preroll, start, arm


def nan_sample(model: SpatialModel) -> Sample:
    """A sample of NaN: where SAP stopped before the first sample."""
    nan3, bodies = np.full(3, np.nan), model.system.bodies
    return Sample({b.name: (nan3, np.full((3, 3), np.nan)) for b in bodies},
                  {b.name: (nan3, nan3) for b in bodies}, {b.name: (nan3, nan3) for b in bodies},
                  {name: (nan3, nan3, nan3) for name in model.joints}, np.full(len(model.actuators), np.nan))


def run_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
    """Build, start from the reference, step to every sample, read."""
    times = np.asarray(times, dtype=float)
    clock = time.perf_counter()
    dt = float(settings["timestep"]) / int(settings["refine"])
    model, t0, preroll, start, arm = built(system, times, settings)
    topo = model.topo
    build_time = time.perf_counter() - clock
    simulator = Simulator(model.diagram)
    continuous = settings.get("integrator", "sap") != "sap"
    # A continuous plant (`continuous`): Drake's error-controlled RK3 at
    # most a step long; its velocities and accelerations are of the state
    # itself, no half-step shift.
    shift = 0.0 if continuous else dt
    if continuous:
        integrator = simulator.get_mutable_integrator()
        integrator.set_target_accuracy(float(settings["accuracy"]))
        integrator.set_maximum_step_size(dt)
        integrator.request_initial_step_size_target(dt)
    context = simulator.get_mutable_context()
    context.SetTime(0.0)               # Drake's clock is 0 at t0 (the planar `run`)
    plant_context = model.plant.GetMyMutableContextFromRoot(context)
    set_start(model, plant_context, start, t0, shift)
    still = switch_off_still_balls(model, plant_context, arm)
    simulator.Initialize()
    rows, clock, stopped = [], time.perf_counter(), None
    for k, n in enumerate(np.round((times - t0) / dt).astype(int)):
        if n > 0 and stopped is None:
            try:
                simulator.AdvanceTo((n - STEP_MARGIN) * dt)
            except RuntimeError as exc:     # SAP stops on a NaN it meets ("the Hessian … is NaN")
                stopped = (k, str(exc).split(".")[0])
        rows.append(read(model, plant_context) if stopped is None else rows[-1] if rows else nan_sample(model))
    wall = time.perf_counter() - clock
    frame = columns(system, model, times, rows, shift)
    facts = {"wall_time_s": wall, "build_time_s": build_time, "step": dt, "preroll_steps_used": preroll,
             "steps": int(round((times[-1] - t0) / dt)),
             "drive_gains": " ".join(f"{kp:.6g} {kd:.6g}" for kp, kd in model.gains) or "none",
             "cut_joints": " ".join(j.name for j in topo.cuts) or "none",
             "ball_constraints_switched_off": len(still)}
    with np.errstate(all="ignore"):
        blown = ~np.isfinite(frame.to_numpy(dtype=float)).all(axis=1) | ~(joint_gaps(system, rows) <= 10 * arm)
    if stopped is not None:
        blown[stopped[0]:] = True
        facts["stopped"] = stopped[1]
    if blown.any():
        # Drake's SAP runs on through a blow-up (the planar `Run.blown_up`):
        # from the first sample where a joint has come apart (a gap of ten
        # times the scene's size) or a value is not finite, the run is NaN.
        first = int(np.argmax(blown))
        frame.iloc[first:, 1:] = np.nan
        facts["blown_up_at"] = float(times[first])
    return RawRun(frame, {}, RunInfo.of(facts))


def joint_gaps(system: SpatialSystem, rows: list[Sample]) -> np.ndarray:
    """Per sample the largest distance between the two points of a joint
    that holds them together (all kinds but the sliding ones), m."""
    motion = Motion(system, rows)
    gaps = [np.linalg.norm(motion.point(j.body_j, j.point_j) - motion.point(j.body_i, j.point_i), axis=1)
            for j in system.joints if j.kind not in ("prismatic", "cylindrical", "planar")]
    return np.max(gaps, axis=0) if gaps else np.zeros(len(rows))


def lever(system: SpatialSystem) -> float:
    """The arm of the constraints that hold a cut joint's axis: the
    scene's size (the largest distance of a joint point from its body's
    centre of mass), at least 1 cm."""
    arms = [np.linalg.norm(np.subtract(point, system.body(body).com))
            for j in system.joints for body, point in ((j.body_i, j.point_i), (j.body_j, j.point_j)) if body != GROUND]
    return max([0.01, *arms])


def columns(system: SpatialSystem, model: SpatialModel, times: np.ndarray, rows: list[Sample],
            dt: float) -> pd.DataFrame:
    """The raw columns: body motion (velocities moved half a step on,
    v_n + dt/2·a_n: `set_start`), joint reactions, drive efforts, torque
    laws."""
    cols: dict[str, np.ndarray] = {"t": times.copy()}
    for b in system.bodies:
        p = np.array([r.poses[b.name][0] for r in rows])
        R = np.array([r.poses[b.name][1] for r in rows])
        alpha = np.array([r.accelerations[b.name][0] for r in rows])
        a = np.array([r.accelerations[b.name][1] for r in rows])
        w = np.array([r.velocities[b.name][0] for r in rows]) + 0.5 * dt * alpha
        v = np.array([r.velocities[b.name][1] for r in rows]) + 0.5 * dt * a
        q = matrix_to_quaternion(R)
        for k, c in enumerate("xyz"):
            cols[f"{b.name}.{c}"] = p[:, k]
        for k, c in enumerate("wxyz"):
            cols[f"{b.name}.q{c}"] = q[:, k]
        for name, x in (("v", v), ("w", w), ("a", a), ("alpha", alpha)):
            for k, c in enumerate("xyz"):
                cols[f"{b.name}.{name}{c}"] = x[:, k]
    cols.update(reaction_columns(system, model.topo, rows, times))
    for k, d in enumerate(system.drives):
        effort = "T" if system.joint(d.joint).kind == "revolute" else "F"
        cols[f"{d.name}.{effort}"] = model.topo.of_joint(d.joint).sign * np.array([r.actuation[k] for r in rows])
    for law in system.torques:
        cols[f"{law.name}.T"] = np.asarray(law.law.value(times), float) * np.ones(len(times))
    return pd.DataFrame(cols)[["t", *system.motion_columns(), *system.reaction_columns()]]
