"""Each joint kind of the spatial reference against a motion known in
closed form: the universal joint's transmission (Hooke), a body on a
cylindrical and on a planar joint under gravity (uniform acceleration,
constant spin, reactions from Newton–Euler), a body fixed to a driven
crank (the same as one body of the combined inertia)."""

from __future__ import annotations

import numpy as np

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.columns import body_state
from mechval.reference.spatial.dynamics import SpatialDynamics
from mechval.reference.spatial.rotation import cross, frame_from_axis
from mechval.reference.spatial.solver import SpatialSolver
from mechval.reference.spatial.system import SpatialBody, SpatialDrive, SpatialJoint, SpatialSystem
from spatial_mechanisms import HookesJoint, GRAVITY, inertia, revolute, turned_about, unit, wrapped

ROUNDING = 1e-12
INTEGRATED = 1e-9


def test_universal_joint_transmits_as_hookes_joint():
    """Shafts along x̂ and a2 = (cos β, sin β, 0) crossing at O; with the
    input's pin p1 = Rx(θ1)·ẑ and the output's p2 = cos θ2·e_b + sin θ2·ẑ
    (e_b = ẑ × a2), the cross keeps p1·p2 = 0:
    −sin θ1·cos β·cos θ2 + cos θ1·sin θ2 = 0, so tan θ2 = cos β·tan θ1
    (Hooke's joint, e.g. Uicker, Pennock & Shigley, *Theory of Machines and
    Mechanisms*, 4th ed. 2011, the universal joint's angular relation)."""
    hooke = HookesJoint()
    beta, a2, law, system = hooke.beta, hooke.a2, hooke.law, hooke.system
    t = np.linspace(0.0, 3.0, 301)
    sol = SpatialSolver(system).solve(t)
    pose, _, _ = body_state(system, sol.frame)
    theta1 = law.angle(t)
    expected = np.arctan2(np.cos(beta) * np.sin(theta1), np.cos(theta1))
    error = np.abs(wrapped(turned_about(pose.A[:, 1], a2) - expected)).max()
    assert error <= ROUNDING, f"output angle off by {error:.3g} rad"


def sliding_body(kind: str, axis) -> tuple[SpatialSystem, np.ndarray]:
    """A body, centre of mass at its frame's origin and joint point, on a
    `kind` joint to the ground through the world origin along `axis`."""
    axis = unit(axis)
    frame = frame_from_axis(axis)
    body = SpatialBody("body", 1.5, (0.0, 0.0, 0.0), inertia(40, 1e-2))
    joint = SpatialJoint("J", kind, GROUND, "body", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), frame, frame)
    return SpatialSystem(kind, (body,), (joint,), (), GRAVITY), axis


def free_run(system, velocity, omega, t):
    sol = SpatialDynamics(system, {"body": (tuple(velocity), tuple(omega))}).solve(t)
    pose, w, dw = body_state(system, sol.frame)
    return sol, pose, w[:, 0], dw[:, 0]


def joint_load(frame) -> tuple[np.ndarray, np.ndarray]:
    return (frame[[f"J.F{c}" for c in "xyz"]].to_numpy(), frame[[f"J.M{c}" for c in "xyz"]].to_numpy())


def gyroscopic(system, pose, omega) -> np.ndarray:
    J = pose.A[:, 0] @ system.bodies[0].inertia @ np.swapaxes(pose.A[:, 0], -1, -2)
    return cross(omega, np.einsum("nij,nj->ni", J, omega))


def test_cylindrical_joint_slides_and_spins_freely():
    """Along the axis u: s̈ = g·u, spin about u constant (no torque about
    it: the centre of mass is on the axis); the joint supplies the rest:
    F = m(G̈ − g), and about G (= Pj) the gyroscopic moment ω × J·ω of a
    spin about a non-principal axis."""
    system, u = sliding_body("cylindrical", (1.0, 1.0, 1.0))
    g, m = np.asarray(GRAVITY), system.bodies[0].mass
    t = np.linspace(0.0, 1.0, 51)
    sol, pose, w, dw = free_run(system, 0.4 * u, 7.0 * u, t)
    expected_G = np.outer(0.4 * t + 0.5 * (g @ u) * t * t, u)
    assert np.abs(pose.G[:, 0] - expected_G).max() <= INTEGRATED
    assert np.abs(w[:, 3:] - 7.0 * u).max() <= INTEGRATED * 7.0
    F, M = joint_load(sol.frame)
    assert np.abs(F - m * ((g @ u) * u - g)).max() <= ROUNDING * m * 9.81
    gyro = gyroscopic(system, pose, w[:, 3:])
    assert np.abs(M - gyro).max() <= ROUNDING * np.abs(gyro).max()


def test_planar_joint_moves_in_its_plane():
    """In the plane of normal n: G̈ = g − (g·n)·n, spin about n constant;
    the joint pushes F = −m(g·n)·n and supplies ω × J·ω about G."""
    system, n = sliding_body("planar", (0.2, -0.3, 1.0))
    g, m = np.asarray(GRAVITY), system.bodies[0].mass
    t = np.linspace(0.0, 1.0, 51)
    v0 = unit(np.cross(n, [1.0, 0.0, 0.0])) * 0.5
    sol, pose, w, dw = free_run(system, v0, -5.0 * n, t)
    in_plane = g - (g @ n) * n
    assert np.abs(pose.G[:, 0] - (np.outer(t, v0) + 0.5 * np.outer(t * t, in_plane))).max() <= INTEGRATED
    assert np.abs(w[:, 3:] + 5.0 * n).max() <= INTEGRATED * 5.0
    F, M = joint_load(sol.frame)
    assert np.abs(F + m * (g @ n) * n).max() <= ROUNDING * m * 9.81
    gyro = gyroscopic(system, pose, w[:, 3:])
    assert np.abs(M - gyro).max() <= ROUNDING * np.abs(gyro).max()


def test_fixed_joint_makes_one_body():
    """A driven crank with a second body fixed to it needs the drive torque
    of one body of the combined mass, centre of mass and inertia (the
    parallel-axis theorem, Steiner)."""
    law = DriveLaw(0.2, 3.0, 1.5)
    axis = unit((0.3, 0.1, 1.0))
    crank = SpatialBody("crank", 2.0, (0.1, 0.0, 0.05), inertia(50))
    plate = SpatialBody("plate", 1.0, (0.3, 0.1, -0.1), inertia(51))
    hinge = revolute("O", GROUND, "crank", (0.0, 0.0, 0.0), axis)
    weld = SpatialJoint("W", "fixed", "crank", "plate", (0.25, 0.0, 0.0), (0.25, 0.0, 0.0))
    two = SpatialSystem("crank and plate", (crank, plate), (hinge, weld), (SpatialDrive("O", law),), GRAVITY)
    mass = crank.mass + plate.mass
    com = (crank.mass * np.array(crank.com) + plate.mass * np.array(plate.com)) / mass

    def shifted(b):
        d = np.array(b.com) - com
        return b.inertia + b.mass * ((d @ d) * np.eye(3) - np.outer(d, d))

    one = SpatialSystem("one body", (SpatialBody("crank", mass, tuple(com), shifted(crank) + shifted(plate)),),
                        (hinge,), (SpatialDrive("O", law),), GRAVITY)
    t = np.linspace(0.0, 2.0, 101)
    torque_two = SpatialSolver(two).solve(t).frame["drive.T"].to_numpy()
    torque_one = SpatialSolver(one).solve(t).frame["drive.T"].to_numpy()
    assert np.abs(torque_two - torque_one).max() <= ROUNDING * np.abs(torque_one).max()


def test_the_dynamics_at_a_single_instant_is_the_initial_state():
    """An engine reads a free scene's start from the reference at its first
    instant alone: the consistent initial state, no integration."""
    system, _ = sliding_body("cylindrical", (0.0, 0.0, 1.0))
    one = free_run(system, (0.0, 0.0, 0.3), (0.0, 0.0, 2.0), np.array([0.0]))[0]
    many = free_run(system, (0.0, 0.0, 0.3), (0.0, 0.0, 2.0), np.array([0.0, 0.1]))[0]
    assert len(one.frame) == 1
    np.testing.assert_allclose(one.frame.iloc[0].to_numpy(), many.frame.iloc[0].to_numpy(), rtol=0, atol=1e-12)
