"""Positions of a planar mechanism: assembly, mobility, and the branch
followed through a run (the sequential part of `mechval.reference.planar.solver`).

1. **Assembly** at the first instant: the approximate pose (angles, and
   origins where given; the others placed by walking the joints from the
   ground) is closed by Gauss–Newton on the joint equations alone
   (minimum-norm steps), then on all rows with the drives at φ(t0).
2. **Mobility**: the rank of the joint rows' Jacobian (SVD, scaled to be
   dimensionless, singular values below `RANK_TOL`·σmax count as zero)
   gives the mobility n − rank; the drives must match it and, with the
   joint rows, have full column rank. Rows beyond that rank are redundant
   (e.g. a parallelogram's third crank): no fixed subset of rows could
   stand in for them over a whole run (the one left out may be the only
   one that holds a body at some instant), so redundant mechanisms are
   solved by least squares on all rows (`mechval.reference.planar.tree`).
3. **Continuation**: nodes marched from t0 to the last instant, each one
   Newton-solved from the Taylor predictor q + h·q̇ + ½h²·q̈ of the node
   before, the step adapted to keep that predictor within `DELTA_TARGET`
   of the solution (so the branch is followed). A step is retried shorter
   where its node, or the Newton-corrected midpoint of its Hermite
   interpolant, has the Jacobian's determinant of the other sign (the
   mirror branch: near a dead centre the two branches pass within
   ~√(distance) of each other, so Newton converges to either; the true
   path never changes sign without a singular Jacobian), or where that
   midpoint lies further than the Taylor target from its interpolant (a
   sharp turn stepped over). Every requested instant is then predicted by
   quintic Hermite interpolation between its two nodes
   and corrected in one batch (`mechval.reference.planar.solver`).

Step sizes are measured scaled: lengths over the mechanism's size L,
angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from mechval.model.mechanism import GROUND, BodyPose, Mechanism
from mechval.reference.planar.constraints import Constraints, MechanismError
from mechval.reference.planar.linear import ROUNDING, last_max, settled, solve_one

#: Singular values below RANK_TOL·σmax of the scaled Jacobian count as zero
#: (a structurally redundant row gives ~1e-16; a mechanism near a toggle
#: position still has σmin/σmax far above 1e-9 wherever it can be solved
#: to the accuracy a reference needs).
RANK_TOL = 1e-9
#: Scaled size of the Taylor predictor's error the continuation aims for:
#: the quintic Hermite predictor between nodes is then within ~1e-8, so
#: the batched correction converges in two or three iterations.
DELTA_TARGET = 1e-3
#: A node whose Newton correction exceeds this (scaled) is retried with a
#: shorter step: it may have crossed to another branch.
DELTA_MAX = 5e-2
NEWTON_ITERATIONS = 30
#: Continuation steps (accepted or retried) a run may take: a longer run,
#: many minutes, is refused naming time.end (the seed four-bar's 509
#: revolutions take about 17,000; tests/test_planar_solver.py).
MAX_STEPS = 30_000
#: A continuation node is only a predictor: Newton stops there once its
#: scaled step is below this (quadratic convergence: the error left is ~1e-18).
NODE_STEP = 1e-9


@dataclass(frozen=True)
class Structure:
    """Mobility and redundancy of the assembled mechanism."""

    grubler: int           # 3·bodies − 2·joints (Grübler–Kutzbach)
    joint_rank: int        # rank of the 2·joints joint rows
    mobility: int          # coordinates − joint_rank
    rank: int              # rank of all rows (joints and drives)
    rows: int              # all rows

    @property
    def redundant(self) -> int:
        """Rows that add no rank: redundant constraints."""
        return self.rows - self.rank


def mechanism_size(mech: Mechanism) -> float:
    """L (m): the largest coordinate of any joint, centre-of-mass or
    force-element point in its body frame (world for the ground)."""
    points = [p for j in mech.joints for p in (j.point_i, j.point_j)] + [b.com for b in mech.bodies]
    points += [p for f in mech.forces for p in (getattr(f, "point_a", (0, 0)), getattr(f, "point_b", (0, 0)))]
    size = max((abs(v) for p in points for v in p), default=0.0)
    return size if size > 0 else 1.0


class Scaling:
    """Dimensionless rows and columns: Js = Dr·J·Dc with lengths over L."""

    def __init__(self, c: Constraints, size: float):
        self.size = size
        self.column = np.where(c.column_is_angular(), 1.0, size)     # q = Dc·z
        self.inverse_column = 1.0 / self.column
        self.row = np.where(c.row_is_angular(), 1.0, 1.0 / size)

    def jacobian(self, J: np.ndarray) -> np.ndarray:
        return J * self.row[..., :, None] * self.column[..., None, :]

    def step(self, dq: np.ndarray) -> np.ndarray:
        """Largest scaled component of each instant's step (instants,)."""
        return last_max(np.abs(dq * self.inverse_column))

    def tolerance(self, q: np.ndarray) -> np.ndarray:
        """The fixed point: a scaled step within rounding of the instant's
        largest scaled coordinate (at least 1: lengths near L, angles near
        a radian; an angle of many turns carries a larger ulp)."""
        return ROUNDING * np.maximum(last_max(np.abs(q * self.inverse_column)), 1.0)


def initial_guess(c: Constraints, pose: Mapping[str, BodyPose]) -> np.ndarray:
    """q (n,) from the approximate pose: angles as given, origins as given
    or placed by walking the joints (revolute first) from the ground so
    that each joint's two points coincide."""
    mech = c.mech
    missing = [b.name for b in mech.bodies if b.name not in pose]
    if missing:
        raise MechanismError(f"assembly.{missing[0]}", "no angle given for this body")
    theta = {b: float(pose[b].theta) for b in c.bodies} | {GROUND: 0.0}
    origin = {b: (pose[b].x, pose[b].y) for b in c.bodies if pose[b].x is not None and pose[b].y is not None}
    origin[GROUND] = (0.0, 0.0)
    rot = lambda b, p: (np.cos(theta[b]) * p[0] - np.sin(theta[b]) * p[1],
                        np.sin(theta[b]) * p[0] + np.cos(theta[b]) * p[1])
    joints = sorted(mech.joints, key=lambda j: j.kind != "revolute")
    placed = True
    while placed:
        placed = False
        for j in joints:
            for known, p_known, other, p_other in ((j.body_i, j.point_i, j.body_j, j.point_j),
                                                   (j.body_j, j.point_j, j.body_i, j.point_i)):
                if known in origin and other not in origin:
                    wx, wy = rot(known, p_known)
                    ox, oy = rot(other, p_other)
                    origin[other] = (origin[known][0] + wx - ox, origin[known][1] + wy - oy)
                    placed = True
    q = np.zeros(c.n)
    for k, body in enumerate(mech.bodies):
        gx, gy = rot(body.name, body.com)
        ox, oy = origin.get(body.name, (0.0, 0.0))
        q[3 * k:3 * k + 3] = ox + gx, oy + gy, theta[body.name]
    return q


def gauss_newton(c: Constraints, scaling: Scaling, q: np.ndarray, t0: float,
                 rows: np.ndarray, key: str, what: str) -> np.ndarray:
    """Close the rows `rows` at one instant from q: minimum-norm least-squares
    steps (scaled), halved while they do not reduce the residual; stops at
    the fixed point (a step within rounding)."""
    t = np.array([t0])
    norm = lambda q: float(np.abs(c.residual(q[None], t)[0, rows] * scaling.row[rows]).max())
    previous = np.inf
    for _ in range(NEWTON_ITERATIONS):
        Js = scaling.jacobian(c.jacobian(q[None])[0])[rows]
        res = c.residual(q[None], t)[0, rows] * scaling.row[rows]
        dz, *_ = np.linalg.lstsq(Js, -res, rcond=None)
        dq = dz * scaling.column
        before, step = norm(q), 1.0
        while step > 1e-3 and norm(q + step * dq) > before and before > 1e-13:
            step /= 2
        q = q + step * dq
        size = scaling.step(step * dq)
        if settled(size, previous, scaling.tolerance(q)) and norm(q) <= 1e-9:
            return q
        previous = size
    if norm(q) <= 1e-12:
        return q
    raise MechanismError(key, f"the pose cannot be assembled: {what} stay open by {norm(q):.3g} "
                              f"(scaled by the mechanism's size {scaling.size:.3g} m) after "
                              f"{NEWTON_ITERATIONS} Gauss–Newton steps")


def rank(A: np.ndarray) -> int:
    s = np.linalg.svd(A, compute_uv=False)
    return int(np.sum(s > RANK_TOL * s[0])) if s.size and s[0] > 0 else 0


def _joint_rows(c: Constraints) -> np.ndarray:
    return np.array([k for k, row in enumerate(c.rows) if row.kind != "drive"], dtype=int)


def _assembled_joints(c: Constraints, scaling: Scaling, pose: Mapping[str, BodyPose], t0: float) -> np.ndarray:
    """q near `pose` that closes every joint (the drives not yet imposed)."""
    return gauss_newton(c, scaling, initial_guess(c, pose), t0, _joint_rows(c), "assembly", "the joints")


def redundant_joint_rows(c: Constraints, scaling: Scaling, pose: Mapping[str, BodyPose], t0: float) -> int:
    """Joint equations beyond the rank of the joints' Jacobian at the pose
    assembled near `pose`: redundant constraints (1 for a parallelogram
    with a third crank). The drives play no part, so this holds for a
    mechanism whose motion is not all prescribed too."""
    rows = _joint_rows(c)
    if not rows.size:
        return 0
    Js = scaling.jacobian(c.jacobian(_assembled_joints(c, scaling, pose, t0)[None])[0])
    return int(rows.size - rank(Js[rows]))


def structure(c: Constraints, scaling: Scaling, q: np.ndarray) -> Structure:
    """Mobility and ranks at the pose q; refuses drives that do not match
    the mobility or do not fix the motion."""
    mech = c.mech
    Js = scaling.jacobian(c.jacobian(q[None])[0])
    joint_rows = _joint_rows(c)
    joint_rank = rank(Js[joint_rows]) if joint_rows.size else 0
    mobility = c.n - joint_rank
    grubler = 3 * len(mech.bodies) - 2 * len(mech.joints)
    drives = len(mech.drives)
    counts = (f"Grübler count 3·{len(mech.bodies)} bodies − 2·{len(mech.joints)} joints = {grubler}; "
              f"the Jacobian of the {len(joint_rows)} joint equations in {c.n} coordinates has rank "
              f"{joint_rank}, so the mobility is {mobility}")
    if drives != mobility:
        raise MechanismError("drive", f"{drives} drive{'s' if drives != 1 else ''} for a mechanism of mobility "
                                      f"{mobility} ({counts})")
    full_rank = rank(Js)
    if full_rank < c.n:
        raise MechanismError("drive", f"the drives do not determine the motion: with them the Jacobian has rank "
                                      f"{full_rank} < {c.n} coordinates ({counts})")
    return Structure(grubler, joint_rank, mobility, full_rank, c.m)


def assemble(c: Constraints, scaling: Scaling, pose: Mapping[str, BodyPose], t0: float) -> tuple[np.ndarray, Structure]:
    """The assembled q at t0 and the mechanism's structure there."""
    q = _assembled_joints(c, scaling, pose, t0)
    found = structure(c, scaling, q)
    q = gauss_newton(c, scaling, q, t0, np.arange(c.m), "assembly", f"the joints with the drives at t = {t0:.6g} s")
    return q, found


@dataclass(frozen=True)
class Nodes:
    """Solved instants of the continuation: t (k,), q, q̇, q̈ (k, n)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray

    def predict(self, t: np.ndarray) -> np.ndarray:
        """Quintic Hermite interpolation of q at instants t (within the nodes)."""
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, max(len(self.t) - 2, 0))
        if len(self.t) == 1:
            return np.repeat(self.q, len(t), axis=0)
        h = (self.t[k + 1] - self.t[k])[:, None]
        s = (t[:, None] - self.t[k][:, None]) / h
        s2, s3 = s * s, s * s * s
        s4, s5 = s3 * s, s3 * s2
        return ((1 - 10 * s3 + 15 * s4 - 6 * s5) * self.q[k] + (s - 6 * s3 + 8 * s4 - 3 * s5) * h * self.v[k]
                + 0.5 * (s2 - 3 * s3 + 3 * s4 - s5) * h * h * self.a[k]
                + (10 * s3 - 15 * s4 + 6 * s5) * self.q[k + 1] + (-4 * s3 + 7 * s4 - 3 * s5) * h * self.v[k + 1]
                + 0.5 * (s3 - 2 * s4 + s5) * h * h * self.a[k + 1])


def newton(c: Constraints, scaling: Scaling, q: np.ndarray, t: float) -> tuple[np.ndarray, bool]:
    """Newton at one instant (q (1, n)), to a scaled step of NODE_STEP."""
    tt = np.array([t])
    for _ in range(NEWTON_ITERATIONS):
        f = c.frames(q)
        try:
            dq = -solve_one(c.jacobian(q, f)[0], c.residual(q, tt, f)[0], scaling.row, scaling.column)[None]
        except np.linalg.LinAlgError:
            return q, False
        q = q + dq
        size = scaling.step(dq)
        if not np.isfinite(size).all():
            return q, False
        if (size <= NODE_STEP).all():
            return q, True
    return q, False


def orientation(c: Constraints, scaling: Scaling, q: np.ndarray) -> float:
    """The sign of the (scaled) Jacobian's determinant at q (1, n), which
    tells an assembly branch from its mirror; 0 where Φq is not square (a
    redundant mechanism: no determinant to compare)."""
    return float(np.linalg.slogdet(scaling.jacobian(c.jacobian(q)[0]))[0]) if c.m == c.n else 0.0


def interpolates(c: Constraints, scaling: Scaling, step: Nodes, sign: float, delta_target: float) -> bool:
    """Does the two-node `step` hold the branch between its nodes? Its
    Hermite interpolant at the midpoint, Newton-corrected, must stay on the
    branch (same orientation) and within `delta_target` (scaled): ~δ² where
    the motion is smooth (quintic against the nodes' quadratic Taylor
    error δ), but of the order of the branches' distance where both nodes
    lie on the branch and the step passes over a dead centre's closest
    approach, the crank's sharp turn between them (the batch's predictor
    would miss it and Newton would not settle there)."""
    t_mid = np.array([0.5 * (step.t[0] + step.t[1])])
    guess = step.predict(t_mid)
    mid, ok = newton(c, scaling, guess, float(t_mid[0]))
    return ok and scaling.step(mid - guess)[0] <= delta_target and orientation(c, scaling, mid) == sign


def march(c: Constraints, scaling: Scaling, q0: np.ndarray, t0: float, t_end: float,
          rates: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
          delta_target: float = DELTA_TARGET) -> Nodes:
    """Continuation nodes from (t0, q0) to t_end; `rates(q, t)` gives q̇, q̈.
    A larger `delta_target` (up to DELTA_MAX / 5) follows the branch with
    fewer nodes, too far apart for the batch's predictor but enough to
    check that the loop closes all along."""
    q = q0[None]
    t = t0
    v, a = rates(q, np.array([t]))
    ts, qs, vs, as_ = [t], [q[0]], [v[0]], [a[0]]
    span = t_end - t0
    if span <= 0:
        return Nodes(np.array(ts), np.array(qs), np.array(vs), np.array(as_))
    speed = lambda v, a: (float(np.abs(v / scaling.column).max()), float(np.abs(a / scaling.column).max()))
    vmax, amax = speed(v, a)
    h = min(span, 0.1 / vmax if vmax > 0 else np.inf, np.sqrt(0.2 / amax) if amax > 0 else np.inf)
    h_min = 1e-10 * span
    sign = orientation(c, scaling, q)
    steps = 0
    while t < t_end:
        steps += 1
        if steps > MAX_STEPS:
            share = (t - t0) / span
            raise MechanismError("time.end", f"the reference's continuation reached only t = {t:.6g} s of {t_end:g} s "
                                             f"in {MAX_STEPS:,} steps, the limit (the run would need about "
                                             f"{1 / max(share, 1e-300):.3g} times as many); shorten time.end")
        h = min(h, t_end - t)
        if t_end - (t + h) < 1e-9 * h:   # land on t_end exactly
            h = t_end - t
        predicted = q + h * v + 0.5 * h * h * a
        solved, ok = newton(c, scaling, predicted, t + h)
        delta = float(scaling.step(solved - predicted)[0]) if ok else np.inf
        ok = ok and delta <= DELTA_MAX and orientation(c, scaling, solved) == sign
        if ok:
            t_new = t + h if t_end - (t + h) > 1e-12 * span else t_end
            v_new, a_new = rates(solved, np.array([t_new]))
            step = Nodes(np.array([t, t_new]), np.vstack([q, solved]), np.vstack([v, v_new]), np.vstack([a, a_new]))
            ok = interpolates(c, scaling, step, sign, delta_target)
        if not ok:
            h /= 4
            if h < h_min:
                raise MechanismError("time", f"the loop cannot close, or locks, just after t = {t:.6g} s: Newton "
                                             f"from the previous instant fails for every step down to {h_min:.3g} s")
            continue
        t, q, v, a = t_new, solved, v_new, a_new
        ts.append(t), qs.append(q[0]), vs.append(v[0]), as_.append(a[0])
        h *= min(2.0, max(0.3, 0.9 * (delta_target / max(delta, 1e-300)) ** (1 / 3)))
    return Nodes(np.array(ts), np.array(qs), np.array(vs), np.array(as_))
