"""Run health as data: what a simulation did besides its signals.

Computed at every output sample from an engine's raw columns and the
`Mechanism` alone (so the same for every engine):
- `nonfinite`: number of NaN/inf values among the raw columns, not counting
  those the engine declared missing with a reason;
- `gap`: largest distance between the two sides of any joint (m): for a
  revolute joint the two pin positions, for a prismatic joint the distance
  of body_j's point from body_i's guide line (the loop-closure gap);
- `drive_error`: |crank angle − φ(t)| (rad), how well the drive tracks;
- `assembly_flip`: 1 where the assembly branch differs from the
  reference's (the builder's `assembly` sign, e.g. the side of B relative
  to A→O4), else 0;
- `power_residual`: |T·ω − dE/dt − damper losses| / max|T·ω| with E the
  kinetic + potential energy computed from the engine's own body motion.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
import pandas as pd

from .kinematics import joint_gaps, point_motion, slide_rate
from .mechanism import DRIVE_TORQUE, GROUND, Mechanism

HEALTH_COLUMNS = ("nonfinite", "gap", "drive_error", "assembly_flip", "power_residual")


def power_balance(mech: Mechanism, raw) -> tuple[np.ndarray, np.ndarray]:
    """Drive power T·ω and the rate of energy plus damper losses, from the
    motion in `raw` (Norton §11.2 energy method)."""
    gx, gy = mech.gravity
    rate = 0.0
    for body in mech.bodies:
        G = point_motion(raw, body.name, body.com)
        w, al = np.asarray(raw[f"{body.name}.omega"]), np.asarray(raw[f"{body.name}.alpha"])
        rate = rate + body.mass * (G["vx"] * G["ax"] + G["vy"] * G["ay"] - gx * G["vx"] - gy * G["vy"]) \
            + body.izz * w * al
    omega = lambda name: 0.0 if name == GROUND else np.asarray(raw[f"{name}.omega"])
    for joint in mech.joints:
        if joint.kind == "revolute":
            relative = omega(joint.body_j) - omega(joint.body_i)
        else:
            relative = slide_rate(raw, joint)
        rate = rate + joint.damping * relative**2
    drive = mech.joint(mech.drive.joint)
    power = np.asarray(raw[DRIVE_TORQUE]) * (omega(drive.body_j) - omega(drive.body_i))
    return power, rate


def health(mech: Mechanism, raw: pd.DataFrame, missing: Mapping[str, str] = ()) -> pd.DataFrame:
    """Health columns (HEALTH_COLUMNS) at every sample of an engine's raw run."""
    t = raw["t"].to_numpy()
    columns = [c for c in mech.motion_columns() + mech.reaction_columns() if c in raw and c not in missing]
    values = raw[columns].to_numpy(dtype=float)
    drive = mech.joint(mech.drive.joint)
    angle = lambda name: 0.0 if name == GROUND else raw[f"{name}.theta"].to_numpy()
    result = {
        "t": t,
        "nonfinite": (~np.isfinite(values)).sum(axis=1),
        "gap": joint_gaps(mech, raw),
        "drive_error": np.abs(angle(drive.body_j) - angle(drive.body_i) - mech.drive.law.angle(t)),
    }
    if mech.assembly is not None:
        reference = mech.assembly(mech.motion(t))
        result["assembly_flip"] = (np.sign(mech.assembly(raw)) != np.sign(reference)).astype(int)
    power, rate = power_balance(mech, raw)
    result["power_residual"] = np.abs(power - rate) / max(float(np.nanmax(np.abs(power))), 1e-300)
    return pd.DataFrame(result)
