"""The delta robot's drive torques against an independent computation:
Jourdain's principle of virtual power (Kane's equations) on its
closed-form kinematics, with nothing of the spatial reference.

Kinematics: the platform translates (3-RUU, Tsai's condition), so its
position p(θ) is the closed-form inverse kinematics θ(p)
(`delta_arm_angle`) inverted by Newton; each arm turns about its pin u
by θ − θ0; each rod's attitude is fixed by its end points B, C and its
pins w ∥ u × (C − B) (both pins are perpendicular to the rod and the
arm's pin). Rates by central differences in time, and the partial
velocities ∂v/∂θ̇k, ∂ω/∂θ̇k by central differences of the kinematics in
θk. Then τk = Σ_bodies ∂v_G/∂θ̇k · (m·a_G − m·g) + ∂ω/∂θ̇k · (I·α + ω × I·ω).
The differences bound the agreement: 1e-7 of the torques' peak (measured 1.9e-9)."""

import numpy as np

from mechval.reference.spatial.solver import SpatialSolver
from spatial_mechanisms import GRAVITY, Delta

#: Central differences in time (s) and in the arm angles (rad): their
#: truncation (h²) and rounding (ε/h², ε/h) errors meet near these.
DT, DTHETA = 1e-4, 1e-5
#: The agreement the differences allow, of the torques' peak.
AGREE = 1e-7


def unit(v):
    return v / np.linalg.norm(v)


def turned(axis, angle):
    k = unit(np.asarray(axis, dtype=float))
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


class DeltaKinematics:
    """Every body's centre of mass and attitude as functions of the arm angles."""

    def __init__(self, m: Delta):
        self.m = m
        self.e = [np.array([np.cos(phi), np.sin(phi), 0.0]) for phi in m.legs]
        self.u = [np.cross([0.0, 0.0, 1.0], e) for e in self.e]
        self.p = m.start.copy()

    def platform(self, theta) -> np.ndarray:
        """p(θ): Newton on the closed-form θ(p), from the last solution."""
        p = self.p.copy()
        for _ in range(50):
            miss = self.m.arm_angles(p) - theta
            if np.abs(miss).max() < 1e-15:
                break
            J = np.stack([(self.m.arm_angles(p + h) - self.m.arm_angles(p - h)) / 2e-7
                          for h in 1e-7 * np.eye(3)], axis=1)
            p = p - np.linalg.solve(J, miss)
        self.p = p
        return p

    def elbow(self, k, theta_k) -> np.ndarray:
        m = self.m
        return m.base * self.e[k] + m.arm * (np.cos(theta_k) * self.e[k] - np.sin(theta_k) * np.array([0, 0, 1.0]))

    def rod_frame(self, k, B, C) -> np.ndarray:
        d = unit(C - B)
        w = unit(np.cross(self.u[k], d))
        return np.stack([d, w, np.cross(d, w)], axis=1)

    def poses(self, theta) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Body name → (centre of mass, rotation from its assembly attitude)."""
        m, p = self.m, self.platform(theta)
        poses = {"platform": (p.copy(), np.eye(3))}
        for k in range(3):
            A, B, C = m.base * self.e[k], self.elbow(k, theta[k]), p + m.plate * self.e[k]
            R_arm = turned(self.u[k], theta[k] - m.theta0[k])
            B0, C0 = self.elbow(k, m.theta0[k]), m.start + m.plate * self.e[k]
            poses[f"arm{k}"] = (A + R_arm @ ((A + B0) / 2 - A), R_arm)
            poses[f"rod{k}"] = ((B + C) / 2, self.rod_frame(k, B, C) @ self.rod_frame(k, B0, C0).T)
        return poses


def angular(R_minus, R_plus, R, h):
    """ω from a central difference of rotations: (Ṙ·Rᵀ)'s axial vector."""
    W = (R_plus - R_minus) / (2 * h) @ R.T
    return 0.5 * np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]])


def virtual_power_torques(m: Delta, t: np.ndarray) -> np.ndarray:
    kin = DeltaKinematics(m)
    bodies = {b.name: b for b in m.system.bodies}
    g = np.asarray(GRAVITY)
    angles = lambda s: np.array([th0 + law.angle(s) for th0, law in zip(m.theta0, m.laws)])
    torques = np.zeros((len(t), 3))
    for n, s in enumerate(t):
        at = {h: kin.poses(angles(s + h)) for h in (-2 * DT, -DT, DT, 2 * DT)}
        at[0.0] = kin.poses(angles(s))
        partial = []
        for k in range(3):
            dth = DTHETA * np.eye(3)[k]
            lo, hi = kin.poses(angles(s) - dth), kin.poses(angles(s) + dth)
            kin.poses(angles(s))                     # Newton restarts from here
            partial.append(lo), partial.append(hi)
        for name, body in bodies.items():
            G, R = at[0.0][name]
            a = (at[DT][name][0] - 2 * G + at[-DT][name][0]) / DT ** 2
            om = angular(at[-DT][name][1], at[DT][name][1], R, DT)
            om_minus = angular(at[-2 * DT][name][1], at[0.0][name][1], at[-DT][name][1], DT)
            om_plus = angular(at[0.0][name][1], at[2 * DT][name][1], at[DT][name][1], DT)
            al = (om_plus - om_minus) / (2 * DT)
            I = R @ np.asarray(body.inertia) @ R.T
            force, moment = body.mass * (a - g), I @ al + np.cross(om, I @ om)
            for k in range(3):
                lo, hi = partial[2 * k][name], partial[2 * k + 1][name]
                dv = (hi[0] - lo[0]) / (2 * DTHETA)
                dw = angular(lo[1], hi[1], R, DTHETA)
                torques[n, k] += dv @ force + dw @ moment
    return torques


def test_delta_drive_torques_match_the_virtual_power_of_its_closed_form_motion():
    """Inertia is 1.3 % of the torques' peak and the gyroscopic terms
    2.3e-7 of it here: the check sees both, not statics alone."""
    m = Delta()
    t = np.linspace(0.0, 1.0, 21)
    frame = SpatialSolver(m.system).solve(t).frame
    reference = frame[[f"drive{k}.T" for k in range(3)]].to_numpy()
    independent = virtual_power_torques(m, t)
    error = np.abs(reference - independent).max() / np.abs(independent).max()
    assert error <= AGREE, f"drive torques differ by {error:.3g} of their peak"
