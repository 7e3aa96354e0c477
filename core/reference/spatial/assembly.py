"""The constraint rows of `mechval.reference.spatial.joints`, evaluated
by one compiled loop over instants and rows: Φ, Φq, −Φt and γ.

The rows are not written here: `joints.Constraints` encodes its row
names (`joints.ROW_NAMES`, e.g. "dx", "xi.zj", "yi.d") as a table of
integers, and this loop only knows the two shapes a row can take (the
module docstring of `joints`): a component of d = Pj − Pi, or the dot
product x·y of two of the seven world vectors a joint carries (its
frames' axes xi … zj and d); and the two drives, revolute
cos φ·(yi·xj) − sin φ·(xi·xj) and prismatic zi·d − φ.

Per vector: its value, rate and bias (rate and bias as
`joints.Constraints`' docstring defines them) and its variation per end
of the joint, a 3 × 6 block [δG | δπ] (zero for the ground).
Compiled as `kernel` says.
"""

from __future__ import annotations

import numpy as np

from mechval.reference.spatial.kernel import kernel

#: Row shapes of the encoded table.
COMPONENT, DOT, REVOLUTE_DRIVE, PRISMATIC_DRIVE = 0, 1, 2, 3
#: Vector slots of a joint: its frames' axes, then d = Pj − Pi.
SLOTS = ("xi", "yi", "zi", "xj", "yj", "zj", "d")
D = 6
#: Flags and slots as elements of global arrays: numba types those as
#: runtime values, where a literal True or 2 in a call compiles the
#: callee once more per value (measured: five copies of `instant`, eight
#: of `_dot`, a cold compile of 37 s of CPU).
NO, YES = np.zeros(1, dtype=np.bool_), np.ones(1, dtype=np.bool_)
SLOT = np.arange(7)


@kernel
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@kernel
def _minus_skew(h0, h1, h2, blocks, j, slot, side, sign):
    """blocks[j, slot, side, :, 3:] = −(sign·h)~ (δ(A·h') = δπ × h = −h̃·δπ)."""
    blocks[j, slot, side, 0, 4], blocks[j, slot, side, 0, 5] = sign * h2, -sign * h1
    blocks[j, slot, side, 1, 3], blocks[j, slot, side, 1, 5] = -sign * h2, sign * h0
    blocks[j, slot, side, 2, 3], blocks[j, slot, side, 2, 4] = sign * h1, -sign * h0


@kernel
def _vectors(G, A, w, j, body, arm, frame, value, rate, bias, blocks, need_blocks, moving):
    """The seven vectors of joint j at one instant (see the module) into
    value[j], rate[j], bias[j], blocks[j]; rates and biases zero unless
    `moving`, blocks only if `need_blocks`. Every array is indexed, never
    sliced: a slice is a view whose reference count numba updates with an
    atomic instruction, which cost a fifth of the batch's time."""
    if need_blocks:
        for slot in range(7):
            for side in range(2):
                for r in range(3):
                    for q in range(6):
                        blocks[j, slot, side, r, q] = 0.0
    for slot in range(7):
        for r in range(3):
            rate[j, slot, r] = 0.0
            bias[j, slot, r] = 0.0
    for r in range(3):
        value[j, D, r] = 0.0
    for side in range(2):
        b = body[j, side]
        sign = 1.0 if side == 1 else -1.0
        for k in range(3):
            slot = 3 * side + k
            if b < 0:
                for r in range(3):
                    value[j, slot, r] = frame[j, side, r, k]
                continue
            for r in range(3):
                value[j, slot, r] = A[b, r, 0] * frame[j, side, 0, k] + A[b, r, 1] * frame[j, side, 1, k] \
                    + A[b, r, 2] * frame[j, side, 2, k]
            h0, h1, h2 = value[j, slot, 0], value[j, slot, 1], value[j, slot, 2]
            if moving:
                r0, r1, r2 = _cross(w[b, 3], w[b, 4], w[b, 5], h0, h1, h2)
                rate[j, slot, 0], rate[j, slot, 1], rate[j, slot, 2] = r0, r1, r2
                bias[j, slot, 0], bias[j, slot, 1], bias[j, slot, 2] = _cross(w[b, 3], w[b, 4], w[b, 5], r0, r1, r2)
            if need_blocks:
                _minus_skew(h0, h1, h2, blocks, j, slot, side, 1.0)
        if b < 0:
            for r in range(3):
                value[j, D, r] += sign * arm[j, side, r]
            continue
        a0 = A[b, 0, 0] * arm[j, side, 0] + A[b, 0, 1] * arm[j, side, 1] + A[b, 0, 2] * arm[j, side, 2]
        a1 = A[b, 1, 0] * arm[j, side, 0] + A[b, 1, 1] * arm[j, side, 1] + A[b, 1, 2] * arm[j, side, 2]
        a2 = A[b, 2, 0] * arm[j, side, 0] + A[b, 2, 1] * arm[j, side, 1] + A[b, 2, 2] * arm[j, side, 2]
        value[j, D, 0] += sign * (G[b, 0] + a0)
        value[j, D, 1] += sign * (G[b, 1] + a1)
        value[j, D, 2] += sign * (G[b, 2] + a2)
        if moving:
            t0, t1, t2 = _cross(w[b, 3], w[b, 4], w[b, 5], a0, a1, a2)
            s0, s1, s2 = _cross(w[b, 3], w[b, 4], w[b, 5], t0, t1, t2)
            rate[j, D, 0] += sign * (w[b, 0] + t0)
            rate[j, D, 1] += sign * (w[b, 1] + t1)
            rate[j, D, 2] += sign * (w[b, 2] + t2)
            bias[j, D, 0] += sign * s0
            bias[j, D, 1] += sign * s1
            bias[j, D, 2] += sign * s2
        if need_blocks:
            for r in range(3):
                blocks[j, D, side, r, r] = sign
            _minus_skew(a0, a1, a2, blocks, j, D, side, sign)


@kernel
def _inner(u, x, v, y, j):
    """u[j, x]·v[j, y] (numba's @ calls BLAS: slower at this size)."""
    return 0.0 + u[j, x, 0] * v[j, y, 0] + u[j, x, 1] * v[j, y, 1] + u[j, x, 2] * v[j, y, 2]


@kernel
def _dot(j, x, y, value, rate, bias, blocks, part, need_blocks):
    """x·y of joint j's slots x, y: its value and γ; its variation per end
    in part (2, 6) if `need_blocks`."""
    for side in range(2 if need_blocks else 0):
        for q in range(6):
            s = 0.0
            for c in range(3):
                s += value[j, y, c] * blocks[j, x, side, c, q] + value[j, x, c] * blocks[j, y, side, c, q]
            part[side, q] = s
    v = _inner(value, x, value, y, j)
    gamma = -(_inner(bias, x, value, y, j) + 2 * _inner(rate, x, rate, y, j) + _inner(value, x, bias, y, j))
    return v, gamma


@kernel
def workspace(joints):
    """Scratch arrays of `instant` for a system of `joints` joints."""
    return (np.empty((joints, 7, 3)), np.empty((joints, 7, 3)), np.empty((joints, 7, 3)),
            np.empty((joints, 7, 2, 3, 6)), np.zeros((2, 6)), np.zeros((2, 6)))


@kernel
def instant(G, A, w, law, body, arm, frame, shape, joint, first, second, jacobian, moving, phi, jac, rhs, gamma,
            work):
    """The rows at one instant into phi, rhs, gamma (m,) and, if
    `jacobian`, added into jac (m, n) (zero it first); arguments as
    `assemble`'s for that instant, `work` from `workspace`."""
    value, rate, bias, blocks, part, other = work
    m = len(shape)
    need_blocks = jacobian or moving       # a revolute drive's γ reads its rows' variations
    for j in range(len(body)):
        _vectors(G, A, w, j, body, arm, frame, value, rate, bias, blocks, need_blocks, moving)
    for r in range(m):
        j = joint[r]
        g = 0.0
        if shape[r] == COMPONENT:
            c = first[r]
            phi[r] = value[j, D, c]
            if need_blocks:
                for side in range(2):
                    for q in range(6):
                        part[side, q] = blocks[j, D, side, c, q]
            g = -bias[j, D, c]
        elif shape[r] == DOT:
            phi[r], g = _dot(j, first[r], second[r], value, rate, bias, blocks, part, need_blocks)
        elif shape[r] == PRISMATIC_DRIVE:
            k = first[r]
            s, g = _dot(j, SLOT[2], SLOT[D], value, rate, bias, blocks, part, need_blocks)
            phi[r] = s - law[k, 0]
            g += law[k, 2]
            rhs[r] = law[k, 1]
        else:
            # f = c·S − s·C, S = yi·xj = sin θ, C = xi·xj = cos θ, c, s = cos φ, sin φ;
            # f̈ = c·S̈ − s·C̈ + 2(ċ·Ṡ − ṡ·Ċ) + c̈·S − s̈·C
            k = first[r]
            angle, speed, acc = law[k, 0], law[k, 1], law[k, 2]
            S, S_gamma = _dot(j, SLOT[1], SLOT[3], value, rate, bias, blocks, other, need_blocks)
            C, C_gamma = _dot(j, SLOT[0], SLOT[3], value, rate, bias, blocks, part, need_blocks)
            cos, sin = np.cos(angle), np.sin(angle)
            S_rate, C_rate = 0.0, 0.0
            for side in range(2):
                b = body[j, side]
                if b >= 0 and moving:
                    s_side, c_side = 0.0, 0.0
                    for q in range(6):
                        s_side += other[side, q] * w[b, q]
                        c_side += part[side, q] * w[b, q]
                    S_rate += s_side
                    C_rate += c_side
            for side in range(2):
                for q in range(6):
                    part[side, q] = cos * other[side, q] - sin * part[side, q]
            dc, ds = -sin * speed, cos * speed
            ddc, dds = -cos * speed ** 2 - sin * acc, -sin * speed ** 2 + cos * acc
            phi[r] = cos * S - sin * C
            g = cos * S_gamma - sin * C_gamma - 2 * (dc * S_rate - ds * C_rate) - ddc * S + dds * C
            rhs[r] = -(dc * S - ds * C)
        gamma[r] = g
        if jacobian:
            for side in range(2):
                b = body[j, side]
                if b >= 0:
                    for q in range(6):
                        jac[r, 6 * b + q] += part[side, q]


@kernel
def assemble(G, A, w, law, body, arm, frame, shape, joint, first, second, jacobian, moving, n):
    """Φ (N, m), Φq (N, m, n) (empty unless `jacobian`), −Φt and γ (N, m);
    `moving` False: w is zero (the vectors' rates and biases are skipped).

    G (N, nb, 3), A (N, nb, 3, 3), w (N, nb, 6); law (N, drives, 3): each
    drive's φ, φ̇, φ̈; per joint body (J, 2) (−1: ground), arm (J, 2, 3),
    frame (J, 2, 3, 3); per row its shape, joint, and first, second: the
    slots of a DOT, the component of a COMPONENT, the drive of a drive.
    """
    N, m = G.shape[0], len(shape)
    phi, rhs, gamma = np.zeros((N, m)), np.zeros((N, m)), np.zeros((N, m))
    jac = np.zeros((N, m, n) if jacobian else (N, 0, 0))
    work = workspace(len(body))
    for i in range(N):
        instant(G[i], A[i], w[i], law[i], body, arm, frame, shape, joint, first, second, jacobian, moving,
                phi[i], jac[i], rhs[i], gamma[i], work)
    return phi, jac, rhs, gamma
