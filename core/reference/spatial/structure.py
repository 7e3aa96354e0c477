"""Assembly of a spatial system and the facts of its structure: Newton
from the stated poses to a closed loop, then the Jacobian's rank (mobility,
redundant constraints) and which rows to keep in the square solves.

Scaling (as the planar reference's): length rows over the system's size L,
translation columns times L, so every entry of the scaled Jacobian is
dimensionless and of order one, and a rank decision by singular values
means the same at any unit of length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.joints import Constraints, Pose
from mechval.reference.spatial.lu import LU
from mechval.reference.spatial.rotation import exp_map, orthonormalised

#: A singular value of the scaled Jacobian below this fraction of the
#: largest counts as zero (a redundant row): exact redundancy leaves ~eps.
RANK_TOL = 1e-9
#: Newton's fixed point: a scaled step within rounding of the iterate, or
#: a step that no longer halves once below STAGNATION (the residual's
#: noise floor), as `mechval.reference.planar.linear.settled`.
ROUNDING = 8 * np.finfo(float).eps
STAGNATION = 1e-11
NEWTON_ITERATIONS = 40
#: Chord iterations between fresh Jacobians in a batch.
CHORD = 8
#: A closed loop's scaled residual (every row, redundant ones included).
CLOSED = 1e-9
#: Rows whose remaining norms lie within this fraction of the largest are
#: a tie in the pivoted pick (`pivoted_rows`), taken in the rows' order: a
#: symmetric mechanism has exact ties, and which of them a BLAS kernel's
#: rounding favours must not decide the rows kept (Bricard's did).
TIE = 1e-6


@dataclass(frozen=True)
class Structure:
    """Mobility by Grübler–Kutzbach and by rank; redundant rows; the rows
    the square solves keep (`independent`)."""

    grubler: int
    mobility: int
    rank: int
    rows: int
    redundant: int
    independent: tuple[int, ...]


class Scaling:
    def __init__(self, c: Constraints):
        system = c.system
        points = [np.asarray(b.position, dtype=float) for b in system.bodies]
        points += [np.asarray(p, dtype=float) for j in system.joints for p in (j.point_i, j.point_j)]
        spread = max((np.linalg.norm(p - q) for p in points for q in points), default=0.0)
        self.size = spread if spread > 0 else 1.0
        lengths = np.array([r.kind.startswith("d") or r.kind.endswith(".d") or
                            (r.kind == "drive" and system.joint(r.joint).kind == "prismatic") for r in c.rows])
        self.row = np.where(lengths, 1 / self.size, 1.0)
        self.column = np.tile([self.size] * 3 + [1.0] * 3, len(c.bodies))

    def jacobian(self, J: np.ndarray) -> np.ndarray:
        return J * self.row[:, None] * self.column[None, :]

    def step(self, dq: np.ndarray) -> np.ndarray:
        """Per instant, the largest scaled component of a step (N, n)."""
        return np.abs(dq / self.column).max(axis=1) if dq.shape[1] else np.zeros(len(dq))


def kept(a: np.ndarray, rows: tuple[int, ...]) -> np.ndarray:
    """a[:, rows]: no copy where the rows are all of a's, in order (no
    redundant rows: the common case, and a copy of (N, m, n) costs)."""
    return a if tuple(rows) == tuple(range(a.shape[1])) else a[:, list(rows)]


def initial_pose(c: Constraints) -> Pose:
    bodies = c.system.bodies
    A = np.array([orthonormalised(np.asarray(b.rotation, dtype=float)) for b in bodies]).reshape(1, -1, 3, 3)
    G = np.array([np.asarray(b.position, dtype=float) + A[0, k] @ np.asarray(b.com, dtype=float)
                  for k, b in enumerate(bodies)]).reshape(1, -1, 3)
    return Pose(G, A)


def moved(pose: Pose, dq: np.ndarray) -> Pose:
    """The pose after a step (δG, δπ) per body, rotations on the group."""
    step = dq.reshape(len(pose), -1, 6)
    return Pose(pose.G + step[..., :3], exp_map(step[..., 3:]) @ pose.A)


def settled(size: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """The iterate is at its fixed point after this step: the step was
    within rounding, or stagnated at the noise floor, or the rate of
    convergence puts the next step a tenth below rounding (at least the
    linear rate's size²/previous; Newton's quadratic one is faster): the
    step just taken was the last that counts."""
    with np.errstate(divide="ignore", invalid="ignore"):
        quadratic = size * size / previous <= 0.1 * ROUNDING
    return (size <= ROUNDING) | ((size >= 0.5 * previous) & (size <= STAGNATION)) | (quadratic & (size < previous) & np.isfinite(previous))


def newton(c: Constraints, scaling: Scaling, pose: Pose, t: np.ndarray, rows: tuple[int, ...] | None,
           where: str = "assembly", lu: LU | None = None) -> Pose:
    """Newton on Φ(q, t) = 0 to the fixed point. With `rows` (as many as
    coordinates) each step solves those rows squarely, all instants at
    once; without, one instant by least squares on all rows (the
    minimum-norm step: assembly, redundant or not). Raises MechanismError
    where it does not settle or the loop does not close. `lu`: the kept
    rows' Jacobian factorised at `pose`, if at hand."""
    if not c.m:      # free bodies: nothing to close
        return pose
    previous = np.full(len(pose), np.inf)
    done = np.zeros(len(pose), dtype=bool)
    for it in range(NEWTON_ITERATIONS):
        # batches: chord iterations, the kept rows' Jacobian factorised at the
        # first iterate and afresh every CHORD iterations (each further
        # iteration evaluates Φ alone: cheaper than a Jacobian and its LU)
        fresh = rows is None or (it % CHORD == 0 and not (it == 0 and lu is not None))
        out = c.evaluate(pose, t, jacobian=fresh)
        if rows is None:
            Js = scaling.jacobian(out["jac"][0])
            dq = -np.linalg.lstsq(Js, out["phi"][0] * scaling.row, rcond=None)[0] * scaling.column
            dq = dq[None]
        else:
            if fresh:
                lu = LU(kept(out["jac"], rows))
                previous = np.full(len(pose), np.inf)      # the rate estimate starts over
            dq = -lu.solve(kept(out["phi"], rows))
        size = scaling.step(dq)
        dq[done] = 0.0
        pose = moved(pose, dq)
        done |= settled(size, previous)
        if done.all():
            break
        previous = size
    residual = np.abs(c.evaluate(pose, t, jacobian=False)["phi"] * scaling.row).max(axis=1)
    refuse_unclosed(done, residual, t, where, scaling.size)
    return pose


def refuse_unclosed(done: np.ndarray, residual: np.ndarray, t: np.ndarray, where: str, size: float) -> None:
    """Raise where Newton did not settle or the loop did not close."""
    if not done.all() or residual.max() > CLOSED:
        k = int(np.argmax(np.where(done, residual, np.inf)))
        raise MechanismError("joint" if where == "assembly" else "time",
                             f"the loop cannot close at t = {t[k]:.6g} s ({where}): Newton ends with a scaled "
                             f"residual {residual[k]:.3g} (size {size:.3g} m)")


def _rank(M: np.ndarray) -> int:
    if not M.size:
        return 0
    s = np.linalg.svd(M, compute_uv=False)
    return int((s > RANK_TOL * s[0]).sum()) if s[0] > 0 else 0


def pivoted_rows(A: np.ndarray, count: int) -> list[int]:
    """`count` rows of A picked as QR with column pivoting of Aᵀ would
    (Golub & Van Loan 2013, §5.4.2: at each step the row whose part
    orthogonal to those already picked is longest), but with ties (within
    TIE) going to the first row, so the pick is the same on any machine."""
    R = np.array(A, dtype=float)
    picked: list[int] = []
    for _ in range(count):
        norms = np.sqrt(np.einsum("ij,ij->i", R, R))
        norms[picked] = -1.0
        k = int(np.flatnonzero(norms >= (1 - TIE) * norms.max())[0])
        q = R[k] / norms[k]
        R -= np.einsum("ij,j->i", R, q)[:, None] * q
        picked.append(k)
    return picked


def kept_rows(c: Constraints, J: np.ndarray, joint_rank: int) -> tuple[int, ...]:
    """The rows the square solves keep at a pose whose scaled Jacobian is
    J: `joint_rank` joint rows by `pivoted_rows` (the best-conditioned
    set), then each drive row that adds to the rank."""
    joint_rows = [k for k, r in enumerate(c.rows) if r.kind != "drive"]
    keep = sorted(joint_rows[k] for k in pivoted_rows(J[joint_rows], joint_rank)) if joint_rows else []
    for k, r in enumerate(c.rows):
        if r.kind == "drive" and _rank(J[keep + [k]]) > len(keep):
            keep.append(k)
    return tuple(keep)


def structure(c: Constraints, scaling: Scaling, pose: Pose) -> Structure:
    """Rank of the joints' rows and of all rows at the assembled pose
    (one instant), and the independent rows (`kept_rows`), the joints'
    rows before the drives'."""
    J = scaling.jacobian(c.evaluate(pose, np.zeros(1))["jac"][0])
    joint_rows = [k for k, r in enumerate(c.rows) if r.kind != "drive"]

    rank = _rank
    joint_rank = rank(J[joint_rows])
    total = rank(J)
    keep = kept_rows(c, J, joint_rank)
    n = c.n
    system = c.system
    constrained = {"spherical": 3, "revolute": 5, "universal": 4, "cylindrical": 4, "prismatic": 5, "planar": 3,
                   "fixed": 6}
    grubler = 6 * len(system.bodies) - sum(constrained[j.kind] for j in system.joints)
    return Structure(grubler=grubler, mobility=n - joint_rank, rank=total, rows=c.m,
                     redundant=len(joint_rows) - joint_rank, independent=keep)
