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

from .mechanism import DRIVE_TORQUE, GROUND, Mechanism, point_motion, rotate


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


def _joint_world(mech: Mechanism, motion: pd.DataFrame, joint) -> tuple[dict, dict]:
    """Motion of the joint point on body_j and on body_i (world)."""
    return point_motion(motion, joint.body_j, joint.point_j), point_motion(motion, joint.body_i, joint.point_i)


def _body_terms(mech: Mechanism, motion: pd.DataFrame, layout: Layout):
    """Per instant: force-row right-hand sides (n, 2nb), moment/axial rows
    (n, k, nu) and their right-hand sides (n, k)."""
    n, nu = len(motion), len(layout.unknowns)
    prismatic = [j for j in mech.joints if j.kind == "prismatic"]
    k = len(layout.bodies) + len(prismatic)
    b_force = np.zeros((n, layout.n_force_rows))
    A_var = np.zeros((n, k, nu))
    b_var = np.zeros((n, k))
    gx, gy = mech.gravity
    com = {}
    for idx, body in enumerate(mech.bodies):
        G = point_motion(motion, body.name, body.com)
        com[body.name] = G
        b_force[:, 2 * idx] = body.mass * (G["ax"] - gx)
        b_force[:, 2 * idx + 1] = body.mass * (G["ay"] - gy)
        b_var[:, idx] = body.izz * motion[f"{body.name}.alpha"].to_numpy()
    row = {b: i for i, b in enumerate(layout.bodies)}
    omega = lambda name: 0.0 if name == GROUND else motion[f"{name}.omega"].to_numpy()
    for joint in mech.joints:
        P, P_i = _joint_world(mech, motion, joint)
        cx, cy = layout.column[f"{joint.name}.Fx"], layout.column[f"{joint.name}.Fy"]
        if joint.kind == "prismatic":
            theta_i = 0.0 if joint.body_i == GROUND else motion[f"{joint.body_i}.theta"].to_numpy()
            ux, uy = rotate(np.asarray(theta_i, dtype=float), joint.axis)
            v_rel = (P["vx"] - P_i["vx"]) * ux + (P["vy"] - P_i["vy"]) * uy
            damper = (-joint.damping * v_rel * ux, -joint.damping * v_rel * uy)
        else:
            damper_torque = -joint.damping * (omega(joint.body_j) - omega(joint.body_i))
        for body, sign in ((joint.body_j, 1.0), (joint.body_i, -1.0)):
            if body == GROUND:
                continue
            b_idx = row[body]
            rx, ry = P["x"] - com[body]["x"], P["y"] - com[body]["y"]
            A_var[:, b_idx, cx] = -sign * ry
            A_var[:, b_idx, cy] = sign * rx
            if joint.kind == "prismatic":
                A_var[:, b_idx, layout.column[f"{joint.name}.M"]] = sign
                # Known damper force: moves to the right-hand side.
                fx, fy = sign * damper[0], sign * damper[1]
                b_force[:, 2 * b_idx] -= fx
                b_force[:, 2 * b_idx + 1] -= fy
                b_var[:, b_idx] -= rx * fy - ry * fx
            else:
                b_var[:, b_idx] -= sign * damper_torque
        if joint.kind == "prismatic":
            axial = len(layout.bodies) + prismatic.index(joint)
            A_var[:, axial, cx] = ux
            A_var[:, axial, cy] = uy
    drive = mech.joint(mech.drive.joint)
    for body, sign in ((drive.body_j, 1.0), (drive.body_i, -1.0)):
        if body != GROUND:
            A_var[:, row[body], layout.column[DRIVE_TORQUE]] = sign
    return b_force, A_var, b_var


def assemble(mech: Mechanism, motion: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """The full square system A·x = b per instant: (n, N, N), (n, N), names."""
    layout = Layout.of(mech)
    C = _incidence(mech, layout)
    b_force, A_var, b_var = _body_terms(mech, motion, layout)
    A = np.concatenate([np.broadcast_to(C, (len(motion),) + C.shape), A_var], axis=1)
    return A, np.concatenate([b_force, b_var], axis=1), layout.unknowns


def reactions(mech: Mechanism, motion: pd.DataFrame, chunk: int = 1 << 16) -> pd.DataFrame:
    """Joint reactions and drive torque (raw columns) at every instant.

    Exact to rounding: the null-space split is an exact change of variables.
    Processed in chunks to bound memory on very long runs.
    """
    layout = Layout.of(mech)
    C = _incidence(mech, layout)
    C_pinv = np.linalg.pinv(C)
    _, _, vt = np.linalg.svd(C)
    Z = vt[C.shape[0]:].T                           # (nu, k) null-space basis
    parts = []
    for start in range(0, len(motion), chunk):
        m = motion.iloc[start:start + chunk]
        b_force, A_var, b_var = _body_terms(mech, m, layout)
        x_p = b_force @ C_pinv.T
        reduced = A_var @ Z
        rhs = b_var - np.einsum("nku,nu->nk", A_var, x_p)
        y = np.linalg.solve(reduced, rhs[..., None])[..., 0]
        parts.append(x_p + y @ Z.T)
    x = np.concatenate(parts) if parts else np.zeros((0, len(layout.unknowns)))
    return pd.DataFrame(x, columns=list(layout.unknowns), index=motion.index)
