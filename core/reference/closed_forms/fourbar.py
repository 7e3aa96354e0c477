"""Four-bar linkage: closed-form kinematics and its scene.

Links (classic numbering): 1 ground O2→O4 of length d along +x, 2 crank
O2→A (a), 3 coupler A→B (b), 4 rocker O4→B (c). Vector loop (Norton eq. 4.5a)

    a·e^{jθ2} + b·e^{jθ3} − c·e^{jθ4} − d = 0.

Positions are solved geometrically (triangle A–B–O4 on the diagonal
s = |O4 − A|, law of cosines; equivalent to Norton eqs. 4.10/4.13) so that
every angle comes out continuous without unwrapping; velocities and
accelerations by Cramer's rule on the differentiated loop (Norton eqs. 6.18,
7.12; `loop.solve_loop_rates`).

Branch "open": B lies left of the directed line A→O4 (convex O2-A-B-O4);
"crossed": right of it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np
import pandas as pd

from mechval.model.drive import DriveLaw
from mechval.reference.closed_forms.loop import LoopAnalysis, cond2, crank_pin, interval_extremes, sign_changes, solve_loop_rates
from mechval.model.mechanism import GROUND, Body, Joint
from mechval.model.scenario import LinkMass, ScenarioError

LINKS = ("crank", "coupler", "rocker")
PINS = ("O2", "A", "B", "O4")


@dataclass(frozen=True)
class FourBarGeometry:
    ground: float
    crank: float
    coupler: float
    rocker: float
    branch: str = "open"

    @property
    def sign(self) -> float:
        return 1.0 if self.branch == "open" else -1.0

    def link_length(self, link: str) -> float:
        return getattr(self, link)


Geometry = FourBarGeometry


def position(g: FourBarGeometry, theta2: np.ndarray) -> dict[str, np.ndarray]:
    """θ3, θ4 (continuous) and the diagonal s for crank angles θ2.

    ψ is the angle of O4 − A. For a < d it stays within (−π/2, π/2); for
    a > d it turns with the crank and is written as θ2 + π + a bounded
    correction, so both forms are continuous in θ2. γ (angle at A between
    AO4 and AB, law of cosines) and δ (angle at O4 between the extension of
    AO4 and O4B) lie in [0, π]; θ3 = ψ ± γ, θ4 = ψ ± δ.
    """
    a, b, c, d = g.crank, g.coupler, g.rocker, g.ground
    s2, c2 = np.sin(theta2), np.cos(theta2)
    if a < d:
        psi = np.arctan2(-a * s2, d - a * c2)
    else:
        psi = theta2 + np.pi + np.arctan2(d * s2, a - d * c2)
    s = np.sqrt(a * a + d * d - 2 * a * d * c2)
    cos_gamma = (b * b + s * s - c * c) / (2 * b * s)
    gamma = np.arccos(cos_gamma)
    delta = np.arctan2(b * np.sin(gamma), b * np.cos(gamma) - s)
    return dict(theta3=psi + g.sign * gamma, theta4=psi + g.sign * delta, diagonal=s, cos_gamma=cos_gamma)


def kinematics(g: FourBarGeometry, law: DriveLaw, t: np.ndarray) -> dict[str, np.ndarray]:
    """θ, ω, α of crank, coupler and rocker at instants t (Norton 4.x/6.18/7.12)."""
    a, b, c = g.crank, g.coupler, g.rocker
    th2, w2, al2 = law.angle(t), law.rate(t), law.acceleration(t)
    pos = position(g, th2)
    th3, th4 = pos["theta3"], pos["theta4"]
    (c2, s2), e3, e4 = ((np.cos(th), np.sin(th)) for th in (th2, th3, th4))
    # Velocity loop: b·ω3·j·e3 − c·ω4·j·e4 = −a·ω2·j·e2.
    w3, w4 = solve_loop_rates(b, e3, c, e4, a * w2 * s2, -a * w2 * c2)
    # Acceleration loop: b·α3·j·e3 − c·α4·j·e4 =
    #   −a·(α2·j − ω2²)·e2 + b·ω3²·e3 − c·ω4²·e4.
    rx = a * al2 * s2 + a * w2**2 * c2 + b * w3**2 * e3[0] - c * w4**2 * e4[0]
    ry = -a * al2 * c2 + a * w2**2 * s2 + b * w3**2 * e3[1] - c * w4**2 * e4[1]
    al3, al4 = solve_loop_rates(b, e3, c, e4, rx, ry)
    return dict(theta2=th2, omega2=w2, alpha2=al2, theta3=th3, omega3=w3, alpha3=al3,
                theta4=th4, omega4=w4, alpha4=al4)


def body_motion(g: FourBarGeometry, law: DriveLaw, t: np.ndarray) -> pd.DataFrame:
    """Raw motion columns of the three body frames (origins O2, A, O4)."""
    k = kinematics(g, law, t)
    zero = np.zeros_like(k["theta2"])
    origin = {
        "crank": (zero, zero, zero, zero, zero, zero),
        "coupler": crank_pin(g.crank, k["theta2"], k["omega2"], k["alpha2"]),
        "rocker": (zero + g.ground, zero, zero, zero, zero, zero),
    }
    columns = {"t": np.asarray(t, dtype=float)}
    for link, n in zip(LINKS, (2, 3, 4)):
        x, y, vx, vy, ax, ay = origin[link]
        columns.update({f"{link}.x": x, f"{link}.y": y, f"{link}.theta": k[f"theta{n}"],
                        f"{link}.vx": vx, f"{link}.vy": vy, f"{link}.omega": k[f"omega{n}"],
                        f"{link}.ax": ax, f"{link}.ay": ay, f"{link}.alpha": k[f"alpha{n}"]})
    return pd.DataFrame(columns)


def check_closure(g: FourBarGeometry, law: DriveLaw, t: np.ndarray, source, key="geometry") -> None:
    """Refuse a run in which the loop cannot close (or locks) at some instant.

    The diagonal s² = a² + d² − 2ad·cosθ2 must stay strictly between
    (b − c)² and (b + c)². Its extremes over the run follow exactly from the
    extremes of cosθ2 over the crank's angle range; the dense grid t only
    locates the first failing instant for the message.
    """
    a, b, c, d = g.crank, g.coupler, g.rocker, g.ground
    if a == d:
        raise ScenarioError(source, f"{key}.crank", "crank equals ground: A passes through O4, the loop is singular")
    th2 = law.angle(t)
    cmin, cmax = interval_extremes(float(th2.min()), float(th2.max()), np.cos)
    s_lo, s_hi = np.sqrt(a * a + d * d - 2 * a * d * cmax), np.sqrt(a * a + d * d - 2 * a * d * cmin)
    if abs(b - c) < s_lo and s_hi < b + c:
        return
    s = np.sqrt(a * a + d * d - 2 * a * d * np.cos(th2))
    bad = np.flatnonzero((s >= b + c) | (s <= abs(b - c)))
    where = (f"at t = {t[bad[0]]:.6g} s (θ2 = {th2[bad[0]]:.6g} rad), |O4A| = {s[bad[0]]:.6g} m"
             if bad.size else f"within the run, |O4A| ranges over [{s_lo:.6g}, {s_hi:.6g}] m")
    raise ScenarioError(
        source, key,
        f"the loop cannot close {where}; coupler + rocker = {b + c:.6g} m and "
        f"|coupler − rocker| = {abs(b - c):.6g} m must strictly bound it "
        f"(ground {d:.6g}, crank {a:.6g}, coupler {b:.6g}, rocker {c:.6g} m)")


SIGNAL_MAP = {
    **{f"{q}{n}": f"{link}.{q}" for link, n in zip(LINKS, (2, 3, 4)) for q in ("theta", "omega", "alpha")},
    "F12x": "O2.Fx", "F12y": "O2.Fy", "F32x": "A.Fx", "F32y": "A.Fy",
    "F43x": "B.Fx", "F43y": "B.Fy", "F14x": "O4.Fx", "F14y": "O4.Fy", "T12": "drive.T",
}


def scene_parts(g: FourBarGeometry, mass: Mapping[str, LinkMass],
                damping: Mapping[str, float]) -> tuple[tuple[Body, ...], tuple[Joint, ...]]:
    """Bodies with frames at their first joint, x along the link; joints
    ordered (body_i, body_j) so each reaction is the canonical Fij."""
    a, b, c, d = g.crank, g.coupler, g.rocker, g.ground
    bodies = tuple(Body(link, mass[link].mass, (mass[link].com, 0.0), mass[link].izz) for link in LINKS)
    joints = (
        Joint("O2", "revolute", GROUND, "crank", (0.0, 0.0), (0.0, 0.0), damping=damping.get("O2", 0.0)),
        Joint("A", "revolute", "coupler", "crank", (0.0, 0.0), (a, 0.0), damping=damping.get("A", 0.0)),
        Joint("B", "revolute", "rocker", "coupler", (c, 0.0), (b, 0.0), damping=damping.get("B", 0.0)),
        Joint("O4", "revolute", GROUND, "rocker", (d, 0.0), (0.0, 0.0), damping=damping.get("O4", 0.0)),
    )
    return bodies, joints


def assembly_indicator(g: FourBarGeometry) -> Callable[[Mapping[str, np.ndarray]], np.ndarray]:
    return lambda raw: assembly_side(g, raw)


def assembly_side(g: FourBarGeometry, raw) -> np.ndarray:
    """(O4 − A) × (B − A) from the coupler's pose: > 0 on the open branch
    (B left of A→O4), < 0 on the crossed one."""
    ax, ay, th3 = (np.asarray(raw[f"coupler.{q}"]) for q in ("x", "y", "theta"))
    return (g.ground - ax) * np.sin(th3) - (-ay) * np.cos(th3)


def fourbar_type(ground: float, crank: float, coupler: float, rocker: float) -> tuple[str, str]:
    """Grashof condition s + l vs p + q and the resulting linkage type
    (Norton §2.12)."""
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


def analysis(g: FourBarGeometry, k: dict[str, np.ndarray], t: np.ndarray) -> LoopAnalysis:
    """Grashof, the coupler–rocker transmission angle, the toggles (crank
    and coupler collinear) over the kinematics k at instants t."""
    th2, th3, th4 = k["theta2"], k["theta3"], k["theta4"]
    grashof, kind = fourbar_type(g.ground, g.crank, g.coupler, g.rocker)
    toggles = [(float(x), "toggle: crank and coupler collinear (rocker at a limit, ω4 = 0)")
               for x in sign_changes(t, np.sin(th3 - th2))]
    return LoopAnalysis(grashof, kind, np.abs(np.arcsin(np.sin(th4 - th3))), toggles)


def jacobian_condition(g: FourBarGeometry, k: dict[str, np.ndarray]) -> np.ndarray:
    """Unknowns (ω3, ω4): columns b·j·e3, −c·j·e4 (metres)."""
    b, c, th3, th4 = g.coupler, g.rocker, k["theta3"], k["theta4"]
    return cond2(-b * np.sin(th3), c * np.sin(th4), b * np.cos(th3), -c * np.cos(th4))
