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

import numpy as np

from mechval.reference.spatial.assembly import NO, YES, instant, workspace
from mechval.reference.spatial.kernel import kernel
from mechval.reference.spatial.lu import _factor, _inverse_norm, _solve_one, norm1


@kernel
def factorise(G, A, law, body, arm, frame, shape, joint, first, second, rows, row, column, jac, lu, piv, scratch):
    """At one pose: Φ, −Φt into scratch's phi, rhs; Φq into jac (m, n),
    zeroed here; the kept rows' LU into lu (1, n, n), piv (1, n). Returns
    their scaled 1-norm (inf where the LU is singular)."""
    work, phi, rhs, gamma, rest, none, X = scratch
    n = len(rows)
    jac[:] = 0.0
    rhs[:] = 0.0
    instant(G, A, rest, law, body, arm, frame, shape, joint, first, second, YES[0], NO[0], phi, jac, rhs, gamma, work)
    for a in range(n):
        for q in range(n):
            lu[0, a, q] = jac[rows[a], q]
    norm = norm1(lu[0], row, column, X[0])      # X: scratch until the condition
    return norm if _factor(lu, piv) else np.inf


@kernel
def rates_at(G, A, law, body, arm, frame, shape, joint, first, second, rows, lu, piv, w, dw, scratch):
    """w, ẇ (n,) at the pose `factorise` left its factors and −Φt for."""
    work, phi, rhs, gamma, rest, none, X = scratch
    n = len(rows)
    nb = n // 6
    for a in range(n):
        w[a] = rhs[rows[a]]
    _solve_one(lu[0], piv[0], w)
    instant(G, A, w.reshape((nb, 6)), law, body, arm, frame, shape, joint, first, second, NO[0], YES[0],
            phi, none, rhs, gamma, work)
    for a in range(n):
        dw[a] = gamma[rows[a]]
    _solve_one(lu[0], piv[0], dw)


@kernel
def solved(G, A, law, body, arm, frame, shape, joint, first, second, rows, row, column, jac, lu, piv, w, dw,
           scratch):
    """At one solved instant: `factorise`, then `rates_at`; Φ at the pose
    left in scratch's phi; returns the scaled condition (inf where the LU
    is singular). `scratch` from `workspace_of`."""
    norm = factorise(G, A, law, body, arm, frame, shape, joint, first, second, rows, row, column, jac, lu, piv,
                     scratch)
    if not np.isfinite(norm):
        return np.inf
    rates_at(G, A, law, body, arm, frame, shape, joint, first, second, rows, lu, piv, w, dw, scratch)
    return norm * _inverse_norm(lu[0], piv[0], row, column, scratch[6])


@kernel
def workspace_of(joints, m, n):
    """The scratch arrays `solved` uses."""
    return (workspace(joints), np.empty(m), np.empty(m), np.empty(m), np.zeros((n // 6, 6)), np.empty((0, 0)),
            np.empty((n, n)))


@kernel
def velocities(G, A, law, body, arm, frame, shape, joint, first, second, rows, row_all, column):
    """`solved` at N instants: Φq (N, m, n), the kept rows' LU and pivots
    (N, n, n), (N, n), w and ẇ (N, n), the scaled condition (N,) (inf:
    singular)."""
    N, nb = G.shape[0], G.shape[1]
    m, n = len(shape), 6 * nb
    jac = np.empty((N, m, n))
    lu, piv = np.empty((N, n, n)), np.empty((N, n), np.int64)
    w, dw, condition = np.empty((N, n)), np.empty((N, n)), np.empty(N)
    scratch = workspace_of(len(body), m, n)
    row = row_all[rows]
    for i in range(N):
        condition[i] = solved(G[i], A[i], law[i], body, arm, frame, shape, joint, first, second, rows, row, column,
                              jac[i], lu[i:i + 1], piv[i:i + 1], w[i], dw[i], scratch)
    return jac, lu, piv, w, dw, condition
