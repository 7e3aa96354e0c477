"""The batch's positions and rates, instant after instant in compiled
code: chord Newton from the continuation's prediction, exactly as
`structure.newton` iterates (the same CHORD refresh and `settled` test)
but with the previous instant's factors at its solution as the chord
matrix (instants ~1e-5 of a turn apart: as good as a fresh Jacobian at
the prediction, and computed anyway for that instant's rates), then
`motion.solved` at the solution: one Jacobian, one LU and one condition
per instant instead of two of each, and no (N, m, n) array passing
through memory between the steps. The continuation's nodes and the
assembly keep `structure.newton` (one instant, or least squares).
"""
from __future__ import annotations

import numba
import numpy as np

from mechval.reference.spatial.assembly import NO, YES, instant
from mechval.reference.spatial.lu import _factor, _inverse_norm, _solve_one, norm1
from mechval.reference.spatial.motion import solved, workspace_of

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
def march(G, A, law, body, arm, frame, shape, joint, first, second, rows, row_all, column, follows, repick, chord,
          iterations, rounding, stagnation):
    """Newton from predicted poses G (N, nb, 3), A (N, nb, 3, 3), instant
    after instant, with the kept `rows`; row_all, column: the scales. The
    chord matrix of an instant is the LU at the previous instant's
    solution (`motion.solved`, computed there anyway for the rates) where
    the instant `follows` it in the run, else a fresh one at the
    prediction (and afresh from the prediction where Newton fails with
    the previous one); fresh again every `chord` iterations. Returns the solved
    G, A; poor (the rows' condition at the previous solution, or at the
    prediction, or at the instant's own solution above `repick`; or
    singular); done; each closing residual
    (scaled, every row); and `motion.velocities`' outputs at the solutions."""
    N, nb = G.shape[0], G.shape[1]
    m, n = len(shape), 6 * nb
    predicted_G, predicted_A = G, A
    G, A = G.copy(), A.copy()
    poor, done, residual = np.zeros(N, np.bool_), np.zeros(N, np.bool_), np.full(N, np.inf)
    jac, lu, piv = np.empty((N, m, n)), np.empty((N, n, n)), np.empty((N, n), np.int64)
    w, dw, condition = np.zeros((N, n)), np.zeros((N, n)), np.full(N, np.inf)
    scratch = workspace_of(len(body), m, n)
    work, phi, rhs, gamma, rest, none, X = scratch
    chord_lu, chord_piv, newton_jac = np.empty((1, n, n)), np.empty((1, n), np.int64), np.empty((m, n))
    dq, R, out = np.empty(n), np.empty((3, 3)), np.empty((3, 3))
    row = row_all[rows]
    have = False
    i, retried = 0, False
    while i < N:
        have = have and follows[i]
        previous = np.inf
        for it in range(iterations):
            fresh = it % chord == 0 and not (it == 0 and have)
            if fresh:
                newton_jac[:] = 0.0
            instant(G[i], A[i], rest, law[i], body, arm, frame, shape, joint, first, second, fresh, NO[0],
                    phi, newton_jac, rhs, gamma, work)
            if fresh:
                for a in range(n):
                    chord_lu[0, a] = newton_jac[rows[a]]
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
            _solve_one(chord_lu[0], chord_piv[0], dq)
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
        if not done[i] and have and not retried:
            G[i], A[i] = predicted_G[i], predicted_A[i]
            have, retried, poor[i] = False, True, False
            continue
        retried = False
        have = False
        if done[i]:     # the rates; Φ at the solution is left in phi
            condition[i] = solved(G[i], A[i], law[i], body, arm, frame, shape, joint, first, second, rows, row,
                                  column, jac[i], lu[i:i + 1], piv[i:i + 1], w[i], dw[i], scratch)
            poor[i] = poor[i] or condition[i] > repick
            if np.isfinite(condition[i]):
                chord_lu[:] = lu[i:i + 1]
                chord_piv[:] = piv[i:i + 1]
                have = True
        else:
            instant(G[i], A[i], rest, law[i], body, arm, frame, shape, joint, first, second, NO[0], NO[0],
                    phi, none, rhs, gamma, work)
        worst = 0.0
        for r in range(m):
            worst = max(worst, abs(phi[r] * row_all[r]))
        residual[i] = worst
        i += 1
    return G, A, poor, done, residual, jac, lu, piv, w, dw, condition
