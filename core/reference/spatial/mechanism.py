"""The `Mechanism` of a spatial scene: what the harness and every adapter
see. Its kind is "spatial"; it has no planar bodies or joints; `spatial`
holds the `SpatialSystem`, `motion` the spatial reference's motion columns
(solved, or integrated from the scene's initial state at the first instant
asked), and its signals are the raw columns under their own names
(docs/conventions.md, "Spatial signals")."""

from __future__ import annotations

import numpy as np
import pandas as pd

from mechval.model.mechanism import Mechanism
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.dynamics import SpatialDynamics
from mechval.reference.spatial.joints import Constraints
from mechval.reference.spatial.resultants import resultant_columns
from mechval.reference.spatial.solver import SpatialSolution, solve_spatial
from mechval.reference.spatial.structure import Scaling, initial_pose, newton, structure
from mechval.reference.spatial.system import SpatialSystem

KIND = "spatial"


def spatial_solution(system: SpatialSystem, t: np.ndarray, reactions: bool = True,
                     rtol: float | None = None) -> SpatialSolution:
    """The reference at instants t: solved positions, rates and reactions
    (without `reactions`: the motion columns only) of a prescribed scene;
    a torque-driven or free one integrated from its initial state at t[0]
    (at `rtol`, default the reference's own `dynamics.RTOL`)."""
    t = np.asarray(t, dtype=float)
    if system.forward_dynamics:
        dynamics = SpatialDynamics(system, system.velocities, t0=float(t[0]))
        return dynamics.solve(t, reactions=reactions, **({} if rtol is None else {"rtol": rtol}))
    return solve_spatial(system, t, reactions)


class _Motion:
    """The reference's motion columns at instants t (each call solves; the
    reactions are not computed)."""

    def __init__(self, system: SpatialSystem):
        self.system = system

    def __call__(self, t: np.ndarray) -> pd.DataFrame:
        return spatial_solution(self.system, t, reactions=False).frame.reset_index(drop=True)


def spatial_signal_map(system: SpatialSystem) -> dict[str, str]:
    """Canonical signal → raw column: the same names (motion, then
    reactions, drive efforts and torque laws, and with redundant
    constraints each body's resultant, `mechval.reference.spatial.resultants`).
    A spherical joint's moment is zero by its kind, its values rounding:
    not a signal (judged relative to its class's peak, rounding would be
    the bound)."""
    torque_free = {f"{j.name}.M{c}" for j in system.joints if j.kind == "spherical" for c in "xyz"}
    names = system.motion_columns() + [c for c in system.reaction_columns() if c not in torque_free]
    return {name: name for name in names + (resultant_columns(system) if has_redundant_constraints(system) else [])}


def has_redundant_constraints(system: SpatialSystem) -> bool:
    """Whether the joints' rows are dependent at the assembly (one Newton
    solve at t = 0). A scene that does not assemble says no here: the
    reference refuses it where it runs, with its reason."""
    c = Constraints(system)
    scaling = Scaling(c)
    try:
        pose = newton(c, scaling, initial_pose(c), np.zeros(1), None)
    except MechanismError:
        return False
    return structure(c, scaling, pose).redundant > 0


def spatial_mechanism(system: SpatialSystem, name: str | None = None) -> Mechanism:
    return Mechanism(name=name or system.name, kind=KIND, bodies=(), joints=(), drive=None, gravity=(0.0, 0.0),
                     motion=_Motion(system), signal_map=spatial_signal_map(system), spatial=system)


def scene_size(system: SpatialSystem) -> float:
    """The scene's size (m): the largest distance between its bodies'
    stated origins and joint points (`Scaling.size`)."""
    return Scaling(Constraints(system)).size
