"""What a compiled model of a spatial scene must hold, from the scene
alone: the expectations an engine's spatial model audit is set against
(`mechval.records.audit.audit`), as `expected_model` is for planar ones.

Per body its mass, centre of mass and inertia tensor about it (body
axes); per joint its kind, bodies, point on each body and axis on each
body (zi, zj; a fixed joint's x axes too; a spherical joint has no axis)
and damping; each spring-damper's bodies, points, stiffness, free length
and damping; gravity; contacts off and no joint limits."""

from __future__ import annotations

import numpy as np

from mechval.records.audit import SCENE, Expectation, body_item, joint_item
from mechval.reference.spatial.system import SpatialSystem

INERTIA = (("Ixx", 0, 0), ("Iyy", 1, 1), ("Izz", 2, 2), ("Ixy", 0, 1), ("Ixz", 0, 2), ("Iyz", 1, 2))


def joint_sides(j) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """(side, body, point, joint frame) of both ends of a joint."""
    return [("i", j.body_i, np.asarray(j.point_i, float), np.asarray(j.frame_i, float)),
            ("j", j.body_j, np.asarray(j.point_j, float), np.asarray(j.frame_j, float))]


def axis_columns(kind: str) -> tuple[int, ...]:
    """The joint frame's columns a kind defines: none for a ball, z for the
    rest, x and z for a fixed joint."""
    return () if kind == "spherical" else (0, 2) if kind == "fixed" else (2,)


def expected_spatial(system: SpatialSystem) -> list[Expectation]:
    size = max([1e-3] + [float(np.linalg.norm(p)) for j in system.joints for p in (j.point_i, j.point_j)]
               + [float(np.linalg.norm(b.com)) for b in system.bodies])
    out = []
    for b in system.bodies:
        item, I = body_item(b.name), np.asarray(b.inertia, float)
        out.append(Expectation(item, "mass", float(b.mass), "kg"))
        out += [Expectation(item, f"com {c}", float(b.com[k]), "m", size) for k, c in enumerate("xyz")]
        scale = float(np.abs(I).max())
        out += [Expectation(item, name, float(I[r, c]), "kg·m²", scale) for name, r, c in INERTIA]
    for j in system.joints:
        item = joint_item(j.name)
        out += [Expectation(item, "kind", j.kind), Expectation(item, "bodies", f"{j.body_i} → {j.body_j}"),
                Expectation(item, "damping", float(j.damping))]
        for side, body, point, frame in joint_sides(j):
            out += [Expectation(item, f"point {side} {c}", float(point[k]), "m", size) for k, c in enumerate("xyz")]
            for col in axis_columns(j.kind):
                out += [Expectation(item, f"axis {side} {'xyz'[col]}{c}", float(frame[k, col]), "", 1.0)
                        for k, c in enumerate("xyz")]
    for spring in system.springs:
        item = f"spring {spring.name}"
        out += [Expectation(item, "bodies", f"{spring.body_a} → {spring.body_b}"),
                Expectation(item, "stiffness", float(spring.stiffness), "N/m"),
                Expectation(item, "free length", float(spring.free_length), "m"),
                Expectation(item, "damping", float(spring.damping), "N·s/m")]
        for end, point in (("a", spring.point_a), ("b", spring.point_b)):
            out += [Expectation(item, f"point {end} {c}", float(point[k]), "m", size) for k, c in enumerate("xyz")]
    g = np.asarray(system.gravity, float)
    out += [Expectation(SCENE, f"gravity {c}", float(g[k]), "m/s²", 9.81) for k, c in enumerate("xyz")]
    out += [Expectation(SCENE, "contacts", "off"), Expectation(SCENE, "joint limits", "none")]
    return out
