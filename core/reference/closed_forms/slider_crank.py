"""Offset slider-crank: closed-form kinematics and its scene.

Links: 1 ground with the guide y = e, 2 crank O2→A (r2), 3 connecting rod
A→B (r3), 4 slider at B = (x4, e). Vector loop (Norton eq. 4.14a)

    r2·e^{jθ2} + r3·e^{jθ3} − x4 − j·e = 0,

so r3·sinθ3 = e − r2·sinθ2 (Norton eq. 4.16). Branch "right": x4 greater
than the crank pin's x (cosθ3 > 0, θ3 = asin(h/r3)); "left": θ3 = π − asin
(h/r3). Both are continuous without unwrapping. Velocities and
accelerations follow from the differentiated loop (Norton eqs. 6.20, 7.16):

    r3·ω3·j·e3 − v4 = −r2·ω2·j·e2
    r3·α3·j·e3 − a4 = −r2·(α2·j − ω2²)·e2 + r3·ω3²·e3
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np
import pandas as pd

from mechval.model.drive import DriveLaw
from mechval.reference.closed_forms.loop import LoopAnalysis, cond2, crank_pin, interval_extremes, sign_changes
from mechval.model.mechanism import GROUND, Body, Joint
from mechval.model.scenario import LinkMass, ScenarioError

LINKS = ("crank", "conrod", "slider")
PINS = ("O2", "A", "B", "guide")


@dataclass(frozen=True)
class SliderCrankGeometry:
    crank: float
    conrod: float
    offset: float = 0.0
    branch: str = "right"

    @property
    def sign(self) -> float:
        return 1.0 if self.branch == "right" else -1.0

    def link_length(self, link: str) -> float:
        return getattr(self, link)


Geometry = SliderCrankGeometry


def kinematics(g: SliderCrankGeometry, law: DriveLaw, t: np.ndarray) -> dict[str, np.ndarray]:
    r2, r3, e = g.crank, g.conrod, g.offset
    th2, w2, al2 = law.angle(t), law.rate(t), law.acceleration(t)
    s2, c2 = np.sin(th2), np.cos(th2)
    lift = np.arcsin((e - r2 * s2) / r3)
    th3 = lift if g.sign > 0 else np.pi - lift
    s3, c3 = np.sin(th3), np.cos(th3)
    x4 = r2 * c2 + r3 * c3
    # Imaginary part fixes ω3, the real part then gives v4 (Norton 6.20).
    w3 = -r2 * w2 * c2 / (r3 * c3)
    v4 = -r2 * w2 * s2 - r3 * w3 * s3
    # Norton 7.16, same split.
    al3 = (r2 * w2**2 * s2 - r2 * al2 * c2 + r3 * w3**2 * s3) / (r3 * c3)
    a4 = -r2 * al2 * s2 - r2 * w2**2 * c2 - r3 * al3 * s3 - r3 * w3**2 * c3
    return dict(theta2=th2, omega2=w2, alpha2=al2, theta3=th3, omega3=w3, alpha3=al3,
                x4=x4, v4=v4, a4=a4)


def body_motion(g: SliderCrankGeometry, law: DriveLaw, t: np.ndarray) -> pd.DataFrame:
    """Raw motion columns of the body frames (origins O2, A, B; the slider
    frame keeps θ = 0)."""
    k = kinematics(g, law, t)
    zero = np.zeros_like(k["theta2"])
    th2, w2, al2 = k["theta2"], k["omega2"], k["alpha2"]
    x, y, vx, vy, ax, ay = crank_pin(g.crank, th2, w2, al2)
    frames = {
        "crank": (zero, zero, th2, zero, zero, w2, zero, zero, al2),
        "conrod": (x, y, k["theta3"], vx, vy, k["omega3"], ax, ay, k["alpha3"]),
        "slider": (k["x4"], zero + g.offset, zero, k["v4"], zero, zero, k["a4"], zero, zero),
    }
    columns = {"t": np.asarray(t, dtype=float)}
    for link, values in frames.items():
        columns.update({f"{link}.{q}": v for q, v in
                        zip(("x", "y", "theta", "vx", "vy", "omega", "ax", "ay", "alpha"), values)})
    return pd.DataFrame(columns)


def check_closure(g: SliderCrankGeometry, law: DriveLaw, t: np.ndarray, source, key="geometry") -> None:
    """Refuse a run in which |e − r2·sinθ2| reaches r3 (the rod cannot reach
    the guide, or stands perpendicular to it and locks) at some instant."""
    r2, r3, e = g.crank, g.conrod, g.offset
    th2 = law.angle(t)
    smin, smax = interval_extremes(float(th2.min()), float(th2.max()), np.sin)
    reach = max(abs(e - r2 * smin), abs(e - r2 * smax))
    if reach < r3:
        return
    h = np.abs(e - r2 * np.sin(th2))
    bad = np.flatnonzero(h >= r3)
    where = (f"at t = {t[bad[0]]:.6g} s (θ2 = {th2[bad[0]]:.6g} rad), |offset − crank·sinθ2| = {h[bad[0]]:.6g} m"
             if bad.size else f"within the run, |offset − crank·sinθ2| reaches {reach:.6g} m")
    raise ScenarioError(
        source, key,
        f"the loop cannot close {where}, not less than conrod = {r3:.6g} m "
        f"(crank {r2:.6g}, conrod {r3:.6g}, offset {e:.6g} m)")


SIGNAL_MAP = {
    **{f"{q}{n}": f"{link}.{q}" for link, n in (("crank", 2), ("conrod", 3)) for q in ("theta", "omega", "alpha")},
    "x4": "slider.x", "v4": "slider.vx", "a4": "slider.ax",
    "F12x": "O2.Fx", "F12y": "O2.Fy", "F32x": "A.Fx", "F32y": "A.Fy",
    "F43x": "B.Fx", "F43y": "B.Fy", "F14y": "guide.Fy", "T12": "drive.T",
}


def scene_parts(g: SliderCrankGeometry, mass: Mapping[str, LinkMass],
                damping: Mapping[str, float]) -> tuple[tuple[Body, ...], tuple[Joint, ...]]:
    r2, r3, e = g.crank, g.conrod, g.offset
    bodies = tuple(Body(link, mass[link].mass, (mass[link].com, 0.0), mass[link].izz) for link in LINKS)
    joints = (
        Joint("O2", "revolute", GROUND, "crank", (0.0, 0.0), (0.0, 0.0), damping=damping.get("O2", 0.0)),
        Joint("A", "revolute", "conrod", "crank", (0.0, 0.0), (r2, 0.0), damping=damping.get("A", 0.0)),
        Joint("B", "revolute", "slider", "conrod", (0.0, 0.0), (r3, 0.0), damping=damping.get("B", 0.0)),
        Joint("guide", "prismatic", GROUND, "slider", (0.0, e), (0.0, 0.0), axis=(1.0, 0.0),
              damping=damping.get("guide", 0.0)),
    )
    return bodies, joints


def assembly_indicator(g: SliderCrankGeometry) -> Callable[[Mapping[str, np.ndarray]], np.ndarray]:
    return assembly_side


def assembly_side(raw) -> np.ndarray:
    """x of B relative to the crank pin A (the rod's x extent): > 0 on the
    right branch, < 0 on the left one."""
    return np.cos(np.asarray(raw["conrod.theta"]))


def analysis(g: SliderCrankGeometry, k: dict[str, np.ndarray], t: np.ndarray) -> LoopAnalysis:
    """Whether the crank turns fully, the conrod's transmission angle to the
    guide's normal, the dead centres (crank and conrod collinear)."""
    r2, r3, e = g.crank, g.conrod, g.offset
    th2, th3 = k["theta2"], k["theta3"]
    grashof = ("crank turns fully (conrod > crank + |offset|)" if r3 > r2 + abs(e) else
               "crank cannot turn fully (conrod ≤ crank + |offset|)")
    toggles = [(float(x), "dead centre: crank and conrod collinear (slider at a limit, v4 = 0)")
               for x in sign_changes(t, np.sin(th3 - th2))]
    return LoopAnalysis(grashof, "offset slider-crank" if e else "in-line slider-crank",
                        np.pi / 2 - np.abs(np.arcsin(np.sin(th3))), toggles)


def jacobian_condition(g: SliderCrankGeometry, k: dict[str, np.ndarray]) -> np.ndarray:
    """Unknowns (r3·ω3, v4), so both columns carry metres per second."""
    th3 = k["theta3"]
    return cond2(-np.sin(th3), -1.0 + 0 * th3, np.cos(th3), 0 * th3)
