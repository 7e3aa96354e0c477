"""Run health of a spatial scene, from an engine's raw columns and the
scene alone (the same for every engine; the planar measures are in
`mechval.judging.health`):
- `nonfinite`: NaN/inf values not declared missing with a reason;
- `gap`: the largest violation of a joint's length rows (m): its points'
  distance, or an offset off its axis or plane;
- `constraint_drift`: those lengths over the scene's size, and the joints'
  direction rows (sines of angles, rad), the largest;
- `drive_error`: the drives' rows: sin(θ − φ(t)) (rad) of a revolute drive,
  the slide error over the scene's size of a prismatic one;
- `energy_drift` (a conservative scene: no drive, torque law, body load or
  damper) |E(t) − E(t0)| over the largest kinetic energy of the run, E the
  kinetic, gravitational and spring energy (`mechval.reference.spatial.
  dynamics.energy`) of the engine's own motion.
The power balance and the assembly branch are not judged for spatial
scenes yet: their rows say "missing"."""

from __future__ import annotations

from typing import Mapping

import numpy as np
import pandas as pd

from mechval.judging.health import peak_of
from mechval.reference.spatial.columns import body_state
from mechval.reference.spatial.dynamics import energy
from mechval.reference.spatial.forces import world_inertia
from mechval.reference.spatial.joints import Constraints
from mechval.reference.spatial.structure import Scaling
from mechval.reference.spatial.system import SpatialSystem


def conservative(system: SpatialSystem) -> bool:
    """Nothing does work on it and its energy is all in `energy`: no drive,
    torque law, body load, damper or spring."""
    return not (system.drives or system.torques or system.loads or system.springs
                or any(j.damping for j in system.joints))


def spatial_health(system: SpatialSystem, raw: pd.DataFrame, missing: Mapping[str, str] = ()) -> pd.DataFrame:
    t = raw["t"].to_numpy(dtype=float)
    columns = [c for c in system.motion_columns() + system.reaction_columns() if c in raw and c not in missing]
    result = {"t": t, "nonfinite": (~np.isfinite(raw[columns].to_numpy(dtype=float))).sum(axis=1)}
    c = Constraints(system)
    with np.errstate(invalid="ignore"):
        pose, w, _ = body_state(system, raw)
        phi = np.abs(c.evaluate(pose, t, jacobian=False)["phi"])
    scaling = Scaling(c)
    joint_rows = np.array([r.kind != "drive" for r in c.rows], dtype=bool)
    lengths = scaling.row != 1.0
    worst = lambda values: values.max(axis=1) if values.shape[1] else np.zeros(len(t))
    result["gap"] = worst(phi[:, joint_rows & lengths])
    result["constraint_drift"] = worst((phi * scaling.row)[:, joint_rows])
    if system.drives:
        result["drive_error"] = worst((phi * scaling.row)[:, ~joint_rows])
    if conservative(system):
        E = energy(system, pose, w)
        peak = peak_of(kinetic_energy(system, pose, w))
        result["energy_drift"] = np.abs(E - E[0]) / (peak if peak > 0 else np.nan)
        result["energy"] = E
    return pd.DataFrame(result)


def kinetic_energy(system: SpatialSystem, pose, w: np.ndarray) -> np.ndarray:
    mass = np.array([b.mass for b in system.bodies])
    return 0.5 * (np.einsum("nb,nbi,nbi->n", np.broadcast_to(mass, w.shape[:2]), w[..., :3], w[..., :3])
                  + np.einsum("nbi,nbij,nbj->n", w[..., 3:], world_inertia(system, pose), w[..., 3:]))
