"""Crank-slotted lever (shaper quick-return): kinematics and its scene.

Inversion of the slider-crank chain in which the guide turns: links 1 ground
O2→O4 of length r1 along +x (lever pivot O4 = (r1, 0)), 2 crank O2→A (r2),
3 block pinned to the crank at A, 4 slotted lever pivoted at O4, along which
the block slides. Vector loop (Norton eq. 4.18 with c = 0)

    r2·e^{jθ2} = r1 + r4·e^{jθ4},    θ3 = θ4 (the block turns with the lever),

so r4 = |A − O4| = √(r1² + r2² − 2·r1·r2·cosθ2) and θ4 = arg(A − O4) =
atan2(r2·sinθ2, r2·cosθ2 − r1), kept continuous (for r2 < r1 in (π/2, 3π/2);
for r2 > r1, the Whitworth drive, the lever turns fully and θ4 follows the
crank across turns). The differentiated loop times e^{−jθ4} gives
(Norton eqs. 6.24–6.26, 7.18–7.20 with c = 0)

    ω4 = r2·ω2·cos(θ2 − θ4) / r4,        ṙ4 = r2·ω2·sin(θ4 − θ2),
    α4 = (r2·(α2·cos(θ2 − θ4) − ω2²·sin(θ2 − θ4)) − 2·ṙ4·ω4) / r4,
    r̈4 = −r2·(α2·sin(θ2 − θ4) + ω2²·cos(θ2 − θ4)) + r4·ω4²,

computed by `inverted_slider.slide_loop`. For r2 < r1 the lever swings
between the tangents from O4 to the crank circle (cosθ2 = r2/r1), so at a
constant crank speed the stroke that takes the crank through the far side
lasts longer than the return: time ratio (π + 2·asin(r2/r1)) /
(π − 2·asin(r2/r1)) (`quick_return_ratio`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pandas as pd

from mechval.model.drive import DriveLaw
from mechval.reference.closed_forms.inverted_slider import (first_instant, frames_table, pivot_reach, slide_analysis, slide_condition, slide_loop,
                              slide_signal_map, stroke_time_ratio)
from mechval.reference.closed_forms.loop import LoopAnalysis, crank_pin
from mechval.model.mechanism import GROUND, Body, Joint
from mechval.model.scenario import LinkMass, ScenarioError

LINKS = ("crank", "block", "lever")
PINS = ("O2", "A", "slot", "O4")


@dataclass(frozen=True)
class SlottedLeverGeometry:
    ground: float         # r1 = |O2 O4|
    crank: float          # r2
    lever: float          # slotted length from O4; the block must stay on it

    def link_length(self, link: str) -> float:
        return getattr(self, link)


Geometry = SlottedLeverGeometry


def kinematics(g: SlottedLeverGeometry, law: DriveLaw, t: np.ndarray) -> dict[str, np.ndarray]:
    """θ, ω, α of crank, block (= lever) and lever, and the block's slide
    r4, ṙ4, r̈4 along the lever from O4 (s34, v34, a34)."""
    th2, w2, al2 = law.angle(t), law.rate(t), law.acceleration(t)
    k = slide_loop(g.crank, g.ground, 0.0, 1.0, th2, w2, al2)
    return dict(theta2=th2, omega2=w2, alpha2=al2, **k,
                theta4=k["theta3"], omega4=k["omega3"], alpha4=k["alpha3"])


def quick_return_ratio(g: SlottedLeverGeometry) -> float | None:
    """Forward over return stroke time at a constant crank speed, or None
    for the Whitworth drive (r2 > r1: the lever turns fully, its strokes are
    set by the ram's linkage, which is not modelled)."""
    return stroke_time_ratio(g.crank, g.ground, 0.0)


def body_motion(g: SlottedLeverGeometry, law: DriveLaw, t: np.ndarray) -> pd.DataFrame:
    """Raw motion columns of the body frames: crank at O2, block at A, lever
    at O4, both along the lever (x from O4 towards A)."""
    k = kinematics(g, law, t)
    zero = np.zeros_like(k["theta2"])
    x, y, vx, vy, ax, ay = crank_pin(g.crank, k["theta2"], k["omega2"], k["alpha2"])
    return frames_table(t, {
        "crank": (zero, zero, k["theta2"], zero, zero, k["omega2"], zero, zero, k["alpha2"]),
        "block": (x, y, k["theta4"], vx, vy, k["omega4"], ax, ay, k["alpha4"]),
        "lever": (zero + g.ground, zero, k["theta4"], zero, zero, k["omega4"], zero, zero, k["alpha4"]),
    })


def check_closure(g: SlottedLeverGeometry, law: DriveLaw, t: np.ndarray, source, key="geometry") -> None:
    """Refuse crank = ground (the block passes through O4, where θ4 is
    undefined) and a run in which the block leaves the lever (r4 ≥ lever)."""
    r1, r2 = g.ground, g.crank
    if r2 == r1:
        raise ScenarioError(source, f"{key}.crank", "crank equals ground: the block passes through O4, "
                                                    "the lever angle is undefined there")
    _, hi, th2, r4 = pivot_reach(r2, r1, law, t)
    if hi >= g.lever:
        bad = r4 >= g.lever
        where = first_instant(t, th2, bad, "|O4A|", r4) if bad.any() else f"within the run, |O4A| reaches {hi:.6g} m"
        raise ScenarioError(source, f"{key}.lever",
                            f"the block leaves the lever {where}, not less than lever = {g.lever:.6g} m "
                            f"(ground {r1:.6g}, crank {r2:.6g} m)")


SIGNAL_MAP = slide_signal_map(LINKS, "slot")


def scene_parts(g: SlottedLeverGeometry, mass: Mapping[str, LinkMass],
                damping: Mapping[str, float]) -> tuple[tuple[Body, ...], tuple[Joint, ...]]:
    """The slot is a prismatic joint (lever, block): the block's pin A moves
    along the lever's x axis through O4; its reaction F43 acts at A with the
    couple M43. The block's centre of mass is its pin A."""
    bodies = tuple(Body(link, mass[link].mass, (mass[link].com, 0.0), mass[link].izz) for link in LINKS)
    joints = (
        Joint("O2", "revolute", GROUND, "crank", (0.0, 0.0), (0.0, 0.0), damping=damping.get("O2", 0.0)),
        Joint("A", "revolute", "block", "crank", (0.0, 0.0), (g.crank, 0.0), damping=damping.get("A", 0.0)),
        Joint("slot", "prismatic", "lever", "block", (0.0, 0.0), (0.0, 0.0), axis=(1.0, 0.0),
              damping=damping.get("slot", 0.0)),
        Joint("O4", "revolute", GROUND, "lever", (g.ground, 0.0), (0.0, 0.0), damping=damping.get("O4", 0.0)),
    )
    return bodies, joints


def assembly_indicator(g: SlottedLeverGeometry) -> None:
    """No indicator: the lever's slot takes the block on either side."""
    return None


def analysis(g: SlottedLeverGeometry, k: dict[str, np.ndarray], t: np.ndarray) -> LoopAnalysis:
    return slide_analysis(g.crank, g.ground, 0.0, k, t, ("crank-slotted lever (quick-return)",
                          "Whitworth quick-return (the lever turns fully)"), quick_return_ratio(g))


def jacobian_condition(g: SlottedLeverGeometry, k: dict[str, np.ndarray]) -> np.ndarray:
    return slide_condition(g.crank, g.ground, k)
