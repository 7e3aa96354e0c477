"""The batch's positions, one instant at a time in compiled code: the
kept rows' Jacobian at the prediction, its LU and condition (are these
rows poor there?), then chord Newton to the fixed point, exactly as
`structure.newton` does for a batch with the same LU (fresh every CHORD
iterations, the same `settled` test), and the closing residual.

Numpy's version of the same steps passes every (N, m, n) array through
memory several times; here each instant's Jacobian and factors stay in
the cache. The continuation's nodes and the assembly keep
`structure.newton` (one instant, or least squares).
"""

from __future__ import annotations

import numba
import numpy as np

from mechval.reference.spatial.assembly import instant, workspace
from mechval.reference.spatial.lu import _factor, _inverse_norm, _solve_one

#: exp_map's switch to its series (`rotation.exp_map`).
SERIES = 1e-4


@numba.njit(cache=True, nogil=True)
def _turn(phi, A, R, out):
    """A ← exp(φ̃)·A by Rodrigues' formula, as `rotation.exp_map`."""
    angle2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    angle = np.sqrt(angle2)
    if angle < SERIES:
        a = 1 - angle2 / 6 + angle2 * angle2 / 120
        b = 0.5 - angle2 / 24 + angle2 * angle2 / 720
    else:
        a = np.sin(angle) / angle
        b = (1 - np.cos(angle)) / (angle * angle)
    K = np.zeros((3, 3))
    K[0, 1], K[0, 2], K[1, 0], K[1, 2], K[2, 0], K[2, 1] = -phi[2], phi[1], phi[2], -phi[0], -phi[1], phi[0]
    for r in range(3):
        for c in range(3):
            KK = K[r, 0] * K[0, c] + K[r, 1] * K[1, c] + K[r, 2] * K[2, c]
            R[r, c] = (1.0 if r == c else 0.0) + a * K[r, c] + b * KK
    for r in range(3):
        for c in range(3):
            out[r, c] = R[r, 0] * A[0, c] + R[r, 1] * A[1, c] + R[r, 2] * A[2, c]
    A[:] = out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def positions(G, A, law, body, arm, frame, shape, joint, first, second, rows, row_all, column, repick, chord,
              iterations, rounding, stagnation):
    """Newton from predicted poses G (N, nb, 3), A (N, nb, 3, 3) (copies
    returned solved), with the kept `rows`; the row scales of all rows
    (row_all) and the column scales. Returns G, A, poor (condition at the
    prediction above `repick`, or singular), done, and each instant's
    closing residual (scaled, every row)."""
    N, nb = G.shape[0], G.shape[1]
    m, n = len(shape), 6 * nb
    G, A = G.copy(), A.copy()
    poor, done, residual = np.zeros(N, np.bool_), np.zeros(N, np.bool_), np.full(N, np.inf)
    work = workspace(len(body))
    phi, rhs, gamma = np.empty(m), np.empty(m), np.empty(m)
    jac = np.empty((m, n))
    lu, piv = np.empty((1, n, n)), np.empty((1, n), np.int64)
    rest, dq, X = np.zeros((nb, 6)), np.empty(n), np.empty((n, n))
    row = row_all[rows]
    R, out = np.empty((3, 3)), np.empty((3, 3))
    for i in range(N):
        previous = np.inf
        for it in range(iterations):
            fresh = it % chord == 0
            if fresh:
                jac[:] = 0.0
            instant(G[i], A[i], rest, law[i], body, arm, frame, shape, joint, first, second, fresh, False,
                    phi, jac, rhs, gamma, work)
            if fresh:
                for a in range(n):
                    lu[0, a] = jac[rows[a]]
                norm = 0.0
                if it == 0:
                    for c in range(n):
                        s = 0.0
                        for a in range(n):
                            s += abs(lu[0, a, c] * row[a] * column[c])
                        norm = max(norm, s)
                if not _factor(lu, piv):
                    poor[i] = True
                    break
                if it == 0:
                    poor[i] = norm * _inverse_norm(lu[0], piv[0], row, column, X) > repick
                previous = np.inf          # the rate estimate starts over
            for a in range(n):
                dq[a] = -phi[rows[a]]
            _solve_one(lu[0], piv[0], dq)
            size = 0.0
            for a in range(n):
                size = max(size, abs(dq[a] / column[a]))
            for b in range(nb):
                for r in range(3):
                    G[i, b, r] += dq[6 * b + r]
                _turn(dq[6 * b + 3:6 * b + 6], A[i, b], R, out)
            # `structure.settled`
            quadratic = size * size / previous <= 0.1 * rounding
            if size <= rounding or (size >= 0.5 * previous and size <= stagnation) or \
                    (quadratic and size < previous and np.isfinite(previous)):
                done[i] = True
                break
            previous = size
        instant(G[i], A[i], rest, law[i], body, arm, frame, shape, joint, first, second, False, False,
                phi, jac, rhs, gamma, work)
        worst = 0.0
        for r in range(m):
            worst = max(worst, abs(phi[r] * row_all[r]))
        residual[i] = worst
    return G, A, poor, done, residual
