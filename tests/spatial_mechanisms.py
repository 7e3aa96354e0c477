"""Spatial systems whose motion has a closed form
(`mechval.reference.closed_forms.spatial`), built for the spatial
reference: every body's frame is the world frame at the assembly, so joint
points and axes are written in world axes at that instant."""

from __future__ import annotations

import numpy as np

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND
from mechval.reference.closed_forms import spatial as closed
from mechval.reference.spatial.rotation import frame_from_axis
from mechval.reference.spatial.system import SpatialBody, SpatialDrive, SpatialJoint, SpatialSystem

GRAVITY = (0.0, 0.0, -9.81)


def inertia(seed: int, scale: float = 1e-3) -> np.ndarray:
    """A full, positive-definite inertia tensor (principal moments 1, 1.5,
    2 × scale on turned axes): products of inertia exercise the solver."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q @ np.diag([1.0, 1.5, 2.0]) @ q.T * scale


def body(name: str, com, seed: int, mass: float = 0.5) -> SpatialBody:
    return SpatialBody(name, mass, tuple(np.asarray(com, float)), inertia(seed))


def revolute(name, body_i, body_j, point, axis, reference=None, kind="revolute") -> SpatialJoint:
    frame = frame_from_axis(axis, reference, f"joint.{name}.axis")
    p = tuple(np.asarray(point, float))
    return SpatialJoint(name, kind, body_i, body_j, p, p, frame, frame)


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


class SphericalFourBar:
    """Four revolute axes through O: fixed u = ẑ and w at α1 from it,
    input axis v at α2 from u, output axis s at α4 from w, coupler α3."""

    alphas = np.radians([70.0, 20.0, 60.0, 45.0])
    radius = 0.3
    law = DriveLaw(0.0, 1.1, 0.3)
    branch = 1

    def __init__(self):
        a1, a2, a3, a4 = self.alphas
        self.u, self.w = np.array([0.0, 0.0, 1.0]), np.array([np.sin(a1), 0.0, np.cos(a1)])
        self.v0 = np.array([np.sin(a2), 0.0, np.cos(a2)])
        self.psi0 = float(closed.spherical_fourbar_output(0.0, *self.alphas, branch=self.branch))
        s_local = np.array([np.sin(a4) * np.cos(self.psi0), np.sin(a4) * np.sin(self.psi0), np.cos(a4)])
        self.s0 = np.array([s_local[0] * np.cos(a1) + s_local[2] * np.sin(a1), s_local[1],
                            -s_local[0] * np.sin(a1) + s_local[2] * np.cos(a1)])
        R = self.radius
        self.system = SpatialSystem(
            "spherical four-bar",
            (body("input", R * (self.u + self.v0) / 2, 1), body("coupler", R * (self.v0 + self.s0) / 2, 2),
             body("output", R * (self.s0 + self.w) / 2, 3)),
            (revolute("A", GROUND, "input", R * self.u, self.u, (1.0, 0.0, 0.0)),
             revolute("B", "input", "coupler", R * self.v0, self.v0),
             revolute("C", "coupler", "output", R * self.s0, self.s0),
             revolute("D", GROUND, "output", R * self.w, self.w)),
            (SpatialDrive("A", self.law),), GRAVITY)

    def expected_output(self, t) -> np.ndarray:
        return closed.spherical_fourbar_output(self.law.angle(t), *self.alphas, branch=self.branch)


class Bennett:
    """Bennett's linkage by Denavit–Hartenberg frames F0 (ground) … F3:
    joint k about F(k−1)'s z through its origin; θ1 driven."""

    alpha, beta, a = np.radians(30.0), np.radians(70.0), 0.2
    theta1_0 = 1.0
    law = DriveLaw(0.0, 1.0, 0.0)

    def __init__(self):
        b = self.a * np.sin(self.beta) / np.sin(self.alpha)
        th2 = float(closed.bennett_angle(self.theta1_0, self.alpha, self.beta))
        links = [(self.theta1_0, self.a, self.alpha), (th2, b, self.beta), (-self.theta1_0, self.a, self.alpha)]
        F = [np.eye(4)]
        for link in links:
            F.append(F[-1] @ closed.dh_transform(*link))
        self.frames = F
        names = ["link1", "link2", "link3"]
        bodies = tuple(body(n, (F[k][:3, 3] + F[k + 1][:3, 3]) / 2, 10 + k) for k, n in enumerate(names))
        ends = [GROUND] + names + [GROUND]
        joints = tuple(
            revolute(f"J{k + 1}", ends[k], ends[k + 1], F[k][:3, 3], F[k][:3, 2], F[k][:3, 0])
            for k in range(4))
        self.system = SpatialSystem("Bennett", bodies, joints, (SpatialDrive("J1", self.law),), GRAVITY)

    def expected_theta2(self, t) -> np.ndarray:
        return closed.bennett_angle(self.theta1_0 + self.law.angle(t), self.alpha, self.beta)


class RSSR:
    """Input crank about ẑ through O (ball at radius a), output crank about
    e through C (ball at radius b), coupler of length ℓ. The coupler's
    idle spin about its own line is held by making its output end a
    universal joint (one pin along e, one across): the distance |Q − P|,
    all the output angle depends on, is the RSSR's."""

    a, b, length = 0.1, 0.2, 0.35
    centre = np.array([0.05, 0.3, 0.15])
    e = unit([1.0, 0.3, 0.2])
    law = DriveLaw(0.3, 2.0, 0.5)
    branch = 1

    def __init__(self):
        self.e1 = unit(np.cross(self.e, [0.0, 0.0, 1.0]))
        self.e2 = np.cross(self.e, self.e1)
        th0 = float(self.law.angle(0.0))
        self.psi0 = float(closed.rssr_output(th0, self.a, self.b, self.length, self.centre, self.e1, self.e2,
                                             self.branch))
        P = self.a * np.array([np.cos(th0), np.sin(th0), 0.0])
        Q = self.centre + self.b * (np.cos(self.psi0) * self.e1 + np.sin(self.psi0) * self.e2)
        cross_pin = unit(np.cross(self.e, Q - P))
        ball = SpatialJoint("P", "spherical", "input", "coupler", tuple(P), tuple(P))
        pins = SpatialJoint("Q", "universal", "coupler", "output", tuple(Q), tuple(Q),
                            frame_from_axis(cross_pin), frame_from_axis(self.e))
        self.system = SpatialSystem(
            "RSSR",
            (body("input", P / 2, 20), body("coupler", (P + Q) / 2, 21), body("output", (self.centre + Q) / 2, 22)),
            (revolute("O", GROUND, "input", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0)), ball, pins,
             revolute("C", GROUND, "output", self.centre, self.e)),
            (SpatialDrive("O", DriveLaw(0.0, self.law.omega0, self.law.alpha)),), GRAVITY)
        self.theta0 = th0

    def expected_output(self, t) -> np.ndarray:
        return closed.rssr_output(self.theta0 + self.law.angle(t) - self.law.phi0, self.a, self.b, self.length,
                                  self.centre, self.e1, self.e2, self.branch)


def turned_about(A: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The angle of rotations A (N, 3, 3) known to be about `axis`."""
    s = 0.5 * np.stack([A[:, 2, 1] - A[:, 1, 2], A[:, 0, 2] - A[:, 2, 0], A[:, 1, 0] - A[:, 0, 1]], -1) @ axis
    c = 0.5 * (np.trace(A, axis1=1, axis2=2) - 1)
    return np.arctan2(s, c)


def wrapped(angle) -> np.ndarray:
    return np.angle(np.exp(1j * np.asarray(angle)))


class TumblingBody:
    """A free body spinning mostly about its intermediate principal axis
    (I1 < I2 < I3): ω starts at the quarter period of Landau's solution,
    ω1 = 0, ω2 at its peak, ω3 small, and ω2 flips sign after half a
    period (the intermediate-axis, or Dzhanibekov, flip)."""

    principal = (0.01, 0.02, 0.03)
    omega0 = np.array([0.0, 4.0, 0.2])       # body axes, rad/s
    velocity = (0.3, -0.2, 0.1)              # of the centre of mass, m/s

    def __init__(self):
        rng = np.random.default_rng(7)
        self.turn, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        if np.linalg.det(self.turn) < 0:
            self.turn[:, 0] *= -1
        # body frame along the principal axes, turned in the world
        self.system = SpatialSystem("tumbling body", (SpatialBody("body", 2.0, (0.0, 0.0, 0.0),
                                                                  np.diag(self.principal), rotation=self.turn),), ())
        I = np.array(self.principal)
        self.energy = 0.5 * float(I @ self.omega0 ** 2)
        self.momentum = float(np.linalg.norm(I * self.omega0))
        self.quarter = closed.torque_free_quarter_period(self.principal, self.energy, self.momentum)

    @property
    def velocities(self) -> dict:
        return {"body": (self.velocity, tuple(self.turn @ self.omega0))}

    def expected_omega(self, t) -> np.ndarray:
        return closed.torque_free_omega(np.asarray(t) + self.quarter, self.principal, (1.0, 1.0),
                                        self.energy, self.momentum)


class HeavyTop:
    """A symmetric top on a fixed point (spherical joint at the origin),
    axis tilted by `tilt` from the vertical, started in steady slow
    precession: ω = Ω·ẑ + ψ̇·e3 with Ω from Goldstein's eq. 5.76."""

    mass, arm, tilt, spin = 0.5, 0.04, 0.5, 200.0
    transverse_cm, axial = 2e-4, 3e-4

    def __init__(self):
        c, s = np.cos(self.tilt), np.sin(self.tilt)
        R = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])     # e3 = R·ẑ = (0, −sin θ, cos θ)
        self.e3 = R[:, 2]
        self.transverse = self.transverse_cm + self.mass * self.arm ** 2     # about the fixed point
        self.precession = closed.top_precession_rates(self.tilt, self.spin, self.mass, self.arm, 9.81,
                                                      self.transverse, self.axial)[0]
        psi_dot = self.spin - self.precession * c
        self.omega0 = self.precession * np.array([0.0, 0.0, 1.0]) + psi_dot * self.e3
        self.system = SpatialSystem(
            "heavy top", (SpatialBody("top", self.mass, (0.0, 0.0, self.arm),
                                      np.diag([self.transverse_cm, self.transverse_cm, self.axial]), rotation=R),),
            (SpatialJoint("tip", "spherical", GROUND, "top", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),), (), GRAVITY)

    @property
    def velocities(self) -> dict:
        return {"top": ((0.0, 0.0, 0.0), tuple(self.omega0))}


class Delta:
    """A delta robot whose lower legs are single rods with a universal
    joint at each end (3-RUU): the pins on arm and platform parallel to
    the arm's axis u, the two on the rod parallel to each other (Tsai's
    condition for a translating platform). Arms driven from the assembly's
    angles; the platform's motion is the solver's."""

    base, plate, arm, rod = 0.2, 0.05, 0.2, 0.45
    start = np.array([0.02, -0.01, -0.35])
    laws = (DriveLaw(0.0, 0.4, -0.3), DriveLaw(0.0, -0.2, 0.5), DriveLaw(0.0, 0.3, 0.2))
    branch = -1

    def __init__(self):
        self.legs = np.radians([0.0, 120.0, 240.0])
        self.theta0 = [float(closed.delta_arm_angle(self.start, self.base, self.plate, self.arm, self.rod, phi,
                                                    self.branch)) for phi in self.legs]
        bodies = [SpatialBody("platform", 0.3, tuple(self.start), inertia(60, 1e-4))]
        joints = []
        for k, (phi, th) in enumerate(zip(self.legs, self.theta0)):
            e = np.array([np.cos(phi), np.sin(phi), 0.0])
            u = np.cross([0.0, 0.0, 1.0], e)
            A = self.base * e
            B = A + self.arm * (np.cos(th) * e - np.sin(th) * np.array([0.0, 0.0, 1.0]))
            C = self.start + self.plate * e
            w = unit(np.cross(u, C - B))
            bodies += [SpatialBody(f"arm{k}", 0.2, tuple((A + B) / 2), inertia(61 + k, 1e-4)),
                       SpatialBody(f"rod{k}", 0.1, tuple((B + C) / 2), inertia(64 + k, 1e-4))]
            joints += [revolute(f"R{k}", GROUND, f"arm{k}", A, u, e),
                       SpatialJoint(f"E{k}", "universal", f"arm{k}", f"rod{k}", tuple(B), tuple(B),
                                    frame_from_axis(u), frame_from_axis(w)),
                       SpatialJoint(f"P{k}", "universal", f"rod{k}", "platform", tuple(C), tuple(C),
                                    frame_from_axis(w), frame_from_axis(u))]
        drives = tuple(SpatialDrive(f"R{k}", law, f"drive{k}") for k, law in enumerate(self.laws))
        self.system = SpatialSystem("delta", tuple(bodies), tuple(joints), drives, GRAVITY)

    def arm_angles(self, platform_origin) -> np.ndarray:
        """The closed-form arm angles (N, 3) that put the platform frame's
        origin (the platform's position relative to its start, plus start) there."""
        p = np.asarray(platform_origin, dtype=float)
        return np.stack([closed.delta_arm_angle(p, self.base, self.plate, self.arm, self.rod, phi, self.branch)
                         for phi in self.legs], axis=-1)


class HookesJoint:
    """Hooke's joint: a driven input shaft along x̂ and an output shaft
    along a2 = (cos β, sin β, 0), β = 35°, crossing at O and held in
    bearings, joined by a universal joint whose pins are ẑ on the input
    and e_b = ẑ × a2 on the output; tan θ2 = cos β·tan θ1 (Uicker, Pennock
    & Shigley, *Theory of Machines and Mechanisms*, 4th ed. 2011)."""

    beta = np.radians(35.0)
    law = DriveLaw(0.0, 2.0, 0.7)

    def __init__(self):
        self.a2 = np.array([np.cos(self.beta), np.sin(self.beta), 0.0])
        e_b = np.cross([0.0, 0.0, 1.0], self.a2)
        self.system = SpatialSystem(
            "Hooke", (SpatialBody("input", 1.0, (-0.2, 0.0, 0.0), inertia(30)),
                      SpatialBody("output", 1.0, tuple(0.2 * self.a2), inertia(31))),
            (revolute("R1", GROUND, "input", (-0.3, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
             SpatialJoint("U", "universal", "input", "output", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                          frame_from_axis((0.0, 0.0, 1.0)), frame_from_axis(e_b)),
             revolute("R2", GROUND, "output", 0.3 * self.a2, self.a2, e_b)),
            (SpatialDrive("R1", self.law),), GRAVITY)
