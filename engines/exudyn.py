"""Exudyn adapter: a planar multibody model solved by Exudyn's implicit
second-order solvers (model building in `exudyn_model`).

Conversion of Exudyn's native outputs to the mechval convention:
- Body motion: `NodeRigidBody2D` coordinates are displacements of (x_G,
  y_G, θ) at the centre of mass from the reference coordinates; adding the
  reference gives the absolute, unwrapped state (θ anchored to the
  reference's angle at the start, since the reference pose *is* the node's
  reference). The body frame origin follows from the rigid-body relations
  (`point_motion` at −com).
- Revolute joint: `ObjectJointRevolute2D` `Force` is the force on its
  marker-0 body from its marker-1 body, world axes. Markers are ordered
  [body_j, body_i], so `Force` is Fij as is.
- Prismatic joint: marker 0 must be the axis holder body_i.
  `ObjectJointPrismatic2D` has no `Force` output; its `ForceLocal` (x, y)
  is the force on body_i from body_j in body_i's frame (measured with a
  turned guide), so Fij = −R(θi)·ForceLocal. Its third component stays 0
  even under a couple: M is reported missing with that reason.
- Drives: each a coordinate constraint q1 − q0 = offset(t), on the
  rotation coordinates (revolute) or on a ground coordinate and the slide
  (prismatic); its multiplier λ (`Force` output) gives the effort on
  body_j, T = −λ or F = −λ along the axis (docs/engines.md; the sign tests
  against the reference confirm both).
- Spring-dampers and body torques are engine elements
  (`ObjectConnectorSpringDamper`, `LoadTorqueVector`); they have no
  column of their own.
- Time stamp: the implicit solvers satisfy the equations of motion and the
  constraints at the end of every step, so the sensor value recorded after
  the step to t_n+1 belongs to t_n+1 (no half-step shift as in explicit
  engines; a one-step shift would turn the O(dt²) error into O(dt)).
  Sensors record every step (write period 0), in memory only.
Only in-plane force components and the z couple/torque are reported: the
model is planar, and out-of-plane reactions of a planar loop are statically
indeterminate anyway, so no engine's value there could be compared.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np
import pandas as pd

from mechval.health import drive_errors
from mechval.kinematics import joint_gaps, point_motion, rotate
from mechval.mechanism import GROUND, MOTION_QUANTITIES, Mechanism

from mechval.adapter import FEATURES, as_float, steps_per_interval

from .base import EngineAdapter, RawRun, RunInfo, default_step
from mechval.settings import TIMESTEP, Choice, Flag, Number, Setting

if TYPE_CHECKING:
    import exudyn as exu

    from .exudyn_model import ExudynModel

#: Newton's absolute tolerance per newton of force scale. Newton stops at the
#: relative goal (1e-12 of the step's first residual) or at this floor,
#: whichever comes first; when round-off puts the relative goal out of reach,
#: only the floor ends the iteration, and since the residual is a force a
#: fixed floor such as 1e-14 N is never reached (the solver aborts).
NEWTON_TOLERANCE_PER_NEWTON = 1e-13
#: Rotation per step for the step rule (`default_step`): finer than the
#: shared 0.01 rad, so that index-2 meets SEED_DEFAULT_ERROR of
#: tests/test_exudyn.py on fourbar-seed (figures: docs/engines.md); cost
#: grows as 1/rad_per_step.
RAD_PER_STEP = 0.007
#: The index-3 force transient after the start shrinks like ρ^n over n
#: steps, whatever the step (docs/engines.md); the pre-roll lets it decay
#: by this factor.
INDEX3_TRANSIENT_DECAY = 1e-8
NO_PRISMATIC_COUPLE = "Exudyn 1.13.6 reports no couple of ObjectJointPrismatic2D (ForceLocal[2] stays 0)"


class ExudynAdapter(EngineAdapter):
    """Exudyn 1.13.6; see the module docstring for the reaction conversion."""

    name = "exudyn"
    library = "exudyn"
    distribution = "exudyn"
    settings_spec: ClassVar[Mapping[str, Setting]] = {
        "solver": Choice(("index2", "index3")),
        "timestep": TIMESTEP,
        # At least one: t = 0 must be a solved step (see `prepare`).
        "pre_roll_steps": Number(1, 100_000, whole=True),
        # Index-3 needs ρ < 1 (`index3_transient_steps`).
        "spectral_radius": Number(0.0, 1.0, high_open=True),
        "compute_initial_accelerations": Flag(),
        "full_newton": Flag(),
        "newton_relative_tolerance": Number(0.0, 1.0, low_open=True),
        "newton_absolute_tolerance": Number(0.0, low_open=True),
        "adaptive_step": Flag(),
    }
    #: Also report the index-3 solver. (High accuracy is a smaller step, e.g.
    #: timestep 1e-4 on fourbar-seed, held by tests/test_exudyn.py's
    #: HIGH_ACCURACY_ERROR; a fixed step is no variant for every scene.)
    variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {"default": {}, "index3": {"solver": "index3"}}
    #: Both solvers for `mechval cost` (the ladder sets `timestep`).
    cost_variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {"index2": {}, "index3": {"solver": "index3"}}

    step_settings = ("timestep", "pre_roll_steps", "spectral_radius")
    #: Every drive a coordinate constraint, springs and torques engine
    #: elements (`exudyn_model`).
    features = frozenset(FEATURES)
    output_copies, bytes_per_step = 4, 1600       # every sensor at every step

    def planned_steps(self, times: np.ndarray, settings: Mapping[str, Any]) -> tuple[float, float]:
        """The pre-roll covers index-3's start-up transient (`prepare`)."""
        pre_roll = as_float(settings["pre_roll_steps"])
        rho = settings["spectral_radius"]
        if settings["solver"] == "index3" and 0.0 <= rho < 1.0:
            pre_roll = max(pre_roll, index3_transient_steps(rho))
        return steps_per_interval(times, as_float(settings["timestep"])), pre_roll

    def default_settings(self, mechanism: Mechanism, times: np.ndarray) -> dict[str, Any]:
        """Step from the scenario's motion (`default_step`); each deliberate
        deviation from Exudyn's defaults is a named setting:

        - solver "index2" (trapezoidal index-2, no start-up transient) or
          "index3" (generalised-α, exact closure, force transient after the
          start, decaying like ρ^n: the pre-roll is lengthened to
          `index3_transient_steps(ρ)` steps so it is over before t = 0);
        - pre_roll_steps: steps along φ(t) before t = 0 from the reference
          state (Exudyn reports zero reactions at its first instant);
        - compute_initial_accelerations False: Exudyn's own solve ignores φ''
          of the drive; the kinematic accelerations are supplied instead;
        - full_newton True, tolerances 1e-12 relative and an absolute floor
          scaled by a force estimate: modified Newton at Exudyn's default
          tolerances caps the force accuracy, at no saving (docs/engines.md);
        - adaptive_step False: it silently shrinks steps;
        - spectral_radius (index-3 only): numerical damping; must stay < 1
          (at 1, λ zig-zags from step to step without decay).
        """
        return {
            "solver": "index2",
            "timestep": default_step(mechanism, times, rad_per_step=RAD_PER_STEP),
            "pre_roll_steps": 10,
            "spectral_radius": 0.9,
            "compute_initial_accelerations": False,
            "full_newton": True,
            "newton_relative_tolerance": 1e-12,
            "newton_absolute_tolerance": NEWTON_TOLERANCE_PER_NEWTON * force_scale(mechanism, times),
            "adaptive_step": False,
        }

    def audit(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
        from .exudyn_audit import audit_model   # imports this module: not at the top
        return audit_model(mechanism, times, settings)

    def run(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
        from .exudyn_model import solve   # the engine library, only when running
        clock = time.perf_counter()
        model, simulation, t0 = prepare(mechanism, times, settings)
        build_time = time.perf_counter() - clock
        clock = time.perf_counter()
        solver = solve(model, simulation, settings["solver"])
        wall_time = time.perf_counter() - clock

        state = _node_states(model)
        t_all = t0 + model.mbs.GetSensorStoredData(model.drive_sensor)[:, 0]
        rows = _sample_rows(t_all, times)
        frame, missing, gap, drive_error = _frame(mechanism, model, state, rows, times, t_all)
        info = {
            "steps": len(t_all) - 1,
            "pre_roll_start": t0, "newton_iterations": int(solver.it.newtonStepsCount),
            "jacobian_updates": int(solver.it.newtonJacobiCount),
            "closure_gap_max": float(gap.max()), "drive_error_max": float(drive_error.max()),
            "build_time_s": build_time, "wall_time_s": wall_time,
        }
        return RawRun(frame, missing, RunInfo.of(info))


def prepare(mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]
            ) -> tuple[ExudynModel, exu.SimulationSettings, float]:
    """The model, the solver settings and the start t0 = times[0] minus the
    pre-roll; the solver's time 0 is t0."""
    from .exudyn_model import SOLVERS, build_model, simulation_settings   # the engine library
    if settings["solver"] not in SOLVERS:
        raise ValueError(f"exudyn: solver must be one of {tuple(SOLVERS)}, got {settings['solver']!r}")
    dt = float(settings["timestep"])
    pre_roll = int(settings["pre_roll_steps"])
    if pre_roll < 1:
        # At its first instant Exudyn reports zero reactions and echoes the
        # supplied accelerations: t = 0 must be a solved step.
        raise ValueError(f"exudyn: pre_roll_steps must be at least 1, got {pre_roll}")
    if settings["solver"] == "index3":
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


def _sample_rows(t_all: np.ndarray, times: np.ndarray) -> np.ndarray:
    """The stored step at each sample instant; every sample must be a step
    (the timestep divides the sample interval and the step is fixed)."""
    rows = np.clip(np.searchsorted(t_all, times), 1, len(t_all) - 1)
    rows -= np.abs(t_all[rows - 1] - times) < np.abs(t_all[rows] - times)
    off = np.abs(t_all[rows] - times) > 1e-9 * max(1.0, float(np.abs(times).max()))
    if off.any():
        raise ValueError(f"exudyn: no solver step at t = {times[off][0]!r}; the timestep must divide "
                         f"the sample interval (and adaptive_step be off)")
    return rows


def _node_states(model: ExudynModel) -> dict[str, dict[str, np.ndarray]]:
    """Per body, absolute (x_G, y_G, θ) and their first and second rates
    at every stored step."""
    states = {}
    for body, sensors in model.body_sensors.items():
        data = {kind: model.mbs.GetSensorStoredData(number)[:, 1:4] for kind, number in sensors.items()}
        data["q"] = data["q"] + model.reference[body]
        states[body] = data
    return states


def _frame(mechanism: Mechanism, model: ExudynModel, state: dict[str, dict[str, np.ndarray]],
           rows: np.ndarray, times: np.ndarray, t_all: np.ndarray
           ) -> tuple[pd.DataFrame, dict[str, str], np.ndarray, np.ndarray]:
    """Raw columns at the sample rows and the reasons for missing ones, plus
    the loop-closure gap and the drive tracking error at every stored step."""
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

    gap = joint_gaps(mechanism, motion)
    return pd.DataFrame(columns), missing, gap, drive_errors(mechanism, motion)


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
