"""Joint reactions of a spatial Drake run in mechval's convention: the
load BY body_i ON body_j, force F and its moment M about Pj, world axes.

- Tree joint: Drake's reaction port gives the spatial force on the child
  body at the child joint frame's origin (`spatial.read` turns it to world
  axes). A child body_j gives (F, M) as is; a child body_i gives the
  opposite, −F, and −M moved from Pi to Pj: −M + (Pi − Pj) × F.
- Cut joint (Drake 1.51 reports no constraint force): from the bodies'
  Newton–Euler balance with Drake's own motion (pose, ω of the state,
  the step's accelerations), tree reactions, springs, gravity and scene
  loads, solved for the cut loads by least squares per sample.
- Both then keep only what the joint's constraint rows can carry
  (`constrained`): the part along a joint's free motion is its damper,
  drive or torque law, which the reference reports apart or not at all.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from mechval.model.mechanism import GROUND
from mechval.reference.spatial.rotation import cross, skew
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.drake.spatial_model import scene_loads
from mechval.engines.drake.spatial_tree import SpatialTopology


@dataclass
class Sample:
    """Drake's values at one sample, world axes: per body (origin, rotation)
    and (ω, v of the origin) of the state, (α, a) of the step; per tree
    joint (child frame origin, moment, force) on the tree child; the net
    actuation per actuator."""

    poses: Mapping[str, tuple]
    velocities: Mapping[str, tuple]
    accelerations: Mapping[str, tuple]
    joints: Mapping[str, tuple]
    actuation: np.ndarray


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def constrained(kind: str, F: np.ndarray, M: np.ndarray, zi: np.ndarray, zj: np.ndarray) -> tuple:
    """(F, M) without their parts along the joint's free motion (rows of
    `mechval.reference.spatial.joints`: a revolute carries no moment about
    zi, a slide no force along it, a planar joint only the normal force, a
    universal joint's moment lies along zi × zj, a spherical one has none)."""
    along = lambda x, u: np.einsum("ni,ni->n", x, u)[:, None] * u
    if kind in ("revolute", "cylindrical", "planar"):
        M = M - along(M, zi)
    if kind in ("prismatic", "cylindrical"):
        F = F - along(F, zi)
    if kind == "planar":
        F = along(F, zi)
    if kind == "universal":
        M = along(M, _unit(cross(zi, zj)))
    if kind == "spherical":
        M = np.zeros_like(M)
    return F, M


class Motion:
    """Per body arrays over the samples (N, 3) / (N, 3, 3) and helpers."""

    def __init__(self, system: SpatialSystem, rows: list[Sample]):
        self.system = system
        take = lambda field, name, k: np.array([getattr(r, field)[name][k] for r in rows])
        self.o = {b.name: take("poses", b.name, 0) for b in system.bodies}
        self.R = {b.name: take("poses", b.name, 1) for b in system.bodies}
        self.w = {b.name: take("velocities", b.name, 0) for b in system.bodies}
        self.v = {b.name: take("velocities", b.name, 1) for b in system.bodies}
        self.alpha = {b.name: take("accelerations", b.name, 0) for b in system.bodies}
        self.a = {b.name: take("accelerations", b.name, 1) for b in system.bodies}
        self.n = len(rows)

    def point(self, body: str, p) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        if body == GROUND:
            return np.broadcast_to(p, (self.n, 3))
        return self.o[body] + self.R[body] @ p

    def point_velocity(self, body: str, p) -> np.ndarray:
        if body == GROUND:
            return np.zeros((self.n, 3))
        return self.v[body] + cross(self.w[body], self.R[body] @ np.asarray(p, dtype=float))

    def axis(self, body: str, frame, column: int = 2) -> np.ndarray:
        h = np.asarray(frame, dtype=float)[:, column]
        return np.broadcast_to(h, (self.n, 3)) if body == GROUND else self.R[body] @ h


def reaction_columns(system: SpatialSystem, topo: SpatialTopology, rows: list[Sample],
                     times: np.ndarray) -> dict[str, np.ndarray]:
    """J.Fx … J.Mz of every joint (module docstring)."""
    motion = Motion(system, rows)
    loads = {j.name: tuple(np.array([r.joints[j.name][k] for r in rows]) for k in range(3))
             for j in (tj.joint for tj in topo.tree)}
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for tj in topo.tree:
        j = tj.joint
        at, moment, force = loads[j.name]
        if tj.sign > 0:
            F, M = force, moment
        else:
            F = -force
            M = -moment + cross(at - motion.point(j.body_j, j.point_j), F)
        out[j.name] = (F, M)
    if topo.cuts:
        out.update(cut_loads(system, topo, motion, loads, times))
    cols = {}
    for j in system.joints:
        F, M = constrained(j.kind, *out[j.name], motion.axis(j.body_i, j.frame_i), motion.axis(j.body_j, j.frame_j))
        for k, c in enumerate("xyz"):
            cols[f"{j.name}.F{c}"], cols[f"{j.name}.M{c}"] = F[:, k], M[:, k]
    return cols


def cut_loads(system: SpatialSystem, topo: SpatialTopology, motion: Motion,
              tree_loads: Mapping[str, tuple], times: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(F, M about Pj) of every cut joint from the moving bodies' balance:
    m·(G̈ − g) and J·α + ω × J·ω about G equal the loads on the body."""
    n, names = motion.n, [b.name for b in system.bodies]
    index = {name: k for k, name in enumerate(names)}
    G = {b.name: motion.point(b.name, b.com) for b in system.bodies}
    rhs = np.zeros((n, 6 * len(names)))

    def add(body: str, force: np.ndarray, at: np.ndarray, moment: np.ndarray | None = None) -> None:
        """A known load on `body` moves to the other side of its balance."""
        if body == GROUND:
            return
        k = 6 * index[body]
        rhs[:, k:k + 3] -= force
        rhs[:, k + 3:k + 6] -= cross(at - G[body], force) + (0.0 if moment is None else moment)

    g = np.asarray(system.gravity, dtype=float)
    for b in system.bodies:
        k, arm = 6 * index[b.name], G[b.name] - motion.o[b.name]
        w, al = motion.w[b.name], motion.alpha[b.name]
        acc = motion.a[b.name] + cross(al, arm) + cross(w, cross(w, arm))
        J = motion.R[b.name] @ np.asarray(b.inertia, float) @ np.swapaxes(motion.R[b.name], 1, 2)
        Jw = np.einsum("nij,nj->ni", J, w)
        rhs[:, k:k + 3] += b.mass * (acc - g)
        rhs[:, k + 3:k + 6] += np.einsum("nij,nj->ni", J, al) + cross(w, Jw)
    for tj in topo.tree:
        at, moment, force = tree_loads[tj.joint.name]
        add(tj.child, force, at, moment)
        add(tj.parent, -force, at, -moment)
    for s in system.springs:
        pa, pb = motion.point(s.body_a, s.point_a), motion.point(s.body_b, s.point_b)
        length = np.linalg.norm(pb - pa, axis=1)
        u = (pb - pa) / length[:, None]
        rate = np.einsum("ni,ni->n", motion.point_velocity(s.body_b, s.point_b)
                         - motion.point_velocity(s.body_a, s.point_a), u)
        tension = (s.stiffness * (length - s.free_length) + s.damping * rate)[:, None]
        add(s.body_a, tension * u, pa)
        add(s.body_b, -tension * u, pb)
    applied = [scene_loads(system, t, lambda body, k=k: np.eye(3) if body == GROUND else motion.R[body][k])
               for k, t in enumerate(times)] if (system.loads or system.torques) else None
    if applied is not None:
        for b in system.bodies:
            force = np.array([a[b.name][0] for a in applied])
            torque = np.array([a[b.name][1] for a in applied])
            add(b.name, force, G[b.name], torque)
    coef = np.zeros((n, 6 * len(names), 6 * len(topo.cuts)))
    eye = np.broadcast_to(np.eye(3), (n, 3, 3))
    for c, cut in enumerate(topo.cuts):
        Pj = motion.point(cut.body_j, cut.point_j)
        for body, sign in ((cut.body_j, 1.0), (cut.body_i, -1.0)):
            if body == GROUND:
                continue
            k = 6 * index[body]
            coef[:, k:k + 3, 6 * c:6 * c + 3] = sign * eye
            coef[:, k + 3:k + 6, 6 * c:6 * c + 3] = sign * skew(Pj - G[body])
            coef[:, k + 3:k + 6, 6 * c + 3:6 * c + 6] = sign * eye
    x = np.full((n, 6 * len(topo.cuts)), np.nan)
    finite = np.isfinite(coef).all(axis=(1, 2)) & np.isfinite(rhs).all(axis=1)      # a blown-up run is NaN
    for i in np.flatnonzero(finite):
        x[i] = np.linalg.lstsq(coef[i], rhs[i], rcond=None)[0]
    return {cut.name: (x[:, 6 * c:6 * c + 3], x[:, 6 * c + 3:6 * c + 6]) for c, cut in enumerate(topo.cuts)}

