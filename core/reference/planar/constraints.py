"""Constraint equations of a planar mechanism in absolute coordinates.

Coordinates: per moving body k, q[3k:3k+3] = (x, y, θ) of its centre of
mass G in world axes and its angle (Nikravesh, *Computer-Aided Analysis of
Mechanical Systems*, 1988, ch. 3–6; Haug, *Computer Aided Kinematics and
Dynamics of Mechanical Systems*, 1989, ch. 3). A body-fixed point p (body
frame) lies at P = G + R(θ)·s with s = p − com, so ∂P/∂θ = ẑ × r,
r = R·s. The ground is not a coordinate: its points are world points.

Rows of Φ(q, t) = 0, in order (`Row.kind`):
- revolute joint (2 rows, "pin x", "pin y"): Pj − Pi = 0;
- prismatic joint (2 rows): "angle": θj − θi − θ0 = 0 (θ0 the held
  angle), then "slide": n·(Pj − Pi) = 0 with n = ẑ × u and u = Ri·axis;
- each drive (1 row, "drive"): θj − θi − φ(t) = 0 (revolute joint) or
  u·(Pj − Pi) − φ(t) = 0 (prismatic joint).

Velocities solve Φq·q̇ = −Φt and accelerations Φq·q̈ = γ with
γ = −(Φq·q̇)q·q̇ − 2·Φqt·q̇ − Φtt (Nikravesh 1988, ch. 3), written out
per row in `gamma`. Everything is vectorised over instants: q has shape (instants, n).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mechval.model.mechanism import GROUND, Mechanism


class MechanismError(ValueError):
    """The mechanism cannot be solved as given: `key` names what is at
    fault (a scenario key), `reason` says why. The caller that knows the
    scenario's file turns it into a ScenarioError."""

    def __init__(self, key: str, reason: str):
        self.key, self.reason = key, reason
        super().__init__(f"{key}: {reason}")

    def __reduce__(self):
        return type(self), (self.key, self.reason)


@dataclass(frozen=True)
class Row:
    """One constraint row: what it is, of which joint (or drive)."""

    kind: str          # "pin x", "pin y", "angle", "slide", "drive"
    joint: str
    drive: str = ""    # the drive's name for a "drive" row


@dataclass(frozen=True)
class Attachment:
    """A joint's point on one body: the body's index (−1 for the ground)
    and the point relative to the centre of mass (or world, for ground)."""

    body: int
    s: tuple[float, float]


class Constraints:
    """Φ, Φq, −Φt and γ of a mechanism, vectorised over instants."""

    def __init__(self, mech: Mechanism):
        self.mech = mech
        self.bodies = tuple(b.name for b in mech.bodies)
        self.index = {name: k for k, name in enumerate(self.bodies)}
        self.n = 3 * len(self.bodies)
        self.com = {b.name: b.com for b in mech.bodies}
        self._check()
        rows: list[Row] = []
        self.joint_rows: dict[str, int] = {}
        for j in mech.joints:
            self.joint_rows[j.name] = len(rows)
            kinds = ("pin x", "pin y") if j.kind == "revolute" else ("angle", "slide")
            rows += [Row(kind, j.name) for kind in kinds]
        self.drive_rows: dict[str, int] = {}
        for d in mech.drives:
            self.drive_rows[d.name] = len(rows)
            rows.append(Row("drive", d.joint, d.name))
        self.rows = tuple(rows)
        self.m = len(rows)
        self._index()

    def _check(self) -> None:
        """Refuse joints, drives and forces that name unknown bodies or
        joints, and a joint from a body to itself."""
        known = set(self.bodies) | {GROUND}
        joints = {j.name for j in self.mech.joints}
        for j in self.mech.joints:
            for body in (j.body_i, j.body_j):
                if body not in known:
                    raise MechanismError(f"joint.{j.name}",
                                         f"unknown body {body!r} (bodies: {', '.join(sorted(known))})")
            if j.body_i == j.body_j:
                raise MechanismError(f"joint.{j.name}", f"joins {j.body_i!r} to itself")
        for d in self.mech.drives:
            if d.joint not in joints:
                raise MechanismError(f"drive.{d.name}",
                                     f"unknown joint {d.joint!r} (joints: {', '.join(sorted(joints))})")
        names = [d.name for d in self.mech.drives]
        if len(set(names)) != len(names):
            raise MechanismError("drive", f"two drives share a name (drives: {', '.join(names)})")
        for f in self.mech.forces:
            for body in (getattr(f, "body", None), getattr(f, "body_a", None), getattr(f, "body_b", None)):
                if body is not None and body not in known:
                    raise MechanismError(f"force.{f.name}", f"unknown body {body!r}")

    def attach(self, body: str, p: tuple[float, float]) -> Attachment:
        if body == GROUND:
            return Attachment(-1, (float(p[0]), float(p[1])))
        c = self.com[body]
        return Attachment(self.index[body], (p[0] - c[0], p[1] - c[1]))

    # -- geometry of body-fixed points over instants ------------------------------------------

    def trig(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """cos θ and sin θ of every body, (instants, bodies) each."""
        th = q[:, 2::3]
        return np.cos(th), np.sin(th)

    def point(self, q: np.ndarray, a: Attachment, trig) -> tuple[np.ndarray, ...]:
        """World position P and arm r = R·s of an attachment: (Px, Py, rx, ry)."""
        if a.body < 0:
            zero = np.zeros(len(q))
            return zero + a.s[0], zero + a.s[1], zero, zero
        c, s = trig[0][:, a.body], trig[1][:, a.body]
        rx, ry = c * a.s[0] - s * a.s[1], s * a.s[0] + c * a.s[1]
        return q[:, 3 * a.body] + rx, q[:, 3 * a.body + 1] + ry, rx, ry

    def point_velocity(self, v: np.ndarray, a: Attachment, P) -> tuple[np.ndarray, np.ndarray]:
        """Ṗ = Ġ + ω ẑ × r, for the point P = self.point(...)."""
        if a.body < 0:
            zero = np.zeros(len(v))
            return zero, zero
        w = v[:, 3 * a.body + 2]
        return v[:, 3 * a.body] - w * P[3], v[:, 3 * a.body + 1] + w * P[2]

    def axis(self, joint, trig, count: int) -> tuple[np.ndarray, np.ndarray]:
        """World slide axis u = Ri·axis of a prismatic joint (its normal is
        n = ẑ × u = (−uy, ux))."""
        ax, ay = joint.axis
        k = self.attach(joint.body_i, joint.point_i).body
        if k < 0:
            zero = np.zeros(count)
            return zero + ax, zero + ay
        c, s = trig[0][:, k], trig[1][:, k]
        return c * ax - s * ay, s * ax + c * ay

    # -- Φ, Φq, −Φt, γ, vectorised over joints --------------------------------------------------

    def _index(self) -> None:
        """Per-joint arrays (the ground is body index nb, a zero pose)."""
        mech, nb = self.mech, len(self.bodies)
        ends = [(self.attach(j.body_i, j.point_i), self.attach(j.body_j, j.point_j)) for j in mech.joints]
        self.bi = np.array([ai.body if ai.body >= 0 else nb for ai, _ in ends], dtype=int)
        self.bj = np.array([aj.body if aj.body >= 0 else nb for _, aj in ends], dtype=int)
        self.si = np.array([ai.s for ai, _ in ends], dtype=float).reshape(-1, 2)
        self.sj = np.array([aj.s for _, aj in ends], dtype=float).reshape(-1, 2)
        self.ax = np.array([j.axis for j in mech.joints], dtype=float).reshape(-1, 2)
        self.held = np.array([j.held_angle if j.kind == "prismatic" else 0.0 for j in mech.joints])
        first = np.array([self.joint_rows[j.name] for j in mech.joints], dtype=int)
        self.rev = np.array([k for k, j in enumerate(mech.joints) if j.kind == "revolute"], dtype=int)
        self.pri = np.array([k for k, j in enumerate(mech.joints) if j.kind == "prismatic"], dtype=int)
        self.first = first
        joint_index = {j.name: k for k, j in enumerate(mech.joints)}
        drives = mech.drives
        self.d_joint = np.array([joint_index[d.joint] for d in drives], dtype=int)
        self.d_row = np.array([self.drive_rows[d.name] for d in drives], dtype=int)
        slide = np.array([mech.joint(d.joint).kind == "prismatic" for d in drives], dtype=bool)
        self.d_rev, self.d_pri, self.d_slide = np.flatnonzero(~slide), np.flatnonzero(slide), slide
        self.d_pri_column = np.searchsorted(self.pri, self.d_joint[self.d_pri])   # among the prismatic joints
        self.laws = tuple(d.law for d in drives)
        self._sparsity()

    def frames(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Everything Φ, Φq and γ need at q, for all joints at once: body
        angles with their cos and sin (instants, bodies + ground), each
        joint's arms ri, rj, its d = Pj − Pi and its axis u = Ri·axis."""
        qa = np.concatenate([q, np.zeros((len(q), 3))], axis=1)
        th = qa[:, 2::3]
        c, s = np.cos(th), np.sin(th)
        ci, si_, cj, sj_ = c[:, self.bi], s[:, self.bi], c[:, self.bj], s[:, self.bj]
        rxi, ryi = ci * self.si[:, 0] - si_ * self.si[:, 1], si_ * self.si[:, 0] + ci * self.si[:, 1]
        rxj, ryj = cj * self.sj[:, 0] - sj_ * self.sj[:, 1], sj_ * self.sj[:, 0] + cj * self.sj[:, 1]
        dx = qa[:, 3 * self.bj] + rxj - qa[:, 3 * self.bi] - rxi
        dy = qa[:, 3 * self.bj + 1] + ryj - qa[:, 3 * self.bi + 1] - ryi
        # the axis only matters at prismatic joints: zero elsewhere, which
        # spares an all-revolute mechanism its arithmetic
        ux, uy = np.zeros_like(dx), np.zeros_like(dx)
        if self.pri.size:
            cp, sp, axis = ci[:, self.pri], si_[:, self.pri], self.ax[self.pri]
            ux[:, self.pri], uy[:, self.pri] = cp * axis[:, 0] - sp * axis[:, 1], sp * axis[:, 0] + cp * axis[:, 1]
        return dict(th=th, cos=c, sin=s, rxi=rxi, ryi=ryi, rxj=rxj, ryj=ryj, dx=dx, dy=dy, ux=ux, uy=uy)

    def _laws(self, t: np.ndarray, which: str) -> np.ndarray:
        """φ, φ̇ or φ̈ of every drive, (instants, drives)."""
        return np.stack([getattr(law, which)(t) for law in self.laws], axis=-1) if self.laws else np.zeros((len(t), 0))

    def residual(self, q: np.ndarray, t: np.ndarray, f: dict | None = None) -> np.ndarray:
        """Φ(q, t), shape (instants, m); `f`: this q's `frames`, if at hand."""
        f = f or self.frames(q)
        phi = np.empty((len(q), self.m))
        rev, pri = self.rev, self.pri
        phi[:, self.first[rev]], phi[:, self.first[rev] + 1] = f["dx"][:, rev], f["dy"][:, rev]
        relative = f["th"][:, self.bj] - f["th"][:, self.bi]
        phi[:, self.first[pri]] = relative[:, pri] - self.held[pri]
        phi[:, self.first[pri] + 1] = -f["uy"][:, pri] * f["dx"][:, pri] + f["ux"][:, pri] * f["dy"][:, pri]
        value = relative[:, self.d_joint]
        if self.d_pri.size:
            slide = self.d_joint[self.d_pri]
            value[:, self.d_pri] = f["ux"][:, slide] * f["dx"][:, slide] + f["uy"][:, slide] * f["dy"][:, slide]
        phi[:, self.d_row] = value - self._laws(t, "angle")
        return phi

    def _sparsity(self) -> None:
        """The Jacobian's nonzeros: constant ones (±1) as a template, and
        groups of varying ones (flat index, per-joint quantity, joints, sign)."""
        nb, n = len(self.bodies), self.n
        template = np.zeros(self.m * n)
        groups: list[tuple[np.ndarray, str, np.ndarray, float]] = []

        def entries(rows, joints, side, offset, key=None, sign=1.0):
            b = side[joints]
            keep = b < nb
            flat = rows[keep] * n + 3 * b[keep] + offset
            if key is None:
                template[flat] = sign
            elif flat.size:
                groups.append((flat, key, joints[keep], sign))

        rev, pri = self.rev, self.pri
        dr, dp = self.d_joint[self.d_rev], self.d_joint[self.d_pri]
        rows_dr, rows_dp = self.d_row[self.d_rev], self.d_row[self.d_pri]
        for rows, joints in ((self.first[rev], rev),):              # pins: Pj − Pi
            entries(rows, joints, self.bj, 0), entries(rows, joints, self.bi, 0, sign=-1.0)
            entries(rows + 1, joints, self.bj, 1), entries(rows + 1, joints, self.bi, 1, sign=-1.0)
            entries(rows, joints, self.bj, 2, "ryj", -1.0), entries(rows, joints, self.bi, 2, "ryi", 1.0)
            entries(rows + 1, joints, self.bj, 2, "rxj", 1.0), entries(rows + 1, joints, self.bi, 2, "rxi", -1.0)
        for rows, joints in ((self.first[pri], pri), (rows_dr, dr)):   # θj − θi
            entries(rows, joints, self.bj, 2), entries(rows, joints, self.bi, 2, sign=-1.0)
        for rows, joints, w in ((self.first[pri] + 1, pri, "n"), (rows_dp, dp, "u")):   # w·(Pj − Pi)
            entries(rows, joints, self.bj, 0, w + "x"), entries(rows, joints, self.bi, 0, w + "x", -1.0)
            entries(rows, joints, self.bj, 1, w + "y"), entries(rows, joints, self.bi, 1, w + "y", -1.0)
            entries(rows, joints, self.bj, 2, w + "_arm_j"), entries(rows, joints, self.bi, 2, w + "_turn_i")
        self._template, self._groups = template, tuple(groups)
        self._subsets: dict[tuple[int, ...], tuple] = {}

    def _subset(self, rows: tuple[int, ...]) -> tuple:
        """The template and groups of the Jacobian restricted to `rows`."""
        if rows not in self._subsets:
            n = self.n
            new = np.full(self.m, -1)
            new[list(rows)] = np.arange(len(rows))
            template = self._template.reshape(self.m, n)[list(rows)].ravel()
            groups = []
            for flat, key, joints, sign in self._groups:
                keep = new[flat // n] >= 0
                if keep.any():
                    groups.append((new[flat // n][keep] * n + (flat % n)[keep], key, joints[keep], sign))
            self._subsets[rows] = (template, tuple(groups))
        return self._subsets[rows]

    def jacobian(self, q: np.ndarray, f: dict | None = None, rows: tuple[int, ...] | None = None,
                 instants_last: bool = False) -> np.ndarray:
        """Φq, shape (instants, m, n), or only the given rows; (m, n,
        instants) with `instants_last`, the tree elimination's layout. For a row
        w·(Pj − Pi) the θ entries are w·(ẑ × rj) and −w·(ẑ × ri) + ∂w/∂θi·d,
        the last −u·d for w = n and n·d for w = u (w turns with body_i)."""
        f = f or self.frames(q)
        ux, uy, dx, dy = f["ux"], f["uy"], f["dx"], f["dy"]
        nx, ny = -uy, ux
        arm = lambda wx, wy, rx, ry: wy * rx - wx * ry       # w·(ẑ × r)
        values = dict(rxj=lambda: f["rxj"], ryj=lambda: f["ryj"], rxi=lambda: f["rxi"], ryi=lambda: f["ryi"],
                      nx=lambda: nx, ny=lambda: ny, ux=lambda: ux, uy=lambda: uy,
                      n_arm_j=lambda: arm(nx, ny, f["rxj"], f["ryj"]), u_arm_j=lambda: arm(ux, uy, f["rxj"], f["ryj"]),
                      n_turn_i=lambda: -arm(nx, ny, f["rxi"], f["ryi"]) - (ux * dx + uy * dy),
                      u_turn_i=lambda: -arm(ux, uy, f["rxi"], f["ryi"]) + (nx * dx + ny * dy))
        template, groups = (self._template, self._groups) if rows is None else self._subset(rows)
        count = len(template) // self.n
        J = np.empty((count * self.n, len(q)) if instants_last else (len(q), count * self.n))
        J[:] = template[:, None] if instants_last else template
        computed: dict[str, np.ndarray] = {}     # only the quantities these rows use
        for flat, key, joints, sign in groups:
            if key not in computed:
                computed[key] = values[key]()
            if instants_last:
                J[flat] = (sign * computed[key][:, joints]).T
            else:
                J[:, flat] = sign * computed[key][:, joints]
        return J.reshape(count, self.n, len(q)) if instants_last else J.reshape(len(q), count, self.n)

    def velocity_rhs(self, t: np.ndarray) -> np.ndarray:
        """−Φt, shape (instants, m): the drives' rates φ̇(t)."""
        rhs = np.zeros((len(t), self.m))
        rhs[:, self.d_row] = self._laws(t, "rate")
        return rhs

    def gamma(self, q: np.ndarray, v: np.ndarray, t: np.ndarray, f: dict | None = None) -> np.ndarray:
        """γ with Φq·q̈ = γ, shape (instants, m).

        pin: ωj²·rj − ωi²·ri; angle: 0; slide (w = n): ωi²·n·d + 2ωi·u·ḋ +
        n·(ωj²·rj − ωi²·ri); along the slide (w = u): φ̈ + ωi²·u·d − 2ωi·n·ḋ
        + u·(ωj²·rj − ωi²·ri); revolute drive: φ̈. Here d = Pj − Pi and
        ḋ its rate (from the second derivative of each row with the q̈ terms
        moved to the left-hand side)."""
        f = f or self.frames(q)
        va = np.concatenate([v, np.zeros((len(v), 3))], axis=1)
        w = va[:, 2::3]
        wi, wj = w[:, self.bi], w[:, self.bj]
        cx = wj * wj * f["rxj"] - wi * wi * f["rxi"]
        cy = wj * wj * f["ryj"] - wi * wi * f["ryi"]
        g = np.zeros((len(q), self.m))
        rev, pri = self.rev, self.pri
        g[:, self.first[rev]], g[:, self.first[rev] + 1] = cx[:, rev], cy[:, rev]
        g[:, self.d_row] = self._laws(t, "acceleration")
        if not pri.size:
            return g
        # the slide terms, at prismatic joints only (column k: joint pri[k])
        ddx = va[:, 3 * self.bj] - wj * f["ryj"] - va[:, 3 * self.bi] + wi * f["ryi"]
        ddy = va[:, 3 * self.bj + 1] + wj * f["rxj"] - va[:, 3 * self.bi + 1] - wi * f["rxi"]
        ux, uy, dx, dy = f["ux"][:, pri], f["uy"][:, pri], f["dx"][:, pri], f["dy"][:, pri]
        wi, cx, cy, ddx, ddy = wi[:, pri], cx[:, pri], cy[:, pri], ddx[:, pri], ddy[:, pri]
        u_d, n_d = ux * dx + uy * dy, -uy * dx + ux * dy
        u_dd, n_dd = ux * ddx + uy * ddy, -uy * ddx + ux * ddy
        u_c, n_c = ux * cx + uy * cy, -uy * cx + ux * cy
        g[:, self.first[pri] + 1] = wi * wi * n_d + 2 * wi * u_dd + n_c
        along = wi * wi * u_d - 2 * wi * n_dd + u_c
        g[:, self.d_row[self.d_pri]] += along[:, self.d_pri_column]
        return g

    # -- scaling -------------------------------------------------------------------------------

    def row_is_angular(self) -> np.ndarray:
        """Rows in radians (angle rows, revolute drives); the others are lengths."""
        return np.array([row.kind == "angle" or (row.kind == "drive" and self.mech.joint(row.joint).kind == "revolute")
                         for row in self.rows])

    def column_is_angular(self) -> np.ndarray:
        return np.tile([False, False, True], len(self.bodies))
