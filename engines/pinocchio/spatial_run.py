"""One Pinocchio run of a spatial scene (`run_spatial`): the model built,
the start taken from the spatial reference at the first instant, RKMK4
from sample to sample (`spatial_dynamics`), each sample read out
(`spatial_readout`); and the dampers' rate RK4's step must resolve
(`force_rate`)."""

from __future__ import annotations

import time
from typing import Any, Mapping

import numpy as np
import pandas as pd
import pinocchio as pin

from mechval.model.mechanism import GROUND
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.dynamics import SpatialDynamics as ReferenceDynamics
from mechval.reference.spatial.rotation import cross
from mechval.reference.spatial.solver import solve_spatial
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.base import RawRun, RunInfo, Unrepresentable
from mechval.engines.pinocchio.adapter import RAD_PER_STEP
from mechval.engines.pinocchio.run import march
from mechval.engines.pinocchio.spatial_dynamics import SpatialDynamics, rkmk4
from mechval.engines.pinocchio.spatial_model import build_spatial_model, start_state
from mechval.engines.pinocchio.spatial_readout import sample


#: A damper counts as the rate c/m·RAD_PER_STEP, so that the step rule's
#: RAD_PER_STEP / Ω gives c/m·dt ≤ 1: a decaying mode needs stability (RK4's
#: real bound is 2.78), not a small turn per step.
DAMPER_RAD = RAD_PER_STEP


def reference_start(system: SpatialSystem, t0: float) -> tuple[dict[str, pin.SE3], dict[str, np.ndarray]]:
    """Each body's pose and (origin velocity, ω) at t0 from the reference:
    the prescribed motion solved there, or the consistent initial state a
    torque-driven or free run starts from (its projected velocities)."""
    poses, twists = {}, {}
    if system.forward_dynamics:
        start = ReferenceDynamics(system, system.velocities, t0=t0)
        for k, b in enumerate(system.bodies):
            A, w = start.pose0.A[0, k], start.w0[0, k]
            arm = A @ np.asarray(b.com, dtype=float)
            poses[b.name] = pin.SE3(A, start.pose0.G[0, k] - arm)
            twists[b.name] = np.concatenate([w[:3] - cross(w[3:], arm), w[3:]])
        return poses, twists
    frame = solve_spatial(system, np.array([t0])).frame
    for b in system.bodies:
        take = lambda names: frame[[f"{b.name}.{n}" for n in names.split()]].to_numpy()[0]   # noqa: E731
        w, x, y, z = take("qw qx qy qz")
        poses[b.name] = pin.SE3(pin.Quaternion(w, x, y, z).normalized().matrix(), take("x y z"))
        twists[b.name] = np.concatenate([take("vx vy vz"), take("wx wy wz")])
    return poses, twists


def force_rate(system: SpatialSystem) -> float:
    """The fastest rate of the scene's spring-dampers on their own: √(k/m)
    of the spring, and c/m of the damper over `DAMPER_RAD`, m the lighter
    moving body it joins: RK4's stability needs the damper's rate too,
    which the shared step rule (`mechval.model.kinematics.spring_rate`)
    leaves out (A05: RK4 diverges at the motion's step;
    tests/test_spatial_pinocchio.py)."""
    rate = 0.0
    for s in system.springs:
        mass = min(system.body(b).mass for b in (s.body_a, s.body_b) if b != GROUND)
        rate = max(rate, np.sqrt(s.stiffness / mass), s.damping / mass * DAMPER_RAD)
    return float(rate)


def run_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
    """The scene's raw columns at `times` (see the modules named above)."""
    times = np.asarray(times, dtype=float)
    clock = time.perf_counter()
    sm = build_spatial_model(system)
    dynamics = SpatialDynamics(sm, system, settings)
    try:
        start = reference_start(system, float(times[0]))
    except MechanismError as exc:           # a start the reference refuses: the scene's key and reason
        raise Unrepresentable(exc.key, exc.reason) from None
    q, v = start_state(sm, system, *start)
    build_time = time.perf_counter() - clock

    clock = time.perf_counter()
    rows, residual, steps = march(times, settings["timestep"], q, v,
                                  lambda t0, q, v, dt, n: rkmk4(dynamics, t0, q, v, dt, n),
                                  lambda t, q, v: sample(sm, dynamics, system, t, q, v))
    wall_time = time.perf_counter() - clock
    frame = pd.DataFrame(rows)[["t"] + system.motion_columns() + system.reaction_columns()]
    info = {
        "build_time_s": build_time, "wall_time_s": wall_time, "steps": steps * max(len(times) - 1, 0),
        "constraint_dynamics_calls": dynamics.calls, "proximal_iterations_max": dynamics.iterations_max,
        "newton_euler_residual_max": residual, "loop_constraints": len(sm.constraints),
    }
    return RawRun(frame, {}, RunInfo.of(info))
