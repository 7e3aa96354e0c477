"""Shared pieces of the closed-form loop-closure analysis.

References: R. L. Norton, *Design of Machinery*, 5th ed. (Norton below),
ch. 4 (position), 6 (velocity), 7 (acceleration), complex-number
(vector-loop) method.
"""

from __future__ import annotations

from dataclasses import dataclass

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
    rigid-body relations are `mechval.model.kinematics.point_motion`."""
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


@dataclass(frozen=True)
class LoopAnalysis:
    """A closed form's own engineering analysis over a run (`mechval.reference.analysis`):
    its Grashof condition or slider rule, linkage type, transmission angle
    μ at each instant (rad, acute), toggle instants (t, what), and for a
    quick-return linkage the forward/return stroke time ratio, closed form
    (constant crank speed) and measured from the run's motion."""

    grashof: str
    linkage_type: str
    transmission: np.ndarray
    toggles: list[tuple[float, str]]
    quick_return: float | None = None
    quick_return_measured: float | None = None


def sign_changes(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Instants where f changes sign, linearly interpolated between samples."""
    k = np.flatnonzero(np.signbit(f[:-1]) != np.signbit(f[1:]))
    return t[k] - f[k] * (t[k + 1] - t[k]) / (f[k + 1] - f[k])


def cond2(m11, m12, m21, m22) -> np.ndarray:
    """2-norm condition number of 2×2 matrices from their singular values."""
    frob2 = m11**2 + m12**2 + m21**2 + m22**2
    det = np.abs(m11 * m22 - m12 * m21)
    root = np.sqrt(np.maximum(frob2**2 - 4 * det**2, 0.0))
    s_max = np.sqrt((frob2 + root) / 2)
    with np.errstate(divide="ignore"):
        return np.where(det > 0, s_max**2 / np.where(det > 0, det, 1.0), np.inf)


def measured_stroke_ratio(t: np.ndarray, omega_out: np.ndarray, omega2: np.ndarray) -> float | None:
    """Mean forward over mean return stroke time of a rocking link: strokes
    run between sign changes of its rate; a forward stroke turns it the way
    the crank turns. None without a complete stroke of each kind."""
    ends = sign_changes(t, omega_out)
    if len(ends) < 3:
        return None
    mid = (ends[:-1] + ends[1:]) / 2
    forward = np.sign(np.interp(mid, t, omega_out)) == np.sign(np.interp(mid, t, omega2))
    if forward.all() or not forward.any():
        return None
    durations = np.diff(ends)
    return float(durations[forward].mean() / durations[~forward].mean())
