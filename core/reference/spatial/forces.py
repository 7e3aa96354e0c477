"""Mass matrix and applied forces of a spatial system, per body in the
coordinates of `mechval.reference.spatial.joints` (Ġ, ω world).

Newton–Euler per body (Shabana 2005, §4.9; Nikravesh 1988, eq. 11.26):
m·G̈ = F and J·ω̇ + ω × (J·ω) = N about G, J = A·J'·Aᵀ in world axes;
so M = diag(m·I, J) and Q = (F, N − ω × J·ω): the gyroscopic term is a
velocity-dependent applied load. Q holds gravity, constant body loads,
spring-dampers (tension k(ℓ − ℓ0) + c·ℓ̇ pulling the points together),
joint dampers (−c·(ωj − ωi)·zi about zi on body_j at a revolute joint,
−c·ṡ along zi at Pj on body_j at a prismatic one; the opposite on body_i)
and joint torques (T·zi on body_j, −T·zi on body_i). Drive efforts and
reactions come from the multipliers, not from Q.
"""

from __future__ import annotations

import numpy as np

from mechval.reference.spatial.rotation import cross
from mechval.reference.spatial.joints import Constraints, Pose
from mechval.reference.spatial.system import SpatialSystem


def world_inertia(system: SpatialSystem, pose: Pose) -> np.ndarray:
    """J = A·J'·Aᵀ of every body, (N, nb, 3, 3)."""
    J_body = np.array([np.asarray(b.inertia, dtype=float) for b in system.bodies]).reshape(-1, 3, 3)
    return pose.A @ J_body @ np.swapaxes(pose.A, -1, -2)


def mass_matrix(system: SpatialSystem, pose: Pose) -> np.ndarray:
    """Block-diagonal M, (N, n, n)."""
    nb, N = len(system.bodies), len(pose)
    M = np.zeros((N, 6 * nb, 6 * nb))
    J = world_inertia(system, pose)
    for k, b in enumerate(system.bodies):
        M[:, 6 * k:6 * k + 3, 6 * k:6 * k + 3] = b.mass * np.eye(3)
        M[:, 6 * k + 3:6 * k + 6, 6 * k + 3:6 * k + 6] = J[:, k]
    return M


class AppliedForces:
    """Q(q, q̇, t) of a system, (N, n), vectorised over instants."""

    def __init__(self, constraints: Constraints):
        self.c = constraints
        self.system = system = constraints.system
        #: The bodies' mass (nb,), inertia about the centre of mass in body
        #: axes (nb, 3, 3) and gravity (3,): Q's gravity and gyroscopic
        #: loads, which `outputs.multipliers` computes itself.
        self.mass = np.array([b.mass for b in system.bodies], dtype=float)
        self.inertia = np.array([np.asarray(b.inertia, dtype=float) for b in system.bodies]).reshape(-1, 3, 3)
        self.gravity = np.asarray(system.gravity, dtype=float)
        self.has_applied = bool(system.loads or system.torques or system.springs
                                or any(j.damping for j in system.joints))

    def _at(self, Q, pose: Pose, body: int, P, force) -> None:
        """A force at world point P on a body (ground: nothing)."""
        if body < 0:
            return
        Q[:, 6 * body:6 * body + 3] += force
        Q[:, 6 * body + 3:6 * body + 6] += cross(P - pose.G[:, body], force)

    def _couple(self, Q, body: int, torque) -> None:
        if body >= 0:
            Q[:, 6 * body + 3:6 * body + 6] += torque

    def generalised(self, pose: Pose, w: np.ndarray, t: np.ndarray, J: np.ndarray | None = None) -> np.ndarray:
        """Q at N instants; J: the world inertias, if the caller has them."""
        system = self.system
        N, nb = len(pose), len(system.bodies)
        Q = np.zeros((N, 6 * nb))
        J = world_inertia(system, pose) if J is None else J
        for k, b in enumerate(system.bodies):
            om = w[:, k, 3:]
            Q[:, 6 * k:6 * k + 3] += b.mass * self.gravity
            Q[:, 6 * k + 3:6 * k + 6] -= cross(om, np.einsum("nij,nj->ni", J[:, k], om))
        self._add_applied(Q, pose, w, t)
        return Q

    def applied(self, pose: Pose, w: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """Q but its gravity and gyroscopic loads (the bodies' constant
        loads, joint dampers and torques, spring-dampers); None where the
        system has none of them."""
        if not self.has_applied:
            return None
        Q = np.zeros((len(pose), self.c.n))
        self._add_applied(Q, pose, w, t)
        return Q

    def _add_applied(self, Q: np.ndarray, pose: Pose, w: np.ndarray, t: np.ndarray) -> None:
        system, c = self.system, self.c
        for load in system.loads:
            k = c.index[load.body]
            Q[:, 6 * k:6 * k + 3] += np.asarray(load.force, dtype=float)
            Q[:, 6 * k + 3:6 * k + 6] += np.asarray(load.torque, dtype=float)
        for j in system.joints:
            if j.damping:
                self._damper(Q, pose, w, j)
        for torque in system.torques:
            j = system.joint(torque.joint)
            bi, _, bj, _ = c.ends[j.name]
            z = c.axis(pose, None, bi, j.frame_i[:, 2]).value
            T = np.asarray(torque.law.value(t), dtype=float)[:, None] * z
            self._couple(Q, bj, T)
            self._couple(Q, bi, -T)
        for spring in system.springs:
            self._spring(Q, pose, w, spring)

    def _damper(self, Q, pose: Pose, w, j) -> None:
        c = self.c
        bi, si, bj, sj = c.ends[j.name]
        z = c.axis(pose, None, bi, j.frame_i[:, 2]).value
        omega = lambda b: w[:, b, 3:] if b >= 0 else 0.0   # noqa: E731
        if j.kind == "revolute":
            torque = -j.damping * np.einsum("ni,ni->n", omega(bj) - omega(bi), z)[:, None] * z
            self._couple(Q, bj, torque)
            self._couple(Q, bi, -torque)
            return
        Pi, Pj = c.point(pose, w, bi, si), c.point(pose, w, bj, sj)
        # ṡ = d/dt (zi·d) = żi·d + zi·ḋ
        z_rate = cross(omega(bi), z) if bi >= 0 else 0.0 * z
        d = Pj.value - Pi.value
        rate = np.einsum("ni,ni->n", z_rate, d) + np.einsum("ni,ni->n", z, Pj.rate - Pi.rate)
        force = -j.damping * rate[:, None] * z
        self._at(Q, pose, bj, Pj.value, force)
        self._at(Q, pose, bi, Pj.value, -force)

    def _spring(self, Q, pose: Pose, w, e) -> None:
        c = self.c
        com = lambda name: np.asarray(self.system.body(name).com, dtype=float) if name in c.index else 0.0   # noqa: E731
        ba, bb = c.index.get(e.body_a, -1), c.index.get(e.body_b, -1)
        Pa = c.point(pose, w, ba, np.asarray(e.point_a, dtype=float) - com(e.body_a))
        Pb = c.point(pose, w, bb, np.asarray(e.point_b, dtype=float) - com(e.body_b))
        d = Pb.value - Pa.value
        length = np.linalg.norm(d, axis=1)
        unit = d / length[:, None]
        tension = e.stiffness * (length - e.free_length)
        if e.damping:
            tension = tension + e.damping * np.einsum("ni,ni->n", Pb.rate - Pa.rate, unit)
        self._at(Q, pose, bb, Pb.value, -tension[:, None] * unit)
        self._at(Q, pose, ba, Pa.value, tension[:, None] * unit)
