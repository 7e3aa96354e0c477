"""Pinocchio's constraint dynamics of a spatial scene with its drives and
applied effects, and the Lie-group Runge–Kutta that integrates it
(Pinocchio computes dynamics; it has no time integrator).

Applied effects (spring-dampers, body loads, torque laws, joint dampers)
are wrenches on the scene's bodies, world axes about the world origin,
mapped to generalised forces by the bodies' world Jacobians (τ = Jᵀ·w),
whether their joint is in the tree or cut; gravity is the model's.
Drives are tree coordinates whose acceleration is prescribed (±φ''(t)):
`constraintDynamics` is affine in τ at a given state, so one call at the
applied forces and one per drive with a unit effort give the efforts
that meet every drive (a k × k solve), as in the planar adapter
(engines/pinocchio/dynamics.py).

Integrator: RKMK4, the classical Runge–Kutta in the Lie algebra
(Munthe-Kaas, *High order Runge–Kutta methods on manifolds*, Appl.
Numer. Math. 29 (1999) 115–127). The configuration is never added to:
each stage's q is q_n ⊕ ξ (`pin.integrate`: the exponential map of each
joint's group, unit quaternions for spherical and free joints), and the
stage's tangent k = dexp⁻¹_ξ(v) (`pin.dIntegrate` with respect to ξ,
solved for k), so the method keeps RK4's fourth order on SO(3) and SE(3)
and keeps every quaternion unit; v, a vector, is integrated as in RK4.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import pinocchio as pin

from mechval.model.mechanism import GROUND
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.pinocchio.spatial_model import SpatialModel, frame_jacobian

WORLD = pin.ReferenceFrame.WORLD
ALIGNED = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class Kinematics:
    """Each body's pose, origin velocity and ω (world) at one (q, v):
    what the applied effects and the read-out need."""

    def __init__(self, sm: SpatialModel, q: np.ndarray, v: np.ndarray):
        pin.forwardKinematics(sm.model, sm.data, q, v)
        self.sm, self.pose, self.twist = sm, {}, {}
        for body, f in sm.frame_of.items():
            self.pose[body] = pin.updateFramePlacement(sm.model, sm.data, f)
            velocity = pin.getFrameVelocity(sm.model, sm.data, f, ALIGNED)
            self.twist[body] = (np.array(velocity.linear), np.array(velocity.angular))

    def point(self, body: str, p) -> tuple[np.ndarray, np.ndarray]:
        """World position and velocity of a body point (body axes)."""
        p = np.asarray(p, dtype=float)
        if body == GROUND:
            return p, np.zeros(3)
        pose, (v, w) = self.pose[body], self.twist[body]
        arm = pose.rotation @ p
        return pose.translation + arm, v + np.cross(w, arm)

    def axis(self, body: str, h) -> np.ndarray:
        return np.asarray(h, float) if body == GROUND else self.pose[body].rotation @ np.asarray(h, float)

    def omega(self, body: str) -> np.ndarray:
        return np.zeros(3) if body == GROUND else self.twist[body][1]


def applied_wrenches(system: SpatialSystem, kin: Kinematics, t: float) -> dict[str, np.ndarray]:
    """Per body, [F; M about the world origin] (world axes) of every
    applied effect but gravity, as `mechval.reference.spatial.forces` has them."""
    out: dict[str, np.ndarray] = {}

    def add(body: str, force=np.zeros(3), at=np.zeros(3), couple=np.zeros(3)) -> None:
        if body != GROUND:
            w = out.setdefault(body, np.zeros(6))
            w[:3] += force
            w[3:] += np.cross(at, force) + couple

    for load in system.loads:
        add(load.body, np.asarray(load.force, float), kin.point(load.body, system.body(load.body).com)[0],
            np.asarray(load.torque, float))
    for torque in system.torques:           # T·zi on body_j, −T·zi on body_i
        j = system.joint(torque.joint)
        couple = float(torque.law.value(t)) * kin.axis(j.body_i, j.frame_i[:, 2])
        add(j.body_j, couple=couple)
        add(j.body_i, couple=-couple)
    for j in system.joints:
        if not j.damping:
            continue
        z = kin.axis(j.body_i, j.frame_i[:, 2])
        if j.kind == "revolute":            # −c·(ωj − ωi)·zi about zi on body_j
            couple = -j.damping * float((kin.omega(j.body_j) - kin.omega(j.body_i)) @ z) * z
            add(j.body_j, couple=couple)
            add(j.body_i, couple=-couple)
            continue
        (pi, vi), (pj, vj) = kin.point(j.body_i, j.point_i), kin.point(j.body_j, j.point_j)
        rate = float(np.cross(kin.omega(j.body_i), z) @ (pj - pi) + z @ (vj - vi))    # ṡ = żi·d + zi·ḋ
        add(j.body_j, -j.damping * rate * z, pj)
        add(j.body_i, j.damping * rate * z, pj)
    for s in system.springs:                # tension pulls the points together
        (pa, va), (pb, vb) = kin.point(s.body_a, s.point_a), kin.point(s.body_b, s.point_b)
        d = pb - pa
        length = float(np.linalg.norm(d))
        e = d / length
        tension = s.stiffness * (length - s.free_length) + s.damping * float((vb - va) @ e)
        add(s.body_a, tension * e, pa)
        add(s.body_b, -tension * e, pb)
    return out


@dataclass(frozen=True)
class Solution:
    """The dynamics at one state: accelerations, drive efforts on their
    coordinates, the applied wrenches and the constraints' λ."""

    a: np.ndarray
    efforts: np.ndarray
    wrenches: dict
    lam: np.ndarray


class SpatialDynamics:
    """v̇ = f(t, q, v) of one scene on its Pinocchio model."""

    def __init__(self, sm: SpatialModel, system: SpatialSystem, settings: Mapping[str, Any]):
        self.sm, self.system = sm, system
        steps = float(settings["baumgarte_steps"])
        if steps > 0:                   # critically damped, time constant `steps` RK4 steps
            rate = 1.0 / (steps * float(settings["timestep"]))
            for constraint in sm.constraints:
                constraint.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(rate**2, 2.0 * rate))
        self.prox = pin.ProximalSettings(float(settings["proximal_accuracy"]), float(settings["proximal_mu"]),
                                         int(settings["proximal_max_iterations"]))
        tree = [sm.tree_joint(d.joint) for d in system.drives]
        self.drive_coordinates = np.array([sm.model.joints[tj.index].idx_v for tj in tree], dtype=int)
        self.drive_signs = np.array([tj.sign for tj in tree])
        self.laws = [d.law for d in system.drives]
        self.has_wrenches = bool(system.loads or system.torques or system.springs
                                 or any(j.damping for j in system.joints))
        self.calls = 0
        self.iterations_max = 0

    def forward(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        sm = self.sm
        a = pin.constraintDynamics(sm.model, sm.data, q, v, tau, sm.constraints, sm.constraint_data, self.prox)
        self.calls += 1
        self.iterations_max = max(self.iterations_max, self.prox.iter)
        return np.array(a)

    def applied(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, dict]:
        """τ = Σ Jᵀ·w of the applied wrenches, and the wrenches."""
        tau = np.zeros(self.sm.model.nv)
        if not self.has_wrenches:
            return tau, {}
        sm = self.sm
        wrenches = applied_wrenches(self.system, Kinematics(sm, q, v), t)
        pin.computeJointJacobians(sm.model, sm.data, q)
        for body, w in wrenches.items():
            tau += frame_jacobian(sm.model, sm.data, sm.frame_of[body], WORLD).T @ w
        return tau, wrenches

    def solve(self, t: float, q: np.ndarray, v: np.ndarray, final: bool = False) -> Solution:
        """The dynamics at (t, q, v); `final` re-solves at the computed
        efforts so that λ and the accelerations belong to them exactly."""
        tau, wrenches = self.applied(q, v, t)
        a = self.forward(q, v, tau)
        drives = self.drive_coordinates
        if not len(drives):
            return Solution(a, np.zeros(0), wrenches, np.array(self.sm.data.lambda_c))
        wanted = self.drive_signs * np.array([float(law.acceleration(t)) for law in self.laws]) - a[drives]
        responses = np.empty((len(drives), len(a)))
        for k, coordinate in enumerate(drives):
            tau[coordinate] += 1.0
            responses[k] = self.forward(q, v, tau) - a
            tau[coordinate] -= 1.0
        efforts = np.linalg.solve(responses[:, drives].T, wanted)
        tau[drives] += efforts
        a = self.forward(q, v, tau) if final else a + efforts @ responses
        return Solution(a, efforts, wrenches, np.array(self.sm.data.lambda_c))


def rkmk4(dynamics: SpatialDynamics, t0: float, q: np.ndarray, v: np.ndarray, dt: float, steps: int
          ) -> tuple[np.ndarray, np.ndarray]:
    """`steps` RKMK4 steps of dt on (q, v) from t0 (see the module)."""
    model = dynamics.sm.model

    def tangent(xi: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """k with d/dt (q_n ⊕ ξ) = v: k = (∂(q ⊕ ξ)/∂ξ)⁻¹·v."""
        return np.linalg.solve(np.reshape(pin.dIntegrate(model, q, xi, pin.ArgumentPosition.ARG1),
                                          (model.nv, model.nv)), velocity)

    for n in range(steps):
        t = t0 + n * dt
        k1, a1 = v, dynamics.solve(t, q, v).a
        xi2 = 0.5 * dt * k1
        v2 = v + 0.5 * dt * a1
        k2, a2 = tangent(xi2, v2), dynamics.solve(t + 0.5 * dt, pin.integrate(model, q, xi2), v2).a
        xi3 = 0.5 * dt * k2
        v3 = v + 0.5 * dt * a2
        k3, a3 = tangent(xi3, v3), dynamics.solve(t + 0.5 * dt, pin.integrate(model, q, xi3), v3).a
        xi4 = dt * k3
        v4 = v + dt * a3
        k4, a4 = tangent(xi4, v4), dynamics.solve(t + dt, pin.integrate(model, q, xi4), v4).a
        q = pin.integrate(model, q, dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4))
        v = v + dt / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
    return q, v
