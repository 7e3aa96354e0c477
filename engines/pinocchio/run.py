"""One Pinocchio run of a generic planar mechanism: the model built, the
start state taken from the reference, RK4 from sample to sample, each
sample read out (`readout`)."""

from __future__ import annotations

import time
from typing import Any, Callable, Mapping

import numpy as np
import pandas as pd

from mechval.judging.health import drive_errors
from mechval.model.kinematics import joint_gaps
from mechval.model.mechanism import Mechanism

from mechval.engines.base import RawRun, RunInfo, reference_motion
from mechval.engines.pinocchio.dynamics import Dynamics, rk4
from mechval.engines.pinocchio.model import build_model, coordinates
from mechval.engines.pinocchio.readout import sample


def steps_per_sample(times: np.ndarray, dt: float) -> int:
    """Whole steps per sample interval (the setting divides it)."""
    if len(times) < 2:
        return 0
    return max(1, int(round(float(times[1] - times[0]) / dt)))


def march(times: np.ndarray, timestep: float, q, v, advance: Callable, read: Callable) -> tuple[list[dict], float, int]:
    """From (q, v) at times[0], `advance(t0, q, v, dt, steps)` from sample to
    sample in whole steps, each sample read out by `read(t, q, v)` →
    (row, residual): the rows, the largest residual and the steps per
    sample. A state gone non-finite ends as one FloatingPointError."""
    steps = steps_per_sample(times, float(timestep))
    dt = float(times[1] - times[0]) / steps if steps else 0.0
    rows, residual = [], 0.0
    with np.errstate(all="ignore"):         # a blow-up ends as one error below, not numpy warnings
        for n, t in enumerate(times):
            if n:
                q, v = advance(float(times[n - 1]), q, v, dt, steps)
            if not (np.isfinite(q).all() and np.isfinite(v).all()):
                raise FloatingPointError(f"pinocchio: the state is not finite at t = {float(t)!r}")
            row, off = read(float(t), q, v)
            rows.append({"t": float(t)} | row)
            residual = max(residual, off)
    return rows, residual, steps


def simulate_run(mech: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
    clock = time.perf_counter()
    pm = build_model(mech)
    dynamics = Dynamics(pm, mech, settings)
    # The consistent start (pose and velocities), one read of the run's
    # recorded inputs; a prescribed mechanism's motion is then the drive
    # laws' alone, a torque-driven or free one integrated from there.
    start = reference_motion(mech, np.asarray(times[:1], dtype=float))
    q, v = coordinates(pm, mech, {c: start[c].to_numpy() for c in start.columns})
    build_time = time.perf_counter() - clock

    clock = time.perf_counter()
    rows, residual, steps = march(times, settings["timestep"], q, v,
                                  lambda t0, q, v, dt, n: rk4(dynamics, t0, q, v, dt, n),
                                  lambda t, q, v: sample(pm, dynamics, mech, t, q, v))
    wall_time = time.perf_counter() - clock

    frame = pd.DataFrame(rows)
    frame = frame[["t"] + mech.motion_columns() + mech.reaction_columns()]
    gap = joint_gaps(mech, frame)
    tracking = drive_errors(mech, frame) if mech.drives else np.zeros(len(frame))
    info = {
        "build_time_s": build_time, "wall_time_s": wall_time, "steps": steps * max(len(times) - 1, 0),
        "constraint_dynamics_calls": dynamics.calls, "proximal_iterations_max": dynamics.iterations_max,
        "rnea_residual_max": residual, "closure_gap_max": float(np.max(gap)),
        "drive_error_max": float(np.max(tracking)),
    }
    return RawRun(frame, {}, RunInfo.of(info))
