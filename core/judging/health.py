"""Run health as data: what a simulation did besides its signals.

Computed at every output sample from an engine's raw columns and the
`Mechanism` alone (so the same for every engine):
- `nonfinite`: number of NaN/inf values among the raw columns, not counting
  those the engine declared missing with a reason;
- `gap`: largest distance between the two sides of any joint (m): for a
  revolute joint the two pin positions, for a prismatic joint the distance
  of body_j's point from body_i's guide line (the loop-closure gap);
- `constraint_drift`: the same gaps over the mechanism's size L
  (`mechval.reference.planar.positions.mechanism_size`) and, for a prismatic joint,
  its angle error |θj − θi − held angle| (rad): the largest, so a gap of
  δ counts as the turn δ/L of a link of the mechanism's size;
- `drive_error`: |crank angle − φ(t)| (rad), how well the drive tracks
  (with several drives the largest; a prismatic drive's slide error counts
  as the angle it subtends at the mechanism's size); none without drives;
- `assembly_flip`: 1 where the assembly branch differs from the
  reference's (the builder's `assembly` sign, e.g. the side of B relative
  to A→O4), else 0; in a forward-dynamics scene the branch of the first
  sample, the consistent initial state every run starts from;
- `power_residual`: |P_in − dE/dt + other applied power| / max|P_in|, P_in
  = T·ω of the drives and torque laws, E the kinetic + potential energy
  from the engine's own body motion, the other applied power the dampers'
  losses and body torques (`mechval.judging.energy`); in a scene with neither
  drives nor torque laws, over max|dK/dt| (K the kinetic energy: the rate
  at which energy is exchanged);
- `energy_drift` (a conservative scene: no drive, torque law, body torque
  or damper) |E(t) − E(t0)| / S, or else `energy_balance`
  |E(t) − E(t0) − W(t)| / S, with W the work of the applied power
  (`mechval.judging.energy.work`) and the scale S = max over the run of K,
  |V − V(t0)| and |W| (V the potential energy): the energy the motion
  exchanges (E itself has an arbitrary zero of gravity's potential);
  `energy_quadrature` estimates W's quadrature error on the same scale.

The frame also holds the series the report draws: `energy` E(t) and
`work` W(t) (J).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
import pandas as pd

from mechval.judging.energy import (applied_power, conservative, energy_rate, input_power, kinetic_energy, kinetic_rate,
                     potential_energy, work, work_error)
from mechval.model.kinematics import joint_gap, joint_gaps, slide_motion, slide_rate  # noqa: F401  (tests import them here)
from mechval.model.mechanism import GROUND, Mechanism
from mechval.reference.planar.positions import mechanism_size

#: The judged health measures (mechval.judging.compare.HEALTH_BOUNDS); a mechanism
#: has one of energy_drift and energy_balance, and drive_error only with drives.
HEALTH_COLUMNS = ("nonfinite", "gap", "drive_error", "assembly_flip", "power_residual", "constraint_drift",
                  "energy_drift", "energy_balance")
#: Measures that do not apply to every mechanism, and why (a mechanism
#: they do not apply to has no such column, and the comparison no row).
NOT_APPLICABLE = {
    "drive_error": "no prescribed drive",
    "energy_drift": "work is done on the mechanism (drives, torque laws, body torques or dampers): "
                    "judged as health.energy_balance",
    "energy_balance": "nothing does work on the mechanism: its energy is conserved, judged as health.energy_drift",
}


def drive_errors(mech: Mechanism, raw) -> np.ndarray:
    """The largest drive tracking error per sample (rad): |θj − θi − φ(t)|
    for a revolute drive, |s − φ(t)| / L for a prismatic one (s its slide,
    L the largest joint-point coordinate)."""
    t = np.asarray(raw["t"])
    angle = lambda name: 0.0 if name == GROUND else np.asarray(raw[f"{name}.theta"])
    size = max((abs(v) for j in mech.joints for v in j.point_i + j.point_j), default=1.0) or 1.0
    errors = []
    for drive in mech.drives:
        joint = mech.joint(drive.joint)
        if joint.kind == "revolute":
            errors.append(np.abs(angle(joint.body_j) - angle(joint.body_i) - drive.law.angle(t)))
        else:
            errors.append(np.abs(slide_motion(raw, joint)["s"] - drive.law.angle(t)) / size)
    return np.max(errors, axis=0)


def power_balance(mech: Mechanism, raw) -> tuple[np.ndarray, np.ndarray]:
    """Input power T·ω of the drives and torque laws, and what it must
    equal: the rate of energy minus the other applied power (damper losses,
    body torques), from the motion in `raw` (Norton §11.2 energy method)."""
    power = input_power(mech, raw)
    return power, energy_rate(mech, raw) - (applied_power(mech, raw) - power)


def constraint_drifts(mech: Mechanism, raw) -> np.ndarray:
    """The largest joint gap over the mechanism's size, or prismatic angle
    error (rad), at each sample (module docstring)."""
    size = mechanism_size(mech)
    angle = lambda name: 0.0 if name == GROUND else np.asarray(raw[f"{name}.theta"])
    drifts = []
    for joint in mech.joints:
        drifts.append(joint_gap(raw, joint) / size)
        if joint.kind == "prismatic":
            error = angle(joint.body_j) - angle(joint.body_i) - joint.held_angle
            drifts.append(np.abs(np.angle(np.exp(1j * error))))     # wrapped to (−π, π]
    return np.max(drifts, axis=0) + np.zeros(len(raw["t"]))


def energy_health(mech: Mechanism, raw) -> dict[str, np.ndarray]:
    """energy, work, the relative drift or balance residual and the work's
    quadrature error (module docstring)."""
    t = np.asarray(raw["t"], dtype=float)
    kinetic, potential = kinetic_energy(mech, raw), potential_energy(mech, raw)
    energy = kinetic + potential
    power = applied_power(mech, raw)
    done = np.zeros(len(t)) if conservative(mech) else work(t, power)
    scale = max(peak_of(kinetic), peak_of(np.abs(potential - potential[0])), peak_of(np.abs(done)))
    scale = scale if scale > 0 else np.nan     # nothing moves: no energy to judge a drift by
    residual = np.abs(energy - energy[0] - done) / scale
    quadrature = np.zeros(len(t)) if conservative(mech) else work_error(t, power) / scale
    name = "energy_drift" if conservative(mech) else "energy_balance"
    return {name: residual, "energy": energy, "work": done, "energy_quadrature": quadrature}


def peak_of(values) -> float:
    """The largest value, NaN left out; NaN if every value is NaN (a run
    that blew up from its start: its failure is reported once, without
    numpy's All-NaN warning before it)."""
    values = np.asarray(values, dtype=float)
    values = values[~np.isnan(values)]
    return float(values.max()) if values.size else np.nan


def health(mech: Mechanism, raw: pd.DataFrame, missing: Mapping[str, str] = ()) -> pd.DataFrame:
    """Health columns (HEALTH_COLUMNS) at every sample of an engine's raw run."""
    if mech.spatial is not None:
        from mechval.judging.spatial_health import spatial_health     # it imports this module
        return spatial_health(mech.spatial, raw, missing)
    t = raw["t"].to_numpy()
    columns = [c for c in mech.motion_columns() + mech.reaction_columns() if c in raw and c not in missing]
    values = raw[columns].to_numpy(dtype=float)
    result = {
        "t": t,
        "nonfinite": (~np.isfinite(values)).sum(axis=1),
        "gap": joint_gaps(mech, raw),
        "constraint_drift": constraint_drifts(mech, raw),
    }
    if mech.drives:
        result["drive_error"] = drive_errors(mech, raw)
    if mech.assembly is not None:
        side = np.sign(mech.assembly(raw))
        reference = side[0] if mech.forward_dynamics else np.sign(mech.assembly(mech.motion(t)))
        result["assembly_flip"] = (side != reference).astype(int)
    power, rate = power_balance(mech, raw)
    peak = peak_of(np.abs(power))
    if not (mech.drives or mech.torque_drives):
        peak = peak_of(np.abs(kinetic_rate(mech, raw)))
    # At rest (a free scene released at an equilibrium) there is no power to
    # scale by: the residual is then undefined, not rounding over 1e-300.
    # A prescribed scene held still keeps the old floor (its residual is then
    # rounding over 1e-300, as before).
    scale = max(peak, 1e-300) if mech.drives else (peak if peak > 0 else np.nan)
    result["power_residual"] = np.abs(power - rate) / scale
    result.update(energy_health(mech, raw))
    return pd.DataFrame(result)
