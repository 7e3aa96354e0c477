"""Reading a spatial solution's raw columns back as arrays: each body's
pose, velocities and accelerations about its centre of mass (the
coordinates of `mechval.reference.spatial.joints`), for checks that work on
the outputs alone (energy, power, momentum)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from mechval.reference.spatial.joints import Pose
from mechval.reference.spatial.rotation import cross, quaternion_to_matrix
from mechval.reference.spatial.system import SpatialSystem


def _take(frame: pd.DataFrame, body: str, names: str) -> np.ndarray:
    return frame[[f"{body}.{n}" for n in names.split()]].to_numpy()


def body_state(system: SpatialSystem, frame: pd.DataFrame) -> tuple[Pose, np.ndarray, np.ndarray]:
    """Pose, (Ġ, ω) and (G̈, ω̇) per body, (N, nb, 6) each, from raw columns."""
    G, A, w, dw = [], [], [], []
    for b in system.bodies:
        R = quaternion_to_matrix(_take(frame, b.name, "qw qx qy qz"))
        arm = R @ np.asarray(b.com, dtype=float)
        om, al = _take(frame, b.name, "wx wy wz"), _take(frame, b.name, "alphax alphay alphaz")
        G.append(_take(frame, b.name, "x y z") + arm)
        A.append(R)
        w.append(np.concatenate([_take(frame, b.name, "vx vy vz") + cross(om, arm), om], axis=1))
        acc = _take(frame, b.name, "ax ay az") + cross(al, arm) + cross(om, cross(om, arm))
        dw.append(np.concatenate([acc, al], axis=1))
    return Pose(np.stack(G, 1), np.stack(A, 1)), np.stack(w, 1), np.stack(dw, 1)
