"""Shared pieces of the closed-form loop-closure analysis.

References: R. L. Norton, *Design of Machinery*, 5th ed. (Norton below),
ch. 4 (position), 6 (velocity), 7 (acceleration), complex-number
(vector-loop) method.
"""

from __future__ import annotations

import numpy as np


def solve_loop_rates(p: float, trig_p: tuple, q: float, trig_q: tuple,
                     rx: np.ndarray, ry: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve p·u·j·e^{jθp} − q·v·j·e^{jθq} = rx + j·ry for real u, v.

    The differentiated loop equation of a four-bar is linear in the two
    unknown rates with this matrix (Norton eq. 6.18 for velocities, 7.12 for
    accelerations, where the known terms are moved to the right-hand side);
    Cramer's rule gives
        u = −(rx·cosθq + ry·sinθq) / (p·sin(θp − θq)),
        v = −(rx·cosθp + ry·sinθp) / (q·sin(θp − θq)).
    trig_p, trig_q = (cosθ, sinθ), computed once by the caller.
    """
    (cp, sp), (cq, sq) = trig_p, trig_q
    sin_pq = sp * cq - cp * sq
    u = -(rx * cq + ry * sq) / (p * sin_pq)
    v = -(rx * cp + ry * sp) / (q * sin_pq)
    return u, v


def crank_pin(a: float, theta, omega, alpha) -> tuple:
    """x, y, vx, vy, ax, ay of the crank pin A = a·e^{jθ} of a crank turning
    about the origin: v = a·ω·j·e^{jθ}, acc = a·(α·j − ω²)·e^{jθ} (Norton
    ch. 6, 7). The closed forms keep this order of operations; the general
    rigid-body relations are `mechval.kinematics.point_motion`."""
    c, s = np.cos(theta), np.sin(theta)
    return (a * c, a * s, -a * omega * s, a * omega * c,
            -a * alpha * s - a * omega**2 * c, a * alpha * c - a * omega**2 * s)


def interval_extremes(theta_lo: float, theta_hi: float, fn) -> tuple[float, float]:
    """Exact min and max of fn(θ) ∈ {cos, sin} over [theta_lo, theta_hi].

    The extremes of cos/sin lie at the interval ends or at the interior
    stationary points (multiples of π for cos, π/2 + kπ for sin).
    """
    shift = 0.0 if fn is np.cos else np.pi / 2
    k_lo = np.ceil((theta_lo - shift) / np.pi)
    k_hi = np.floor((theta_hi - shift) / np.pi)
    candidates = [theta_lo, theta_hi] + [shift + k * np.pi for k in np.arange(k_lo, min(k_hi, k_lo + 1) + 1)]
    values = fn(np.array(candidates))
    return float(values.min()), float(values.max())
