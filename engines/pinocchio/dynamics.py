"""Pinocchio's constraint dynamics of the planar model with its drives, and
the fixed-step RK4 that integrates it (Pinocchio computes dynamics; it has
no time integrator of its own).

A drive prescribes its tree coordinate's acceleration (±φ''(t)); its
effort is the computed torque that gives it. `constraintDynamics` (the
KKT system of the tree's mass matrix and the loops' point constraints,
solved by Pinocchio's proximal method, which copes with the redundant z
row of a point constraint in the plane) is affine in τ at a given state,
so one call at the applied forces and one per drive with a unit effort on
its coordinate give the efforts that meet every drive's acceleration (a
k × k solve); a last call at those efforts gives the accelerations and the
loops' forces λ (`Solution`). Pinocchio 4.1 marks `constraintDynamics`'s
API as "will change": tests/test_pinocchio.py pins its signature.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import pinocchio as pin

from mechval.model.mechanism import Mechanism

from mechval.engines.pinocchio.forces import Effects, effects, generalised
from mechval.engines.pinocchio.model import PinocchioModel


@dataclass(frozen=True)
class Solution:
    """The dynamics at one state: accelerations, the generalised forces
    along the tree's coordinates (drive efforts, torque laws and dampers
    there: what `rnea` must give back), the drive efforts on their own
    coordinates, the body wrenches of the other applied effects and the
    loops' forces (3 per loop, Pinocchio's `lambda_c`)."""

    a: np.ndarray
    tau_joints: np.ndarray
    efforts: np.ndarray
    wrenches: dict
    lam: np.ndarray


class Dynamics:
    """ẍ = f(t, q, v) of one mechanism on its Pinocchio model."""

    def __init__(self, pm: PinocchioModel, mech: Mechanism, settings: Mapping[str, Any]):
        self.pm, self.mech = pm, mech
        self.fx: Effects = effects(pm, mech)
        steps = float(settings["baumgarte_steps"])
        if steps > 0:                   # critically damped, time constant `steps` RK4 steps
            rate = 1.0 / (steps * float(settings["timestep"]))
            for constraint in pm.constraints:
                constraint.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(rate**2, 2.0 * rate))
        self.prox = pin.ProximalSettings(float(settings["proximal_accuracy"]), float(settings["proximal_mu"]),
                                         int(settings["proximal_max_iterations"]))
        tree = [pm.tree_joint(d.joint) for d in mech.drives]
        self.drive_coordinates = np.array([tj.coordinate for tj in tree], dtype=int)
        self.drive_signs = np.array([tj.sign for tj in tree])
        self.laws = [d.law for d in mech.drives]
        self.alphas = np.array([float(law.alpha) for law in self.laws])
        self.calls = 0
        self.iterations_max = 0

    def forward(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        pm = self.pm
        a = pin.constraintDynamics(pm.model, pm.data, q, v, tau, pm.constraints, pm.constraint_data, self.prox)
        self.calls += 1
        self.iterations_max = max(self.iterations_max, self.prox.iter)
        return np.array(a)

    def solve(self, t: float, q: np.ndarray, v: np.ndarray, final: bool = False) -> Solution:
        """The dynamics at (t, q, v); `final` re-solves at the computed
        efforts so that λ and the accelerations belong to them exactly."""
        tau_joints, on_bodies, wrenches = generalised(self.pm, self.fx, q, v, t)
        tau = tau_joints + on_bodies
        a = self.forward(q, v, tau)
        drives = self.drive_coordinates
        if not len(drives):
            return Solution(a, tau_joints, np.zeros(0), wrenches, np.array(self.pm.data.lambda_c))
        # φ'' of each law (the quadratic DriveLaw's is its constant alpha).
        wanted = self.drive_signs * self.alphas - a[drives]
        responses = np.empty((len(drives), len(a)))
        for k, coordinate in enumerate(drives):
            tau[coordinate] += 1.0
            responses[k] = self.forward(q, v, tau) - a
            tau[coordinate] -= 1.0
        if len(drives) == 1:
            efforts = wanted / responses[0, drives]
        else:
            efforts = np.linalg.solve(responses[:, drives].T, wanted)
        tau[drives] += efforts
        tau_joints = tau_joints.copy()
        tau_joints[drives] += efforts
        a = self.forward(q, v, tau) if final else a + efforts @ responses
        return Solution(a, tau_joints, efforts, wrenches, np.array(self.pm.data.lambda_c))


def rk4(dynamics: Dynamics, t0: float, q: np.ndarray, v: np.ndarray, dt: float, steps: int
        ) -> tuple[np.ndarray, np.ndarray]:
    """`steps` classical Runge–Kutta steps of dt on (q, v) from t0 (the
    coordinates are plain angles and slides: q̇ = v)."""
    for n in range(steps):
        t = t0 + n * dt
        a1 = dynamics.solve(t, q, v).a
        q2, v2 = q + 0.5 * dt * v, v + 0.5 * dt * a1
        a2 = dynamics.solve(t + 0.5 * dt, q2, v2).a
        q3, v3 = q + 0.5 * dt * v2, v + 0.5 * dt * a2
        a3 = dynamics.solve(t + 0.5 * dt, q3, v3).a
        q4, v4 = q + dt * v3, v + dt * a3
        a4 = dynamics.solve(t + dt, q4, v4).a
        q = q + dt / 6.0 * (v + 2 * v2 + 2 * v3 + v4)
        v = v + dt / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
    return q, v
