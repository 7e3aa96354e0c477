"""Inverted slider-crank (hand pump): closed-form kinematics and its scene.

Inversion #3 of the slider-crank chain (Norton §4.7, Fig. 4-10): the sliding
joint is between links 3 and 4. Links: 1 ground O2→O4 of length d along +x,
2 crank O2→A (a), 3 rod pinned to the crank at A and sliding through a
sleeve at B, 4 rocker O4→B of length c (the offset: the perpendicular
distance from O4 to the rod's line), pivoted at O4. Vector loop (Norton
eqs. 4.18, 4.19 with γ = 90°)

    a·e^{jθ2} − b·e^{jθ3} − c·e^{jθ4} − d = 0,    θ4 = θ3 − σ·π/2,

with b = |BA| > 0 the rod's position in the sleeve and θ3 the direction
B→A. Branch "left": O4 lies left of the directed rod line B→A (σ = +1,
θ4 = θ3 − 90°); "right": right of it (σ = −1, θ4 = θ3 + 90°).

Positions are solved geometrically (equivalent to Norton's half-angle
solution, eq. 4.20, whose ± picks the branch): with A − O4 = ρ·e^{jψ},
b = √(ρ² − c²) and θ3 = ψ + atan2(σ·c, b). Multiplying the differentiated
loop by e^{−jθ3} (δ = θ2 − θ3; Norton eqs. 6.24–6.26, 7.18–7.20 with γ = 90°)

    ω3 = a·ω2·cosδ / b,                  ḃ = −a·ω2·sinδ − σ·c·ω3,
    α3 = (a·(α2·cosδ − ω2²·sinδ) − σ·c·ω3² − 2·ḃ·ω3) / b      (2·ḃ·ω3: Coriolis),
    b̈ = −a·(α2·sinδ + ω2²·cosδ) − σ·c·α3 + b·ω3²,

and ω4 = ω3, α4 = α3. With c = 0 this is also the loop of the crank-slotted
lever (`mechval.reference.closed_forms.slotted_lever`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pandas as pd

from mechval.model.drive import DriveLaw
from mechval.reference.closed_forms.loop import LoopAnalysis, cond2, crank_pin, interval_extremes, measured_stroke_ratio, sign_changes
from mechval.model.mechanism import GROUND, MOTION_QUANTITIES, Body, Joint
from mechval.model.scenario import LinkMass, ScenarioError

LINKS = ("crank", "rod", "rocker")
PINS = ("O2", "A", "sleeve", "O4")


@dataclass(frozen=True)
class InvertedSliderGeometry:
    ground: float
    crank: float
    rod: float            # length of link 3 from A; the sleeve must stay on it
    offset: float = 0.0   # c ≥ 0
    branch: str = "left"

    @property
    def sign(self) -> float:
        return 1.0 if self.branch == "left" else -1.0

    def link_length(self, link: str) -> float:
        return getattr(self, link)


Geometry = InvertedSliderGeometry


def pivot_ray(a: float, d: float, theta2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ρ = |A − O4| and ψ = arg(A − O4), continuous in θ2.

    For a < d, A − O4 always points to −x: ψ = π + atan2(−a·sinθ2, d −
    a·cosθ2) stays in (π/2, 3π/2). For a ≥ d it turns with the crank:
    A − O4 = e^{jθ2}·(a − d·e^{−jθ2}), so ψ = θ2 + atan2(d·sinθ2, a −
    d·cosθ2) with a bounded correction (singular only where A = O4).
    """
    s2, c2 = np.sin(theta2), np.cos(theta2)
    rho = np.sqrt(a * a + d * d - 2 * a * d * c2)
    if a < d:
        return rho, np.pi + np.arctan2(-a * s2, d - a * c2)
    return rho, theta2 + np.arctan2(d * s2, a - d * c2)


def slide_loop(a: float, d: float, c: float, sigma: float, th2, w2, al2) -> dict[str, np.ndarray]:
    """θ3, ω3, α3 and b, ḃ, b̈ of the loop a·e^{jθ2} = d + c·e^{jθ4} + b·e^{jθ3}
    (module docstring)."""
    rho, psi = pivot_ray(a, d, th2)
    b = np.sqrt(rho * rho - c * c)
    th3 = psi + np.arctan2(sigma * c, b)
    sd, cd = np.sin(th2 - th3), np.cos(th2 - th3)
    w3 = a * w2 * cd / b
    bd = -a * w2 * sd - sigma * c * w3
    al3 = (a * (al2 * cd - w2**2 * sd) - sigma * c * w3**2 - 2 * bd * w3) / b
    bdd = -a * (al2 * sd + w2**2 * cd) - sigma * c * al3 + b * w3**2
    return dict(theta3=th3, omega3=w3, alpha3=al3, s34=b, v34=bd, a34=bdd)


def kinematics(g: InvertedSliderGeometry, law: DriveLaw, t: np.ndarray) -> dict[str, np.ndarray]:
    """θ, ω, α of crank, rod and rocker, and the rod's slide b, ḃ, b̈ (s34, v34, a34)."""
    th2, w2, al2 = law.angle(t), law.rate(t), law.acceleration(t)
    k = slide_loop(g.crank, g.ground, g.offset, g.sign, th2, w2, al2)
    return dict(theta2=th2, omega2=w2, alpha2=al2, **k,
                theta4=k["theta3"] - g.sign * np.pi / 2, omega4=k["omega3"], alpha4=k["alpha3"])


def stroke_time_ratio(a: float, d: float, c: float) -> float | None:
    """Forward over return stroke time of the rocking link 3 at a constant
    crank speed (quick-return ratio), or None unless a + c < d (otherwise
    link 3 turns fully or the crank cannot).

    At a stroke end ω3 = 0, so the crank is perpendicular to the rod line,
    which is then tangent to the crank circle at A and passes at the offset
    c from O4: d·cosθ2 = a ∓ c. The crank turns β = acos((a − c)/d) +
    acos((a + c)/d) between the two ends on O4's side (the return) and
    2π − β on the far side (the forward stroke), so the ratio is (2π − β)/β;
    for c = 0, (π + 2·asin(a/d)) / (π − 2·asin(a/d)).
    """
    if a + c >= d:
        return None
    beta = np.arccos((a - c) / d) + np.arccos((a + c) / d)
    return float((2 * np.pi - beta) / beta)


def quick_return_ratio(g: InvertedSliderGeometry) -> float | None:
    return stroke_time_ratio(g.crank, g.ground, g.offset)


def frames_table(t: np.ndarray, frames: dict[str, tuple]) -> pd.DataFrame:
    """Raw motion columns from per-body (x, y, θ, vx, vy, ω, ax, ay, α)."""
    columns = {"t": np.asarray(t, dtype=float)}
    for body, values in frames.items():
        columns.update({f"{body}.{q}": v for q, v in zip(MOTION_QUANTITIES, values)})
    return pd.DataFrame(columns)


def body_motion(g: InvertedSliderGeometry, law: DriveLaw, t: np.ndarray) -> pd.DataFrame:
    """Raw motion columns of the body frames: crank at O2, rod at A (x along
    B→A, so the rod lies on its −x axis), rocker at O4 (x along O4→B)."""
    k = kinematics(g, law, t)
    zero = np.zeros_like(k["theta2"])
    x, y, vx, vy, ax, ay = crank_pin(g.crank, k["theta2"], k["omega2"], k["alpha2"])
    return frames_table(t, {
        "crank": (zero, zero, k["theta2"], zero, zero, k["omega2"], zero, zero, k["alpha2"]),
        "rod": (x, y, k["theta3"], vx, vy, k["omega3"], ax, ay, k["alpha3"]),
        "rocker": (zero + g.ground, zero, k["theta4"], zero, zero, k["omega4"], zero, zero, k["alpha4"]),
    })


def pivot_reach(a: float, d: float, law: DriveLaw, t: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray]:
    """Exact min and max of ρ = |A − O4| over the run (from the extremes of
    cosθ2 over the crank's range), and θ2, ρ on the grid t to locate a failure."""
    th2 = law.angle(t)
    cmin, cmax = interval_extremes(float(th2.min()), float(th2.max()), np.cos)
    lo = np.sqrt(max(a * a + d * d - 2 * a * d * cmax, 0.0))
    hi = np.sqrt(a * a + d * d - 2 * a * d * cmin)
    return float(lo), float(hi), th2, np.sqrt(a * a + d * d - 2 * a * d * np.cos(th2))


def first_instant(t: np.ndarray, th2: np.ndarray, bad: np.ndarray, what: str, values: np.ndarray) -> str:
    """'at t = … s (θ2 = … rad), what = … m' for the first bad grid instant."""
    k = np.flatnonzero(bad)[0]
    return f"at t = {t[k]:.6g} s (θ2 = {th2[k]:.6g} rad), {what} = {values[k]:.6g} m"


def check_closure(g: InvertedSliderGeometry, law: DriveLaw, t: np.ndarray, source, key="geometry") -> None:
    """Refuse a run in which, at some instant, the rod cannot reach the
    sleeve (ρ ≤ c: b = 0 is singular) or the sleeve leaves the rod (b ≥ rod)."""
    a, d, c = g.crank, g.ground, g.offset
    if c < 0:
        raise ScenarioError(source, f"{key}.offset",
                            f"must not be negative, got {c} (the side of the rod O4 lies on is the branch)")
    lo, hi, th2, rho = pivot_reach(a, d, law, t)
    sizes = f"(ground {d:.6g}, crank {a:.6g}, rod {g.rod:.6g}, offset {c:.6g} m)"
    if lo <= c:
        bad = rho <= c
        where = first_instant(t, th2, bad, "|O4A|", rho) if bad.any() else f"within the run, |O4A| reaches {lo:.6g} m"
        raise ScenarioError(source, key, f"the loop cannot close {where}, not more than offset = {c:.6g} m: "
                                         f"the crank pin reaches the sleeve {sizes}")
    b_max = np.sqrt(hi * hi - c * c)
    if b_max >= g.rod:
        b = np.sqrt(rho * rho - c * c)
        bad = b >= g.rod
        where = first_instant(t, th2, bad, "|BA|", b) if bad.any() else f"within the run, |BA| reaches {b_max:.6g} m"
        raise ScenarioError(source, f"{key}.rod", f"the rod leaves the sleeve {where}, not less than rod {sizes}")


def slide_signal_map(links: tuple[str, str, str], slide: str) -> dict[str, str]:
    """Canonical signal → raw column for a linkage whose link 3 slides along
    link 4 at the prismatic joint `slide` (this one and the slotted lever)."""
    return {
        **{f"{q}{n}": f"{link}.{q}" for link, n in zip(links, (2, 3, 4)) for q in ("theta", "omega", "alpha")},
        "s34": f"{slide}.s", "v34": f"{slide}.v", "a34": f"{slide}.a",
        "F12x": "O2.Fx", "F12y": "O2.Fy", "F32x": "A.Fx", "F32y": "A.Fy",
        "F43x": f"{slide}.Fx", "F43y": f"{slide}.Fy", "N43": f"{slide}.N", "M43": f"{slide}.M",
        "F14x": "O4.Fx", "F14y": "O4.Fy", "T12": "drive.T",
    }


SIGNAL_MAP = slide_signal_map(LINKS, "sleeve")


def scene_parts(g: InvertedSliderGeometry, mass: Mapping[str, LinkMass],
                damping: Mapping[str, float]) -> tuple[tuple[Body, ...], tuple[Joint, ...]]:
    """Bodies with frames at O2, A and O4 (see `body_motion`); the rod's
    centre of mass lies `com` from A towards B, i.e. at (−com, 0). The sleeve
    is a prismatic joint (rocker, rod): the rod's point A moves along the
    rocker-frame axis (0, σ) through B = (c, 0); its reaction F43 acts at A
    with the couple M43."""
    m = mass
    bodies = (Body("crank", m["crank"].mass, (m["crank"].com, 0.0), m["crank"].izz),
              Body("rod", m["rod"].mass, (-m["rod"].com, 0.0), m["rod"].izz),
              Body("rocker", m["rocker"].mass, (m["rocker"].com, 0.0), m["rocker"].izz))
    joints = (
        Joint("O2", "revolute", GROUND, "crank", (0.0, 0.0), (0.0, 0.0), damping=damping.get("O2", 0.0)),
        Joint("A", "revolute", "rod", "crank", (0.0, 0.0), (g.crank, 0.0), damping=damping.get("A", 0.0)),
        Joint("sleeve", "prismatic", "rocker", "rod", (g.offset, 0.0), (0.0, 0.0), axis=(0.0, g.sign),
              damping=damping.get("sleeve", 0.0)),
        Joint("O4", "revolute", GROUND, "rocker", (g.ground, 0.0), (0.0, 0.0), damping=damping.get("O4", 0.0)),
    )
    return bodies, joints


def assembly_indicator(g: InvertedSliderGeometry) -> None:
    """No indicator: the sleeve's side is fixed by its axis (0, σ)."""
    return None


def slide_analysis(crank: float, ground: float, offset: float, k: dict[str, np.ndarray], t: np.ndarray,
                   types: tuple[str, str], quick_return: float | None) -> LoopAnalysis:
    """The analysis of a linkage whose link 3 slides along link 4, which
    pivots at O4 (this one and the slotted lever): whether the crank turns
    fully, μ, the stroke ends; `types`: its linkage type when link 3 rocks
    (crank < ground) and when it turns fully."""
    th2, th3 = k["theta2"], k["theta3"]
    grashof = ("crank turns fully (|ground − crank| > offset)" if abs(crank - ground) > offset else
               "crank cannot turn fully (|ground − crank| ≤ offset)")
    # The pin force is normal to the slide, the pin moves normal to the
    # crank: μ = 90° with the crank along the slide, 0 at a stroke end.
    toggles = [(float(x), "stroke end: crank perpendicular to the slide (link 3 at a limit, ω3 = 0)")
               for x in sign_changes(t, np.cos(th2 - th3))]
    return LoopAnalysis(grashof, types[0] if crank < ground else types[1], np.arcsin(np.abs(np.cos(th2 - th3))),
                        toggles, quick_return, measured_stroke_ratio(t, k["omega3"], k["omega2"]))


def slide_condition(crank: float, ground: float, k: dict[str, np.ndarray]) -> np.ndarray:
    """Link 3 slides along link 4 pivoting at O4: unknowns (ρ·ω3, ḃ),
    ρ = |A − O4|, unit columns j·(A − O4)/ρ and e3."""
    th2, th3 = k["theta2"], k["theta3"]
    rx, ry = crank * np.cos(th2) - ground, crank * np.sin(th2)
    rho = np.hypot(rx, ry)
    return cond2(-ry / rho, np.cos(th3), rx / rho, np.sin(th3))


def analysis(g: InvertedSliderGeometry, k: dict[str, np.ndarray], t: np.ndarray) -> LoopAnalysis:
    return slide_analysis(g.crank, g.ground, g.offset, k, t, ("inverted slider-crank, rocking rod",
                          "inverted slider-crank, rotating rod"), quick_return_ratio(g))


def jacobian_condition(g: InvertedSliderGeometry, k: dict[str, np.ndarray]) -> np.ndarray:
    return slide_condition(g.crank, g.ground, k)
