"""`mechval analyse`: each closed form's own analysis (its module's
`analysis`, a `mechval.reference.closed_forms.loop.LoopAnalysis`: Grashof condition or slider rule
and linkage type, transmission angle over the run, toggle / dead-centre
instants inside the run, for the slider-crank inversions with a turning
slide the quick-return time ratio, closed form and measured) with the
distance to singularity (condition number of the velocity Jacobian), and
the trust check of a closed form's reference at the loader. A scene without
a closed form is analysed by `mechval.reference.planar.analysis`, a spatial
one by `mechval.reference.spatial.analysis`. References: Norton,
*Design of Machinery*, §2.12 (Grashof), §4.10 (transmission angle), §4.12
(toggle positions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mechval.reference.linkages import ClosedForm, build_mechanism
from mechval.reference.planar.analysis import analyse_planar, format_planar_analysis
from mechval.reference.spatial.analysis import SpatialAnalysis, analyse_spatial, format_spatial_analysis
from mechval.reference.adapter import raw_reference
from mechval.model.scenario import Scenario, ScenarioError


@dataclass(frozen=True)
class Analysis:
    scenario: str
    mechanism: str
    grashof: str                      # "Grashof", "non-Grashof", "change point", or the slider rule
    linkage_type: str                 # e.g. "crank-rocker"
    transmission_min: float           # rad, acute angle (0 … π/2)
    transmission_max: float
    transmission_t_min: float         # s, where the minimum happens
    toggles: tuple[tuple[float, str], ...]  # (t, what) inside the run
    jacobian_cond_max: float
    jacobian_cond_t: float
    quick_return: float | None = None           # forward/return stroke time, closed form (constant ω2)
    quick_return_measured: float | None = None  # the same from the reference motion of the run


#: Largest condition number of the velocity Jacobian the reference accepts at
#: a sample: its rounding error grows like cond·ε (≈ 1e-9 relative at 1e7),
#: beyond which "exact to rounding" could not be promised.
SINGULAR_COND = 1e7


def check_trustworthy(scenario: Scenario, closed: ClosedForm) -> None:
    """Refuse a scenario of the closed form `closed` whose reference cannot
    be trusted at some sample: values that overflow float64, or a
    configuration too close to singular (condition number above
    SINGULAR_COND). Names the instant and why."""
    with np.errstate(all="ignore"):       # overflow is detected and reported below
        _check_trustworthy(scenario, closed)


def _check_trustworthy(scenario: Scenario, closed: ClosedForm) -> None:
    t = scenario.time.t
    kinematics = closed.kinematics(t)
    _refuse_nonfinite(scenario, t, np.column_stack(list(kinematics.values())), "drive",
                      "the crank's motion overflows float64")
    cond = closed.jacobian_condition(kinematics)
    worst = int(np.argmax(np.where(np.isfinite(cond), cond, np.inf)))
    if not cond[worst] <= SINGULAR_COND:
        raise ScenarioError(scenario.source, "geometry",
                            f"the sample at t = {t[worst]:.6g} s is too close to a singular configuration "
                            f"(velocity Jacobian condition number {cond[worst]:.3g} > {SINGULAR_COND:.0e}); "
                            "its reference values cannot be trusted")
    raw = raw_reference(build_mechanism(scenario), t)
    _refuse_nonfinite(scenario, t, raw.to_numpy(), "mass",
                      "the reaction forces overflow float64 (masses × accelerations too large)")


def _refuse_nonfinite(scenario: Scenario, t: np.ndarray, values: np.ndarray, key: str, why: str) -> None:
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        raise ScenarioError(scenario.source, key, f"{why} at t = {t[int(np.argmax(bad))]:.6g} s")


def analyse(scenario: Scenario, samples: int | None = None) -> Analysis:
    if scenario.mechanism == "spatial":       # prescribed or integrated: its structure either way
        return analyse_spatial(scenario, samples)
    if scenario.forward_dynamics:
        raise ScenarioError(scenario.source, scenario.key("initial"),
                            "`mechval analyse` follows a prescribed motion; this scene's motion is integrated "
                            "(torque-driven or free): see it with `mechval simulate --engine reference`")
    closed = scenario.closed_form
    if closed is None:
        return analyse_planar(scenario, samples)
    return analyse_closed_form(scenario, closed, samples)


def analyse_closed_form(scenario: Scenario, closed: ClosedForm, samples: int | None = None) -> Analysis:
    """The closed form's own analysis (`LoopAnalysis`, each kind's
    `analysis`) and the loop Jacobian's condition over the run."""
    t = np.linspace(0.0, scenario.time.end, samples or max(scenario.time.samples, 2001))
    k = closed.kinematics(t)
    own, cond = closed.module.analysis(closed.geometry, k, t), closed.jacobian_condition(k)
    mu, worst = own.transmission, int(np.argmax(cond))
    return Analysis(
        scenario=scenario.name, mechanism=closed.kind, grashof=own.grashof, linkage_type=own.linkage_type,
        transmission_min=float(mu.min()), transmission_max=float(mu.max()),
        transmission_t_min=float(t[int(np.argmin(mu))]), toggles=tuple(sorted(own.toggles)),
        jacobian_cond_max=float(cond[worst]), jacobian_cond_t=float(t[worst]),
        quick_return=own.quick_return, quick_return_measured=own.quick_return_measured,
    )


def format_analysis(a: Analysis, max_toggles: int = 12) -> str:
    if isinstance(a, SpatialAnalysis):
        return format_spatial_analysis(a, max_toggles)
    if not isinstance(a, Analysis):
        return format_planar_analysis(a, max_toggles)
    lines = [
        f"scenario            {a.scenario} ({a.mechanism})",
        f"Grashof             {a.grashof}",
        f"linkage type        {a.linkage_type}",
        f"transmission angle  {np.degrees(a.transmission_min):.2f}° … {np.degrees(a.transmission_max):.2f}°"
        f" (minimum at t = {a.transmission_t_min:.4g} s)",
        f"Jacobian cond. max  {a.jacobian_cond_max:.4g} at t = {a.jacobian_cond_t:.4g} s",
        f"toggle instants     {len(a.toggles)}",
    ]
    if a.quick_return is not None or a.quick_return_measured is not None:
        shown = lambda x: "n/a" if x is None else f"{x:.6g}"
        lines.insert(4, f"quick-return ratio  {shown(a.quick_return)} closed form (constant crank speed), "
                        f"{shown(a.quick_return_measured)} measured (forward / return stroke time)")
    lines += [f"  t = {t:10.5f} s  {what}" for t, what in a.toggles[:max_toggles]]
    if len(a.toggles) > max_toggles:
        lines.append(f"  … {len(a.toggles) - max_toggles} more")
    return "\n".join(lines)
