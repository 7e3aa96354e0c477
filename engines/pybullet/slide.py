"""PyBullet: the reaction of a multibody joint whose sensor is not read,
derived from the balance of one of its bodies with the engine's own motion.

Why: PyBullet's joint sensor reads right only where the joint hangs from
the fixed ground and its child link carries no further moving link. On a
slide whose parent link turns (the block on a slotted lever, the rod in a
pivoted sleeve) it misreports the force and couple by a Coriolis-like term
in ω·ṡ that does not shrink with the step, and on a joint whose child
carries further links it misreads the force (engine findings,
`mechval.engines.findings`), while PyBullet's motion and its other joint
forces are right. So for each such joint J (`layout`: a slide
between two moving bodies, a drive hung below a moving link, a joint
carrying further links) the adapter reports the reaction that PyBullet's
own simulation implies: Newton–Euler on the body b whose balance gives it
(its child link),

    L_b = m_b·(a_Gb − g) − Σ_k F_k→b − F_ext
    M_b(Q) = izz_b·α_b + (G_b − Q)×m_b·(a_Gb − g) − Σ_k (P_k − Q)×F_k→b
             − Σ_k M_k→b − M_ext(Q)

with Q J's point on its body_j (where the convention takes the reaction),
in world axes. J's load on b is (F_J at Q, M_J) when b is J's body_j and
(−F_J at Q, −M_J) when it is body_i, so F_J = ±L_b and, for a slide,
M_J = ±M_b(Q) (a pin's derived reaction is its force only). The sums run
over b's other joints k, each load as PyBullet reports it (a sensor, a
loop constraint, or derived before: `Layout.derived` lists a body's other
derived joints first): a pin's force at its point on b, a slide's at its
point on its body_j with its couple, a drive's effort (a torque, a torque
law's T, a slide drive's force along its axis at its body_j point; J's own
too: F_J is the reaction alone, as in the reference, the drive force F
being its own column); F_ext and M_ext(Q) are the loads the adapter
applied in the step (dampers, spring-dampers, body torques).

Time stamps (docs/engines.md): the forces read after the step from t_n to
t_n+1 belong to t_n, and so does this balance. PyBullet's semi-implicit
Euler moves the joint coordinates by dt·q̇ with the step's new velocity, so
the second central difference of the centre-of-mass positions,
a_G(t_n) = (x_G(t_n+1) − 2·x_G(t_n) + x_G(t_n−1))/dt², is the step's
velocity change over dt, centred at t_n (the difference of the world
velocity readings over the step is stamped half a step late, an O(dt)
error); α_b = (ω_n+½ − ω_n−½)/dt likewise.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
from mechval.model.kinematics import rotate
from mechval.model.mechanism import GROUND, Joint, Mechanism

#: What the run info says about each derived joint (users see that the
#: column is derived, not read).
DERIVED_NOTE = ("{joint}: {what} derived from the balance of {body} with PyBullet's own motion and its "
                "other joint forces, not read from the joint's sensor (engine findings: the sensor misreads "
                "a slide whose parent turns, and a joint whose child carries further links)")
#: The reason for the first sample's missing value when there is no step
#: before it.
NO_EARLIER_STEP = ("derived from the body's balance, which needs the position one step before the "
                   "sample; with no pre-roll (preroll_steps = 0, or a torque-driven or free run) the first "
                   "sample has none")


def derived_quantities(joint: Joint) -> tuple[str, ...]:
    """The reaction columns a derived joint gives: a slide's force and
    couple, a pin's force."""
    return ("Fx", "Fy", "M") if joint.kind == "prismatic" else ("Fx", "Fy")


def derived_note(joint: Joint, body: str) -> str:
    what = "F and M" if joint.kind == "prismatic" else "F"
    return DERIVED_NOTE.format(joint=joint.name, what=what, body=body)


@dataclass(frozen=True)
class BodyTrack:
    """One body's readings at the samples, (n, 6) arrays of frame origin x,
    y, angle, origin vx, vy, ω (the adapter's BodyState): one step before
    t_n (NaN where there is none), at t_n before the step and after it."""

    earlier: np.ndarray
    before: np.ndarray
    after: np.ndarray


def _cross(r: np.ndarray, f: np.ndarray) -> np.ndarray:
    return r[:, 0] * f[:, 1] - r[:, 1] * f[:, 0]


def _column(reactions: Mapping[str, np.ndarray], name: str) -> np.ndarray:
    return np.asarray(reactions[name], dtype=float)


def _points(state: np.ndarray, point: tuple[float, float]) -> np.ndarray:
    """World positions of a body-fixed point, per sample."""
    return state[:, :2] + np.column_stack(rotate(state[:, 2], point))


def _world(tracks: Mapping[str, BodyTrack], body: str, point: tuple[float, float], n: int) -> np.ndarray:
    """World positions of `body`'s point at t_n (the ground's: fixed)."""
    if body == GROUND:
        return np.tile(np.asarray(point, dtype=float), (n, 1))
    return _points(tracks[body].before, point)


def derived_reaction(mechanism: Mechanism, joint: Joint, body_name: str, tracks: Mapping[str, BodyTrack],
                     reactions: Mapping[str, np.ndarray], loads: np.ndarray, dt: float) -> dict[str, np.ndarray]:
    """F_J (world axes, on body_j) and, for a slide, M_J (about J's point on
    body_j) per sample, from the balance of `body_name`, one of J's bodies
    (module docstring). `tracks` holds every moving body's readings;
    `reactions` the reaction columns known so far ("A.Fx", "drive.T", ...);
    `loads` is (n, 3): the external force on the body and its moment about
    the world origin."""
    body = mechanism.body(body_name)
    track = tracks[body_name]
    n = len(track.before)
    com = lambda state: _points(state, body.com)   # noqa: E731
    accel = (com(track.after) - 2 * com(track.before) + com(track.earlier)) / dt**2
    alpha = (track.after[:, 5] - track.before[:, 5]) / dt
    at = track.before
    Q = _world(tracks, joint.body_j, joint.point_j, n)
    net = body.mass * (accel - np.asarray(mechanism.gravity))
    force = net.copy()
    moment = body.izz * alpha + _cross(com(at) - Q, net)
    efforts = [(d.joint, d.effort_column(mechanism.joint(d.joint).kind)) for d in mechanism.drives]
    efforts += [(law.joint, f"{law.name}.T") for law in mechanism.torque_drives]
    for other in mechanism.joints:
        if body.name not in (other.body_i, other.body_j):
            continue
        sign = 1.0 if other.body_j == body.name else -1.0
        if other.kind == "prismatic":     # a slide's load acts at its point on its body_j
            point = _world(tracks, other.body_j, other.point_j, n)
        else:
            point = _points(at, other.point_j if sign > 0 else other.point_i)
        load = np.zeros((n, 2))
        if other.name != joint.name:
            load += sign * np.column_stack((_column(reactions, f"{other.name}.Fx"),
                                            _column(reactions, f"{other.name}.Fy")))
            if other.kind == "prismatic":
                moment -= sign * _column(reactions, f"{other.name}.M")
        for column in (column for name, column in efforts if name == other.name):
            effort = sign * _column(reactions, column)
            if other.kind == "revolute":
                moment -= effort
                continue
            # A slide's drive force along its axis u, which turns with
            # body_i (whose angle is θj − the held angle).
            theta_i = at[:, 2] - (other.held_angle if sign > 0 else 0.0)
            load += effort[:, None] * np.column_stack(rotate(theta_i, other.axis))
        force -= load
        moment -= _cross(point - Q, load)
    force -= loads[:, :2]
    moment -= loads[:, 2] - _cross(Q, loads[:, :2])
    side = 1.0 if body.name == joint.body_j else -1.0
    out = {f"{joint.name}.Fx": side * force[:, 0], f"{joint.name}.Fy": side * force[:, 1]}
    if joint.kind == "prismatic":
        out[f"{joint.name}.M"] = side * moment
    return out
