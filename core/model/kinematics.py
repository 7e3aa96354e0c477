"""Planar kinematics, written once: the rotation of a body-frame vector, the
motion of a body-fixed point, the slide coordinate of a prismatic joint and
the gap between a joint's two sides. The reference (Newton–Euler), the
canonical signals, the run health, every adapter and the report use these.

Frames as in `mechval.model.mechanism`: a body's pose is (x, y, θ) of its frame
origin in world axes; points and a slide's axis are given in body frames.
`motion` arguments map raw column names ("crank.theta", ...) to arrays (a
DataFrame will do); the ground is at rest in the world frame.

The arithmetic (`turn`, `rigid_velocity`, `rigid_acceleration`) works on
floats and arrays alike. `rotate` takes the cosine and sine with numpy;
`rotate_scalar` with `math`, for an adapter's per-step loop on Python
floats, where numpy costs about a microsecond a call.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from mechval.model.mechanism import GROUND, Joint, Mechanism, Vec2

#: (cos θ, sin θ) of a body angle.
Trig = tuple[np.ndarray, np.ndarray]


def turn(c, s, v: Vec2):
    """R·v, the world components of the body-frame vector v, for the
    rotation with c = cos θ, s = sin θ."""
    return c * v[0] - s * v[1], s * v[0] + c * v[1]


def rotate(theta, v: Vec2) -> tuple[np.ndarray, np.ndarray]:
    """R(θ)·v for an array (or numpy scalar) of body angles θ."""
    return turn(np.cos(theta), np.sin(theta), v)


def rotate_scalar(theta: float, v: Vec2) -> tuple[float, float]:
    """R(θ)·v for one angle, with `math` (see the module docstring)."""
    return turn(math.cos(theta), math.sin(theta), v)


def rigid_velocity(vx, vy, omega, r: Vec2):
    """v_P = v_O + ω ẑ × r of the point at r = R·p from a body's origin O."""
    return vx - omega * r[1], vy + omega * r[0]


def rigid_acceleration(ax, ay, omega, alpha, r: Vec2):
    """a_P = a_O + α ẑ × r − ω²·r of the point at r = R·p from the origin."""
    return ax - alpha * r[1] - omega * omega * r[0], ay + alpha * r[0] - omega * omega * r[1]


def trig(motion: Mapping, body: str) -> Trig:
    """(cos θ, sin θ) of a moving body, for callers that turn many points."""
    theta = np.asarray(motion[f"{body}.theta"])
    return np.cos(theta), np.sin(theta)


def _arm(motion: Mapping, body: str, p: Vec2, cs: Trig | None) -> tuple[np.ndarray, np.ndarray]:
    return turn(*(cs if cs is not None else trig(motion, body)), p)


def _at_rest(motion: Mapping, p: Vec2) -> dict[str, np.ndarray]:
    zero = np.zeros(len(motion["t"]))
    return dict(x=zero + p[0], y=zero + p[1], vx=zero, vy=zero, ax=zero, ay=zero)


def point_position(motion: Mapping, body: str, p: Vec2, cs: Trig | None = None) -> dict[str, np.ndarray]:
    """World position r_P = r_O + R·p of the body-fixed point p (m): x, y.
    `cs` = (cos θ, sin θ) of the body, when the caller already has them."""
    if body == GROUND:
        ground = _at_rest(motion, p)
        return dict(x=ground["x"], y=ground["y"])
    rx, ry = _arm(motion, body, p, cs)
    return dict(x=np.asarray(motion[f"{body}.x"]) + rx, y=np.asarray(motion[f"{body}.y"]) + ry)


def point_motion(motion: Mapping, body: str, p: Vec2, cs: Trig | None = None) -> dict[str, np.ndarray]:
    """Position, velocity and acceleration (world) of the body-fixed point
    p: x, y, vx, vy, ax, ay (`rigid_velocity`, `rigid_acceleration`)."""
    if body == GROUND:
        return _at_rest(motion, p)
    col = lambda q: np.asarray(motion[f"{body}.{q}"])   # noqa: E731
    r = _arm(motion, body, p, cs)
    w, al = col("omega"), col("alpha")
    vx, vy = rigid_velocity(col("vx"), col("vy"), w, r)
    ax, ay = rigid_acceleration(col("ax"), col("ay"), w, al, r)
    return dict(x=col("x") + r[0], y=col("y") + r[1], vx=vx, vy=vy, ax=ax, ay=ay)


def _of_body_i(motion: Mapping, joint: Joint, q: str):
    """A motion column of the joint's body_i (the ground's: 0)."""
    return 0.0 if joint.body_i == GROUND else np.asarray(motion[f"{joint.body_i}.{q}"])


def slide_axis(motion: Mapping, joint: Joint) -> tuple[np.ndarray, np.ndarray]:
    """World components of a prismatic joint's axis u, which turns with
    body_i."""
    return rotate(np.asarray(_of_body_i(motion, joint, "theta"), dtype=float), joint.axis)


def separation(motion: Mapping, joint: Joint) -> dict[str, np.ndarray]:
    """d = P_j − P_i between the joint's points and its rates (world): x,
    y, vx, vy, ax, ay."""
    Pi = point_motion(motion, joint.body_i, joint.point_i)
    Pj = point_motion(motion, joint.body_j, joint.point_j)
    return {q: Pj[q] - Pi[q] for q in Pi}


def slide_rate(motion: Mapping, joint: Joint) -> np.ndarray:
    """(v_Pj − v_Pi)·u, the rate of a prismatic joint's damper: the
    relative velocity of the two joint points along the axis (m/s). It is
    ṡ of `slide_motion` wherever the joint closes (d ∥ u)."""
    d = separation(motion, joint)
    ux, uy = slide_axis(motion, joint)
    return d["vx"] * ux + d["vy"] * uy


def slide_motion(motion: Mapping, joint: Joint) -> dict[str, np.ndarray]:
    """The slide coordinate of a prismatic joint and its rates: s, v, a.

    With u the axis in world axes (turning with body_i at ω_i, α_i),
    n = ẑ × u and d = P_j − P_i (joint points): s = d·u (m), ṡ = ḋ·u +
    ω_i·d·n, s̈ = d̈·u + 2·ω_i·ḋ·n + d·(α_i·n − ω_i²·u).
    """
    d = separation(motion, joint)
    ux, uy = slide_axis(motion, joint)
    nx, ny = -uy, ux
    w, al = _of_body_i(motion, joint, "omega"), _of_body_i(motion, joint, "alpha")
    dx, dy, dvx, dvy = d["x"], d["y"], d["vx"], d["vy"]
    return dict(
        s=dx * ux + dy * uy,
        v=dvx * ux + dvy * uy + w * (dx * nx + dy * ny),
        a=(d["ax"] * ux + d["ay"] * uy + 2 * w * (dvx * nx + dvy * ny)
           + dx * (al * nx - w * w * ux) + dy * (al * ny - w * w * uy)),
    )


def separation_gap(joint: Joint, dx, dy, u: tuple | None = None) -> np.ndarray:
    """Distance between a joint's two sides from d = P_j − P_i (world, m):
    |d| for a revolute joint; for a prismatic joint |d × u|, the offset of
    P_j from the guide line through P_i along the axis u (world)."""
    if joint.kind == "revolute":
        return np.hypot(dx, dy)
    ux, uy = u
    return np.abs(dx * uy - dy * ux)


def joint_gap(motion: Mapping, joint: Joint) -> np.ndarray:
    """Distance between the joint's two sides (m), see `separation_gap`."""
    Pi = point_position(motion, joint.body_i, joint.point_i)
    Pj = point_position(motion, joint.body_j, joint.point_j)
    u = slide_axis(motion, joint) if joint.kind == "prismatic" else None
    return separation_gap(joint, Pj["x"] - Pi["x"], Pj["y"] - Pi["y"], u)


def joint_gaps(mechanism: Mechanism, motion: Mapping) -> np.ndarray:
    """The largest joint gap at each instant (m): the loop-closure gap."""
    return np.max([joint_gap(motion, joint) for joint in mechanism.joints], axis=0)


#: Instants of the step rule's dense grid over a run (`step_rate`).
STEP_RULE_GRID = 20001


def step_rate(mechanism: Mechanism, times: np.ndarray, dense: int = STEP_RULE_GRID) -> float:
    """Ω: the largest over the run and the links of |ω|, √|α| and ∛|jerk|
    (rad/s), from the reference kinematics on a dense grid of the run.

    Speed alone misjudges sharp motion at moderate speed (near the Grashof
    change point), hence the α and jerk terms (docs/engines.md, "step rule").
    Each call solves the reference on that grid: the harness asks once per
    scene (`mechval.harness.plan`) and hands the result to every engine.
    """
    t = dense_grid(times, dense)
    return peak_rate(mechanism, mechanism.motion(t), t)


def dense_grid(times: np.ndarray, dense: int = STEP_RULE_GRID) -> np.ndarray:
    """`dense` instants evenly spread from the run's first to its last."""
    return np.linspace(float(times[0]), float(times[-1]), dense)


def peak_rate(mechanism: Mechanism, motion: Mapping, t: np.ndarray) -> float:
    """Ω of `step_rate` from the motion at the instants t (a spatial
    body's |ω|, |α| and |jerk| are the vectors' norms)."""
    if mechanism.spatial is not None:
        return spatial_peak_rate(mechanism, motion, t)
    rate = 0.0
    for body in mechanism.bodies:
        w = np.asarray(motion[f"{body.name}.omega"], dtype=float)
        al = np.asarray(motion[f"{body.name}.alpha"], dtype=float)
        jerk = np.gradient(al, t)
        rate = max(rate, np.abs(w).max(), np.sqrt(np.abs(al).max()), np.cbrt(np.abs(jerk).max()))
    return float(rate)


def spatial_peak_rate(mechanism: Mechanism, motion: Mapping, t: np.ndarray) -> float:
    """Ω of a spatial scene: its bodies' rates as `peak_rate`, and
    `spring_rate`."""
    rate = spring_rate(mechanism.spatial)
    for body in mechanism.spatial.bodies:
        w = np.stack([np.asarray(motion[f"{body.name}.w{c}"], dtype=float) for c in "xyz"], axis=1)
        al = np.stack([np.asarray(motion[f"{body.name}.alpha{c}"], dtype=float) for c in "xyz"], axis=1)
        jerk = np.gradient(al, t, axis=0)
        rate = max(rate, np.linalg.norm(w, axis=1).max(), np.sqrt(np.linalg.norm(al, axis=1).max()),
                   np.cbrt(np.linalg.norm(jerk, axis=1).max()))
    return float(rate)


def spring_rate(system) -> float:
    """The largest √(Σk/m) over a spatial scene's bodies, Σk the stiffness
    of the springs at the body (rad/s): a stiff spring's oscillation may
    show only in a translation (benchmark A05's slider), which the rotation
    rates miss (with them alone two engines' steps missed A05's
    accelerations, their errors converging as dt²)."""
    stiffness = {b.name: 0.0 for b in system.bodies}
    for spring in system.springs:
        for body in (spring.body_a, spring.body_b):
            if body in stiffness:
                stiffness[body] += spring.stiffness
    return max((math.sqrt(k / system.body(name).mass) for name, k in stiffness.items()
                if k > 0 and system.body(name).mass > 0), default=0.0)
