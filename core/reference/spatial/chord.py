"""The batch's positions and rates, instant after instant in compiled
code: Newton exactly as `structure.newton` iterates (the same CHORD
refresh and `settled` test) from a prediction that is the previous
instant's second-order Taylor step where the instant follows it
(at a batch's spacing, within rounding of the solution), the
continuation's otherwise. The first step factorises the Jacobian at the
prediction; where that step is of rounding size its factors and
condition are the solution's (they differ from those at the solution by
rounding), so the instant costs one Jacobian, one LU and one condition,
and γ once more at the solution; else Newton goes on and `motion.solved`
computes them again at the solution. No (N, m, n) array passes through
memory between the steps. The continuation's nodes and the assembly
keep `structure.newton` (one instant, or least squares).
"""
from __future__ import annotations

import numpy as np

from mechval.reference.spatial.assembly import NO, instant
from mechval.reference.spatial.kernel import kernel
from mechval.reference.spatial.lu import _factor, _inverse_norm, _solve_one, norm1
from mechval.reference.spatial.motion import factorise, rates_at, solved, workspace_of

#: exp_map's switch to its series (`rotation.exp_map`).
SERIES = 1e-4


@kernel
def _turn(p0, p1, p2, A, i, b, K, R):
    """A[i, b] ← exp(φ̃)·A[i, b], φ = (p0, p1, p2), by Rodrigues' formula,
    as `rotation.exp_map`; K, R (3, 3) scratch (indexed, not sliced:
    see `assembly._vectors`)."""
    angle2 = p0 * p0 + p1 * p1 + p2 * p2
    angle = np.sqrt(angle2)
    if angle < SERIES:
        a = 1 - angle2 / 6 + angle2 * angle2 / 120
        c = 0.5 - angle2 / 24 + angle2 * angle2 / 720
    else:
        a = np.sin(angle) / angle
        c = (1 - np.cos(angle)) / (angle * angle)
    K[0, 0], K[0, 1], K[0, 2] = 0.0, -p2, p1
    K[1, 0], K[1, 1], K[1, 2] = p2, 0.0, -p0
    K[2, 0], K[2, 1], K[2, 2] = -p1, p0, 0.0
    for r in range(3):
        for q in range(3):
            KK = K[r, 0] * K[0, q] + K[r, 1] * K[1, q] + K[r, 2] * K[2, q]
            R[r, q] = (1.0 if r == q else 0.0) + a * K[r, q] + c * KK
    for q in range(3):
        x0, x1, x2 = A[i, b, 0, q], A[i, b, 1, q], A[i, b, 2, q]
        for r in range(3):
            A[i, b, r, q] = R[r, 0] * x0 + R[r, 1] * x1 + R[r, 2] * x2


@kernel
def _taylor(G0, A0, w, dw, k, dt, G, A, i, K, R):
    """G[i], A[i] ← the second-order Taylor step over dt from pose k of
    G0, A0 with its rates w, ẇ (k, n), rotations on the group
    (`solver.predict`)."""
    for b in range(G.shape[1]):
        for r in range(3):
            G[i, b, r] = G0[k, b, r] + w[k, 6 * b + r] * dt + 0.5 * dw[k, 6 * b + r] * dt * dt
            for q in range(3):
                A[i, b, r, q] = A0[k, b, r, q]
        _turn(w[k, 6 * b + 3] * dt + 0.5 * dw[k, 6 * b + 3] * dt * dt,
              w[k, 6 * b + 4] * dt + 0.5 * dw[k, 6 * b + 4] * dt * dt,
              w[k, 6 * b + 5] * dt + 0.5 * dw[k, 6 * b + 5] * dt * dt, A, i, b, K, R)


@kernel
def _advance(G, A, w, dw, i, dt, K, R):
    """Instant i's poses from instant i − 1's (`_taylor`), each rotation
    then made orthogonal again by a Newton–Schulz step A ← (3A − A·Aᵀ·A)/2
    (Higham 2008, §8.3): carried from instant to instant, a rotation's
    rounding would otherwise walk away from the group, and Newton, which
    moves bodies only along it, could not close the rows below that
    (tests/test_spatial_rows.py measures it)."""
    _taylor(G, A, w, dw, i - 1, dt, G, A, i, K, R)
    for b in range(G.shape[1]):
        for r in range(3):          # R = A·Aᵀ, K = R·A
            for q in range(3):
                R[r, q] = A[i, b, r, 0] * A[i, b, q, 0] + A[i, b, r, 1] * A[i, b, q, 1] + A[i, b, r, 2] * A[i, b, q, 2]
        for r in range(3):
            for q in range(3):
                K[r, q] = R[r, 0] * A[i, b, 0, q] + R[r, 1] * A[i, b, 1, q] + R[r, 2] * A[i, b, 2, q]
        for r in range(3):
            for q in range(3):
                A[i, b, r, q] = 1.5 * A[i, b, r, q] - 0.5 * K[r, q]


@kernel
def _row_dot(A, i, b, r, P, q):
    """Row r of A[i, b] · row q of P[0, b]: (A·Pᵀ)[r, q]."""
    return A[i, b, r, 0] * P[0, b, q, 0] + A[i, b, r, 1] * P[0, b, q, 1] + A[i, b, r, 2] * P[0, b, q, 2]


@kernel
def _jump(G, A, i, PG, PA, column):
    """The largest scaled component of (δG, δπ) from PG[0], PA[0] to
    G[i], A[i], δπ the small rotation A·PAᵀ (`solver.flat_difference`)."""
    worst = 0.0
    for b in range(G.shape[1]):
        for r in range(3):
            worst = max(worst, abs((G[i, b, r] - PG[0, b, r]) / column[6 * b + r]))
        d0 = 0.5 * (_row_dot(A, i, b, 2, PA, 1) - _row_dot(A, i, b, 1, PA, 2))
        d1 = 0.5 * (_row_dot(A, i, b, 0, PA, 2) - _row_dot(A, i, b, 2, PA, 0))
        d2 = 0.5 * (_row_dot(A, i, b, 1, PA, 0) - _row_dot(A, i, b, 0, PA, 1))
        worst = max(worst, abs(d0 / column[6 * b + 3]))
        worst = max(worst, abs(d1 / column[6 * b + 4]))
        worst = max(worst, abs(d2 / column[6 * b + 5]))
    return worst


@kernel
def march(node_G, node_A, node_w, node_dw, node_t, which, t, law, body, arm, frame, shape, joint, first, second, rows,
          row_all, column, follows, repick, chord, iterations, rounding, stagnation, jac, lu):
    """Newton at instants t, instant after instant, with the kept `rows`;
    row_all, column: the scales. An instant starts from the continuation's
    prediction (node which[i] of node_G (K, nb, 3), node_A (K, nb, 3, 3),
    their rates node_w, node_dw (K, n) at node_t) unless it `follows` the
    one before in the run: then from that one's Taylor step (and from the
    node's where Newton fails from there). Returns the solved G (N, nb,
    3), A (N, nb, 3, 3); poor (the rows' condition at the start or at the
    solution above `repick`, or singular); done; each closing residual
    (scaled, every row); each solution's scaled distance from the node's
    prediction (a jump off the branch); and `motion.velocities`' outputs
    at the solutions, the Jacobians and factors into the first N of `jac`
    (≥ N, m, n) and `lu` (≥ N, n, n): the caller's, reused batch after
    batch (fresh arrays of that size cost their pages' faults every
    batch)."""
    N, nb = len(t), node_G.shape[1]
    m, n = len(shape), 6 * nb
    G, A = np.empty((N, nb, 3)), np.empty((N, nb, 3, 3))
    PG, PA = np.empty((1, nb, 3)), np.empty((1, nb, 3, 3))
    poor, done, residual = np.zeros(N, np.bool_), np.zeros(N, np.bool_), np.full(N, np.inf)
    jump = np.zeros(N)
    jac, lu, piv = jac[:N], lu[:N], np.empty((N, n), np.int64)
    w, dw, condition = np.zeros((N, n)), np.zeros((N, n)), np.full(N, np.inf)
    scratch = workspace_of(len(body), m, n)
    work, phi, rhs, gamma, rest, none, X = scratch
    chord_lu, chord_piv, newton_jac = np.empty((1, n, n)), np.empty((1, n), np.int64), np.empty((m, n))
    dq, K, R = np.empty(n), np.empty((3, 3)), np.empty((3, 3))
    row = row_all[rows]
    have, quick = False, False
    i, retried = 0, False
    while i < N:
        have = have and follows[i]
        _taylor(node_G, node_A, node_w, node_dw, which[i], t[i] - node_t[which[i]], PG, PA, 0, K, R)   # the node's
        if have:
            _advance(G, A, w, dw, i, t[i] - t[i - 1], K, R)
        else:
            G[i], A[i] = PG[0], PA[0]
        # Where the instant before settled at its first step, this one's
        # prediction is as close: its first step factorises the Jacobian at
        # the prediction, kept as the solution's if that step is of
        # rounding size. Else (instants far apart) the chord matrix is the
        # instant before's LU at its solution, or a fresh one.
        own = have and quick
        previous, norm = np.inf, np.inf
        first_step = False
        for it in range(iterations):
            if it == 0 and own:
                norm = factorise(G[i], A[i], law[i], body, arm, frame, shape, joint, first, second, rows, row,
                                 column, jac[i], lu[i:i + 1], piv[i:i + 1], scratch)
                if not np.isfinite(norm):
                    poor[i] = True
                    break
            else:
                if it == 1 and own:       # Newton goes on: the chord matrix is the first step's
                    chord_lu[:] = lu[i:i + 1]
                    chord_piv[:] = piv[i:i + 1]
                fresh = it % chord == 0 and not (it == 0 and have)
                if fresh:
                    newton_jac[:] = 0.0
                instant(G[i], A[i], rest, law[i], body, arm, frame, shape, joint, first, second, fresh, NO[0],
                        phi, newton_jac, rhs, gamma, work)
                if fresh:
                    for a in range(n):
                        for q in range(n):
                            chord_lu[0, a, q] = newton_jac[rows[a], q]
                    norm = norm1(chord_lu[0], row, column, dq)      # dq: scratch until solved for
                    if not _factor(chord_lu, chord_piv):
                        poor[i] = True
                        break
                    if it == 0:
                        poor[i] = norm * _inverse_norm(chord_lu[0], chord_piv[0], row, column, X) > repick
                    previous = np.inf          # the rate estimate starts over
                elif it == 0:
                    poor[i] = condition[i - 1] > repick
            for a in range(n):
                dq[a] = -phi[rows[a]]
            if it == 0 and own:
                _solve_one(lu[i], piv[i], dq)
            else:
                _solve_one(chord_lu[0], chord_piv[0], dq)
            size = 0.0
            for a in range(n):
                size = max(size, abs(dq[a] / column[a]))
            for b in range(nb):
                for r in range(3):
                    G[i, b, r] += dq[6 * b + r]
                _turn(dq[6 * b + 3], dq[6 * b + 4], dq[6 * b + 5], A, i, b, K, R)
            # `structure.settled`
            quadratic = size * size / previous <= 0.1 * rounding
            if size <= rounding or (size >= 0.5 * previous and size <= stagnation) or \
                    (quadratic and size < previous and np.isfinite(previous)):
                done[i] = True
                first_step = it == 0
                break
            previous = size
        if not done[i] and have and not retried:
            have, quick, retried, poor[i] = False, False, True, False
            continue
        retried = False
        if done[i] and first_step and own:
            # settled by the first step, the size of rounding: the factors
            # at the prediction are those at the solution to rounding
            condition[i] = norm * _inverse_norm(lu[i], piv[i], row, column, X)
            poor[i] = condition[i] > repick
            rates_at(G[i], A[i], law[i], body, arm, frame, shape, joint, first, second, rows, lu[i:i + 1],
                     piv[i:i + 1], w[i], dw[i], scratch)
        elif done[i]:
            condition[i] = solved(G[i], A[i], law[i], body, arm, frame, shape, joint, first, second, rows, row,
                                  column, jac[i], lu[i:i + 1], piv[i:i + 1], w[i], dw[i], scratch)
            poor[i] = poor[i] or condition[i] > repick
            if np.isfinite(condition[i]):
                chord_lu[:] = lu[i:i + 1]
                chord_piv[:] = piv[i:i + 1]
        else:
            condition[i] = np.inf
            instant(G[i], A[i], rest, law[i], body, arm, frame, shape, joint, first, second, NO[0], NO[0],
                    phi, none, rhs, gamma, work)
        have = done[i] and np.isfinite(condition[i])
        quick = have and first_step
        jump[i] = _jump(G, A, i, PG, PA, column)
        worst = 0.0
        for r in range(m):
            worst = max(worst, abs(phi[r] * row_all[r]))
        residual[i] = worst
        i += 1
    return G, A, poor, done, residual, jump, jac, lu, piv, w, dw, condition
