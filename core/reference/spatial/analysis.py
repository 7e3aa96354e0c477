"""`mechval analyse` for spatial files: what the spatial reference knows of
the mechanism's structure and of how near it comes to a singular position
(as `mechval.reference.planar.analysis` for planar files).

- mobility: the Grübler–Kutzbach count 6·bodies − Σ (constraints per
  joint: spherical 3, revolute 5, universal 4, cylindrical 4, prismatic 5,
  planar 3, fixed 6) beside the mobility from the rank of the joints'
  Jacobian at the assembly (they differ for overconstrained linkages:
  Bennett's, Bricard's);
- redundant constraints: joint rows beyond that rank;
- the condition number of the scaled Jacobian the reference solves with
  over the run: a prescribed scene's square one (`SpatialSolution.
  condition`, 1-norm) at ≥ 2001 instants; a torque-driven or free scene's
  joint and drive rows (σmax over the σ of the rank the assembly found:
  the rows keep that rank while it is finite) at the file's samples of
  the integrated motion;
- near-singular instants: where that condition peaks (the run's ends
  included) at more than NEAR_SINGULAR times its median over the run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mechval.model.scenario import Scenario, ScenarioError
from mechval.reference.planar.analysis import NEAR_SINGULAR, near_singular_lines
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.columns import body_state
from mechval.reference.spatial.mechanism import spatial_solution
from mechval.reference.spatial.structure import Scaling
from mechval.reference.spatial.joints import Constraints
from mechval.reference.spatial.system import SpatialSystem

#: Constraint equations per joint kind (`joints.ROW_NAMES`).
CONSTRAINED = {"spherical": 3, "revolute": 5, "universal": 4, "cylindrical": 4, "prismatic": 5, "planar": 3,
               "fixed": 6}


@dataclass(frozen=True)
class SpatialAnalysis:
    scenario: str
    bodies: int
    joints: int
    drives: int
    constrained: int                  # Σ constraints of the joints
    grubler: int
    mobility: int
    rank: int
    redundant: int
    integrated: bool                  # the motion is integrated (torque-driven or free)
    condition_max: float              # nan where nothing is constrained
    condition_t: float
    condition_median: float
    near_singular: tuple[tuple[float, float], ...]     # (t, condition) at each peak


def analyse_spatial(scenario: Scenario, samples: int | None = None) -> SpatialAnalysis:
    system: SpatialSystem = scenario.scene
    integrated = system.forward_dynamics
    t = scenario.time.t if integrated else np.linspace(0.0, scenario.time.end,
                                                       samples or max(scenario.time.samples, 2001))
    try:
        solution = spatial_solution(system, t)
    except MechanismError as exc:      # an instant of the denser grid the file's own samples skip
        raise ScenarioError(scenario.source, scenario.key(exc.key), exc.reason) from None
    except np.linalg.LinAlgError:
        raise ScenarioError(scenario.source, "time", "the Jacobian of the rows the reference keeps is exactly "
                                                     "singular at an instant of the run") from None
    s = solution.structure
    cond = _rows_condition(system, solution.frame, s.independent) if integrated else solution.condition
    if cond is None or not len(s.independent):
        cond = np.full(len(t), np.nan)
    median = float(np.median(cond))
    padded = np.concatenate([[-np.inf], cond, [-np.inf]])
    peaks = np.flatnonzero((cond >= padded[:-2]) & (cond > padded[2:]) & (cond > NEAR_SINGULAR * median))
    worst = int(np.nanargmax(cond)) if np.isfinite(cond).any() else 0
    return SpatialAnalysis(
        scenario=scenario.name, bodies=len(system.bodies), joints=len(system.joints), drives=len(system.drives),
        constrained=sum(CONSTRAINED[j.kind] for j in system.joints), grubler=s.grubler, mobility=s.mobility,
        rank=s.rank, redundant=s.redundant, integrated=integrated, condition_max=float(cond[worst]),
        condition_t=float(t[worst]), condition_median=median,
        near_singular=tuple((float(t[k]), float(cond[k])) for k in peaks))


def _rows_condition(system: SpatialSystem, frame, rows: tuple[int, ...]) -> np.ndarray | None:
    """σmax/σr of the scaled Jacobian of all rows, r = the independent
    rows' count, at the states of an integrated run (None without
    constraints): without redundant rows the kept rows' σmax/σmin; with
    them, the condition of the best pick's, whichever rows the dynamics
    keeps (it picks afresh as they turn dependent)."""
    if not rows:
        return None
    c = Constraints(system)
    scaling = Scaling(c)
    pose = body_state(system, frame)[0]
    J = c.evaluate(pose, frame["t"].to_numpy())["jac"]
    s = np.linalg.svd(J * scaling.row[:, None] * scaling.column, compute_uv=False)
    return s[:, 0] / s[:, len(rows) - 1]


def format_spatial_analysis(a: SpatialAnalysis, max_instants: int = 12) -> str:
    how = ("integrated (torque-driven or free): all rows' σmax/σ_rank at the file's samples" if a.integrated
           else "prescribed: the square Jacobian's 1-norm condition")
    lines = [
        f"scenario            {a.scenario} (spatial: {a.bodies} bodies, {a.joints} joints, "
        f"{a.drives} drive{'s' if a.drives != 1 else ''})",
        f"mobility            {a.mobility} from the Jacobian's rank; Grübler–Kutzbach "
        f"6·{a.bodies} − {a.constrained} = {a.grubler}",
        f"redundant           {a.redundant} constraint{'s' if a.redundant != 1 else ''} (Jacobian rank {a.rank})",
    ]
    if np.isnan(a.condition_max):
        lines.append("Jacobian cond. max  none: no joint constrains the bodies")
        return "\n".join(lines)
    lines += [
        f"Jacobian cond. max  {a.condition_max:.4g} at t = {a.condition_t:.4g} s (median {a.condition_median:.4g}; "
        f"{how})",
    ]
    return "\n".join(lines + near_singular_lines(a.near_singular, max_instants))
