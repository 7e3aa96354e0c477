"""Velocities and accelerations at solved positions, one instant at a time
in compiled code: the rows' Jacobian and −Φt, the kept rows' LU, then
Φq·w = −Φt, γ(w), Φq·ẇ = γ, and the exact 1-norm condition from the
same factors (`solver.rates` adds the multipliers, whose right-hand side
needs the applied forces).

Each instant's work stays in the cache; only the Jacobian (for the
reactions) and the factors (for the multipliers' transposed solve) are
written out.
"""

from __future__ import annotations

import numba
import numpy as np

from mechval.reference.spatial.assembly import instant, workspace
from mechval.reference.spatial.lu import _factor, _inverse_norm, _solve_one


@numba.njit(cache=True, nogil=True)
def velocities(G, A, law, body, arm, frame, shape, joint, first, second, rows, row_all, column):
    """Returns Φq (N, m, n), the kept rows' LU and pivots (N, n, n), (N, n),
    w and ẇ (N, n), the scaled condition (N,) and whether every LU is regular."""
    N, nb = G.shape[0], G.shape[1]
    m, n = len(shape), 6 * nb
    jac = np.zeros((N, m, n))
    lu, piv = np.empty((N, n, n)), np.empty((N, n), np.int64)
    w, dw, condition = np.empty((N, n)), np.empty((N, n)), np.empty(N)
    work = workspace(len(body))
    phi, rhs, gamma = np.empty(m), np.empty(m), np.empty(m)
    rest, none, X = np.zeros((nb, 6)), np.empty((0, 0)), np.empty((n, n))
    row = row_all[rows]
    regular = True
    for i in range(N):
        rhs[:] = 0.0
        instant(G[i], A[i], rest, law[i], body, arm, frame, shape, joint, first, second, True, False,
                phi, jac[i], rhs, gamma, work)
        norm = 0.0
        for a in range(n):
            lu[i, a] = jac[i, rows[a]]
        for c in range(n):
            s = 0.0
            for a in range(n):
                s += abs(lu[i, a, c] * row[a] * column[c])
            norm = max(norm, s)
        if not _factor(lu[i:i + 1], piv[i:i + 1]):
            regular = False
            continue
        for a in range(n):
            w[i, a] = rhs[rows[a]]
        _solve_one(lu[i], piv[i], w[i])
        instant(G[i], A[i], w[i].reshape((nb, 6)), law[i], body, arm, frame, shape, joint, first, second, False,
                True, phi, none, rhs, gamma, work)
        for a in range(n):
            dw[i, a] = gamma[rows[a]]
        _solve_one(lu[i], piv[i], dw[i])
        condition[i] = norm * _inverse_norm(lu[i], piv[i], row, column, X)
    return jac, lu, piv, w, dw, condition, regular
