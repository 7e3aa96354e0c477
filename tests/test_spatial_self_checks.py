"""The spatial reference checked against itself: loop closure at its
outputs, rates against finite differences of positions, the drives'
power against the rate of change of energy, each body's Newton–Euler
balance from the reported reactions (the Fij convention), and refusals."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mechval.model.mechanism import GROUND
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.columns import body_state
from mechval.reference.spatial.forces import world_inertia
from mechval.reference.spatial.rotation import cross, frame_from_axis
from mechval.reference.spatial.solver import SpatialSolver
from mechval.reference.spatial.system import SpatialSystem
from spatial_mechanisms import RSSR, SphericalFourBar

#: Rounding-level checks, relative to the quantity's peak.
ROUNDING = 1e-12
#: Central differences at step H: truncation error |f'''|·H²/6, some 1e-9
#: of the peak for these motions (a few rad/s), well below this bound.
H = 1e-5
DIFFERENCE = 1e-7


def solved(mechanism, t):
    sol = SpatialSolver(mechanism.system).solve(t)
    return sol, *body_state(mechanism.system, sol.frame)


@pytest.mark.parametrize("make", [SphericalFourBar, RSSR], ids=["spherical four-bar", "RSSR"])
def test_loop_closes_at_the_outputs(make):
    m = make()
    sol, pose, w, _ = solved(m, np.linspace(0.0, 3.0, 301))
    solver = SpatialSolver(m.system)
    residual = np.abs(solver.c.evaluate(pose, sol.frame["t"].to_numpy())["phi"] * solver.scaling.row).max()
    assert residual <= ROUNDING, f"scaled constraint residual {residual:.3g}"


@pytest.mark.parametrize("make", [SphericalFourBar, RSSR], ids=["spherical four-bar", "RSSR"])
def test_rates_are_the_derivatives_of_positions(make):
    m = make()
    centre = np.linspace(0.2, 2.8, 27)
    t = np.sort(np.concatenate([centre - H, centre, centre + H]))
    _, pose, w, dw = solved(m, t)
    before, at, after = slice(0, None, 3), slice(1, None, 3), slice(2, None, 3)
    dG = (pose.G[after] - pose.G[before]) / (2 * H)
    R = pose.A[after] @ np.swapaxes(pose.A[before], -1, -2)          # exp(2H·ω̃) to O(H³)
    turn = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    checks = {"velocity": (dG, w[at, :, :3]), "angular velocity": (turn / (2 * H), w[at, :, 3:]),
              "acceleration": ((w[after] - w[before]) / (2 * H), dw[at])}
    for name, (difference, reported) in checks.items():
        error = np.abs(difference - reported).max() / np.abs(reported).max()
        assert error <= DIFFERENCE, f"{name}: finite differences off by {error:.3g} of the peak"


@pytest.mark.parametrize("make", [SphericalFourBar, RSSR], ids=["spherical four-bar", "RSSR"])
def test_drive_power_is_the_rate_of_change_of_energy(make):
    """d/dt (T + V) = Σ m·Ġ·G̈ + ω·J·ω̇ − m·g·Ġ (ω·(ω × Jω) = 0), exactly,
    from the reported motion; the drive's power T·φ̇ from its multiplier."""
    m = make()
    t = np.linspace(0.0, 3.0, 301)
    sol, pose, w, dw = solved(m, t)
    J = world_inertia(m.system, pose)
    g = np.asarray(m.system.gravity)
    rate = np.zeros(len(t))
    for k, b in enumerate(m.system.bodies):
        rate += b.mass * np.einsum("ni,ni->n", w[:, k, :3], dw[:, k, :3] - g)
        rate += np.einsum("ni,nij,nj->n", w[:, k, 3:], J[:, k], dw[:, k, 3:])
    drive = m.system.drives[0]
    power = sol.frame[f"{drive.name}.T"].to_numpy() * drive.law.rate(t)
    error = np.abs(power - rate).max() / np.abs(rate).max()
    assert error <= ROUNDING, f"power balance off by {error:.3g} of the peak"


def test_reactions_balance_every_body():
    """RSSR (no redundant rows, every reaction unique): per body, the
    joints' loads as reported (F by body_i on body_j at Pj with moment M
    about Pj; the opposite on body_i), the drive's torque about its axis
    and gravity give m·G̈ and J·ω̇ + ω × J·ω."""
    m = RSSR()
    t = np.linspace(0.0, 3.0, 61)
    sol, pose, w, dw = solved(m, t)
    frame, system = sol.frame, m.system
    J = world_inertia(system, pose)
    index = {b.name: k for k, b in enumerate(system.bodies)}
    force = {b.name: b.mass * np.broadcast_to(system.gravity, (len(t), 3)).copy() for b in system.bodies}
    moment = {b.name: np.zeros((len(t), 3)) for b in system.bodies}
    solver = SpatialSolver(system)
    for j in system.joints:
        F = frame[[f"{j.name}.F{c}" for c in "xyz"]].to_numpy()
        M = frame[[f"{j.name}.M{c}" for c in "xyz"]].to_numpy()
        bi, si, bj, sj = solver.c.ends[j.name]
        Pj = solver.c.point(pose, None, bj, sj).value
        for body, sign in ((j.body_j, 1.0), (j.body_i, -1.0)):
            if body != GROUND:
                G = pose.G[:, index[body]]
                force[body] += sign * F
                moment[body] += sign * (M + cross(Pj - G, F))
    drive = system.drives[0]
    axis = frame_from_axis((0.0, 0.0, 1.0))[:, 2]
    moment["input"] += frame[f"{drive.name}.T"].to_numpy()[:, None] * axis
    for b in system.bodies:
        k = index[b.name]
        om = w[:, k, 3:]
        inertial_moment = np.einsum("nij,nj->ni", J[:, k], dw[:, k, 3:]) + cross(om, np.einsum("nij,nj->ni", J[:, k], om))
        scale = np.abs(force[b.name]).max()
        assert np.abs(force[b.name] - b.mass * dw[:, k, :3]).max() <= ROUNDING * scale
        assert np.abs(moment[b.name] - inertial_moment).max() <= ROUNDING * scale * m.length


# -- refusals ----------------------------------------------------------------------------------


def with_body(system, **changes):
    first = dataclasses.replace(system.bodies[0], **changes)
    return lambda: SpatialSystem(system.name, (first, *system.bodies[1:]), system.joints, system.drives,
                                 system.gravity)


@pytest.mark.parametrize("inertia, reason", [
    (np.diag([1e-3, 1e-3, -1e-4]), "not positive definite"),
    (np.diag([1e-3, 1e-3, 3e-3]), "triangle inequality"),
    (np.array([[1e-3, 1e-4, 0], [0, 1e-3, 0], [0, 0, 1e-3]]), "symmetric"),
])
def test_refuses_an_impossible_inertia(inertia, reason):
    with pytest.raises(MechanismError, match=reason) as caught:
        with_body(RSSR().system, inertia=inertia)()
    assert caught.value.key == "body.input.inertia"


def test_refuses_a_degenerate_axis():
    with pytest.raises(ValueError, match="joint.A.axis: a degenerate axis"):
        frame_from_axis((0.0, 0.0, 0.0), key="joint.A.axis")
    with pytest.raises(ValueError, match="parallel"):
        frame_from_axis((0.0, 0.0, 1.0), (0.0, 0.0, 2.0), key="joint.A.axis")


def test_refuses_mobility_that_does_not_match_the_drives():
    """Both coupler ends spherical: the coupler's spin about its own line
    is a second degree of freedom that one drive leaves free."""
    m = RSSR()
    joints = tuple(dataclasses.replace(j, kind="spherical") if j.name == "Q" else j for j in m.system.joints)
    system = dataclasses.replace(m.system, joints=joints)
    with pytest.raises(MechanismError, match="mobility is 2") as caught:
        SpatialSolver(system).solve(np.linspace(0, 1, 5))
    assert caught.value.key == "drive"


def test_refuses_a_loop_that_cannot_close():
    """The coupler made 5 m long: its far end cannot reach the output crank."""
    m = RSSR()
    P, Q = np.array(m.system.joint("P").point_i), np.array(m.system.joint("Q").point_i)
    far = tuple(P + 5.0 * (Q - P) / np.linalg.norm(Q - P))
    joints = tuple(dataclasses.replace(j, point_i=far) if j.name == "Q" else j for j in m.system.joints)
    with pytest.raises(MechanismError, match="cannot close"):
        SpatialSolver(dataclasses.replace(m.system, joints=joints)).solve(np.linspace(0, 1, 5))


def test_refuses_a_drive_on_a_spherical_joint():
    m = RSSR()
    drive = dataclasses.replace(m.system.drives[0], joint="P")
    with pytest.raises(MechanismError, match="revolute or prismatic"):
        dataclasses.replace(m.system, drives=(drive,))
