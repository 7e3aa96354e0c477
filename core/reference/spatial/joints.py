"""Constraint rows of a spatial system: Φ(q, t), its Jacobian, −Φt and γ.

Coordinates (Nikravesh 1988, ch. 11; Haug 1989, ch. 9, "basic
constraints"): per moving body its centre of mass G (world) and rotation
matrix A; velocities per body (Ġ, ω), ω in world axes; a variation
(δG, δπ) moves G to G + δG and A to exp(δπ̃)·A (`rotation`). The Jacobian
Φq is with respect to those six per body, so Φq·(Ġ, ω) = Φ̇ − Φt.

Every row is built from two kinds of world vectors carried by the bodies:
a body axis h = A·h' (δh = δπ × h, ḣ = ω × h) and a body point
P = G + A·s (δP = δG + δπ × a, a = A·s), and their differences. A row is
such a vector (its three components) or a dot product x·y of two; for the
latter, differentiating twice (Nikravesh 1988, §11.4),
ẍ·y + 2·ẋ·ẏ + x·ÿ = Φq·q̈ − γ, so γ = −(x̄·y + 2·ẋ·ẏ + x·ȳ) where x̄ is
ẍ without its q̈ part: ω × (ω × h) for an axis, ω × (ω × a) for a point.

Rows per kind (`system` names the frames; d = Pj − Pi):
spherical d (3); revolute d, xi·zj, yi·zj (5); universal d, zi·zj (4);
cylindrical xi·zj, yi·zj, xi·d, yi·d (4); prismatic those and xi·yj (5);
planar xi·zj, yi·zj, zi·d (3); fixed d, xi·zj, yi·zj, xi·yj (6).
Drives: revolute sin(θ − φ) written cos φ·(yi·xj) − sin φ·(xi·xj), θ the
angle from xi to xj about zi (its derivative in θ is 1 at the solution);
prismatic zi·d − φ. An effort is then −λ, as in the planar reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mechval.model.mechanism import GROUND
from mechval.reference.spatial import assembly
from mechval.reference.spatial.rotation import cross
from mechval.reference.spatial.system import SpatialSystem

ROW_NAMES = {
    "spherical": ("dx", "dy", "dz"),
    "revolute": ("dx", "dy", "dz", "xi.zj", "yi.zj"),
    "universal": ("dx", "dy", "dz", "zi.zj"),
    "cylindrical": ("xi.zj", "yi.zj", "xi.d", "yi.d"),
    "prismatic": ("xi.zj", "yi.zj", "xi.d", "yi.d", "xi.yj"),
    "planar": ("xi.zj", "yi.zj", "zi.d"),
    "fixed": ("dx", "dy", "dz", "xi.zj", "yi.zj", "xi.yj"),
}


@dataclass(frozen=True)
class Row:
    kind: str       # an entry of ROW_NAMES, or "drive"
    joint: str
    drive: str = ""


@dataclass
class Pose:
    """Positions of the moving bodies at N instants: G (N, nb, 3), A (N, nb, 3, 3)."""

    G: np.ndarray
    A: np.ndarray

    def __len__(self) -> int:
        return len(self.G)


class Vec:
    """A world vector carried by a body, over N instants: value, and with
    velocities its rate and bias (see the module)."""

    def __init__(self, value, rate=None, bias=None):
        self.value, self.rate, self.bias = value, rate, bias


def _dot(x, y):
    return np.einsum("ni,ni->n", x, y)


def encode(name: str) -> tuple[int, int, int]:
    """A row name of ROW_NAMES as (shape, first, second) for `assembly`:
    "dx" the component 0 of d, "xi.zj" the dot product of slots xi and zj."""
    if "." in name:
        x, y = name.split(".")
        return assembly.DOT, assembly.SLOTS.index(x), assembly.SLOTS.index(y)
    return assembly.COMPONENT, "xyz".index(name[1]), 0


class Constraints:
    """Φ, Φq, −Φt and γ of a spatial system, vectorised over instants."""

    def __init__(self, system: SpatialSystem):
        self.system = system
        self.bodies = tuple(b.name for b in system.bodies)
        self.index = {name: k for k, name in enumerate(self.bodies)}
        self.n = 6 * len(self.bodies)
        com = {b.name: np.asarray(b.com, dtype=float) for b in system.bodies}
        rows: list[Row] = []
        self.joint_rows: dict[str, slice] = {}
        self.ends = {}
        for j in system.joints:
            start = len(rows)
            rows += [Row(kind, j.name) for kind in ROW_NAMES[j.kind]]
            self.joint_rows[j.name] = slice(start, len(rows))
            arm = lambda body, p: np.asarray(p, dtype=float) - (com[body] if body != GROUND else 0.0)   # noqa: E731
            self.ends[j.name] = (self.index.get(j.body_i, -1), arm(j.body_i, j.point_i),
                                 self.index.get(j.body_j, -1), arm(j.body_j, j.point_j))
        self.drive_rows: dict[str, int] = {}
        for d in system.drives:
            self.drive_rows[d.name] = len(rows)
            rows.append(Row("drive", d.joint, d.name))
        self.rows = tuple(rows)
        self.m = len(rows)
        # the table `assembly` evaluates: per joint its ends, per row its shape
        joint_number = {j.name: k for k, j in enumerate(system.joints)}
        self.table_joints = (
            np.array([[self.ends[j.name][0], self.ends[j.name][2]] for j in system.joints], dtype=np.int64).reshape(-1, 2),
            np.array([[self.ends[j.name][1], self.ends[j.name][3]] for j in system.joints], dtype=float).reshape(-1, 2, 3),
            np.array([[j.frame_i, j.frame_j] for j in system.joints], dtype=float).reshape(-1, 2, 3, 3))
        drive_number = {d.name: k for k, d in enumerate(system.drives)}
        encoded = [encode(r.kind) if r.kind != "drive" else
                   (assembly.PRISMATIC_DRIVE if system.joint(r.joint).kind == "prismatic" else assembly.REVOLUTE_DRIVE,
                    drive_number[r.drive], 0) for r in rows]
        self.table_rows = (np.array([joint_number[r.joint] for r in rows], dtype=np.int64),
                           *(np.array([e[k] for e in encoded], dtype=np.int64) for k in range(3)))

    # -- body vectors ---------------------------------------------------------------------------

    def axis(self, pose: Pose, w: np.ndarray | None, body: int, h_body: np.ndarray) -> Vec:
        """The world axis A·h' of a body (the ground: h' itself)."""
        N = len(pose)
        if body < 0:
            zero = None if w is None else np.zeros((N, 3))
            return Vec(np.broadcast_to(h_body, (N, 3)), zero, zero)
        h = pose.A[:, body] @ h_body
        if w is None:
            return Vec(h)
        om = w[:, body, 3:]
        rate = cross(om, h)
        return Vec(h, rate, cross(om, rate))

    def point(self, pose: Pose, w: np.ndarray | None, body: int, s: np.ndarray) -> Vec:
        """The world point G + A·s of a body (the ground: s itself)."""
        N = len(pose)
        if body < 0:
            zero = None if w is None else np.zeros((N, 3))
            return Vec(np.broadcast_to(s, (N, 3)), zero, zero)
        a = pose.A[:, body] @ s
        if w is None:
            return Vec(pose.G[:, body] + a)
        om = w[:, body, 3:]
        turn = cross(om, a)
        return Vec(pose.G[:, body] + a, w[:, body, :3] + turn, cross(om, turn))

    # -- rows -----------------------------------------------------------------------------------

    def laws(self, t: np.ndarray) -> np.ndarray:
        """Each drive's φ, φ̇, φ̈ at instants t, (N, drives, 3)."""
        law = np.empty((len(t), len(self.system.drives), 3))
        for k, d in enumerate(self.system.drives):
            law[:, k] = np.stack([d.law.angle(t) + 0 * t, d.law.rate(t) + 0 * t, d.law.acceleration(t) + 0 * t], -1)
        return law

    def evaluate(self, pose: Pose, t: np.ndarray, w: np.ndarray | None = None,
                 jacobian: bool = True) -> dict[str, np.ndarray]:
        """Φ (N, m) and Φq (N, m, n) (unless not `jacobian`); with
        velocities w (N, nb, 6) also −Φt and γ (N, m)."""
        N = len(pose)
        law = self.laws(t)
        velocities = np.zeros((N, len(self.bodies), 6)) if w is None else w
        joint, shape, first, second = self.table_rows
        phi, jac, rhs, gamma = assembly.assemble(
            *(np.ascontiguousarray(x, dtype=float) for x in (pose.G, pose.A, velocities)), law,
            *self.table_joints, shape, joint, first, second, jacobian, w is not None and bool(np.any(w)), self.n)
        out = dict(phi=phi)
        if jacobian:
            out["jac"] = jac
        if w is not None:
            out.update(rhs=rhs, gamma=gamma)
        return out

    def drive_angles(self, pose: Pose) -> dict[str, np.ndarray]:
        """θ of every revolute drive's joint (angle from xi to xj about zi)."""
        angles = {}
        for drive in self.system.drives:
            j = self.system.joint(drive.joint)
            if j.kind != "revolute":
                continue
            bi, _, bj, _ = self.ends[j.name]
            xi, yi = (self.axis(pose, None, bi, j.frame_i[:, k]).value for k in (0, 1))
            xj = self.axis(pose, None, bj, j.frame_j[:, 0]).value
            angles[drive.name] = np.arctan2(_dot(yi, xj), _dot(xi, xj))
        return angles
