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
Compiled with numba (cached beside this module) and releasing the GIL.
"""

from __future__ import annotations

import numba
import numpy as np

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


@numba.njit(cache=True, nogil=True)
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@numba.njit(cache=True, nogil=True)
def _inner(a, b):
    """a·b of short vectors (numba's @ calls BLAS: slower at this size)."""
    s = 0.0
    for k in range(len(a)):
        s += a[k] * b[k]
    return s


@numba.njit(cache=True, nogil=True)
def _minus_skew(h, block, sign):
    """block[:, 3:] = −(sign·h)~ (δ(A·h') = δπ × h = −h̃·δπ)."""
    block[0, 4], block[0, 5] = sign * h[2], -sign * h[1]
    block[1, 3], block[1, 5] = -sign * h[2], sign * h[0]
    block[2, 3], block[2, 4] = sign * h[1], -sign * h[0]


@numba.njit(cache=True, nogil=True)
def _vectors(G, A, w, body, arm, frame, value, rate, bias, blocks, scratch, need_blocks, moving):
    """The seven vectors of one joint at one instant (see the module);
    rates and biases zero unless `moving`, blocks only if `need_blocks`."""
    a, turn, spin = scratch[0], scratch[1], scratch[2]
    if need_blocks:
        blocks[:] = 0.0
    rate[:] = 0.0
    bias[:] = 0.0
    value[D] = 0.0
    for side in range(2):
        b = body[side]
        sign = 1.0 if side == 1 else -1.0
        for k in range(3):
            slot = 3 * side + k
            if b < 0:
                value[slot] = frame[side, :, k]
                continue
            for r in range(3):
                value[slot, r] = A[b, r, 0] * frame[side, 0, k] + A[b, r, 1] * frame[side, 1, k] \
                    + A[b, r, 2] * frame[side, 2, k]
            if moving:
                _cross(w[b, 3:], value[slot], rate[slot])
                _cross(w[b, 3:], rate[slot], bias[slot])
            if need_blocks:
                _minus_skew(value[slot], blocks[slot, side], 1.0)
        if b < 0:
            value[D] += sign * arm[side]
            continue
        for r in range(3):
            a[r] = A[b, r, 0] * arm[side, 0] + A[b, r, 1] * arm[side, 1] + A[b, r, 2] * arm[side, 2]
        for r in range(3):
            value[D, r] += sign * (G[b, r] + a[r])
        if moving:
            _cross(w[b, 3:], a, turn)
            _cross(w[b, 3:], turn, spin)
            for r in range(3):
                rate[D, r] += sign * (w[b, r] + turn[r])
                bias[D, r] += sign * spin[r]
        if need_blocks:
            for r in range(3):
                blocks[D, side, r, r] = sign
            _minus_skew(a, blocks[D, side], sign)


@numba.njit(cache=True, nogil=True)
def _dot(x, y, value, rate, bias, blocks, part, need_blocks):
    """x·y of slots x, y: its value and γ; its variation per end in part
    (2, 6) if `need_blocks`."""
    for side in range(2 if need_blocks else 0):
        for q in range(6):
            s = 0.0
            for c in range(3):
                s += value[y, c] * blocks[x, side, c, q] + value[x, c] * blocks[y, side, c, q]
            part[side, q] = s
    v = _inner(value[x], value[y])
    gamma = -(_inner(bias[x], value[y]) + 2 * _inner(rate[x], rate[y]) + _inner(value[x], bias[y]))
    return v, gamma


@numba.njit(cache=True, nogil=True)
def workspace(joints):
    """Scratch arrays of `instant` for a system of `joints` joints."""
    return (np.empty((joints, 7, 3)), np.empty((joints, 7, 3)), np.empty((joints, 7, 3)),
            np.empty((joints, 7, 2, 3, 6)), np.zeros((2, 6)), np.zeros((2, 6)), np.empty((3, 3)))


@numba.njit(cache=True, nogil=True)
def instant(G, A, w, law, body, arm, frame, shape, joint, first, second, jacobian, moving, phi, jac, rhs, gamma,
            work):
    """The rows at one instant into phi, rhs, gamma (m,) and, if
    `jacobian`, added into jac (m, n) (zero it first); arguments as
    `assemble`'s for that instant, `work` from `workspace`."""
    value, rate, bias, blocks, part, other, scratch = work
    m = len(shape)
    need_blocks = jacobian or moving       # a revolute drive's γ reads its rows' variations
    for j in range(len(body)):
        _vectors(G, A, w, body[j], arm[j], frame[j], value[j], rate[j], bias[j], blocks[j], scratch,
                 need_blocks, moving)
    for r in range(m):
        j = joint[r]
        v, g = value[j], 0.0
        if shape[r] == COMPONENT:
            c = first[r]
            phi[r] = v[D, c]
            if need_blocks:
                part[:] = blocks[j, D, :, c]
            g = -bias[j, D, c]
        elif shape[r] == DOT:
            phi[r], g = _dot(first[r], second[r], v, rate[j], bias[j], blocks[j], part, need_blocks)
        elif shape[r] == PRISMATIC_DRIVE:
            k = first[r]
            s, g = _dot(SLOT[2], SLOT[D], v, rate[j], bias[j], blocks[j], part, need_blocks)
            phi[r] = s - law[k, 0]
            g += law[k, 2]
            rhs[r] = law[k, 1]
        else:
            # f = c·S − s·C, S = yi·xj = sin θ, C = xi·xj = cos θ, c, s = cos φ, sin φ;
            # f̈ = c·S̈ − s·C̈ + 2(ċ·Ṡ − ṡ·Ċ) + c̈·S − s̈·C
            k = first[r]
            angle, speed, acc = law[k, 0], law[k, 1], law[k, 2]
            S, S_gamma = _dot(SLOT[1], SLOT[3], v, rate[j], bias[j], blocks[j], other, need_blocks)
            C, C_gamma = _dot(SLOT[0], SLOT[3], v, rate[j], bias[j], blocks[j], part, need_blocks)
            cos, sin = np.cos(angle), np.sin(angle)
            S_rate, C_rate = 0.0, 0.0
            for side in range(2):
                b = body[j, side]
                if b >= 0 and moving:
                    S_rate += _inner(other[side], w[b])
                    C_rate += _inner(part[side], w[b])
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


@numba.njit(cache=True, nogil=True)
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
