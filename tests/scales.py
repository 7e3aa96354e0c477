"""Dimensionally consistent scales for tests' bounds.

A bound like `1e-6 * max(peak, 1.0)` mixes units (1.0 what: m/s? rad/s²?)
and silently becomes absolute for small mechanisms. These scales come from
the mechanism itself: its size L (m) and its peak rate Ω (rad/s, the step
rule's `step_rate`: the largest |ω|, √|α|, ∛|jerk| over the run).
"""

from __future__ import annotations

import numpy as np

from mechval.model.kinematics import step_rate
from mechval.model.mechanism import Mechanism


def size(mech: Mechanism) -> float:
    """L: the largest joint-point coordinate in any body frame (m)."""
    return max(abs(v) for j in mech.joints for v in j.point_i + j.point_j)


def motion_scales(mech: Mechanism, t: np.ndarray) -> dict[str, float]:
    """Scale per motion quantity: Ω, Ω² (angular) and L·Ω, L·Ω² (linear)."""
    rate, length = step_rate(mech, t), size(mech)
    return {"omega": rate, "alpha": rate**2, "vx": length * rate, "vy": length * rate,
            "ax": length * rate**2, "ay": length * rate**2, "v": length * rate, "a": length * rate**2}


def class_peaks(signals, classes: dict[str, str]) -> dict[str, float]:
    """Per signal class, the largest |value| of any of its signals: the
    scale of an absolute tolerance shared by the class (a force that is zero
    in theory is judged against the other forces, not against 1 N)."""
    peaks: dict[str, float] = {}
    for name in signals.frame.columns:
        if name in classes:
            peak = float(np.abs(signals[name]).max())
            peaks[classes[name]] = max(peaks.get(classes[name], 0.0), peak)
    return peaks
