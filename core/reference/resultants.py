"""Each moving body's resultant constraint load: the one combination of the
joint reactions that stays unique when redundant constraints leave the
reactions themselves indeterminate (docs/conventions.md).

A combination c·λ of the multipliers is unique iff c lies in the row space
of Φqᵀ, i.e. it is a combination of the generalized constraint forces
Φqᵀ·λ = Q − M·q̈. Those are, per body, the net force and the net moment
about its centre of mass of every joint reaction and drive effort acting
on it: set by the body's own motion (Newton–Euler), whatever split of the
load a solver picks. Computed from raw columns alone (joint reactions,
drive efforts, body motion for the lever arms), so the reference and
every engine get the same formula.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from mechval.model.kinematics import point_position, slide_axis
from mechval.model.mechanism import GROUND, Mechanism

#: Canonical quantity → raw column suffix of a body's resultant: net force
#: x, y (N) and net moment about its centre of mass (N·m).
RESULTANT_SIGNALS = {"Rx": "R.Fx", "Ry": "R.Fy", "Rm": "R.M"}
#: Raw column suffixes of a body's resultant: net force x, y (N) and net
#: moment about its centre of mass (N·m).
RESULTANT_QUANTITIES = ("R.Fx", "R.Fy", "R.M")


def resultant_columns(mechanism: Mechanism) -> list[str]:
    return [f"{b.name}.{q}" for b in mechanism.bodies for q in RESULTANT_QUANTITIES]


def resultant_inputs(mechanism: Mechanism) -> list[str]:
    """The raw reaction columns the resultants are made of."""
    laws = {f"{law.name}.T" for law in mechanism.torque_drives}     # applied loads, not reactions
    return [c for c in mechanism.reaction_columns() if c not in laws]


def body_resultants(mechanism: Mechanism, raw: Mapping) -> dict[str, np.ndarray]:
    """Raw columns B.R.Fx, B.R.Fy, B.R.M of every moving body B: the sum of
    the joint reactions and drive efforts on it (Fij = force BY body_i ON
    body_j, so body_j gets +F and body_i −F, both at body_j's joint point
    Pj; a prismatic joint's couple M and a drive's T likewise; a prismatic
    drive's F acts along the axis u at Pj). Moments are about each body's
    centre of mass."""
    n = len(np.asarray(raw["t"]))
    com = {b.name: point_position(raw, b.name, b.com) for b in mechanism.bodies}
    total = {b.name: [np.zeros(n), np.zeros(n), np.zeros(n)] for b in mechanism.bodies}

    def load(body: str, fx, fy, at, couple=0.0) -> None:
        if body == GROUND:
            return
        g, acc = com[body], total[body]
        acc[0] += fx
        acc[1] += fy
        acc[2] += (at["x"] - g["x"]) * fy - (at["y"] - g["y"]) * fx + couple

    col = lambda name: np.asarray(raw[name], dtype=float)   # noqa: E731
    for j in mechanism.joints:
        at = point_position(raw, j.body_j, j.point_j)
        fx, fy = col(f"{j.name}.Fx"), col(f"{j.name}.Fy")
        couple = col(f"{j.name}.M") if j.kind == "prismatic" else 0.0
        load(j.body_j, fx, fy, at, couple)
        load(j.body_i, -fx, -fy, at, -couple)
    for d in mechanism.drives:
        j = mechanism.joint(d.joint)
        at = point_position(raw, j.body_j, j.point_j)
        effort = col(d.effort_column(j.kind))
        if j.kind == "revolute":
            load(j.body_j, 0.0, 0.0, at, effort)
            load(j.body_i, 0.0, 0.0, at, -effort)
        else:
            ux, uy = slide_axis(raw, j)
            load(j.body_j, effort * ux, effort * uy, at)
            load(j.body_i, -effort * ux, -effort * uy, at)
    return {f"{body}.{q}": values for body, parts in total.items() for q, values in zip(RESULTANT_QUANTITIES, parts)}
