"""Engineering outputs of a linkage analysis: Grashof condition and linkage
type, transmission angle over the run, toggle / dead-centre instants inside
the run, and the distance to singularity (condition number of the velocity
Jacobian), and for the slider-crank inversions with a turning slide the
quick-return time ratio (closed form and measured). References: Norton,
*Design of Machinery*, §2.12 (Grashof), §4.10 (transmission angle), §4.12
(toggle positions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .linkages import ClosedForm, build_mechanism
from .planar_analysis import analyse_planar, format_planar_analysis
from .reference import raw_reference
from .scenario import Scenario, ScenarioError


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


def _sign_changes(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Instants where f changes sign, linearly interpolated between samples."""
    k = np.flatnonzero(np.signbit(f[:-1]) != np.signbit(f[1:]))
    return t[k] - f[k] * (t[k + 1] - t[k]) / (f[k + 1] - f[k])


def _cond2(m11, m12, m21, m22) -> np.ndarray:
    """2-norm condition number of 2×2 matrices from their singular values."""
    frob2 = m11**2 + m12**2 + m21**2 + m22**2
    det = np.abs(m11 * m22 - m12 * m21)
    root = np.sqrt(np.maximum(frob2**2 - 4 * det**2, 0.0))
    s_max = np.sqrt((frob2 + root) / 2)
    with np.errstate(divide="ignore"):
        return np.where(det > 0, s_max**2 / np.where(det > 0, det, 1.0), np.inf)


def measured_stroke_ratio(t: np.ndarray, omega_out: np.ndarray, omega2: np.ndarray) -> float | None:
    """Mean forward over mean return stroke time of a rocking link: strokes
    run between sign changes of its rate; a forward stroke turns it the way
    the crank turns. None without a complete stroke of each kind."""
    ends = _sign_changes(t, omega_out)
    if len(ends) < 3:
        return None
    mid = (ends[:-1] + ends[1:]) / 2
    forward = np.sign(np.interp(mid, t, omega_out)) == np.sign(np.interp(mid, t, omega2))
    if forward.all() or not forward.any():
        return None
    durations = np.diff(ends)
    return float(durations[forward].mean() / durations[~forward].mean())


def fourbar_type(ground: float, crank: float, coupler: float, rocker: float) -> tuple[str, str]:
    """Grashof condition s + l vs p + q and the resulting linkage type."""
    lengths = {"ground": ground, "crank": crank, "coupler": coupler, "rocker": rocker}
    ordered = sorted(lengths.values())
    s_plus_l, p_plus_q = ordered[0] + ordered[3], ordered[1] + ordered[2]
    if np.isclose(s_plus_l, p_plus_q, rtol=1e-12):
        return "change point (s + l = p + q)", "change-point linkage"
    if s_plus_l > p_plus_q:
        return "non-Grashof (s + l > p + q)", "triple-rocker"
    shortest = min(lengths, key=lengths.get)
    kind = {"ground": "double-crank", "crank": "crank-rocker", "rocker": "crank-rocker (rocker-crank)",
            "coupler": "double-rocker"}[shortest]
    return "Grashof (s + l < p + q)", kind


#: Largest condition number of the velocity Jacobian the reference accepts at
#: a sample: its rounding error grows like cond·ε (≈ 1e-9 relative at 1e7),
#: beyond which "exact to rounding" could not be promised.
SINGULAR_COND = 1e7


def jacobian_condition(kind: str, geometry, k: dict[str, np.ndarray]) -> np.ndarray:
    """2-norm condition number of the loop's velocity Jacobian at each
    instant, columns scaled to the same units (distance to singularity).
    `geometry`: the kind's Geometry dataclass."""
    th2, th3 = k["theta2"], k["theta3"]
    if kind == "fourbar":
        # Unknowns (ω3, ω4): columns b·j·e3, −c·j·e4 (metres).
        b, c, th4 = geometry.coupler, geometry.rocker, k["theta4"]
        return _cond2(-b * np.sin(th3), c * np.sin(th4), b * np.cos(th3), -c * np.cos(th4))
    if kind == "slider_crank":
        # Unknowns (r3·ω3, v4), so both columns carry metres per second.
        return _cond2(-np.sin(th3), -1.0 + 0 * th3, np.cos(th3), 0 * th3)
    # Link 3 slides along link 4 pivoting at O4: unknowns (ρ·ω3, ḃ),
    # ρ = |A − O4|, unit columns j·(A − O4)/ρ and e3.
    a, d = geometry.crank, geometry.ground
    rx, ry = a * np.cos(th2) - d, a * np.sin(th2)
    rho = np.hypot(rx, ry)
    return _cond2(-ry / rho, np.cos(th3), rx / rho, np.sin(th3))


def check_trustworthy(scenario: Scenario, closed: ClosedForm) -> None:
    """Refuse a scenario of the closed form `closed` whose reference cannot be trusted at some sample:
    values that overflow float64, or a configuration too close to singular
    (condition number above SINGULAR_COND). Names the instant and why."""
    with np.errstate(all="ignore"):       # overflow is detected and reported below
        _check_trustworthy(scenario, closed)


def _check_trustworthy(scenario: Scenario, closed: ClosedForm) -> None:
    t = scenario.time.t
    kinematics = closed.kinematics(t)
    _refuse_nonfinite(scenario, t, np.column_stack(list(kinematics.values())), "drive",
                      "the crank's motion overflows float64")
    cond = jacobian_condition(closed.kind, closed.geometry, kinematics)
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
    if scenario.forward_dynamics:
        raise ScenarioError(scenario.source, scenario.key("initial"), "`mechval analyse` follows a prescribed motion; this scene's "
                                                  "motion is integrated (torque-driven or free): see it with "
                                                  "`mechval simulate --engine reference`")
    closed = scenario.closed_form
    if closed is None:
        return analyse_planar(scenario, samples)
    return analyse_closed_form(scenario, closed, samples)


def analyse_closed_form(scenario: Scenario, closed: ClosedForm, samples: int | None = None) -> Analysis:
    """The closed form's own analysis: Grashof or its slider rule, the
    transmission angle, toggles, the loop Jacobian's condition."""
    g, kind_name = closed.geometry, closed.kind
    t = np.linspace(0.0, scenario.time.end, samples or max(scenario.time.samples, 2001))
    k = closed.kinematics(t)
    th2, th3 = k["theta2"], k["theta3"]
    toggles = []
    quick_return = measured = None
    if kind_name == "fourbar":
        th4 = k["theta4"]
        grashof, kind = fourbar_type(g.ground, g.crank, g.coupler, g.rocker)
        mu = np.abs(np.arcsin(np.sin(th4 - th3)))   # acute angle coupler–rocker
        toggles += [(float(x), "toggle: crank and coupler collinear (rocker at a limit, ω4 = 0)")
                    for x in _sign_changes(t, np.sin(th3 - th2))]
    elif kind_name == "slider_crank":
        r2, r3, e = g.crank, g.conrod, g.offset
        full = r3 > r2 + abs(e)
        grashof = "crank turns fully (conrod > crank + |offset|)" if full else \
            "crank cannot turn fully (conrod ≤ crank + |offset|)"
        kind = "offset slider-crank" if e else "in-line slider-crank"
        mu = np.pi / 2 - np.abs(np.arcsin(np.sin(th3)))  # conrod vs the guide's normal
        toggles += [(float(x), "dead centre: crank and conrod collinear (slider at a limit, v4 = 0)")
                    for x in _sign_changes(t, np.sin(th3 - th2))]
    else:   # slotted_lever, inverted_slider: link 3 slides along link 4, which pivots at O4
        a, d, c = g.crank, g.ground, getattr(g, "offset", 0.0)
        grashof = "crank turns fully (|ground − crank| > offset)" if abs(a - d) > c else \
            "crank cannot turn fully (|ground − crank| ≤ offset)"
        kind = {("slotted_lever", True): "crank-slotted lever (quick-return)",
                ("slotted_lever", False): "Whitworth quick-return (the lever turns fully)",
                ("inverted_slider", True): "inverted slider-crank, rocking rod",
                ("inverted_slider", False): "inverted slider-crank, rotating rod"}[kind_name, a < d]
        # The pin force is normal to the slide, the pin moves normal to the
        # crank: μ = 90° with the crank along the slide, 0 at a stroke end.
        mu = np.arcsin(np.abs(np.cos(th2 - th3)))
        toggles += [(float(x), "stroke end: crank perpendicular to the slide (link 3 at a limit, ω3 = 0)")
                    for x in _sign_changes(t, np.cos(th2 - th3))]
        quick_return = closed.module.quick_return_ratio(g)
        measured = measured_stroke_ratio(t, k["omega3"], k["omega2"])
    cond = jacobian_condition(kind_name, g, k)
    worst = int(np.argmax(cond))
    return Analysis(
        scenario=scenario.name, mechanism=kind_name, grashof=grashof, linkage_type=kind,
        transmission_min=float(mu.min()), transmission_max=float(mu.max()),
        transmission_t_min=float(t[int(np.argmin(mu))]), toggles=tuple(sorted(toggles)),
        jacobian_cond_max=float(cond[worst]), jacobian_cond_t=float(t[worst]),
        quick_return=quick_return, quick_return_measured=measured,
    )


def format_analysis(a: Analysis, max_toggles: int = 12) -> str:
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
