"""A spatial solution's multipliers and raw columns from its poses, rates
and factors, instant by instant in compiled code (as `solver` defines
them; `kernel` says how they compile): each instant's values stay in the
cache, and the columns go straight into the solution's table.

- `multipliers`: λ of the kept rows from M·ẇ + Φqᵀ·λ = Q by the kept
  rows' LU, transposed, with Q's gravity and gyroscopic loads per body
  (`forces`: m·g and −ω × J·ω, J = A·J'·Aᵀ) plus any other applied Q the
  caller passes;
- `motion_columns`: per body `system.MOTION`: its frame origin
  O = G − A·c (c the centre of mass in body axes), the unit quaternion of
  A (w ≥ 0, `rotation.matrix_to_quaternion`), v = Ġ − ω × a,
  ω, G̈ − α × a − ω × (ω × a) (a = A·c), α;
- `reaction_columns`: per joint `system.REACTION` from its rows'
  multipliers, then per drive its effort −λ.
"""

from __future__ import annotations

import numpy as np

from mechval.reference.spatial.kernel import kernel
from mechval.reference.spatial.lu import _solve_transposed_one


@kernel
def _inertia_times(A, i, b, inertia, v0, v1, v2, out, at):
    """out[at:at + 3] = (A·J'·Aᵀ)·v for body b's rotation A[i, b]."""
    # Aᵀ·v, then J'·(Aᵀ·v), then A·(…): J = A·J'·Aᵀ is never formed
    u0 = A[i, b, 0, 0] * v0 + A[i, b, 1, 0] * v1 + A[i, b, 2, 0] * v2
    u1 = A[i, b, 0, 1] * v0 + A[i, b, 1, 1] * v1 + A[i, b, 2, 1] * v2
    u2 = A[i, b, 0, 2] * v0 + A[i, b, 1, 2] * v1 + A[i, b, 2, 2] * v2
    s0 = inertia[b, 0, 0] * u0 + inertia[b, 0, 1] * u1 + inertia[b, 0, 2] * u2
    s1 = inertia[b, 1, 0] * u0 + inertia[b, 1, 1] * u1 + inertia[b, 1, 2] * u2
    s2 = inertia[b, 2, 0] * u0 + inertia[b, 2, 1] * u1 + inertia[b, 2, 2] * u2
    for r in range(3):
        out[at + r] = A[i, b, r, 0] * s0 + A[i, b, r, 1] * s1 + A[i, b, r, 2] * s2


@kernel
def multipliers(lu, piv, A, w, dw, mass, inertia, gravity, applied, rows, lam):
    """lam[i, rows] ← the kept rows' λ at N instants from their LU (lu,
    piv), rotations A (N, nb, 3, 3), rates w, ẇ (N, n), the bodies' mass
    (nb,) and inertia J' (nb, 3, 3) about the centre of mass in body axes,
    gravity (3,), and `applied`: the rest of Q (N, n), or (0, n) for none."""
    N, nb = A.shape[0], A.shape[1]
    n = 6 * nb
    x, inertial = np.empty(n), np.empty(n)
    for i in range(N):
        for b in range(nb):
            k = 6 * b
            for r in range(3):
                x[k + r] = mass[b] * gravity[r] - mass[b] * dw[i, k + r]
            om0, om1, om2 = w[i, k + 3], w[i, k + 4], w[i, k + 5]
            _inertia_times(A, i, b, inertia, om0, om1, om2, inertial, 0)      # J·ω
            _inertia_times(A, i, b, inertia, dw[i, k + 3], dw[i, k + 4], dw[i, k + 5], inertial, 3)   # J·ω̇
            x[k + 3] = -(om1 * inertial[2] - om2 * inertial[1]) - inertial[3]
            x[k + 4] = -(om2 * inertial[0] - om0 * inertial[2]) - inertial[4]
            x[k + 5] = -(om0 * inertial[1] - om1 * inertial[0]) - inertial[5]
        if applied.shape[0]:
            for a in range(n):
                x[a] += applied[i, a]
        _solve_transposed_one(lu[i], piv[i], x)
        for a in range(n):
            lam[i, rows[a]] = x[a]


@kernel
def _quaternion(A, i, b, out, at, k):
    """out[at:at + 4, k] = the unit quaternion (w ≥ 0) of A[i, b] by
    Shepperd's largest diagonal combination (`rotation.matrix_to_quaternion`)."""
    a00, a01, a02 = A[i, b, 0, 0], A[i, b, 0, 1], A[i, b, 0, 2]
    a10, a11, a12 = A[i, b, 1, 0], A[i, b, 1, 1], A[i, b, 1, 2]
    a20, a21, a22 = A[i, b, 2, 0], A[i, b, 2, 1], A[i, b, 2, 2]
    trace = a00 + a11 + a22
    pick, big = 0, trace       # the first largest, as numpy's argmax
    if a00 > big:
        pick, big = 1, a00
    if a11 > big:
        pick, big = 2, a11
    if a22 > big:
        pick = 3
    if pick == 0:
        q0, q1, q2, q3 = 1 + trace, a21 - a12, a02 - a20, a10 - a01
        s = 2 * np.sqrt(q0)
    elif pick == 1:
        q0, q1, q2, q3 = a21 - a12, 1 + 2 * a00 - trace, a01 + a10, a02 + a20
        s = 2 * np.sqrt(q1)
    elif pick == 2:
        q0, q1, q2, q3 = a02 - a20, a01 + a10, 1 + 2 * a11 - trace, a12 + a21
        s = 2 * np.sqrt(q2)
    else:
        q0, q1, q2, q3 = a10 - a01, a02 + a20, a12 + a21, 1 + 2 * a22 - trace
        s = 2 * np.sqrt(q3)
    sign = -1.0 if q0 / s < 0 else 1.0
    out[at, k], out[at + 1, k], out[at + 2, k], out[at + 3, k] = \
        q0 / s * sign, q1 / s * sign, q2 / s * sign, q3 / s * sign


@kernel
def motion_columns(G, A, w, dw, com, out, index):
    """Per body its 19 `system.MOTION` columns into out (19·nb, ≥ N),
    instant i at column index[i], from G (N, nb, 3), A (N, nb, 3, 3),
    w, ẇ (N, n), com (nb, 3)."""
    N, nb = G.shape[0], G.shape[1]
    for i in range(N):
        c = index[i]
        for b in range(nb):
            k, at = 6 * b, 19 * b
            c0, c1, c2 = com[b, 0], com[b, 1], com[b, 2]
            a0 = A[i, b, 0, 0] * c0 + A[i, b, 0, 1] * c1 + A[i, b, 0, 2] * c2       # a = A·c
            a1 = A[i, b, 1, 0] * c0 + A[i, b, 1, 1] * c1 + A[i, b, 1, 2] * c2
            a2 = A[i, b, 2, 0] * c0 + A[i, b, 2, 1] * c1 + A[i, b, 2, 2] * c2
            om0, om1, om2 = w[i, k + 3], w[i, k + 4], w[i, k + 5]
            al0, al1, al2 = dw[i, k + 3], dw[i, k + 4], dw[i, k + 5]
            t0, t1, t2 = om1 * a2 - om2 * a1, om2 * a0 - om0 * a2, om0 * a1 - om1 * a0     # ω × a
            out[at, c], out[at + 1, c], out[at + 2, c] = G[i, b, 0] - a0, G[i, b, 1] - a1, G[i, b, 2] - a2
            _quaternion(A, i, b, out, at + 3, c)
            out[at + 7, c], out[at + 8, c], out[at + 9, c] = w[i, k] - t0, w[i, k + 1] - t1, w[i, k + 2] - t2
            out[at + 10, c], out[at + 11, c], out[at + 12, c] = om0, om1, om2
            out[at + 13, c] = dw[i, k] - (al1 * a2 - al2 * a1) - (om1 * t2 - om2 * t1)
            out[at + 14, c] = dw[i, k + 1] - (al2 * a0 - al0 * a2) - (om2 * t0 - om0 * t2)
            out[at + 15, c] = dw[i, k + 2] - (al0 * a1 - al1 * a0) - (om0 * t1 - om1 * t0)
            out[at + 16, c], out[at + 17, c], out[at + 18, c] = al0, al1, al2


@kernel
def reaction_columns(G, A, jac, lam, ends, arms, starts, stops, drives, out, index):
    """Per joint its 6 `system.REACTION` columns, then per drive its effort
    −λ, into out (6·joints + drives, ≥ N), instant i at column index[i]:
    the load −Φqᵀ·λ of the joint's rows (starts[j] to stops[j]) on body_j
    (ends[j, 1]), or the opposite of
    the one on body_i (ends[j, 0]) where body_j is the ground, its moment
    taken about Pj (body_j's point arms[j, 1] from its centre of mass, or
    a world point on the ground)."""
    N = G.shape[0]
    load = np.empty(6)
    for i in range(N):
        c = index[i]
        for j in range(len(starts)):
            body, sign = ends[j, 1], 1.0
            if body < 0:
                body, sign = ends[j, 0], -1.0
            for q in range(6):
                s = 0.0
                for r in range(starts[j], stops[j]):
                    s += jac[i, r, 6 * body + q] * lam[i, r]
                load[q] = sign * -s
            s0, s1, s2 = arms[j, 1, 0], arms[j, 1, 1], arms[j, 1, 2]
            bj = ends[j, 1]
            if bj >= 0:      # Pj − G of the loaded body
                d0 = G[i, bj, 0] + A[i, bj, 0, 0] * s0 + A[i, bj, 0, 1] * s1 + A[i, bj, 0, 2] * s2 - G[i, body, 0]
                d1 = G[i, bj, 1] + A[i, bj, 1, 0] * s0 + A[i, bj, 1, 1] * s1 + A[i, bj, 1, 2] * s2 - G[i, body, 1]
                d2 = G[i, bj, 2] + A[i, bj, 2, 0] * s0 + A[i, bj, 2, 1] * s1 + A[i, bj, 2, 2] * s2 - G[i, body, 2]
            else:
                d0, d1, d2 = s0 - G[i, body, 0], s1 - G[i, body, 1], s2 - G[i, body, 2]
            at = 6 * j
            out[at, c], out[at + 1, c], out[at + 2, c] = load[0], load[1], load[2]
            out[at + 3, c] = load[3] - (d1 * load[2] - d2 * load[1])
            out[at + 4, c] = load[4] - (d2 * load[0] - d0 * load[2])
            out[at + 5, c] = load[5] - (d0 * load[1] - d1 * load[0])
        for k in range(len(drives)):
            out[6 * len(starts) + k, c] = -lam[i, drives[k]]
