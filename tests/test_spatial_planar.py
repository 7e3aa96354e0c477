"""Every planar built-in, built as a spatial system
(`mechval.reference.spatial.from_planar`), agrees with the planar reference:
positions, velocities, accelerations, reactions and drive efforts.

Prescribed scenes are solved by both references; torque-driven and free
ones are compared at the planar integration's states (accelerations and
reactions from the same state: the equations of motion, free of the two
integrators' different step errors)."""

from __future__ import annotations

import numpy as np
import pytest

from mechval.reference.dynamics import raw_dynamics
from mechval.reference.linkages import build_mechanism
from mechval.reference.planar.solver import raw_planar
from mechval.reference.spatial.dynamics import SpatialDynamics
from mechval.reference.spatial.from_planar import rot_z, spatial_from_planar
from mechval.reference.spatial.joints import Pose
from mechval.reference.spatial.solver import SpatialSolver, State
from mechval.scenarios.loader import builtin_names, load

#: Issue 26: planar scenes built as spatial scenes agree with the planar
#: reference to 1e-12, here of each quantity class's peak.
AGREE = 1e-12
#: At most this many instants of each scene's own grid (evenly picked):
#: enough to cover its motion, few enough to keep the default run short.
INSTANTS = 101

#: planar raw suffix -> (spatial suffix, quantity class)
MOTION = {"x": ("x", "position"), "y": ("y", "position"), "vx": ("vx", "velocity"), "vy": ("vy", "velocity"),
          "omega": ("wz", "omega"), "ax": ("ax", "acceleration"), "ay": ("ay", "acceleration"),
          "alpha": ("alphaz", "alpha")}


#: A scene tagged "long" is compared over its first seconds by default (its
#: whole run, hundreds of turns, is the slow test): the spatial
#: continuation takes some 10 ms a node on one core, 30 nodes a turn.
LONG_WINDOW = 2.0
#: The equations of motion are compared at the states of the run's start:
#: the planar integration to reach them costs 2–3 s of CPU a second.
DYNAMIC_WINDOW = 0.25


def instants(scenario, whole: bool = True, window: float = LONG_WINDOW) -> np.ndarray:
    t = scenario.time.t
    if not whole:
        t = t[t <= window]
    return t[np.unique(np.linspace(0, len(t) - 1, min(INSTANTS, len(t))).round().astype(int))]


def spatial_twin(mech, planar_frame):
    poses = {b.name: tuple(float(planar_frame[f"{b.name}.{q}"].iloc[0]) for q in ("x", "y", "theta"))
             for b in mech.bodies}
    return spatial_from_planar(mech, poses)


def pairs(mech, planar, spatial):
    """(class, planar values, spatial values) of every compared column."""
    for b in mech.bodies:
        for suffix, (name, kind) in MOTION.items():
            yield kind, planar[f"{b.name}.{suffix}"], spatial[f"{b.name}.{name}"]
        theta = 2 * np.arctan2(spatial[f"{b.name}.qz"], spatial[f"{b.name}.qw"])
        yield "angle", planar[f"{b.name}.theta"], planar[f"{b.name}.theta"] + np.angle(
            np.exp(1j * (theta - planar[f"{b.name}.theta"])))
    for column in mech.reaction_columns():
        joint, quantity = column.rsplit(".", 1)
        name = {"M": "Mz"}.get(quantity, quantity)
        kind = "moment" if quantity in ("M", "T") else "force"
        yield kind, planar[column], spatial[f"{joint}.{name}"]


def assert_agree(mech, planar, spatial) -> None:
    worst = worst_errors(mech, planar, spatial)
    bad = {k: v for k, v in worst.items() if v > AGREE}
    assert not bad, f"errors over the class peak: {bad}"


def worst_errors(mech, planar, spatial) -> dict[str, float]:
    """Per quantity class, the largest difference over the class's peak."""
    peaks: dict[str, float] = {}
    rows = [(kind, np.asarray(p, float), np.asarray(s, float)) for kind, p, s in pairs(mech, planar, spatial)]
    for kind, p, _ in rows:
        if np.isfinite(p).any():
            peaks[kind] = max(peaks.get(kind, 0.0), float(np.nanmax(np.abs(p))))
    worst = {}
    for kind, p, s in rows:
        finite = np.isfinite(p)
        assert np.array_equal(finite, np.isfinite(s)), f"{kind}: the references disagree on which values exist"
        error = float(np.abs(p[finite] - s[finite]).max(initial=0.0))
        worst[kind] = max(worst.get(kind, 0.0), error / max(peaks.get(kind, 0.0), 1e-300))
    return worst


PRESCRIBED = [n for n in builtin_names() if not load(n).forward_dynamics]
DYNAMIC = [n for n in builtin_names() if load(n).forward_dynamics]


def prescribed_cases():
    for name in PRESCRIBED:
        if "long" in load(name).tags:
            yield pytest.param(name, False, id=f"{name}-start")
            yield pytest.param(name, True, id=f"{name}-whole", marks=pytest.mark.slow)
        else:
            yield pytest.param(name, True, id=name)


@pytest.mark.parametrize("name, whole", list(prescribed_cases()))
def test_prescribed_planar_builtin_agrees(name, whole):
    scenario = load(name)
    mech = build_mechanism(scenario)
    t = instants(scenario, whole)
    planar = raw_planar(mech, t)
    spatial = SpatialSolver(spatial_twin(mech, planar.frame)).solve(t)
    assert_agree(mech, planar.frame, spatial.frame)
    # the out-of-plane loads of a plane linkage's joints are statically indeterminate in 3-D
    for j in mech.joints:
        if spatial.facts["redundant_constraints"]:
            assert {f"{j.name}.Fz", f"{j.name}.Mx", f"{j.name}.My"} <= set(spatial.missing)


@pytest.mark.parametrize("name", DYNAMIC)
def test_dynamic_planar_builtin_has_the_same_equations_of_motion(name):
    scenario = load(name)
    mech = build_mechanism(scenario)
    t = instants(scenario, whole=False, window=DYNAMIC_WINDOW)
    planar = raw_dynamics(mech, t).frame
    system = spatial_twin(mech, planar)
    dynamics = SpatialDynamics(system)
    G, A, w = [], [], []
    for b in mech.bodies:
        R = rot_z(0.0)[None] * 0 + np.array([rot_z(th) for th in planar[f"{b.name}.theta"]])
        arm = R @ np.array([b.com[0], b.com[1], 0.0])
        om = planar[f"{b.name}.omega"].to_numpy()
        G.append(np.column_stack([planar[f"{b.name}.x"], planar[f"{b.name}.y"], 0 * om]) + arm)
        A.append(R)
        velocity = np.column_stack([planar[f"{b.name}.vx"] - om * arm[:, 1], planar[f"{b.name}.vy"] + om * arm[:, 0],
                                    0 * om])
        w.append(np.column_stack([velocity, 0 * om, 0 * om, om]))
    pose, w = Pose(np.stack(G, 1), np.stack(A, 1)), np.stack(w, 1)
    dw, lam = dynamics.accelerations(pose, w, t)
    jac = dynamics.c.evaluate(pose, t)["jac"]
    frame, _ = dynamics.solver.frame_of(State(t, pose, w, dw, lam, jac, tuple(dynamics.rows)), dynamics.found)
    assert_agree(mech, planar, frame)
