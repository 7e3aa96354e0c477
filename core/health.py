"""Run health as data: what a simulation did besides its signals.

Computed at every output sample from an engine's raw columns and the
`Mechanism` alone (so the same for every engine):
- `nonfinite`: number of NaN/inf values among the raw columns, not counting
  those the engine declared missing with a reason;
- `gap`: largest distance between the two sides of any joint (m): for a
  revolute joint the two pin positions, for a prismatic joint the distance
  of body_j's point from body_i's guide line (the loop-closure gap);
- `drive_error`: |crank angle − φ(t)| (rad), how well the drive tracks
  (with several drives the largest; a prismatic drive's slide error counts
  as the angle it subtends at the mechanism's size);
- `assembly_flip`: 1 where the assembly branch differs from the
  reference's (the builder's `assembly` sign, e.g. the side of B relative
  to A→O4), else 0;
- `power_residual`: |T·ω − dE/dt − damper losses| / max|T·ω| with E the
  kinetic + potential energy computed from the engine's own body motion
  (all drives' power; springs' elastic energy in E and their dampers in the
  losses; body torques' power on the drives' side).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
import pandas as pd

from .kinematics import joint_gaps, point_motion, slide_motion, slide_rate
from .mechanism import GROUND, BodyTorque, Mechanism

HEALTH_COLUMNS = ("nonfinite", "gap", "drive_error", "assembly_flip", "power_residual")


def drive_errors(mech: Mechanism, raw) -> np.ndarray:
    """The largest drive tracking error per sample (rad): |θj − θi − φ(t)|
    for a revolute drive, |s − φ(t)| / L for a prismatic one (s its slide,
    L the largest joint-point coordinate)."""
    t = np.asarray(raw["t"])
    angle = lambda name: 0.0 if name == GROUND else np.asarray(raw[f"{name}.theta"])
    size = max((abs(v) for j in mech.joints for v in j.point_i + j.point_j), default=1.0) or 1.0
    errors = [np.zeros(len(t))]      # no prescribed drive: nothing to track
    for drive in mech.drives:
        joint = mech.joint(drive.joint)
        if joint.kind == "revolute":
            errors.append(np.abs(angle(joint.body_j) - angle(joint.body_i) - drive.law.angle(t)))
        else:
            errors.append(np.abs(slide_motion(raw, joint)["s"] - drive.law.angle(t)) / size)
    return np.max(errors, axis=0)


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
    relative = lambda joint: (omega(joint.body_j) - omega(joint.body_i) if joint.kind == "revolute"
                              else slide_rate(raw, joint))
    for joint in mech.joints:
        rate = rate + joint.damping * relative(joint)**2
    power = 0.0
    for drive in mech.drives:
        joint = mech.joint(drive.joint)
        power = power + np.asarray(raw[drive.effort_column(joint.kind)]) * relative(joint)
    for law in mech.torque_drives:      # applied torque laws work like drives
        power = power + np.asarray(raw[f"{law.name}.T"]) * relative(mech.joint(law.joint))
    for element in mech.forces:
        if isinstance(element, BodyTorque):
            rate = rate - element.torque * omega(element.body)
        else:   # a spring-damper: elastic energy and damper loss
            Pa = point_motion(raw, element.body_a, element.point_a)
            Pb = point_motion(raw, element.body_b, element.point_b)
            dx, dy = Pb["x"] - Pa["x"], Pb["y"] - Pa["y"]
            length = np.hypot(dx, dy)
            stretch = (dx * (Pb["vx"] - Pa["vx"]) + dy * (Pb["vy"] - Pa["vy"])) / length
            rate = rate + (element.stiffness * (length - element.free_length) + element.damping * stretch) * stretch
    return np.asarray(power), rate


def health(mech: Mechanism, raw: pd.DataFrame, missing: Mapping[str, str] = ()) -> pd.DataFrame:
    """Health columns (HEALTH_COLUMNS) at every sample of an engine's raw run."""
    t = raw["t"].to_numpy()
    columns = [c for c in mech.motion_columns() + mech.reaction_columns() if c in raw and c not in missing]
    values = raw[columns].to_numpy(dtype=float)
    result = {
        "t": t,
        "nonfinite": (~np.isfinite(values)).sum(axis=1),
        "gap": joint_gaps(mech, raw),
        "drive_error": drive_errors(mech, raw),
    }
    if mech.assembly is not None:
        reference = mech.assembly(mech.motion(t))
        result["assembly_flip"] = (np.sign(mech.assembly(raw)) != np.sign(reference)).astype(int)
    power, rate = power_balance(mech, raw)
    result["power_residual"] = np.abs(power - rate) / max(float(np.nanmax(np.abs(power))), 1e-300)
    return pd.DataFrame(result)
