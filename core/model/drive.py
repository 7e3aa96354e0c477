"""The prescribed crank drive law shared by the reference and every engine."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DriveLaw:
    """Crank angle φ(t) = phi0 + omega0·t + ½·alpha·t² (rad, rad/s, rad/s²)."""

    phi0: float = 0.0
    omega0: float = 0.0
    alpha: float = 0.0

    def angle(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return self.phi0 + self.omega0 * t + 0.5 * self.alpha * t * t

    def rate(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return self.omega0 + self.alpha * t

    def acceleration(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return np.full_like(t, self.alpha)
