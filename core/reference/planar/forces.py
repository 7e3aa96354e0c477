"""Applied forces of a planar mechanism as generalised forces Q(q, q̇).

Coordinates as in `mechval.reference.planar.constraints`: (x, y, θ) of each moving
body's centre of mass, so the mass matrix is diag(m, m, izz) and a force F
at a point with arm r = P − G contributes (Fx, Fy, (r × F)·ẑ) to its body.
Equations of motion: M·q̈ + Φqᵀ·λ = Q (Nikravesh 1988, ch. 6).

Q holds (docs/conventions.md, "Dampers are separate effects"):
- gravity m·g at each centre of mass;
- joint dampers: −c·(ωj − ωi) on body_j and the opposite on body_i
  (revolute); −c·ṡ·u on body_j at its point Pj and the opposite on body_i
  at the same point (prismatic, ṡ = (Ṗj − Ṗi)·u), as `newton_euler` does;
- spring-dampers: tension f = k·(ℓ − ℓ0) + c·ℓ̇ pulling the two points
  together (−f·e on body_b at Pb, +f·e on body_a at Pa, e = (Pb − Pa)/ℓ);
- constant body torques.
Drive efforts and joint reactions are not in Q: they come from λ.
"""

from __future__ import annotations

import numpy as np

from mechval.model.mechanism import BodyTorque, Mechanism, SpringDamper
from mechval.reference.planar.constraints import Attachment, Constraints


def mass_diagonal(mech: Mechanism) -> np.ndarray:
    """diag(M): (m, m, izz) per moving body."""
    return np.array([v for b in mech.bodies for v in (b.mass, b.mass, b.izz)], dtype=float)


class AppliedForces:
    """Q(q, q̇) of a mechanism, vectorised over instants."""

    def __init__(self, constraints: Constraints):
        self.c = constraints
        self.mech = constraints.mech

    def _add_force(self, Q, a: Attachment, P, fx, fy) -> None:
        """Force (fx, fy) at the attachment's point P (self.c.point)."""
        if a.body < 0:
            return
        k = 3 * a.body
        Q[:, k] += fx
        Q[:, k + 1] += fy
        Q[:, k + 2] += P[2] * fy - P[3] * fx

    def generalised(self, q: np.ndarray, v: np.ndarray, frames: dict | None = None) -> np.ndarray:
        """Q, shape (instants, n); `frames`: `Constraints.frames(q)`, if at hand."""
        c, mech = self.c, self.mech
        Q = np.zeros_like(q)
        trig = (frames["cos"], frames["sin"]) if frames else c.trig(q)
        gx, gy = mech.gravity
        for k, body in enumerate(mech.bodies):
            Q[:, 3 * k] += body.mass * gx
            Q[:, 3 * k + 1] += body.mass * gy
        omega = lambda a: 0.0 if a.body < 0 else v[:, 3 * a.body + 2]
        for j in mech.damped_joints:
            ai, aj = c.attach(j.body_i, j.point_i), c.attach(j.body_j, j.point_j)
            if j.kind == "revolute":
                torque = -j.damping * (omega(aj) - omega(ai))
                if aj.body >= 0:
                    Q[:, 3 * aj.body + 2] += torque
                if ai.body >= 0:
                    Q[:, 3 * ai.body + 2] -= torque
            else:
                Pi, Pj = c.point(q, ai, trig), c.point(q, aj, trig)
                vi, vj = c.point_velocity(v, ai, Pi), c.point_velocity(v, aj, Pj)
                ux, uy = c.axis(j, trig, len(q))
                rate = (vj[0] - vi[0]) * ux + (vj[1] - vi[1]) * uy
                fx, fy = -j.damping * rate * ux, -j.damping * rate * uy
                self._add_force(Q, aj, Pj, fx, fy)
                # On body_i at the same point Pj: its arm is Pj − Gi.
                if ai.body >= 0:
                    arm = (None, None, Pj[0] - q[:, 3 * ai.body], Pj[1] - q[:, 3 * ai.body + 1])
                    self._add_force(Q, ai, arm, -fx, -fy)
        for element in mech.forces:
            if isinstance(element, BodyTorque):
                Q[:, 3 * c.index[element.body] + 2] += element.torque
            elif isinstance(element, SpringDamper):
                self._spring(Q, q, v, trig, element)
        return Q

    def _spring(self, Q, q, v, trig, e: SpringDamper) -> None:
        c = self.c
        aa, ab = c.attach(e.body_a, e.point_a), c.attach(e.body_b, e.point_b)
        Pa, Pb = c.point(q, aa, trig), c.point(q, ab, trig)
        dx, dy = Pb[0] - Pa[0], Pb[1] - Pa[1]
        length = np.hypot(dx, dy)
        ex, ey = dx / length, dy / length
        tension = e.stiffness * (length - e.free_length)
        if e.damping:
            va, vb = c.point_velocity(v, aa, Pa), c.point_velocity(v, ab, Pb)
            tension = tension + e.damping * ((vb[0] - va[0]) * ex + (vb[1] - va[1]) * ey)
        self._add_force(Q, ab, Pb, -tension * ex, -tension * ey)
        self._add_force(Q, aa, Pa, tension * ex, tension * ey)
