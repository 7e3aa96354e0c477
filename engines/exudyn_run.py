"""One Exudyn run of a generic planar mechanism: the model prepared for the
run (pre-roll start, simulation settings) and the read-out converted to the
Fij convention (see `mechval.engines.exudyn`). The adapter (`exudyn`) and
the model audit (`exudyn_audit`) both build on this module.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

import exudyn as exu
import numpy as np
import pandas as pd

from mechval.health import drive_errors
from mechval.kinematics import joint_gaps, point_motion, rotate
from mechval.mechanism import GROUND, MOTION_QUANTITIES, Mechanism

from .exudyn_model import SOLVERS, ExudynModel, build_model, forward_motion, simulation_settings

#: The index-3 force transient after the start shrinks like ρ^n over n
#: steps, whatever the step (docs/engines.md); the pre-roll lets it decay
#: by this factor.
INDEX3_TRANSIENT_DECAY = 1e-8
NO_PRISMATIC_COUPLE = "Exudyn 1.13.6 reports no couple of ObjectJointPrismatic2D (ForceLocal[2] stays 0)"
UNSOLVED_START = ("Exudyn 1.13.6 reports zero reactions at its first instant unless its own initial-acceleration "
                  "solve ran (compute_initial_accelerations), and a run with no pre-roll starts at the first sample")


def prepare(mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]
            ) -> tuple[ExudynModel, exu.SimulationSettings, float]:
    """The model, the solver settings and the start t0 = times[0] minus the
    pre-roll (none for a torque-driven or free mechanism: its motion is
    known only from times[0] on); the solver's time 0 is t0."""
    if settings["solver"] not in SOLVERS:
        raise ValueError(f"exudyn: solver must be one of {tuple(SOLVERS)}, got {settings['solver']!r}")
    dt = float(settings["timestep"])
    pre_roll = int(settings["pre_roll_steps"])
    if mechanism.forward_dynamics and pre_roll != 0:
        raise ValueError(f"exudyn: pre_roll_steps must be 0 for a torque-driven or free mechanism (it starts "
                         f"at its first instant), got {pre_roll}")
    if not mechanism.forward_dynamics and pre_roll < 1:
        # At its first instant Exudyn reports zero reactions and echoes the
        # supplied accelerations: t = 0 must be a solved step.
        raise ValueError(f"exudyn: pre_roll_steps must be at least 1, got {pre_roll}")
    if settings["solver"] == "index3" and pre_roll:
        pre_roll = max(pre_roll, index3_transient_steps(float(settings["spectral_radius"])))
    t0 = float(times[0]) - pre_roll * dt
    return build_model(mechanism, t0), simulation_settings(settings, float(times[-1]) - t0, dt), t0


def index3_transient_steps(spectral_radius: float) -> int:
    """Pre-roll steps that put the index-3 force transient before t = 0."""
    if not 0.0 <= spectral_radius < 1.0:
        raise ValueError(f"exudyn: index3 needs 0 <= spectral_radius < 1 (at 1 the constraint forces "
                         f"zig-zag from step to step without decay), got {spectral_radius!r}")
    if spectral_radius == 0.0:
        return 1
    return int(np.ceil(np.log(INDEX3_TRANSIENT_DECAY) / np.log(spectral_radius)))


def scene_motion(mechanism: Mechanism) -> Mechanism:
    """The mechanism whose `motion` gives its motion over the run: as it is
    for prescribed motion; for a torque-driven or free mechanism, whose
    motion is not known before it is integrated, the forward-dynamics
    reference from the grid's first instant (each grid integrated once),
    so that the step rule and the force scale read it like kinematics."""
    if not mechanism.forward_dynamics:
        return mechanism
    frames: dict[tuple[float, float, int], pd.DataFrame] = {}

    def motion(t: np.ndarray) -> pd.DataFrame:
        t = np.asarray(t, dtype=float)
        key = (float(t[0]), float(t[-1]), len(t))
        if key not in frames:
            frames[key] = forward_motion(mechanism, t)
        return frames[key]

    return dataclasses.replace(mechanism, motion=motion)


def force_scale(mechanism: Mechanism, times: np.ndarray, dense: int = 2001) -> float:
    """Peak over the run of Σ m·|a_G − g| (N): the size of the forces the
    Newton residual is made of."""
    t = np.linspace(float(times[0]), float(times[-1]), dense)
    motion = mechanism.motion(t)
    total = np.zeros_like(t)
    for body in mechanism.bodies:
        g = point_motion(motion, body.name, body.com)
        total += body.mass * np.hypot(g["ax"] - mechanism.gravity[0], g["ay"] - mechanism.gravity[1])
    return float(total.max())


def sample_rows(t_all: np.ndarray, times: np.ndarray) -> np.ndarray:
    """The stored step at each sample instant; every sample must be a step
    (the timestep divides the sample interval and the step is fixed)."""
    rows = np.clip(np.searchsorted(t_all, times), 1, len(t_all) - 1)
    rows -= np.abs(t_all[rows - 1] - times) < np.abs(t_all[rows] - times)
    off = np.abs(t_all[rows] - times) > 1e-9 * max(1.0, float(np.abs(times).max()))
    if off.any():
        raise ValueError(f"exudyn: no solver step at t = {times[off][0]!r}; the timestep must divide "
                         f"the sample interval (and adaptive_step be off)")
    return rows


def node_states(model: ExudynModel) -> dict[str, dict[str, np.ndarray]]:
    """Per body, absolute (x_G, y_G, θ) and their first and second rates
    at every stored step."""
    states = {}
    for body, sensors in model.body_sensors.items():
        data = {kind: model.mbs.GetSensorStoredData(number)[:, 1:4] for kind, number in sensors.items()}
        data["q"] = data["q"] + model.reference[body]
        states[body] = data
    return states


def frame_of(mechanism: Mechanism, model: ExudynModel, state: dict[str, dict[str, np.ndarray]],
           rows: np.ndarray, times: np.ndarray, t_all: np.ndarray, solved_start: bool = False
           ) -> tuple[pd.DataFrame, dict[str, str], np.ndarray, np.ndarray]:
    """Raw columns at the sample rows and the reasons for missing ones, plus
    the loop-closure gap and the drive tracking error at every stored step.
    The reactions and drive efforts at the first stored step are missing
    unless Exudyn solved for them there (`solved_start`)."""
    motion = _frame_motion(mechanism, state, t_all)
    columns = {"t": np.asarray(times, dtype=float)}
    columns.update({name: motion[name].to_numpy()[rows] for name in mechanism.motion_columns()})
    missing = {}

    for joint in mechanism.joints:
        force = model.mbs.GetSensorStoredData(model.joint_sensors[joint.name])[rows, 1:3]
        if joint.kind == "revolute":
            columns[f"{joint.name}.Fx"], columns[f"{joint.name}.Fy"] = force[:, 0], force[:, 1]
        else:
            fx, fy = rotate(_theta(motion, joint.body_i)[rows], (-force[:, 0], -force[:, 1]))
            columns[f"{joint.name}.Fx"], columns[f"{joint.name}.Fy"] = fx, fy
            columns[f"{joint.name}.M"] = np.full(len(rows), np.nan)
            missing[f"{joint.name}.M"] = NO_PRISMATIC_COUPLE
    for drive in mechanism.drives:
        effort = drive.effort_column(mechanism.joint(drive.joint).kind)
        columns[effort] = -model.mbs.GetSensorStoredData(model.drive_sensors[drive.name])[rows, 1]
    if not solved_start and rows[0] == 0:
        for column in (c for c in mechanism.reaction_columns() if c in columns):   # not the torque laws
            columns[column][0] = np.nan
            missing.setdefault(column, UNSOLVED_START)
    for law in mechanism.torque_drives:     # the applied torque, known at every step
        sensor, sign = model.torque_sensors[law.name]
        columns[f"{law.name}.T"] = sign * model.mbs.GetSensorStoredData(sensor)[rows, 3]

    gap = joint_gaps(mechanism, motion)
    tracking = drive_errors(mechanism, motion) if mechanism.drives else np.zeros(len(t_all))
    return pd.DataFrame(columns), missing, gap, tracking


def _frame_motion(mechanism: Mechanism, state: dict[str, dict[str, np.ndarray]],
                  t_all: np.ndarray) -> pd.DataFrame:
    """Motion columns of every body frame origin at every stored step, from
    the centre-of-mass states (rigid-body relations, `point_motion` at −com)."""
    # Sensor columns are (x, y, θ), their rates, their accelerations.
    quantities = {"q": MOTION_QUANTITIES[0:3], "v": MOTION_QUANTITIES[3:6], "a": MOTION_QUANTITIES[6:9]}
    com_motion = pd.DataFrame({"t": t_all} | {
        f"{body}.{q}": s[kind][:, i]
        for body, s in state.items() for kind, names in quantities.items() for i, q in enumerate(names)})
    frames = {"t": t_all}
    for body in mechanism.bodies:
        origin = point_motion(com_motion, body.name, (-body.com[0], -body.com[1]))
        for q in ("theta", "omega", "alpha"):
            origin[q] = com_motion[f"{body.name}.{q}"].to_numpy()
        frames.update({f"{body.name}.{q}": origin[q] for q in MOTION_QUANTITIES})
    return pd.DataFrame(frames)


def _theta(motion: pd.DataFrame, body: str) -> np.ndarray:
    """The body's angle at every stored step (the ground's is 0)."""
    return np.zeros(len(motion)) if body == GROUND else motion[f"{body}.theta"].to_numpy()
