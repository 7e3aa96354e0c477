"""Small linear-algebra pieces the general reference shares: when an
iteration has settled, stacked small inverses, and one-instant solves.
"""

from __future__ import annotations

import numpy as np


#: A Newton iteration has reached its fixed point when its step is within
#: rounding of the iterate (`ROUNDING`·its largest scaled component), or
#: when the step no longer halves (the noise floor of the residual,
#: cond·eps) while below `STAGNATION`.
ROUNDING = 8 * np.finfo(float).eps
STAGNATION = 1e-11


def settled(step: np.ndarray, previous: np.ndarray, floor: np.ndarray | float) -> np.ndarray:
    """Per instant: has the iteration reached its fixed point? (relative
    step sizes of this and the previous iteration, and the rounding floor)."""
    return (step <= floor) | ((step >= 0.5 * previous) & (step <= STAGNATION))


# The tree elimination's stacked matrices keep the instants on the last
# axis, (k, l, instants): each entry is then one contiguous vector, which
# numpy's element-wise loops and reductions over the leading axes run fast.

def matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A·x per instant: A (k, l, instants), x (l, instants)."""
    return np.einsum("ijt,jt->it", A, x)


def inverse(A: np.ndarray) -> np.ndarray:
    """Inverses of stacked square matrices (k, k, instants). Up to 3×3 by
    the adjugate over the determinant, written out entry by entry: over a
    million instants several times faster than LAPACK's per-matrix call,
    and as accurate for the well-conditioned matrices solved here (a
    singular or near-singular instant is refused by its condition number).
    Raises numpy's LinAlgError where a determinant is exactly zero."""
    k = A.shape[0]
    if k > 3:
        return np.linalg.inv(A.transpose(2, 0, 1)).transpose(1, 2, 0)
    if k == 1:
        det = A[0, 0]
        adjugate = np.ones_like(A)
    elif k == 2:
        a, b, c, d = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
        det = a * d - b * c
        adjugate = np.array([[d, -b], [-c, a]])
    else:
        (a, b, c), (d, e, f), (g, h, i) = A
        co = [e * i - f * h, f * g - d * i, d * h - e * g]          # cofactors of the first row
        det = a * co[0] + b * co[1] + c * co[2]
        adjugate = np.array([[co[0], c * h - b * i, b * f - c * e],
                             [co[1], a * i - c * g, c * d - a * f],
                             [co[2], b * g - a * h, a * e - b * d]])
    if np.any(det == 0):
        raise np.linalg.LinAlgError("singular matrix")
    return adjugate / det


def norm_inf(A: np.ndarray) -> np.ndarray:
    """∞-norm (largest absolute row sum) per instant of A (k, l, instants)."""
    return np.abs(A).sum(axis=1).max(axis=0)


def last_max(x: np.ndarray) -> np.ndarray:
    """x.max(axis=-1) for (instants, k): a loop over the short last axis,
    which numpy reduces slowly and runs element-wise operations along fast
    (for a few instants, numpy's reduction, with fewer calls)."""
    if len(x) < 64:
        return x.max(axis=-1)
    out = x[..., 0].copy()
    for j in range(1, x.shape[-1]):
        np.maximum(out, x[..., j], out=out)
    return out


def solve_one(J: np.ndarray, r: np.ndarray, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """J·x = r at one instant (J (m, n)), exactly (square) or in the
    least-squares sense (redundant: consistent, so exactly too), scaled."""
    Js = J * row[:, None] * col[None, :]
    if Js.shape[0] == Js.shape[1]:
        return col * np.linalg.solve(Js, row * r)
    return col * np.linalg.lstsq(Js, row * r, rcond=None)[0]
