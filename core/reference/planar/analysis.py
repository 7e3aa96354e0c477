"""`mechval analyse` for planar files: what the general reference knows of
the mechanism's structure and of how near it comes to a singular position.

- mobility: the Grübler–Kutzbach count 3·bodies − 2·joints beside the
  mobility from the rank of the joints' Jacobian (they differ where joints
  are redundant, as in a parallelogram with a third crank);
- redundant constraints: rows of Φq beyond its rank;
- the condition number of the (scaled, reduced) Jacobian over the run, its
  largest value and when;
- near-singular instants: where that condition peaks (the run's ends
  included) at more than `NEAR_SINGULAR` times its median over the run (a
  toggle or dead-centre position approached).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mechval.reference.linkages import build_mechanism
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.planar.solver import raw_planar
from mechval.model.scenario import Scenario, ScenarioError

NEAR_SINGULAR = 10.0


@dataclass(frozen=True)
class PlanarAnalysis:
    scenario: str
    bodies: int
    joints: int
    drives: int
    grubler: int
    mobility: int
    rank: int
    redundant: int
    condition_max: float
    condition_t: float
    condition_median: float
    near_singular: tuple[tuple[float, float], ...]     # (t, condition) at each peak


def analyse_planar(scenario: Scenario, samples: int | None = None) -> PlanarAnalysis:
    mech = build_mechanism(scenario)
    t = np.linspace(0.0, scenario.time.end, samples or max(scenario.time.samples, 2001))
    try:
        solution = raw_planar(mech, t)
    except MechanismError as exc:      # an instant of the denser grid the file's own samples skip
        raise ScenarioError(scenario.source, exc.key, exc.reason) from None
    cond, s = solution.condition, solution.structure
    median = float(np.median(cond))
    # local maxima, the run's ends included (a run may stop close to a toggle)
    padded = np.concatenate([[-np.inf], cond, [-np.inf]])
    peaks = np.flatnonzero((cond >= padded[:-2]) & (cond > padded[2:]) & (cond > NEAR_SINGULAR * median))
    worst = int(np.argmax(cond))
    return PlanarAnalysis(
        scenario=scenario.name, bodies=len(mech.bodies), joints=len(mech.joints), drives=len(mech.drives),
        grubler=s.grubler, mobility=s.mobility, rank=s.rank, redundant=s.redundant,
        condition_max=float(cond[worst]), condition_t=float(t[worst]), condition_median=median,
        near_singular=tuple((float(t[k]), float(cond[k])) for k in peaks))


def format_planar_analysis(a: PlanarAnalysis, max_instants: int = 12) -> str:
    lines = [
        f"scenario            {a.scenario} (planar: {a.bodies} bodies, {a.joints} joints, "
        f"{a.drives} drive{'s' if a.drives != 1 else ''})",
        f"mobility            {a.mobility} from the Jacobian's rank; Grübler count "
        f"3·{a.bodies} − 2·{a.joints} = {a.grubler}",
        f"redundant           {a.redundant} constraint{'s' if a.redundant != 1 else ''} (Jacobian rank {a.rank})",
        f"Jacobian cond. max  {a.condition_max:.4g} at t = {a.condition_t:.4g} s (median {a.condition_median:.4g})",
    ]
    return "\n".join(lines + near_singular_lines(a.near_singular, max_instants))


def near_singular_lines(near_singular: tuple[tuple[float, float], ...], max_instants: int) -> list[str]:
    """The report's near-singular instants (planar and spatial analyses alike)."""
    lines = [f"near-singular       {len(near_singular)} instant{'s' if len(near_singular) != 1 else ''} "
             f"(condition peaks above {NEAR_SINGULAR:g}× the median)"]
    lines += [f"  t = {t:10.5f} s  condition {c:.4g}" for t, c in near_singular[:max_instants]]
    if len(near_singular) > max_instants:
        lines.append(f"  … {len(near_singular) - max_instants} more")
    return lines
