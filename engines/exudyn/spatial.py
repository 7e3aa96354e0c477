"""One Exudyn run of a spatial scene (`SpatialSystem`): start state from the
spatial reference, the model (`spatial_model`), the solve, and the read-out
in mechval's raw columns.

Read-out:
- Body motion: the node is the body frame origin, so its Position,
  Velocity, Acceleration (world) are the columns as they are; the attitude
  from its RotationMatrix (quaternion with qw ≥ 0); AngularVelocity and
  AngularAcceleration are world axes.
- Joint reaction: `ObjectJointGeneric`'s ForceLocal is its translational
  multipliers λt in J0 axes and TorqueLocal its raw rotational multipliers
  λr (Exudyn's CObjectJointGeneric.cpp). Its equations of motion carry
  +C_qᵀλ on the left, so the load on body_j (marker 1) is −C_q1ᵀλ: force
  F = −A_J0·λt at Pj, and a couple −Σ λr·(b1 × a0) for each rotation
  constraint a0·b1 = 0 (a0 a J0 axis, b1 a J1 axis; `ROTATION_ROWS`).
  Moment about Pj: that couple alone (the force acts at Pj).
- Drive effort: −λ of its coordinate constraint (T about zi, F along zi,
  on body_j), as in the planar model.
- Torque law: the applied torque read back from its load's sensor.
"""

from __future__ import annotations

import time
from typing import Any, Mapping

import exudyn as exu
import numpy as np
import pandas as pd

from mechval.adapter import RawRun, RunInfo, Unrepresentable
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.mechanism import spatial_solution
from mechval.reference.spatial.rotation import matrix_to_quaternion
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.exudyn.model import SOLVERS, simulation_settings, solve
from mechval.engines.exudyn.run import index3_transient_steps, sample_rows
from mechval.engines.exudyn.spatial_model import CONSTRAINED_AXES, SpatialModel, build_spatial

def rotation_rows(axes: tuple[int, ...]) -> list[tuple[int, int, int]]:
    """The rotation constraints a0·b1 = 0 of an `ObjectJointGeneric` with
    `constrainedAxes` axes, as (multiplier 0..2 of TorqueLocal, J0 axis of
    a0, J1 axis of b1) (CObjectJointGeneric::ComputeAlgebraicEquations)."""
    rot = tuple(axes[3:])
    if sum(rot) == 3:
        return [(0, 2, 1), (1, 2, 0), (2, 0, 1)]
    if sum(rot) == 2:
        free = rot.index(0)
        return [(k, free, k) for k in range(3) if k != free]
    if sum(rot) == 1:
        locked = rot.index(1)
        free1, free2 = (k for k in range(3) if k != locked)
        return [(locked, free1, free2)]
    return []


UNSOLVED_START = ("Exudyn 1.13.6 reports zero reactions at its first instant unless its own initial-acceleration "
                  "solve ran (compute_initial_accelerations), and a run with no pre-roll starts at the first sample")


def start_frame(system: SpatialSystem, t0: float, t1: float) -> pd.DataFrame:
    """The reference's raw columns at t0 (one row): solved, or the
    forward-dynamics reference's consistent initial state (asked over
    [t0, t1]: its integrator refuses a single instant)."""
    t = np.array([t0, t1]) if system.forward_dynamics else np.array([t0])
    frame = spatial_solution(system, t).frame.iloc[:1]
    if not np.all(np.isfinite(frame[system.motion_columns()].to_numpy(dtype=float))):
        raise Unrepresentable("initial", f"the reference gives no consistent state at t = {t0!r}")
    return frame


def run_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
    """Exudyn's run of `system` at the instants `times` (settings: the
    adapter's `settings_spec`)."""
    times = np.asarray(times, dtype=float)
    if system.forward_dynamics != (int(settings["pre_roll_steps"]) == 0):
        raise ValueError("exudyn: pre_roll_steps must be 0 for a torque-driven or free scene and at least 1 "
                         "for a prescribed one")
    if settings["solver"] not in SOLVERS:
        raise ValueError(f"exudyn: solver must be one of {tuple(SOLVERS)}, got {settings['solver']!r}")
    dt = float(settings["timestep"])
    clock = time.perf_counter()
    model, t0, pre_roll = prepare_spatial(system, times, settings)
    dof = model.mbs.ComputeSystemDegreeOfFreedom()
    redundant = int(dof["redundantConstraints"])
    if redundant and settings["solver"] == "index2":
        raise ValueError(f"exudyn: solver 'index2' cannot run {redundant} redundant constraint(s): its velocity-level "
                         f"constraints drift apart until Newton fails; use 'index3'")
    simulation = simulation_settings(settings, float(times[-1]) - t0, dt)
    if redundant:
        # Exudyn's way with redundant constraints (its bricardMechanism
        # example): Eigen's full-pivot LU, which solves the singular
        # system by least squares instead of stopping.
        simulation.linearSolver.solverType = exu.LinearSolverType.EigenDense
        simulation.linearSolver.ignoreSingularJacobian = True
    build_time = time.perf_counter() - clock
    clock = time.perf_counter()
    solver = solve(model, simulation, settings["solver"])
    wall_time = time.perf_counter() - clock

    t_all = t0 + model.mbs.GetSensorStoredData(model.clock_sensor)[:, 0]
    rows = sample_rows(t_all, times)
    frame, missing = read_frame(system, model, rows, times, bool(settings["compute_initial_accelerations"]),
                                resultants=redundant > 0)
    info = {"steps": len(t_all) - 1, "pre_roll_start": t0, "pre_roll_steps_used": pre_roll,
            "newton_iterations": int(solver.it.newtonStepsCount), "jacobian_updates": int(solver.it.newtonJacobiCount),
            "redundant_constraints": redundant, "degrees_of_freedom": int(dof["degreeOfFreedom"]),
            "linear_solver": "EigenDense full pivot" if redundant else "EXUdense",
            "build_time_s": build_time, "wall_time_s": wall_time}
    return RawRun(frame, missing, RunInfo.of(info))


def prepare_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]
                    ) -> tuple[SpatialModel, float, int]:
    """The model a run starts from, the solver's start t0 and the pre-roll
    steps used (the run and the model audit build the same)."""
    dt = float(settings["timestep"])
    pre_roll = int(settings["pre_roll_steps"])
    if settings["solver"] == "index3" and pre_roll:
        pre_roll = max(pre_roll, index3_transient_steps(float(settings["spectral_radius"])))
    while True:     # halved until the reference closes the loop at the pre-roll's start
        t0 = float(times[0]) - pre_roll * dt
        try:
            start = start_frame(system, t0, float(times[1]))
            break
        except (ValueError, Unrepresentable):
            if pre_roll == 0:
                raise
            pre_roll //= 2
    return build_spatial(system, start, t0), t0, pre_roll


def read_frame(system: SpatialSystem, model: SpatialModel, rows: np.ndarray, times: np.ndarray,
               solved_start: bool, resultants: bool = False) -> tuple[pd.DataFrame, dict[str, str]]:
    mbs = model.mbs
    data = lambda sensor: mbs.GetSensorStoredData(sensor)[rows, 1:]  # noqa: E731
    columns: dict[str, np.ndarray] = {"t": times}
    rotation = {GROUND: np.broadcast_to(np.eye(3), (len(rows), 3, 3))}
    for body in system.bodies:
        s = model.body_sensors[body.name]
        R = data(s["RotationMatrix"]).reshape(-1, 3, 3)
        rotation[body.name] = R
        values = {"x y z": data(s["Position"]), "qw qx qy qz": matrix_to_quaternion(R),
                  "vx vy vz": data(s["Velocity"]), "wx wy wz": data(s["AngularVelocity"]),
                  "ax ay az": data(s["Acceleration"]), "alphax alphay alphaz": data(s["AngularAcceleration"])}
        for names, array in values.items():
            for k, name in enumerate(names.split()):
                columns[f"{body.name}.{name}"] = array[:, k]
    for joint in system.joints:
        force_sensor, torque_sensor = model.joint_sensors[joint.name]
        J0, J1 = model.joint_frames[joint.name]
        A0, A1 = rotation[joint.body_i] @ J0, rotation[joint.body_j] @ J1
        F = -np.einsum("nij,nj->ni", A0, data(force_sensor))
        lam = data(torque_sensor)
        M = np.zeros_like(F)
        for row, a, b in rotation_rows(CONSTRAINED_AXES[joint.kind]):
            M -= lam[:, [row]] * np.cross(A1[:, :, b], A0[:, :, a])
        for k, c in enumerate("xyz"):
            columns[f"{joint.name}.F{c}"], columns[f"{joint.name}.M{c}"] = F[:, k], M[:, k]
    for drive in system.drives:
        effort = "T" if system.joint(drive.joint).kind == "revolute" else "F"
        columns[f"{drive.name}.{effort}"] = -data(model.drive_sensors[drive.name])[:, 0]
    laws = [f"{law.name}.T" for law in system.torques]
    for law, column in zip(system.torques, laws):
        sensor, sign, axis = model.torque_sensors[law.name]
        columns[column] = sign * data(sensor) @ axis
    if resultants:
        columns.update(resultant_columns(system, columns, rotation))
    missing: dict[str, str] = {}
    if not solved_start and rows[0] == 0:
        for column in (c for c in columns if c not in laws and c not in system.motion_columns() and c != "t"):
            columns[column] = columns[column].copy()
            columns[column][0] = np.nan
            missing[column] = UNSOLVED_START
    return pd.DataFrame(columns), missing


def resultant_columns(system: SpatialSystem, columns: Mapping[str, np.ndarray], rotation: Mapping[str, np.ndarray]
                      ) -> dict[str, np.ndarray]:
    """Each body's resultant constraint load B.R.Fx … B.R.Mz (force, and
    moment about its centre of mass; world), summed from its joints'
    reactions and its revolute drives' efforts: unique however a solver
    splits the multipliers of redundant constraints, as the reference's."""
    vec = lambda name, q: np.stack([columns[f"{name}.{q}{c}"] for c in "xyz"], axis=-1)  # noqa: E731
    origin = {b.name: np.stack([columns[f"{b.name}.{c}"] for c in "xyz"], axis=-1) for b in system.bodies}
    com = {b.name: origin[b.name] + rotation[b.name] @ np.asarray(b.com, dtype=float) for b in system.bodies}
    total = {b.name: [0.0, 0.0] for b in system.bodies}
    for joint in system.joints:
        F, M = vec(joint.name, "F"), vec(joint.name, "M")
        Pj = (origin[joint.body_j] + rotation[joint.body_j] @ np.asarray(joint.point_j, dtype=float)
              if joint.body_j != GROUND else np.asarray(joint.point_j, dtype=float))
        for body, sign in ((joint.body_j, 1.0), (joint.body_i, -1.0)):
            if body != GROUND:
                total[body][0] = total[body][0] + sign * F
                total[body][1] = total[body][1] + sign * (M + np.cross(Pj - com[body], F))
    for drive in system.drives:
        joint = system.joint(drive.joint)
        if joint.kind != "revolute":
            continue
        axis = rotation[joint.body_i] @ np.asarray(joint.frame_i, dtype=float)[:, 2]
        torque = columns[f"{drive.name}.T"][:, None] * axis
        for body, sign in ((joint.body_j, 1.0), (joint.body_i, -1.0)):
            if body != GROUND:
                total[body][1] = total[body][1] + sign * torque
    out = {}
    for body, (F, M) in total.items():
        for k, c in enumerate("xyz"):
            out[f"{body}.R.F{c}"] = np.broadcast_to(F, (len(columns["t"]), 3))[:, k].copy()
            out[f"{body}.R.M{c}"] = np.broadcast_to(M, (len(columns["t"]), 3))[:, k].copy()
    return out


#: Newton's absolute floor per newton of force scale, and its relative
#: goal, for spatial runs: looser than the planar 1e-13 and 1e-12 because
#: with redundant constraints the full-pivot least-squares solve leaves a
#: residual of ~1e-12 of the step's first one (measured on the spherical
#: four-bar: stuck at 1.1e-12 relative, 9.9e-12 absolute, so the planar
#: goals abort the solver at its first step). A force error of 1e-10 of
#: the scale is far below any tolerance.
SPATIAL_NEWTON_RELATIVE = 1e-10
SPATIAL_NEWTON_PER_NEWTON = 1e-11
def force_scale(system: SpatialSystem, t: np.ndarray, frame: pd.DataFrame) -> float:
    """Σ m·|a_G − g|·max(1, r) (N; r the largest distance from a body's
    centre of mass to its joint points), the largest over the reference
    motion `frame` at the instants t: Newton's absolute goal scales with it."""
    from mechval.reference.spatial.columns import body_state

    _, _, dw = body_state(system, frame)
    total = np.zeros(len(t))
    g = np.asarray(system.gravity, dtype=float)
    for k, b in enumerate(system.bodies):
        arm = max((float(np.linalg.norm(np.subtract(p, b.com))) for j in system.joints
                   for body, p in ((j.body_i, j.point_i), (j.body_j, j.point_j)) if body == b.name), default=0.0)
        total += b.mass * np.linalg.norm(dw[:, k, :3] - g, axis=1) * max(1.0, arm)
    return float(total.max())


def redundant_constraints(system: SpatialSystem, times: np.ndarray) -> int:
    """Exudyn's own count of redundant constraints, on the model at the
    first instant."""
    model = build_spatial(system, start_frame(system, float(times[0]), float(times[1])), float(times[0]))
    return int(model.mbs.ComputeSystemDegreeOfFreedom()["redundantConstraints"])


def spatial_settings(mechanism, times: np.ndarray, rates, rad_per_step: float) -> dict[str, Any]:
    """The adapter's settings for a spatial scene (docs/engines.md, Exudyn,
    "Spatial scenes"): the planar step rule with Ω of the reference motion
    (`rates`: the reference motion on a dense grid of the run and its Ω;
    solved here when None or not spatial); the index-3 solver where
    Exudyn finds redundant constraints (index-2's velocity-level
    constraints drift apart there and its least-squares residual grows
    until Newton fails: measured on the spherical four-bar, from 1e-11 to
    above the goal in 85 steps), else index-2; Newton goals
    SPATIAL_NEWTON_*."""
    from mechval.engines.base import default_step, peak_rates

    system = mechanism.spatial
    rates = peak_rates(mechanism, times) if rates is None else rates
    scale = force_scale(system, np.asarray(rates.t, dtype=float), pd.DataFrame(rates.motion))
    dt = default_step(mechanism, times, rad_per_step=rad_per_step, rate=rates.rate)
    redundant = redundant_constraints(system, times)
    solver = "index3" if redundant else "index2"
    fd = system.forward_dynamics
    spectral = 0.9
    return {
        "solver": solver,
        "timestep": dt,
        "pre_roll_steps": 0 if fd else (index3_transient_steps(spectral) if redundant else 10),
        "spectral_radius": spectral,
        "compute_initial_accelerations": fd and all(getattr(d.law, "alpha", 1.0) == 0.0 for d in system.drives),
        "full_newton": True,
        "newton_relative_tolerance": SPATIAL_NEWTON_RELATIVE,
        "newton_absolute_tolerance": SPATIAL_NEWTON_PER_NEWTON * max(scale, 1e-3),
        "adaptive_step": False,
    }
