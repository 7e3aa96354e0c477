"""One Exudyn run of a generic planar mechanism: the model prepared for the
run (pre-roll start, simulation settings) and the read-out converted to the
Fij convention (see `mechval.engines.exudyn.adapter`). The adapter (`exudyn`) and
the model audit (`audit`) both build on this module.
"""

from __future__ import annotations

from typing import Any, Mapping

import exudyn as exu
import numpy as np
import pandas as pd

from mechval.records import engine_inputs
from mechval.judging.health import drive_errors
from mechval.model.kinematics import joint_gaps, point_motion, rotate
from mechval.model.mechanism import GROUND, MOTION_QUANTITIES, BodyPose, Mechanism
from mechval.reference.planar.scene import SolvedMotion
from mechval.reference.planar.solver import raw_planar

from mechval.engines.exudyn.model import SOLVERS, ExudynModel, build_model, simulation_settings
from mechval.engines.exudyn.slide import UNDERIVABLE, slide_couples

#: The index-3 force transient after the start shrinks like ρ^n over n
#: steps, whatever the step (docs/engines.md); the pre-roll lets it decay
#: by this factor.
INDEX3_TRANSIENT_DECAY = 1e-8
#: Relative (and absolute, for values near 0) agreement of the pre-roll's
#: motion at the first sample with the run's reference there: the same
#: branch agrees to the solvers' rounding (~1e-12), another differs by O(1).
SAME_STATE = 1e-6
UNSOLVED_START = ("Exudyn 1.13.6 reports zero reactions at its first instant unless its own initial-acceleration "
                  "solve ran (compute_initial_accelerations), and a run with no pre-roll starts at the first sample")


def prepare(mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]
            ) -> tuple[ExudynModel, exu.SimulationSettings, float]:
    """The model, the solver settings and the start t0 = times[0] minus the
    pre-roll (none for a torque-driven or free mechanism: its motion is
    known only from times[0] on; shortened where the reference cannot
    close the loop that early, `pre_roll_start`); the solver's time 0 is
    t0."""
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
    index3 = settings["solver"] == "index3"
    if index3 and pre_roll:
        pre_roll = max(pre_roll, index3_transient_steps(float(settings["spectral_radius"])))
    pre_roll, start = pre_roll_start(mechanism, times, pre_roll, dt)
    if index3 and pre_roll:
        settings = {**settings, "spectral_radius": index3_spectral_radius(float(settings["spectral_radius"]), pre_roll)}
    t0 = float(times[0]) - pre_roll * dt
    return build_model(mechanism, t0, start), simulation_settings(settings, float(times[-1]) - t0, dt), t0


def index3_spectral_radius(spectral_radius: float, pre_roll: int) -> float:
    """The spectral radius of an index-3 run whose pre-roll has `pre_roll`
    steps: as set, unless that is too few steps for the start-up
    transient to decay by INDEX3_TRANSIENT_DECAY (a pre-roll shortened by
    `pre_roll_start`); then lowered so that it does, ρ = DECAY^(1/n): the
    transient's size grows with the step and near a dead centre, and one
    left at t = 0 can exceed the default bounds many times over
    (tests/test_exudyn_pre_roll.py measures it)."""
    if index3_transient_steps(spectral_radius) <= pre_roll:
        return spectral_radius
    return min(spectral_radius, INDEX3_TRANSIENT_DECAY ** (1.0 / pre_roll))


def pre_roll_start(mechanism: Mechanism, times: np.ndarray, steps: int, dt: float
                   ) -> tuple[int, pd.DataFrame | None]:
    """The longest pre-roll of `steps` steps along φ(t) before times[0],
    halved (as MuJoCo's adapter does) until the reference closes the loop
    over it on the run's branch, and the reference state at its start
    (raw motion columns, one row; None for no pre-roll, when the state is
    the run's first).

    The scene guarantees closure over the run only: before t = 0 the drive
    law may leave the range where the loop closes (a run that starts near
    a dead centre), and a reference that assembles at the pre-roll start
    from the file's pose (meant for t = 0) may not find it there at all.
    With no step left the run starts at times[0]: Exudyn then reports zero
    reactions at that first sample, which are missing with that reason."""
    if steps == 0:
        return 0, None
    first = mechanism.motion(times[:1])
    while steps:
        t = float(times[0]) - dt * np.arange(steps, -1, -1)
        # One read of the run's inputs (`mechval.records.engine_inputs`): the state
        # at the pre-roll's start, or none where it does not close.
        start = engine_inputs.read(mechanism, "start on the run's branch", t, None,
                                   lambda: _start_on_the_run_s_branch(mechanism, t, first))
        if len(start):
            return steps, start
        steps //= 2
    return 0, None


def _start_on_the_run_s_branch(mechanism: Mechanism, t: np.ndarray, first: pd.DataFrame) -> pd.DataFrame:
    """The reference motion's first row over instants t (the last is the
    run's first instant), or no row where the loop does not close at all of
    them or the motion does not arrive at the run's own first state
    `first`. The general reference (`SolvedMotion`) is assembled at t[0]
    from the run's first pose rather than from the file's, so it starts on
    the run's branch; a closed form holds its branch at every instant."""
    columns, none = mechanism.motion_columns(), pd.DataFrame()
    motion_of = engine_inputs.source_motion(mechanism)
    try:
        with np.errstate(invalid="ignore"):
            if isinstance(motion_of, SolvedMotion):
                pose = {b.name: BodyPose(*(float(first[f"{b.name}.{q}"].iloc[0]) for q in ("theta", "x", "y")))
                        for b in mechanism.bodies}
                motion = raw_planar(mechanism, t, pose).frame
            else:
                motion = motion_of(t)
    except ValueError:                      # MechanismError: the loop cannot close, or a singular pose
        return none
    values, arrival = motion[columns].to_numpy(dtype=float), first[columns].to_numpy(dtype=float)[0]
    if not np.isfinite(values).all():
        return none
    if not np.allclose(values[-1], arrival, rtol=SAME_STATE, atol=SAME_STATE):
        return none                         # it closed on another branch
    return motion[["t"] + columns].iloc[:1].reset_index(drop=True)


def index3_transient_steps(spectral_radius: float) -> int:
    """Pre-roll steps that put the index-3 force transient before t = 0."""
    if not 0.0 <= spectral_radius < 1.0:
        raise ValueError(f"exudyn: index3 needs 0 <= spectral_radius < 1 (at 1 the constraint forces "
                         f"zig-zag from step to step without decay), got {spectral_radius!r}")
    if spectral_radius == 0.0:
        return 1
    return int(np.ceil(np.log(INDEX3_TRANSIENT_DECAY) / np.log(spectral_radius)))


def force_scale(mechanism: Mechanism, motion: Mapping, t: np.ndarray) -> float:
    """Peak over the instants t of Σ m·|a_G − g|·max(1, r/1 m) (N), r the
    largest distance from the body's centre of mass to its joints, from the
    reference motion at t: the size of the forces the Newton residual is
    made of and of their moments about the centres of mass (N·m: arms
    beyond a metre make those the larger rows)."""
    total = np.zeros_like(t)
    for body in mechanism.bodies:
        g = point_motion(motion, body.name, body.com)
        arm = max((float(np.hypot(p[0] - body.com[0], p[1] - body.com[1])) for j in mechanism.joints
                   for b, p in ((j.body_i, j.point_i), (j.body_j, j.point_j)) if b == body.name), default=0.0)
        total += body.mass * np.hypot(g["ax"] - mechanism.gravity[0], g["ay"] - mechanism.gravity[1]) * max(1.0, arm)
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
    for drive in mechanism.drives:
        effort = drive.effort_column(mechanism.joint(drive.joint).kind)
        columns[effort] = -model.mbs.GetSensorStoredData(model.drive_sensors[drive.name])[rows, 1]
    laws = [f"{law.name}.T" for law in mechanism.torque_drives]
    for law, column in zip(mechanism.torque_drives, laws):     # the applied torque, known at every step
        sensor, sign = model.torque_sensors[law.name]
        columns[column] = sign * model.mbs.GetSensorStoredData(sensor)[rows, 3]
    missing.update(_slide_couples(mechanism, columns, state, rows))
    if not solved_start and rows[0] == 0:
        for column in (c for c in mechanism.reaction_columns() if c not in laws):
            columns[column][0] = np.nan
            missing.setdefault(column, UNSOLVED_START)

    gap = joint_gaps(mechanism, motion)
    tracking = drive_errors(mechanism, motion) if mechanism.drives else np.zeros(len(t_all))
    return pd.DataFrame(columns), missing, gap, tracking


def _slide_couples(mechanism: Mechanism, columns: dict[str, np.ndarray], state: dict[str, dict[str, np.ndarray]],
                   rows: np.ndarray) -> dict[str, str]:
    """Put each slide's couple "J.M" into `columns`, derived from its
    body's balance (`slide`), or NaN; returns the reasons for the
    missing ones."""
    slides = [f"{j.name}.M" for j in mechanism.joints if j.kind == "prismatic"]
    if not slides:
        return {}
    coordinates, rates = (np.hstack([state[b.name][kind][rows] for b in mechanism.bodies]) for kind in ("q", "v"))
    couples = slide_couples(mechanism, columns, coordinates, rates)
    if couples is None:
        columns.update({column: np.full(len(rows), np.nan) for column in slides})
        return dict.fromkeys(slides, UNDERIVABLE)
    columns.update(couples)
    return {}


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
