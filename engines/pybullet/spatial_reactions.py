"""The loads a spatial run applies each step (`Loads`) and the tree
joints' reactions derived from them (`tree_reactions`).

PyBullet has no spring element between bodies, no joint damping that is
exact (its `jointDamping` takes the mid-step rate, O(dt), docs/engines.md)
and keeps no external load beyond one step, so springs, joint dampers,
body loads and torque laws are external loads (`applyExternalForce`,
`applyExternalTorque`, world axes) set before every step; rates at t_n are
the mid-step readings extrapolated, 1.5·v_n − 0.5·v_n−1, as for planar
scenes. What each sampled step applied is kept for the balance.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from mechval.engines.pybullet.model import p
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.rotation import quaternion_to_matrix
from mechval.reference.spatial.system import SpatialSystem

AT_REST = (np.zeros(3), np.eye(3), np.zeros(3), np.zeros(3))


class Loads:
    """Springs, dampers, body loads and torque laws as external loads."""

    def __init__(self, system: SpatialSystem):
        self.system = system
        self.damped = [j for j in system.joints if j.damping and j.kind in ("revolute", "prismatic")]
        self.needs_every_step = bool(system.springs or self.damped or system.torques)
        self.history: dict[str, tuple[float, float | None]] = {}
        self.torque_values: dict[str, float] = {}

    def apply(self, model, state, t: float, dt: float) -> dict[str, np.ndarray]:
        """Apply this step's loads; returns per body (force, moment about
        the world origin), 6 numbers, world axes."""
        self.model, self.applied, self.state, self.dt = model, {}, state, dt
        for load in self.system.loads:
            G = self._point(load.body, self.system.body(load.body).com)
            self._push(load.body, np.asarray(load.force, float), G, np.asarray(load.torque, float))
        for law in self.system.torques:
            joint = self.system.joint(law.joint)
            value = float(law.law.value(t))
            self.torque_values[law.name] = value
            z = self._rot(joint.body_i) @ joint.frame_i[:, 2]
            self._push(joint.body_j, np.zeros(3), np.zeros(3), value * z)
            self._push(joint.body_i, np.zeros(3), np.zeros(3), -value * z)
        for joint in self.damped:
            self._damp(joint)
        for spring in self.system.springs:
            self._spring(spring)
        return self.applied

    def _rot(self, body: str) -> np.ndarray:
        return self.state.get(body, AT_REST)[1] if body != GROUND else np.eye(3)

    def _point(self, body: str, point) -> np.ndarray:
        s = self.state.get(body, AT_REST)
        return s[0] + s[1] @ np.asarray(point, float)

    def _point_velocity(self, body: str, point) -> np.ndarray:
        s = self.state.get(body, AT_REST)
        return s[2] + np.cross(s[3], s[1] @ np.asarray(point, float))

    def _extrapolated(self, key: str, mid: float) -> float:
        """1.5·mid_n − 0.5·mid_n−1: the rate at t_n from mid-step ones."""
        last = self.history.get(key, (None, mid))[1]
        return 1.5 * mid - 0.5 * (mid if last is None else last)

    def _damp(self, joint) -> None:
        zi = self._rot(joint.body_i) @ joint.frame_i[:, 2]
        if joint.kind == "revolute":
            mid = float(zi @ (self.state.get(joint.body_j, AT_REST)[3] - self.state.get(joint.body_i, AT_REST)[3]))
            load = -joint.damping * self._extrapolated(joint.name, mid)
            self.history[joint.name] = (0.0, mid)
            self._push(joint.body_j, np.zeros(3), np.zeros(3), load * zi)
            self._push(joint.body_i, np.zeros(3), np.zeros(3), -load * zi)
            return
        Pj = self._point(joint.body_j, joint.point_j)
        # The slide rate of point_j relative to the body_i point under it.
        vi = self.state.get(joint.body_i, AT_REST)
        rel = self._point_velocity(joint.body_j, joint.point_j) - (vi[2] + np.cross(vi[3], Pj - vi[0]))
        mid = float(zi @ rel)
        load = -joint.damping * self._extrapolated(joint.name, mid)
        self.history[joint.name] = (0.0, mid)
        self._push(joint.body_j, load * zi, Pj, np.zeros(3))
        self._push(joint.body_i, -load * zi, Pj, np.zeros(3))

    def _spring(self, spring) -> None:
        pa, pb = self._point(spring.body_a, spring.point_a), self._point(spring.body_b, spring.point_b)
        d = pb - pa
        length = float(np.linalg.norm(d))
        e = d / length
        last = self.history.get(spring.name)
        if last is None:
            mid = float(e @ (self._point_velocity(spring.body_b, spring.point_b)
                             - self._point_velocity(spring.body_a, spring.point_a)))
        else:
            mid = (length - last[0]) / self.dt
        rate = self._extrapolated(spring.name, mid)
        self.history[spring.name] = (length, mid)
        tension = spring.stiffness * (length - spring.free_length) + spring.damping * rate
        self._push(spring.body_a, tension * e, pa, np.zeros(3))
        self._push(spring.body_b, -tension * e, pb, np.zeros(3))

    def _push(self, body: str, force: np.ndarray, at: np.ndarray, torque: np.ndarray) -> None:
        if body == GROUND:
            return
        uid, link = self.model.handles[body]
        c = self.model.client
        if force.any():
            p.applyExternalForce(uid, link, tuple(force), tuple(at), p.WORLD_FRAME, physicsClientId=c)
        if torque.any():
            p.applyExternalTorque(uid, link, tuple(torque), p.WORLD_FRAME, physicsClientId=c)
        total = self.applied.setdefault(body, np.zeros(6))
        total[:3] += force
        total[3:] += np.cross(at, force) + torque


def _take(frame: pd.DataFrame, body: str, names: str) -> np.ndarray:
    return frame[[f"{body}.{n}" for n in names.split()]].to_numpy(dtype=float)


def tree_reactions(system: SpatialSystem, model, frame: pd.DataFrame, applied: list) -> dict[str, np.ndarray]:
    """Each tree joint's Fij and Mij (about Pj) from the balance of the
    bodies below it: Σ (m·a_G, G×m·a_G + J·α + ω×J·ω) less their loads
    (gravity, the applied ones, the loop joints' reactions), about Pj; a
    drive's effort (read) taken out."""
    n = len(frame)
    g = np.asarray(system.gravity, dtype=float)
    inertial, state = {}, {}
    for b in system.bodies:
        R = quaternion_to_matrix(_take(frame, b.name, "qw qx qy qz"))
        r = R @ np.asarray(b.com, float)
        w, al = _take(frame, b.name, "wx wy wz"), _take(frame, b.name, "alphax alphay alphaz")
        G = _take(frame, b.name, "x y z") + r
        aG = _take(frame, b.name, "ax ay az") + np.cross(al, r) + np.cross(w, np.cross(w, r))
        J = R @ b.inertia @ np.swapaxes(R, -1, -2)
        Jw = np.einsum("nij,nj->ni", J, w)
        force = b.mass * (aG - g)
        moment = np.cross(G, force) + np.einsum("nij,nj->ni", J, al) + np.cross(w, Jw)
        loads = np.array([step.get(b.name, np.zeros(6)) for step in applied])
        inertial[b.name] = np.concatenate([force, moment], axis=1) - loads
        state[b.name] = (_take(frame, b.name, "x y z"), R)
    for name, loop in model.loops.items():
        j = loop.joint
        F, M = _take(frame, name, "Fx Fy Fz"), _take(frame, name, "Mx My Mz")
        Pj = _world_point(state, j.body_j, j.point_j, n)
        about_origin = np.concatenate([F, M + np.cross(Pj, F)], axis=1)
        for body, sign in ((j.body_j, 1.0), (j.body_i, -1.0)):
            if body != GROUND:
                inertial[body] = inertial[body] - sign * about_origin
    below = _subtrees(model)
    out = {}
    for name, tj in model.tree.items():
        j = tj.joint
        total = sum(inertial[b] for b in below[tj.child])
        Pj = _world_point(state, j.body_j, j.point_j, n)
        F, M = total[:, :3], total[:, 3:] - np.cross(Pj, total[:, :3])
        if tj.child != j.body_j:
            F, M = -F, -M
        zi = _world_rot(state, j.body_i, n) @ j.frame_i[:, 2]
        for d in system.drives:
            if d.joint == name:
                if j.kind == "revolute":
                    M = M - frame[f"{d.name}.T"].to_numpy()[:, None] * zi
                else:
                    F = F - frame[f"{d.name}.F"].to_numpy()[:, None] * zi
        for k, axis in enumerate("xyz"):
            out[f"{name}.F{axis}"], out[f"{name}.M{axis}"] = F[:, k], M[:, k]
    return out


def _world_rot(state, body: str, n: int) -> np.ndarray:
    return np.broadcast_to(np.eye(3), (n, 3, 3)) if body == GROUND else state[body][1]


def _world_point(state, body: str, point, n: int) -> np.ndarray:
    if body == GROUND:
        return np.broadcast_to(np.asarray(point, float), (n, 3))
    x, R = state[body]
    return x + R @ np.asarray(point, float)


def _subtrees(model) -> dict[str, list[str]]:
    """Per body, itself and every body hung below it in its multibody."""
    children: dict[str, list[str]] = {}
    for tj in model.tree.values():
        children.setdefault(tj.parent, []).append(tj.child)
    out = {}

    def collect(body: str) -> list[str]:
        if body not in out:
            out[body] = [body] + [b for c in children.get(body, []) for b in collect(c)]
        return out[body]
    for body in model.parent_joint:
        collect(body)
    return out
