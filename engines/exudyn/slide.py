"""Exudyn: the couple of each slide (prismatic joint), derived from the
moment balance of one of its bodies with Exudyn's own motion and reactions.

Why: `ObjectJointPrismatic2D` reports no couple (its `ForceLocal[2]` stays
0 under any couple), while everything else on the body is at hand. As the
PyBullet adapter does for its slides (the PyBullet adapter's `slide`), the couple is the
one the engine's own solution implies. Euler's equation about the centre of
mass G of a moving body b (Norton, *Design of Machinery*, §11.4,
eq. 11.1c):

    izz_b·α_b = Q_b + L_b + R_b + Σ_J s(J, b)·M_J

Q_b: the applied loads' moment about G (dampers, spring-dampers, body
torques: `AppliedForces`, from Exudyn's node states; gravity acts at G);
L_b: the torque laws, T on body_j and −T on body_i; R_b: the moment about G
of every joint reaction and drive effort as Exudyn reports it, with every
slide couple left out (`body_resultants`); s(J, b) = +1 when b is J's body_j,
−1 when its body_i (M_J is the couple by body_i on body_j, at J's point on
body_j: a couple is the same about any point). One equation per slide, on
its body_j (its body_i when body_j is the ground or already holds another
slide's equation), gives a small constant system solved at every sample.

Exudyn's implicit solvers satisfy the equations of motion at the end of
every step with the accelerations and multipliers they store, at the same
instant (no half-step shift), so the balance holds to Newton's tolerance.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from mechval.model.mechanism import GROUND, Joint, Mechanism
from mechval.reference.planar.constraints import Constraints
from mechval.reference.planar.forces import AppliedForces
from mechval.reference.resultants import body_resultants

#: The reason given for slide couples no balance can single out.
UNDERIVABLE = ("Exudyn 1.13.6 reports no couple of ObjectJointPrismatic2D (ForceLocal[2] stays 0), and the slides' "
               "couples cannot be told apart from the balances of their bodies")
#: What the run info says about the derived couples.
DERIVED_NOTE = "{joint}.M derived from the moment balance of {body} with Exudyn's own motion and reactions"


def balance_bodies(mechanism: Mechanism, slides: tuple[Joint, ...]) -> list[str] | None:
    """Per slide the moving body whose balance gives its couple (body_j
    first), no body twice; None when the balances cannot give every couple."""
    chosen: list[str] = []
    for slide in slides:
        body = next((b for b in (slide.body_j, slide.body_i) if b != GROUND and b not in chosen), None)
        if body is None:
            return None
        chosen.append(body)
    sides = np.array([[_side(slide, body) for slide in slides] for body in chosen])
    return chosen if abs(np.linalg.det(sides)) > 0.5 else None


def derived_note(mechanism: Mechanism) -> str:
    """What the run info says about the derived couples ("" for none)."""
    slides = tuple(j for j in mechanism.joints if j.kind == "prismatic")
    bodies = balance_bodies(mechanism, slides) if slides else None
    return "; ".join(DERIVED_NOTE.format(joint=j.name, body=b) for j, b in zip(slides, bodies or ()))


def _side(joint: Joint, body: str) -> float:
    return 1.0 if body == joint.body_j else -1.0 if body == joint.body_i else 0.0


def slide_couples(mechanism: Mechanism, columns: Mapping[str, np.ndarray], coordinates: np.ndarray,
                  rates: np.ndarray) -> dict[str, np.ndarray] | None:
    """"J.M" of every slide J at the samples, from the raw `columns` there
    (motion of every body frame, every other reaction, drive effort and
    torque law) and the centre-of-mass coordinates and their rates in
    `Mechanism.bodies` order ((samples, 3·bodies): x_G, y_G, θ of each);
    None when the balances cannot give them (`balance_bodies`)."""
    slides = tuple(j for j in mechanism.joints if j.kind == "prismatic")
    bodies = balance_bodies(mechanism, slides)
    if bodies is None:
        return None
    n = len(np.asarray(columns["t"]))
    without = dict(columns) | {f"{slide.name}.M": np.zeros(n) for slide in slides}
    resultants = body_resultants(mechanism, without)
    applied = AppliedForces(Constraints(mechanism)).generalised(coordinates, rates)
    index = {body.name: k for k, body in enumerate(mechanism.bodies)}
    laws = {body: np.zeros(n) for body in bodies}
    for law in mechanism.torque_drives:
        joint = mechanism.joint(law.joint)
        for body in bodies:
            laws[body] = laws[body] + _side(joint, body) * np.asarray(columns[f"{law.name}.T"])
    rest = np.array([mechanism.body(body).izz * np.asarray(columns[f"{body}.alpha"])
                     - applied[:, 3 * index[body] + 2] - laws[body] - resultants[f"{body}.R.M"]
                     for body in bodies])
    sides = np.array([[_side(slide, body) for slide in slides] for body in bodies])
    couples = np.linalg.solve(sides, rest)
    return {f"{slide.name}.M": couple for slide, couple in zip(slides, couples)}
