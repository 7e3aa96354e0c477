"""Planar kinematics shared by the reference, health, signals and adapters."""

from __future__ import annotations

import numpy as np

from .mechanism import Mechanism


def step_rate(mechanism: Mechanism, times: np.ndarray, dense: int = 20001) -> float:
    """Ω: the largest over the run and the links of |ω|, √|α| and ∛|jerk|
    (rad/s), from the reference kinematics on a dense grid.

    Speed alone misjudges sharp motion at moderate speed (near the Grashof
    change point), hence the α and jerk terms (docs/engines.md, "step rule").
    """
    t = np.linspace(float(times[0]), float(times[-1]), dense)
    motion = mechanism.motion(t)
    rate = 0.0
    for body in mechanism.bodies:
        w = motion[f"{body.name}.omega"].to_numpy()
        al = motion[f"{body.name}.alpha"].to_numpy()
        jerk = np.gradient(al, t)
        rate = max(rate, np.abs(w).max(), np.sqrt(np.abs(al).max()), np.cbrt(np.abs(jerk).max()))
    return float(rate)
