"""Each moving body's resultant constraint load in a spatial scene: the
combination of joint reactions and drive efforts that stays unique when
redundant constraints leave the reactions themselves indeterminate (as
`mechval.reference.resultants` for planar scenes; docs/conventions.md).

From raw columns alone, so the reference and every engine get the same
formula: per joint, F and M about Pj act on body_j and −F, −M on body_i
(moved to each body's centre of mass); a drive's effort acts about (or
along) zi on body_j, the opposite on body_i. Torque laws are applied
loads, not reactions: left out. Columns `B.R.Fx` … `B.R.Mz` (world axes,
moments about the centre of mass)."""

from __future__ import annotations

from typing import Mapping

import numpy as np

from mechval.model.mechanism import GROUND
from mechval.reference.spatial.rotation import quaternion_to_matrix
from mechval.reference.spatial.system import SpatialSystem

RESULTANT = ("R.Fx", "R.Fy", "R.Fz", "R.Mx", "R.My", "R.Mz")


def resultant_columns(system: SpatialSystem) -> list[str]:
    return [f"{b.name}.{q}" for b in system.bodies for q in RESULTANT]


def resultant_inputs(system: SpatialSystem) -> list[str]:
    """The raw reaction columns the resultants are made of."""
    laws = {f"{law.name}.T" for law in system.torques}
    return [c for c in system.reaction_columns() if c not in laws]


def spatial_resultants(system: SpatialSystem, raw: Mapping) -> dict[str, np.ndarray]:
    n = len(np.asarray(raw["t"]))
    take = lambda name, quantities: np.stack([np.asarray(raw[f"{name}.{q}"], dtype=float)      # noqa: E731
                                              for q in quantities.split()], axis=1)
    attitude = {b.name: quaternion_to_matrix(take(b.name, "qw qx qy qz")) for b in system.bodies}
    attitude[GROUND] = np.broadcast_to(np.eye(3), (n, 3, 3))
    origin = {b.name: take(b.name, "x y z") for b in system.bodies}
    origin[GROUND] = np.zeros((n, 3))
    com = {b.name: origin[b.name] + attitude[b.name] @ np.asarray(b.com, dtype=float) for b in system.bodies}
    total = {b.name: np.zeros((n, 6)) for b in system.bodies}

    def act(body: str, at: np.ndarray, force: np.ndarray, moment: np.ndarray) -> None:
        if body != GROUND:
            total[body] += np.concatenate([force, moment + np.cross(at - com[body], force)], axis=1)

    for j in system.joints:
        Pj = origin[j.body_j] + attitude[j.body_j] @ np.asarray(j.point_j, dtype=float)
        F, M = take(j.name, "Fx Fy Fz"), take(j.name, "Mx My Mz")
        act(j.body_j, Pj, F, M)
        act(j.body_i, Pj, -F, -M)
    for d in system.drives:
        j = system.joint(d.joint)
        Pj = origin[j.body_j] + attitude[j.body_j] @ np.asarray(j.point_j, dtype=float)
        axis = attitude[j.body_i] @ np.asarray(j.frame_i, dtype=float)[:, 2]
        effort = np.asarray(raw[f"{d.name}.{'T' if j.kind == 'revolute' else 'F'}"], dtype=float)[:, None] * axis
        zero = np.zeros((n, 3))
        load = (zero, effort) if j.kind == "revolute" else (effort, zero)
        act(j.body_j, Pj, *load)
        act(j.body_i, Pj, -load[0], -load[1])
    return {f"{name}.{q}": values[:, k] for name, values in total.items() for k, q in enumerate(RESULTANT)}
