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
from mechval.reference.spatial.rotation import cross, skew
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
    """A world vector carried by bodies, over N instants: value, its
    variation per body (N, 3, 6) blocks, rate and bias (see the module)."""

    def __init__(self, value, parts, rate=None, bias=None):
        self.value, self.parts, self.rate, self.bias = value, parts, rate, bias

    def __sub__(self, other: "Vec") -> "Vec":
        parts = dict(self.parts)
        for b, block in other.parts.items():
            parts[b] = parts[b] - block if b in parts else -block
        rate = None if self.rate is None or other.rate is None else self.rate - other.rate
        bias = None if self.bias is None or other.bias is None else self.bias - other.bias
        return Vec(self.value - other.value, parts, rate, bias)


class Axes:
    """The three axes of a joint frame on one body, each computed on first use."""

    def __init__(self, c: "Constraints", pose, w, body: int, frame: np.ndarray, blocks: bool = True):
        self.args, self.frame, self.cache, self.blocks = (pose, w, body), frame, {}, blocks
        self.c = c

    def __getitem__(self, k: int) -> Vec:
        if k not in self.cache:
            pose, w, body = self.args
            self.cache[k] = self.c.axis(pose, w, body, self.frame[:, k], self.blocks)
        return self.cache[k]

    def lazy(self, k: int) -> "Lazy":
        return Lazy(self, k)


class Lazy:
    def __init__(self, axes: Axes, k: int):
        self.axes, self.k = axes, k

    def get(self) -> Vec:
        return self.axes[self.k]


def _dot(x, y):
    return np.einsum("ni,ni->n", x, y)


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

    # -- body vectors ---------------------------------------------------------------------------

    def axis(self, pose: Pose, w: np.ndarray | None, body: int, h_body: np.ndarray, blocks: bool = True) -> Vec:
        N = len(pose)
        if body < 0:
            zero = None if w is None else np.zeros((N, 3))
            return Vec(np.broadcast_to(h_body, (N, 3)), {}, zero, zero)
        h = pose.A[:, body] @ h_body
        if blocks:
            block = np.zeros((N, 3, 6))
            block[:, :, 3:] = -skew(h)
        parts = {body: block} if blocks else {}
        if w is None:
            return Vec(h, parts)
        om = w[:, body, 3:]
        rate = cross(om, h)
        return Vec(h, parts, rate, cross(om, rate))

    def point(self, pose: Pose, w: np.ndarray | None, body: int, s: np.ndarray, blocks: bool = True) -> Vec:
        N = len(pose)
        if body < 0:
            zero = None if w is None else np.zeros((N, 3))
            return Vec(np.broadcast_to(s, (N, 3)), {}, zero, zero)
        a = pose.A[:, body] @ s
        parts = {}
        if blocks:
            block = np.zeros((N, 3, 6))
            block[:, :, :3] = np.eye(3)
            block[:, :, 3:] = -skew(a)
            parts = {body: block}
        if w is None:
            return Vec(pose.G[:, body] + a, parts)
        om = w[:, body, 3:]
        turn = cross(om, a)
        return Vec(pose.G[:, body] + a, parts, w[:, body, :3] + turn, cross(om, turn))

    # -- rows -----------------------------------------------------------------------------------

    def evaluate(self, pose: Pose, t: np.ndarray, w: np.ndarray | None = None,
                 jacobian: bool = True) -> dict[str, np.ndarray]:
        """Φ (N, m) and Φq (N, m, n) (unless not `jacobian`); with
        velocities w (N, nb, 6) also −Φt and γ (N, m)."""
        N, m = len(pose), self.m
        out = dict(phi=np.zeros((N, m)))
        if jacobian:
            out["jac"] = np.zeros((N, m, self.n))
        if w is not None:
            out.update(rhs=np.zeros((N, m)), gamma=np.zeros((N, m)))
        rows = iter(range(m))

        def put(row: int, value, parts, gamma=None):
            out["phi"][:, row] = value
            for b, block in parts.items() if jacobian else ():
                out["jac"][:, row, 6 * b:6 * b + 6] += block
            if w is not None:
                out["gamma"][:, row] = gamma

        def vector(v: Vec):
            for c in range(3):
                put(next(rows), v.value[:, c], {b: blk[:, c] for b, blk in v.parts.items()},
                    None if w is None else -v.bias[:, c])

        def dot(x: Vec, y: Vec, coefficient: float | np.ndarray = 1.0, row: int | None = None):
            value = _dot(x.value, y.value)
            parts: dict[int, np.ndarray] = {}
            for first, second in ((x, y), (y, x)):
                for b, blk in first.parts.items():
                    term = np.einsum("ni,nij->nj", second.value, blk)
                    parts[b] = parts[b] + term if b in parts else term
            gamma = None
            if w is not None:
                gamma = -(_dot(x.bias, y.value) + 2 * _dot(x.rate, y.rate) + _dot(x.value, y.bias))
            return value, parts, gamma

        def scalar(x: Lazy | Vec, y: Lazy | Vec):
            put(next(rows), *dot(*(v.get() if isinstance(v, Lazy) else v for v in (x, y))))

        frames = {}
        for j in self.system.joints:
            bi, si, bj, sj = self.ends[j.name]
            ax_i, ax_j = Axes(self, pose, w, bi, j.frame_i, jacobian), Axes(self, pose, w, bj, j.frame_j, jacobian)
            d = self.point(pose, w, bj, sj, jacobian) - self.point(pose, w, bi, si, jacobian)
            frames[j.name] = (ax_i, ax_j, d)
            xi, yi, zi = (ax_i.lazy(k) for k in range(3))
            xj, yj, zj = (ax_j.lazy(k) for k in range(3))
            if j.kind in ("spherical", "revolute", "universal", "fixed"):
                vector(d)
            if j.kind == "universal":
                scalar(zi, zj)
            if j.kind in ("revolute", "cylindrical", "prismatic", "planar", "fixed"):
                scalar(xi, zj), scalar(yi, zj)
            if j.kind in ("cylindrical", "prismatic"):
                scalar(xi, d), scalar(yi, d)
            if j.kind == "planar":
                scalar(zi, d)
            if j.kind in ("prismatic", "fixed"):
                scalar(xi, yj)
        for drive in self.system.drives:
            row = next(rows)
            ax_i, ax_j, d = frames[drive.joint]
            law = drive.law
            phi, rate, acc = law.angle(t) + 0 * t, law.rate(t) + 0 * t, law.acceleration(t) + 0 * t
            if self.system.joint(drive.joint).kind == "prismatic":
                value, parts, gamma = dot(ax_i[2], d)
                put(row, value - phi, parts, None if w is None else gamma + acc)
                if w is not None:
                    out["rhs"][:, row] = rate
                continue
            # f = c·S − s·C with S = yi·xj = sin θ, C = xi·xj = cos θ, c, s = cos φ, sin φ
            S, S_parts, S_gamma = dot(ax_i[1], ax_j[0])
            C, C_parts, C_gamma = dot(ax_i[0], ax_j[0])
            c, s = np.cos(phi), np.sin(phi)
            parts = {b: c[:, None] * S_parts.get(b, 0) - s[:, None] * C_parts.get(b, 0)
                     for b in set(S_parts) | set(C_parts)}
            gamma = None
            if w is not None:
                # f̈ = c·S̈ − s·C̈ + 2(ċ·Ṡ − ṡ·Ċ) + c̈·S − s̈·C, with Ṡ, Ċ = rates
                S_rate = sum(np.einsum("nj,nj->n", blk, w[:, b]) for b, blk in S_parts.items()) if S_parts else 0 * t
                C_rate = sum(np.einsum("nj,nj->n", blk, w[:, b]) for b, blk in C_parts.items()) if C_parts else 0 * t
                dc, ds = -s * rate, c * rate
                ddc, dds = -c * rate ** 2 - s * acc, -s * rate ** 2 + c * acc
                gamma = c * S_gamma - s * C_gamma - 2 * (dc * S_rate - ds * C_rate) - ddc * S + dds * C
                out["rhs"][:, row] = -(dc * S - ds * C)
            put(row, c * S - s * C, parts, gamma)
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
