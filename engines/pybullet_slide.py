"""PyBullet: the reaction of a slide between two moving bodies, derived from
the balance of the slide's body_j with the engine's own motion.

Why: PyBullet's joint sensor on a prismatic joint whose parent link turns
(the block on a slotted lever, the rod in a pivoted sleeve) misreports the
force and couple by a Coriolis-like term in ω·ṡ that does not shrink with
the step (an engine finding, `mechval.engines.findings`), while PyBullet's
motion and its other joint forces are right. So the adapter reports, for
each prismatic joint J between two moving bodies, the reaction that
PyBullet's own simulation implies (Newton–Euler on body j = J's body_j):

    F_J = m_j·(a_Gj − g) − Σ_k F_k→j − F_ext
    M_J = izz_j·α_j + (G_j − P)×m_j·(a_Gj − g) − Σ_k (P_k − P)×F_k→j
          − Σ_k M_k→j − M_ext(P)

P is J's point on body j (the couple is taken there, as everywhere); the
sums run over body j's other joints k, with the forces F_k→j at their points
P_k and the couples M_k→j (another slide's couple, a drive torque, a
torque law's T) exactly as PyBullet reports them (constraint forces and
leaf sensors), a slide drive's force along its axis (J's own too: F_J is
the slide's reaction alone, as in the reference, the drive force F being
its own column); F_ext and M_ext(P) are the loads the adapter applied in
the step (dampers, spring-dampers, body torques).

Time stamps (docs/engines.md): the forces read after the step from t_n to
t_n+1 belong to t_n, and so does this balance. PyBullet's semi-implicit
Euler moves the joint coordinates by dt·q̇ with the step's new velocity, so
the second central difference of the centre-of-mass positions,
a_G(t_n) = (x_G(t_n+1) − 2·x_G(t_n) + x_G(t_n−1))/dt², is the step's
velocity change over dt, centred at t_n (the difference of the world
velocity readings over the step is stamped half a step late, an O(dt)
error); α_j = (ω_n+½ − ω_n−½)/dt likewise.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
from mechval.kinematics import rotate
from mechval.mechanism import GROUND, Joint, Mechanism

#: What the run info says about each derived slide (users see that the
#: column is derived, not read).
DERIVED_NOTE = ("{joint}: F and M derived from the balance of {body} with PyBullet's own motion and "
                "its other joint forces, not read from the slide's sensor (engine finding: the sensor "
                "misreports a slide whose parent turns)")
#: The reason for the first sample's missing value when there is no step
#: before it.
NO_EARLIER_STEP = ("derived from the body's balance, which needs the position one step before the "
                   "sample; with no pre-roll (preroll_steps = 0, or a torque-driven or free run) the first "
                   "sample has none")


def derived_slides(mechanism: Mechanism) -> tuple[Joint, ...]:
    """The prismatic joints between two moving bodies (their sensor's
    parent turns; a slide on the ground reads right)."""
    return tuple(j for j in mechanism.joints if j.kind == "prismatic" and GROUND not in (j.body_i, j.body_j))


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


def slide_reaction(mechanism: Mechanism, joint: Joint, track: BodyTrack, reactions: Mapping[str, np.ndarray],
                   loads: np.ndarray, dt: float) -> dict[str, np.ndarray]:
    """F_J (world axes, on body_j) and M_J (about J's point on body_j) per
    sample (module docstring). `reactions` holds the raw reaction columns
    as read ("A.Fx", "drive.T", ...); `loads` is (n, 3): the external
    force on body_j and its moment about the world origin."""
    body = mechanism.body(joint.body_j)
    com = lambda state: _points(state, body.com)   # noqa: E731
    accel = (com(track.after) - 2 * com(track.before) + com(track.earlier)) / dt**2
    alpha = (track.after[:, 5] - track.before[:, 5]) / dt
    at = track.before
    P = _points(at, joint.point_j)
    net = body.mass * (accel - np.asarray(mechanism.gravity))
    force = net.copy()
    moment = body.izz * alpha + _cross(com(at) - P, net)
    efforts = [(d.joint, d.effort_column(mechanism.joint(d.joint).kind)) for d in mechanism.drives]
    efforts += [(law.joint, f"{law.name}.T") for law in mechanism.torque_drives]
    for other in mechanism.joints:
        if body.name not in (other.body_i, other.body_j):
            continue
        sign = 1.0 if other.body_j == body.name else -1.0
        point = other.point_j if other.body_j == body.name else other.point_i
        if other is not joint:
            f = sign * np.column_stack((_column(reactions, f"{other.name}.Fx"),
                                        _column(reactions, f"{other.name}.Fy")))
            force -= f
            moment -= _cross(_points(at, point) - P, f)
            if other.kind == "prismatic":
                moment -= sign * _column(reactions, f"{other.name}.M")
        for column in (column for name, column in efforts if name == other.name):
            effort = sign * _column(reactions, column)
            if other.kind == "revolute":
                moment -= effort
                continue
            # A slide's drive force along its axis u (turning with body_i,
            # whose angle is θj − the held angle), at its point on this body.
            theta_i = at[:, 2] - (other.held_angle if sign > 0 else 0.0)
            f = effort[:, None] * np.column_stack(rotate(theta_i, other.axis))
            force -= f
            moment -= _cross(_points(at, point) - P, f)
    force -= loads[:, :2]
    moment -= loads[:, 2] - _cross(P, loads[:, :2])
    return {f"{joint.name}.Fx": force[:, 0], f"{joint.name}.Fy": force[:, 1], f"{joint.name}.M": moment}
