"""One OpenSim run of a planar mechanism: the start state from the
reference, Simbody's error-controlled integration to each sample, and the
read-out converted to mechval's conventions (see
`mechval.engines.opensim.adapter`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import opensim as osim
import pandas as pd

from mechval.judging.health import drive_errors
from mechval.model.kinematics import joint_gaps, slide_motion
from mechval.model.mechanism import GROUND, MOTION_QUANTITIES, Mechanism

from mechval.engines.base import reference_motion
from mechval.engines.opensim.model import OpensimModel, build_model, quiet

#: Simbody's integrators by the names of OpenSim's Manager (error-controlled
#: except the fixed-step SemiExplicitEuler2's and Verlet's fallbacks).
INTEGRATORS = {
    "RungeKuttaMerson": osim.Manager.IntegratorMethod_RungeKuttaMerson,
    "RungeKuttaFeldberg": osim.Manager.IntegratorMethod_RungeKuttaFeldberg,
    "RungeKutta3": osim.Manager.IntegratorMethod_RungeKutta3,
    "RungeKutta2": osim.Manager.IntegratorMethod_RungeKutta2,
    "SemiExplicitEuler2": osim.Manager.IntegratorMethod_SemiExplicitEuler2,
    "Verlet": osim.Manager.IntegratorMethod_Verlet,
    "CPodes": osim.Manager.IntegratorMethod_CPodes,
}


#: Steps Simbody may take per sample interval, as a multiple of the
#: declared one per `max_step` (at least STEP_LIMIT_MIN): a run that needs
#: more is stopped rather than left to shrink its step without end (gravity
#: 1e49 did: no answer in minutes; now NaN at once).
STEP_LIMIT_FACTOR = 100
STEP_LIMIT_MIN = 1000
#: The smallest step, as a fraction of `max_step`: far below any step a
#: run that meets its accuracy takes (about max_step / 2), it stops the step
#: from shrinking without end: with gravity 1e49 and no floor Simbody gave no
#: answer in minutes even under the step limit; with it, NaN at once
#: (tests/test_fuzz.py's blow-up case).
MIN_STEP_FRACTION = 1e-9


def step_limit(times: np.ndarray, max_step: float) -> int:
    interval = float(times[1] - times[0]) if len(times) > 1 else max_step
    return max(STEP_LIMIT_MIN, STEP_LIMIT_FACTOR * math.ceil(interval / max_step - 1e-9))


@dataclass
class Prepared:
    """The built model, its initial state at times[0] and the Manager."""

    built: OpensimModel
    state: osim.State
    manager: osim.Manager
    start: pd.DataFrame


def start_state(mechanism: Mechanism, t0: float) -> pd.DataFrame:
    """The reference state at the first instant (the only read of the
    reference: prescribed or forward dynamics alike start there)."""
    return reference_motion(mechanism, np.array([t0]))


def coordinate_values(mechanism: Mechanism, built: OpensimModel, start: pd.DataFrame) -> dict[str, tuple[float, float]]:
    """(q, q̇) of every tree coordinate from the reference's body motion:
    θj − θi or the slide s, negated where the tree reverses the joint."""
    angle = lambda body, q: 0.0 if body == GROUND else float(start[f"{body}.{q}"].iloc[0])   # noqa: E731
    values = {}
    for name, tj in built.tree.items():
        joint = tj.joint
        if joint.kind == "revolute":
            q = angle(joint.body_j, "theta") - angle(joint.body_i, "theta")
            u = angle(joint.body_j, "omega") - angle(joint.body_i, "omega")
        else:
            slide = slide_motion(start, joint)
            q, u = float(slide["s"][0]), float(slide["v"][0])
        values[name] = (tj.sign * q, tj.sign * u)
    for name in built.loop_pins:        # the finding's probe only: child body_j
        joint = mechanism.joint(name)
        values[name] = (angle(joint.body_j, "theta") - angle(joint.body_i, "theta"),
                        angle(joint.body_j, "omega") - angle(joint.body_i, "omega"))
    return values


def prepare(mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any], closure: str = "point") -> Prepared:
    """The model at the reference's state at times[0], and a Manager set up
    with the settings (no analyses, no storage: nothing written); `closure`
    as for `build_model`."""
    method = INTEGRATORS.get(settings["integrator"])
    if method is None:
        raise ValueError(f"opensim: integrator must be one of {tuple(INTEGRATORS)}, got {settings['integrator']!r}")
    t0 = float(times[0])
    start = start_state(mechanism, t0)
    with quiet():
        built = build_model(mechanism, closure)
        state = built.model.initSystem()
        state.setTime(t0)
        for name, (q, u) in coordinate_values(mechanism, built, start).items():
            joint = built.joints.get(name) or built.loop_pins[name]
            coordinate = joint.get_coordinates(0)
            coordinate.setValue(state, q, False)
            coordinate.setSpeedValue(state, u)
        manager = osim.Manager(built.model)
        manager.setIntegratorMethod(method)
        manager.setIntegratorAccuracy(float(settings["accuracy"]))
        manager.setIntegratorConstraintTolerance(float(settings["constraint_tolerance"]))
        manager.setIntegratorMaximumStepSize(float(settings["max_step"]))
        manager.setIntegratorInternalStepLimit(step_limit(times, float(settings["max_step"])))
        manager.setIntegratorMinimumStepSize(MIN_STEP_FRACTION * float(settings["max_step"]))
        manager.setPerformAnalyses(False)
        manager.setWriteToStorage(False)
        manager.setRecordStatesTrajectory(False)
        manager.initialize(state)
    return Prepared(built, state, manager, start)


def read_run(mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> tuple[pd.DataFrame, dict]:
    """The raw frame at `times` (angles unwrapped from the reference's at
    the start) and the run's facts."""
    clock = time.perf_counter()
    prepared = prepare(mechanism, times, settings)
    build_time = time.perf_counter() - clock
    clock = time.perf_counter()
    columns = integrate(prepared, mechanism, times)
    wall_time = time.perf_counter() - clock
    for body in mechanism.bodies:
        theta = np.unwrap(columns[f"{body.name}.theta"])
        start = float(prepared.start[f"{body.name}.theta"].iloc[0])
        columns[f"{body.name}.theta"] = theta + 2 * np.pi * np.round((start - theta[0]) / (2 * np.pi))
    columns["t"] = np.asarray(times, dtype=float)
    frame = pd.DataFrame({name: columns[name] for name in
                          ["t", *mechanism.motion_columns(), *mechanism.reaction_columns()]})
    info = {"build_time_s": build_time, "wall_time_s": wall_time,
            "closure_gap_max": float(joint_gaps(mechanism, frame).max())}
    if mechanism.drives:
        info["drive_error_max"] = float(drive_errors(mechanism, frame).max())
    return frame, info


def integrate(prepared: Prepared, mechanism: Mechanism, times: np.ndarray) -> dict[str, np.ndarray]:
    """Raw columns at every sample: the Manager integrates to each sample
    in turn (its own steps in between), and the state there is realised to
    accelerations and read."""
    columns: dict[str, list[float]] = {}
    model, built = prepared.built.model, prepared.built
    with quiet():
        for k, t in enumerate(times):
            state = prepared.manager.getState() if k == 0 else prepared.manager.integrate(float(t))
            if abs(state.getTime() - t) > 1e-9 * max(1.0, abs(t)):
                raise RuntimeError(f"opensim: Simbody stopped at t = {state.getTime():.9g} s, before the sample at "
                                   f"{t:.9g} s (more than its internal step limit per sample interval)")
            model.realizeAcceleration(state)
            for name, value in sample(mechanism, built, state).items():
                columns.setdefault(name, []).append(value)
    return {name: np.asarray(values) for name, values in columns.items()}


def sample(mechanism: Mechanism, built: OpensimModel, state: osim.State) -> dict[str, float]:
    """Every raw column at one realised state, in mechval's conventions."""
    row = {"t": state.getTime()}
    for body in mechanism.bodies:
        b = built.bodies[body.name]
        pose, velocity, acceleration = (b.getTransformInGround(state), b.getVelocityInGround(state),
                                        b.getAccelerationInGround(state))
        rotation = pose.R()
        row |= {f"{body.name}.x": pose.p()[0], f"{body.name}.y": pose.p()[1],
                f"{body.name}.theta": math.atan2(rotation.get(1, 0), rotation.get(0, 0)),
                f"{body.name}.vx": velocity.get(1)[0], f"{body.name}.vy": velocity.get(1)[1],
                f"{body.name}.omega": velocity.get(0)[2],
                f"{body.name}.ax": acceleration.get(1)[0], f"{body.name}.ay": acceleration.get(1)[1],
                f"{body.name}.alpha": acceleration.get(0)[2]}
    drives = {d.joint: d for d in mechanism.drives}
    for name, tj in built.tree.items():
        reaction = built.joints[name].calcReactionOnChildExpressedInGround(state)
        moment, force = reaction.get(0), reaction.get(1)
        # Simbody's mobilizer reaction carries the mobility forces applied
        # across it (a damper, an actuator): they are applied loads, not
        # the joint's reaction, so they come out first (on the child: +f).
        applied = mobility_force(built, state, name)
        if tj.joint.kind == "revolute":
            moment_z = moment[2] - applied
            force_xy = np.array([force[0], force[1]])
        else:
            moment_z = moment[2]
            force_xy = np.array([force[0], force[1]]) - tj.sign * applied * _axis(built, state, tj.joint)
        row |= tree_reaction(mechanism, built, state, tj, force_xy, moment_z, drives.get(name))
    for name, closure in built.closures.items():
        row |= closure_reaction(mechanism, built, state, name, closure)
    for name, pin in built.loop_pins.items():         # the finding's probe only; child body_j
        force = pin.calcReactionOnChildExpressedInGround(state).get(1)
        row |= {f"{name}.Fx": force[0], f"{name}.Fy": force[1]}
    for law in mechanism.torque_drives:
        row[f"{law.name}.T"] = built.tree[law.joint].sign * built.actuators[law.name].getActuation(state)
    return row


def mobility_force(built: OpensimModel, state: osim.State, joint: str) -> float:
    """The generalised force the joint's damper and torque law apply on its
    coordinate: −c·q̇ and the actuation."""
    total = 0.0
    coordinate = built.coordinate(joint)
    damper = built.forces.get(joint)
    if isinstance(damper, osim.SpringGeneralizedForce):
        total -= damper.getViscosity() * coordinate.getSpeedValue(state)
    for law, actuator in built.actuators.items():
        if actuator.get_coordinate() == coordinate.getName():
            total += actuator.getActuation(state)
    return total


def tree_reaction(mechanism, built, state, tj, force: np.ndarray, moment: float, drive) -> dict[str, float]:
    """A mobilizer's reaction (on its child at the child's joint point,
    ground axes) as Fij on body_j, its couple M (slides), and the drive
    effort it carries: the z moment (revolute) or the force along the axis
    (slide), which are the prescribed motion's, removed from Fij and M."""
    joint = tj.joint
    if tj.reversed:
        # The load on body_i at point_i is (f, m); body_j gets (−f, −m) there,
        # which at point_j is the couple −m − (Pi − Pj) × f.
        arm = _world_point(built, state, joint.body_i, joint.point_i) - _world_point(built, state, joint.body_j,
                                                                                     joint.point_j)
        force, moment = -force, -moment - (arm[0] * force[1] - arm[1] * force[0])
    out = {}
    if joint.kind == "revolute":
        if drive is not None:
            out[drive.effort_column("revolute")] = moment
    else:
        u = _axis(built, state, joint)
        along = float(force @ u)
        if drive is not None:
            out[drive.effort_column("prismatic")] = along
            force = force - along * u
        out[f"{joint.name}.M"] = moment
    out[f"{joint.name}.Fx"], out[f"{joint.name}.Fy"] = force
    return out


def closure_reaction(mechanism, built, state, name: str, closure: osim.PointConstraint) -> dict[str, float]:
    """A loop-closing pin's Fij: the point constraint's force on body_j
    (`getConstraintForcesAsVector` lists, per constrained body, the
    spatial force the constraint applies at its origin in ground axes;
    only the force part is kept: the pin carries no moment)."""
    joint = mechanism.joint(name)
    forces = osim.VectorOfSpatialVec()
    closure.calcConstraintForces(state, forces, osim.Vector())
    # One spatial force (moment, force) per constrained body, in the
    # constraint's order: body_i's frame first, body_j's second; Simbody
    # gives them as the term Gᵀ·λ on the left of M·u̇ + Gᵀ·λ = f, i.e. minus
    # the force the constraint applies (the sign tests against the
    # reference confirm it).
    on_j = forces.get(1).get(1)
    return {f"{name}.Fx": -on_j[0], f"{name}.Fy": -on_j[1]}


def _body_index(built: OpensimModel, body: str) -> int:
    return 0 if body == GROUND else built.bodies[body].getMobilizedBodyIndex()


def _world_point(built: OpensimModel, state: osim.State, body: str, point) -> np.ndarray:
    if body == GROUND:
        return np.array(point, dtype=float)
    p = built.bodies[body].findStationLocationInGround(state, osim.Vec3(point[0], point[1], 0.0))
    return np.array([p[0], p[1]])


def _axis(built: OpensimModel, state: osim.State, joint) -> np.ndarray:
    """The slide's axis u in world axes (it turns with body_i)."""
    theta = 0.0
    if joint.body_i != GROUND:
        r = built.bodies[joint.body_i].getTransformInGround(state).R()
        theta = math.atan2(r.get(1, 0), r.get(0, 0))
    a = math.atan2(joint.axis[1], joint.axis[0]) + theta
    return np.array([math.cos(a), math.sin(a)])
