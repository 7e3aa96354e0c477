"""Newton–Euler inverse dynamics of a driven planar mechanism, per instant.

For every moving body b (Norton, *Design of Machinery*, §11.4–11.6,
eqs. 11.1 and 11.9 for the four-bar; §11.7 for the slider-crank):

    Σ F = m_b·(a_Gb − g)                      (2 rows)
    Σ (P − G_b) × F + Σ couples = Izz_b·α_b     (1 row, about the centre of mass)

Unknowns: the in-plane force of every joint (by body_i on body_j, world
axes), the couple of every prismatic joint, and the drive torque T on the
crank. A prismatic joint adds one row: its force has no component along the
sliding axis (the guide damper is a separate, known force). For the
four-bar this is the classic 9×9 system (8 pin force components + T12).

Viscous dampers are known loads computed from the motion: −c·ω_rel on
body_j, +c·ω_rel on body_i (and likewise for a guide, −c·v_rel along the
axis); they are not part of the joint reactions nor of T.

Solving: the force rows have constant coefficients (±1, the joint/body
incidence), so every instant's solution is x = x_p + Z·y with x_p = C⁺·b_f
and Z a basis of C's null space, both computed once; only the small
moment/axial system (M·Z)·y = b_m − M·x_p is solved per instant, in one
vectorised call. `assemble` gives the full square system for checks and
for the per-instant loop that the benchmark compares against.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from mechval.model.kinematics import point_motion, point_position, slide_axis, slide_rate, trig
from mechval.model.mechanism import DRIVE_TORQUE, GROUND, Mechanism


@dataclass(frozen=True)
class Layout:
    """Row and column indices of the Newton–Euler system of a mechanism."""

    unknowns: tuple[str, ...]          # raw reaction column names, then drive.T
    bodies: tuple[str, ...]
    column: dict

    @classmethod
    def of(cls, mech: Mechanism) -> "Layout":
        unknowns = tuple(mech.reaction_columns())
        return cls(unknowns, tuple(b.name for b in mech.bodies), {u: k for k, u in enumerate(unknowns)})

    @property
    def n_force_rows(self) -> int:
        return 2 * len(self.bodies)


def _incidence(mech: Mechanism, layout: Layout) -> np.ndarray:
    """Constant force-row matrix C: +1 for a joint force on its body_j, −1 on
    its body_i (Newton's third law)."""
    C = np.zeros((layout.n_force_rows, len(layout.unknowns)))
    row = {b: 2 * k for k, b in enumerate(layout.bodies)}
    for j in mech.joints:
        for body, sign in ((j.body_j, 1.0), (j.body_i, -1.0)):
            if body != GROUND:
                C[row[body], layout.column[f"{j.name}.Fx"]] = sign
                C[row[body] + 1, layout.column[f"{j.name}.Fy"]] = sign
    return C


def _equations(mech: Mechanism, motion, layout: Layout):
    """The instant-dependent parts of the system, stored per quantity (arrays
    over the instants, so that every operation below is contiguous):
    force-row right-hand sides (2nb, n); the moment and axial rows as sparse
    maps {unknown column: coefficient (array or number)}; their right-hand
    sides (k, n). `motion` maps the motion columns (`motion_columns()`) to
    arrays; the instants themselves are not needed."""
    n = len(np.atleast_1d(motion[f"{mech.bodies[0].name}.x"]))
    prismatic = [j for j in mech.joints if j.kind == "prismatic"]
    b_force = np.zeros((layout.n_force_rows, n))
    rows: list[dict] = [{} for _ in range(len(layout.bodies) + len(prismatic))]
    b_var = np.zeros((len(rows), n))
    gx, gy = mech.gravity
    turns = {b.name: trig(motion, b.name) for b in mech.bodies}
    com = {}
    for idx, body in enumerate(mech.bodies):
        G = com[body.name] = point_motion(motion, body.name, body.com, turns[body.name])
        b_force[2 * idx] = body.mass * (G["ax"] - gx)
        b_force[2 * idx + 1] = body.mass * (G["ay"] - gy)
        b_var[idx] = body.izz * motion[f"{body.name}.alpha"]
    row = {b: i for i, b in enumerate(layout.bodies)}
    omega = lambda name: 0.0 if name == GROUND else motion[f"{name}.omega"]
    for joint in mech.joints:
        P = point_position(motion, joint.body_j, joint.point_j, turns.get(joint.body_j))
        cx, cy = layout.column[f"{joint.name}.Fx"], layout.column[f"{joint.name}.Fy"]
        if joint.kind == "prismatic":
            ux, uy = slide_axis(motion, joint)
            v_rel = slide_rate(motion, joint)
            damper = (-joint.damping * v_rel * ux, -joint.damping * v_rel * uy)
            rows[len(layout.bodies) + prismatic.index(joint)].update({cx: ux, cy: uy})
        else:
            damper_torque = -joint.damping * (omega(joint.body_j) - omega(joint.body_i))
        for body, sign in ((joint.body_j, 1.0), (joint.body_i, -1.0)):
            if body == GROUND:
                continue
            b_idx = row[body]
            rx, ry = P["x"] - com[body]["x"], P["y"] - com[body]["y"]
            rows[b_idx].update({cx: -sign * ry, cy: sign * rx})
            if joint.kind == "prismatic":
                rows[b_idx][layout.column[f"{joint.name}.M"]] = sign
                # Known damper force: moves to the right-hand side.
                fx, fy = sign * damper[0], sign * damper[1]
                b_force[2 * b_idx] -= fx
                b_force[2 * b_idx + 1] -= fy
                b_var[b_idx] -= rx * fy - ry * fx
            else:
                b_var[b_idx] -= sign * damper_torque
    drive = mech.joint(mech.drive.joint)
    for body, sign in ((drive.body_j, 1.0), (drive.body_i, -1.0)):
        if body != GROUND:
            rows[row[body]][layout.column[DRIVE_TORQUE]] = sign
    return b_force, rows, b_var


def _columns(motion: pd.DataFrame) -> dict[str, np.ndarray]:
    return {name: motion[name].to_numpy() for name in motion.columns}


def assemble(mech: Mechanism, motion: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """The full square system A·x = b per instant: (n, N, N), (n, N), names."""
    layout = Layout.of(mech)
    C = _incidence(mech, layout)
    b_force, rows, b_var = _equations(mech, _columns(motion), layout)
    n = len(motion)
    A = np.zeros((n, len(layout.unknowns), len(layout.unknowns)))
    A[:, :len(C)] = C
    for r, entries in enumerate(rows):
        for column, coefficient in entries.items():
            A[:, len(C) + r, column] = coefficient
    return A, np.concatenate([b_force, b_var]).T, layout.unknowns


def _det(M) -> np.ndarray:
    """Determinants of small matrices stored per entry, M[r][c] an array over
    instants, by Laplace expansion along the first row."""
    k = len(M)
    if k == 2:
        return M[0][0] * M[1][1] - M[0][1] * M[1][0]
    if k == 3:   # rule of Sarrus
        (a, b, c), (d, e, f), (g, h, i) = M
        return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return sum((-1) ** j * M[0][j] * _det([[r[c] for c in range(k) if c != j] for r in M[1:]]) for j in range(k))


def solve_small(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve small systems stored per entry, A (k, k, n) and b (k, n), by
    Cramer's rule: for the 3×3 and 4×4 reduced systems this is much faster
    than np.linalg.solve, which calls LAPACK once per instant; the tests
    check it against that solve to ~1e-12."""
    k = len(A)
    det = _det(A)
    x = np.empty_like(b)
    for i in range(k):     # A with column i replaced by b, as views (no copies)
        x[i] = _det([[b[r] if c == i else A[r][c] for c in range(k)] for r in range(k)]) / det
    return x


def reaction_values(mech: Mechanism, motion) -> np.ndarray:
    """Joint reactions and drive torque, (unknowns, instants), in the order
    of `Mechanism.reaction_columns`; `motion` maps each of
    `Mechanism.motion_columns()` to an array over the instants. Exact to
    rounding: the null-space split is an exact change of variables."""
    layout = Layout.of(mech)
    C = _incidence(mech, layout)
    _, _, vt = np.linalg.svd(C)
    Z = vt[C.shape[0]:].T                           # (nu, k) null-space basis
    b_force, rows, rhs = _equations(mech, motion, layout)
    x_p = np.linalg.pinv(C) @ b_force               # (nu, n)
    reduced = np.zeros((len(rows), Z.shape[1], b_force.shape[1]))
    for r, entries in enumerate(rows):
        for column, coefficient in entries.items():
            reduced[r] += Z[column][:, None] * coefficient
            rhs[r] -= coefficient * x_p[column]
    return x_p + Z @ solve_small(reduced, rhs)


def reactions(mech: Mechanism, motion: pd.DataFrame) -> pd.DataFrame:
    """Joint reactions and drive torque as raw columns (see reaction_values)."""
    values = reaction_values(mech, _columns(motion))
    return pd.DataFrame(values.T, columns=mech.reaction_columns(), index=motion.index)
