"""Spatial scenes for tests/test_spatial_exudyn.py and its figures: each a
`SpatialSystem` and the instants of its run; and the per-class comparison
of an engine's raw columns with the spatial reference's
(mechval.model.scenario.DEFAULT_TOLERANCE: positions and quaternion
components absolute, the other classes max|error| / max|reference| over
the class's columns)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND, TorqueLaw
from mechval.model.scenario import DEFAULT_TOLERANCE
from mechval.reference.spatial.system import (BodyLoad, JointTorque, SpatialBody, SpatialDrive, SpatialJoint,
                                              SpatialSystem, Spring)
from mechval.records.signals import SIGNAL_CLASS
from mechval.reference.spatial.rotation import frame_from_axis
from spatial_benchmarks import Bricard, FlyballGovernor
from spatial_mechanisms import (HookesJoint, GRAVITY, Bennett, Delta, HeavyTop, RSSR, SphericalFourBar, TumblingBody, inertia,
                                revolute, unit)
from test_spatial_joint_kinds import sliding_body


def worst_ratios(engine: pd.DataFrame, reference: pd.DataFrame, missing, engine_missing=()
                 ) -> dict[str, tuple[float, str]]:
    """Per class: error / DEFAULT_TOLERANCE (ratio ≤ 1 passes) and the
    worst column; only the columns the reference reports, and of a column
    the engine declares missing (with its reason) its finite values."""
    errors: dict[str, list] = {}
    for column in reference.columns[1:]:
        if column in missing:
            continue
        cls = SIGNAL_CLASS[column]
        ref = reference[column].to_numpy(dtype=float)
        err = np.abs(engine[column].to_numpy(dtype=float) - ref)
        if column in engine_missing:
            err = err[np.isfinite(err)]
        if not np.isfinite(err).all():
            raise AssertionError(f"{column}: the engine gives no value at some instant")
        worst = errors.setdefault(cls, [0.0, 0.0, column])
        if err.max() > worst[0]:
            worst[0], worst[2] = float(err.max()), column
        worst[1] = max(worst[1], float(np.abs(ref).max()))
    out = {}
    for cls, (err, peak, column) in errors.items():
        scale = 1.0 if cls in ("position", "angle") else peak
        out[cls] = (err / scale / DEFAULT_TOLERANCE[cls] if scale > 0 else (0.0 if err == 0 else np.inf), column)
    return out


def with_velocities(m) -> SpatialSystem:
    return dataclasses.replace(m.system, velocities=m.velocities)


def universal_joint() -> SpatialSystem:
    """Hooke's joint between two driven-and-following shafts
    (tests/test_spatial_joint_kinds.py's scene)."""
    return HookesJoint().system


def sliding(kind: str, axis, velocity, spin) -> SpatialSystem:
    system, u = sliding_body(kind, axis)
    v = unit(np.cross(u, [1.0, 0.0, 0.0])) if kind == "planar" else u
    return dataclasses.replace(system, velocities={"body": (tuple(velocity * v), tuple(spin * u))})


def welded_crank() -> SpatialSystem:
    """A driven crank with a plate fixed to it off its axis."""
    axis = unit((0.3, 0.1, 1.0))
    return SpatialSystem(
        "crank and plate", (SpatialBody("crank", 2.0, (0.1, 0.0, 0.05), inertia(50)),
                            SpatialBody("plate", 1.0, (0.3, 0.1, -0.1), inertia(51))),
        (revolute("O", GROUND, "crank", (0.0, 0.0, 0.0), axis),
         SpatialJoint("W", "fixed", "crank", "plate", (0.25, 0.0, 0.0), (0.25, 0.0, 0.0))),
        (SpatialDrive("O", DriveLaw(0.2, 3.0, 1.5)),), GRAVITY)


def torque_pendulum() -> SpatialSystem:
    """A double pendulum on tilted pins under gravity: a torque law at its
    top pin, a spring from the ground to the lower link, a constant body
    load (force and torque) on the lower link, a damper in the knee; free
    otherwise."""
    top, knee = unit((0.2, 1.0, 0.1)), unit((0.0, 1.0, 0.3))
    law = TorqueLaw("A", torque=0.3, amplitude=0.8, frequency=0.7, phase=0.4, name="motor")
    return SpatialSystem(
        "torqued pendulum",
        (SpatialBody("upper", 1.0, (0.15, 0.0, -0.05), inertia(70, 1e-2)),
         SpatialBody("lower", 0.7, (0.35, 0.02, -0.1), inertia(71, 1e-2))),
        (revolute("A", GROUND, "upper", (0.0, 0.0, 0.0), top, (1.0, 0.0, 0.0)),
         dataclasses.replace(revolute("B", "upper", "lower", (0.3, 0.0, -0.05), knee, (1.0, 0.0, 0.0)), damping=0.05)),
        gravity=GRAVITY,
        springs=(Spring("spring", GROUND, (0.3, 0.2, 0.3), "lower", (0.45, 0.0, -0.1), 40.0, 0.3, 0.5),),
        loads=(BodyLoad("push", "lower", (0.5, -0.3, 0.2), (0.05, 0.02, -0.03)),),
        torques=(JointTorque("A", law, "motor"),))


def rotating_slide(kind: str) -> SpatialSystem:
    """An arm driven about the vertical carries a slider on a radial guide
    (its joint frame turns with the arm): prismatic with a prescribed slide
    through a damped guide, or cylindrical and free to slide and spin
    (started with the arm's motion: forward dynamics with a drive)."""
    arm = SpatialBody("arm", 1.0, (0.2, 0.0, 0.0), inertia(80, 1e-2))
    slider = SpatialBody("slider", 0.5, (0.3, 0.0, 0.0), inertia(81, 1e-3))
    guide = frame_from_axis((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    slide = SpatialJoint("S", kind, "arm", "slider", (0.1, 0.0, 0.0), (0.1, 0.0, 0.0), guide, guide,
                         damping=0.3 if kind == "prismatic" else 0.0)
    # The free slider's run starts from Exudyn's own initial-acceleration
    # solve, which ignores φ'' of a drive: a steady spin there.
    spin = SpatialDrive("O", DriveLaw(0.0, 2.0, 0.5 if kind == "prismatic" else 0.0), "spin")
    drives = (spin, SpatialDrive("S", DriveLaw(0.0, 0.1, 0.2), "push")) if kind == "prismatic" else (spin,)
    system = SpatialSystem(f"rotating {kind} slide", (arm, slider),
                           (revolute("O", GROUND, "arm", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0)), slide),
                           drives, GRAVITY)
    if kind == "prismatic":
        return system
    start = {"arm": ((0.0, 0.0, 0.0), (0.0, 0.0, 2.0)), "slider": ((0.0, 0.0, 0.0), (0.0, 0.0, 2.0))}
    return dataclasses.replace(system, velocities=start)


def tumbling() -> tuple[SpatialSystem, np.ndarray]:
    m = TumblingBody()
    return with_velocities(m), np.linspace(0.0, 2.4 * m.quarter, 121)


def heavy_top() -> tuple[SpatialSystem, np.ndarray]:
    m = HeavyTop()
    return with_velocities(m), np.linspace(0.0, 0.25 * np.pi / m.precession, 51)


#: name → (system, instants) builders.
CASES = {
    "spherical four-bar": lambda: (SphericalFourBar().system, np.linspace(0.0, 1.0, 21)),
    "RSSR": lambda: (RSSR().system, np.linspace(0.0, 1.0, 21)),
    "Bennett": lambda: (Bennett().system, np.linspace(0.0, 1.0, 21)),
    "delta": lambda: (Delta().system, np.linspace(0.0, 1.0, 21)),
    "Bricard (A04)": lambda: (Bricard().system, np.linspace(0.0, 1.0, 21)),
    # A05 is stiff: the reference's explicit integrator covers milliseconds
    # (tests/test_spatial_benchmarks.py, FLYBALL_SPAN); undamped it is not.
    "flyball (A05)": lambda: (with_velocities(FlyballGovernor()), np.linspace(0.0, 0.0025, 11)),
    "flyball undamped": lambda: (with_velocities(FlyballGovernor(damping=0.0)), np.linspace(0.0, 0.05, 26)),
    "T-handle": tumbling,
    "heavy top": heavy_top,
    "universal": lambda: (universal_joint(), np.linspace(0.0, 1.0, 21)),
    "cylindrical": lambda: (sliding("cylindrical", (1.0, 1.0, 1.0), 0.4, 7.0), np.linspace(0.0, 1.0, 21)),
    "planar": lambda: (sliding("planar", (0.2, -0.3, 1.0), 0.5, -5.0), np.linspace(0.0, 1.0, 21)),
    "prismatic": lambda: (sliding("prismatic", (0.3, -1.0, 0.5), 0.4, 0.0), np.linspace(0.0, 1.0, 21)),
    "prismatic drive on a turning guide": lambda: (rotating_slide("prismatic"), np.linspace(0.0, 1.0, 21)),
    "cylindrical on a turning guide": lambda: (rotating_slide("cylindrical"), np.linspace(0.0, 1.0, 21)),
    "fixed": lambda: (welded_crank(), np.linspace(0.0, 1.0, 21)),
    "torque law, spring, load, damper": lambda: (torque_pendulum(), np.linspace(0.0, 1.0, 21)),
}
