"""Rotations of many instants at once: skew matrices, the exponential map
(Rodrigues' formula) that updates a rotation matrix on the group, and
unit quaternions (Euler parameters) for output and integration.

A body's attitude is its rotation matrix A (body axes to world axes),
never angles: no parametrisation with singular points. A small rotation
δπ (a world-axes rotation vector) moves A to exp(δπ̃)·A (Shabana,
*Dynamics of Multibody Systems*, 2005, §2.4; Murray, Li & Sastry 1994,
§2.2). Arrays carry the instants first: vectors (..., 3), matrices
(..., 3, 3), quaternions (..., 4) as (w, x, y, z).
"""

from __future__ import annotations

import numpy as np


def skew(v: np.ndarray) -> np.ndarray:
    """ṽ with ṽ·x = v × x, shape (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b over the last axis (numpy's cross moves axes about: several
    times slower on the short arrays of one instant)."""
    out = np.empty(np.broadcast_shapes(np.shape(a), np.shape(b)))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def exp_map(phi: np.ndarray) -> np.ndarray:
    """exp(φ̃): the rotation by |φ| about φ/|φ| (Rodrigues), accurate to
    rounding for small φ too (the series of sin x/x and (1 − cos x)/x²)."""
    phi = np.asarray(phi, dtype=float)
    angle2 = np.einsum("...i,...i->...", phi, phi)
    angle = np.sqrt(angle2)
    small = angle < 1e-4
    safe = np.where(small, 1.0, angle)
    a = np.where(small, 1 - angle2 / 6 + angle2 * angle2 / 120, np.sin(safe) / safe)
    b = np.where(small, 0.5 - angle2 / 24 + angle2 * angle2 / 720, (1 - np.cos(safe)) / (safe * safe))
    K = skew(phi)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def orthonormalised(A: np.ndarray) -> np.ndarray:
    """The rotation nearest A (its polar factor): rounding does not
    accumulate over many group updates."""
    u, _, vt = np.linalg.svd(A)
    return u @ vt


def quaternion_to_matrix(p: np.ndarray) -> np.ndarray:
    """A(p) of a quaternion (w, x, y, z), normalised first (Haug 1989, eq. 6.3.10)."""
    p = np.asarray(p, dtype=float)
    p = p / np.linalg.norm(p, axis=-1, keepdims=True)
    w, x, y, z = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    A = np.empty(p.shape[:-1] + (3, 3))
    A[..., 0, 0], A[..., 0, 1], A[..., 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    A[..., 1, 0], A[..., 1, 1], A[..., 1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    A[..., 2, 0], A[..., 2, 1], A[..., 2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    return A


def matrix_to_quaternion(A: np.ndarray) -> np.ndarray:
    """The unit quaternion (w ≥ 0) of rotation matrices, by the largest of
    the four diagonal combinations (Shepperd 1978), stable everywhere."""
    A = np.asarray(A, dtype=float)
    trace = A[..., 0, 0] + A[..., 1, 1] + A[..., 2, 2]
    candidates = np.stack([trace, A[..., 0, 0], A[..., 1, 1], A[..., 2, 2]], axis=-1)
    pick = np.argmax(candidates, axis=-1)
    q = np.empty(A.shape[:-2] + (4,))
    d = lambda i, j: A[..., i, j]   # noqa: E731
    forms = [
        (1 + trace, d(2, 1) - d(1, 2), d(0, 2) - d(2, 0), d(1, 0) - d(0, 1)),
        (d(2, 1) - d(1, 2), 1 + 2 * d(0, 0) - trace, d(0, 1) + d(1, 0), d(0, 2) + d(2, 0)),
        (d(0, 2) - d(2, 0), d(0, 1) + d(1, 0), 1 + 2 * d(1, 1) - trace, d(1, 2) + d(2, 1)),
        (d(1, 0) - d(0, 1), d(0, 2) + d(2, 0), d(1, 2) + d(2, 1), 1 + 2 * d(2, 2) - trace),
    ]
    for k, form in enumerate(forms):
        mask = pick == k
        if mask.any():
            vec = np.stack([np.asarray(c)[mask] if np.ndim(c) else np.broadcast_to(c, mask.shape)[mask]
                            for c in form], axis=-1)
            q[mask] = vec / (2 * np.sqrt(vec[..., k]))[..., None]
    return q * np.where(q[..., :1] < 0, -1.0, 1.0)


def quaternion_rate(p: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """ṗ = ½·(0, ω) ⊗ p for the world angular velocity ω (Haug 1989, eq. 6.3.23)."""
    w, v = p[..., :1], p[..., 1:]
    scalar = -np.einsum("...i,...i->...", omega, v)[..., None]
    vector = w * omega + cross(omega, v)
    return 0.5 * np.concatenate([scalar, vector], axis=-1)


def frame_from_axis(axis, reference=None, key: str = "axis") -> np.ndarray:
    """A rotation whose z column is `axis` (normalised) and whose x column
    is `reference` made orthogonal to it (any perpendicular if None).
    Raises ValueError naming `key` for a degenerate axis or reference."""
    z = np.asarray(axis, dtype=float)
    if z.shape != (3,) or not np.isfinite(z).all() or np.linalg.norm(z) < 1e-9:
        raise ValueError(f"{key}: a degenerate axis {tuple(np.ravel(z))} (needs three finite components, not all zero)")
    z = z / np.linalg.norm(z)
    if reference is None:
        reference = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = np.asarray(reference, dtype=float)
    x = x - (x @ z) * z
    if x.shape != (3,) or not np.isfinite(x).all() or np.linalg.norm(x) < 1e-9:
        raise ValueError(f"{key}: the reference direction {tuple(np.ravel(reference))} is parallel to the axis")
    x = x / np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])
