"""One sample's read-out of a spatial scene's Pinocchio model in mechval's
raw columns (`SpatialSystem.motion_columns`, `reaction_columns`).

- Motion: each body's Pinocchio `Frame` at its frame origin: position and
  attitude from `oMf` (the quaternion with w ≥ 0), the origin's velocity
  and ω, classical acceleration and α, world axes (`LOCAL_WORLD_ALIGNED`).
- Loop forces: λ of a constraint (Pinocchio's `lambda_c`, the first
  constraint frame's axes; a force, or force and moment for CONTACT_6D)
  acts as +λ on the first frame's body at its point and −λ on the second's
  (`LAMBDA_ON_FIRST`, as the planar read-out measured). A cut joint's
  reaction is the load of its constraints on body_j (a carrier is
  massless: its weld passes body_i's load on).
- Tree joints: Newton–Euler per body, W_b = inertial wrench − applied
  ones (gravity, the applied effects, loop forces), summed over the
  child's subtree, is what the joint passes from the parent to the child;
  less a drive's effort, it is the reaction on the child, turned to
  "by body_i on body_j, moment about Pj". The same W_b mapped by the
  bodies' Jacobians must give back the drive efforts on their coordinates
  and zero on every other: its largest miss is the fact
  `newton_euler_residual_max` (a check of λ's sign and of the sums).
- Drive efforts: the computed effort on the drive's coordinate, times the
  tree joint's sign (T or F on body_j); torque laws: their value.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from mechval.model.mechanism import GROUND
from mechval.reference.spatial.rotation import matrix_to_quaternion
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.pinocchio.spatial_dynamics import ALIGNED, WORLD, Kinematics, SpatialDynamics
from mechval.engines.pinocchio.spatial_model import SpatialModel, frame_jacobian

#: λ acts on the constraint's first frame with this sign (measured: the
#: Newton–Euler residual of the passive joints vanishes with it).
LAMBDA_ON_FIRST = 1.0


def wrench(force, moment, at) -> np.ndarray:
    """[F; M about the world origin] of a force and couple at a point."""
    return np.concatenate([force, moment + np.cross(at, force)])


def loop_wrenches(sm: SpatialModel, lam: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Each body's wrench from the loops' constraints, and each cut joint's
    wrench on its body_j (world, about the origin)."""
    on_body: dict[str, np.ndarray] = {}
    on_j: dict[str, np.ndarray] = {}
    offsets = np.cumsum([0] + [c.residualSize() for c in sm.constraints])
    for cut in sm.cuts:
        total = np.zeros(6)
        for k in cut.constraints:
            data, part = sm.constraint_data[k], LAMBDA_ON_FIRST * lam[offsets[k]:offsets[k + 1]]
            R = data.oMc1.rotation
            force, moment = R @ part[:3], (R @ part[3:] if len(part) == 6 else np.zeros(3))
            first = wrench(force, moment, data.oMc1.translation)
            second = -wrench(force, moment, data.oMc2.translation if len(part) == 3 else data.oMc1.translation)
            for body, w in ((cut.first, first), (cut.second, second)):
                if body and body != GROUND:
                    on_body[body] = on_body.get(body, np.zeros(6)) + w
            total += first if cut.first == cut.joint.body_j else second
        on_j[cut.joint.name] = total
    return on_body, on_j


def about(w: np.ndarray, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Force and moment about `point` of a wrench about the origin."""
    return w[:3], w[3:] - np.cross(point, w[:3])


def sample(sm: SpatialModel, dynamics: SpatialDynamics, system: SpatialSystem, t: float, q: np.ndarray,
           v: np.ndarray) -> tuple[dict[str, float], float]:
    """Raw columns at one instant and the Newton–Euler residual."""
    model, data = sm.model, sm.data
    solution = dynamics.solve(t, q, v, final=True)
    lam = solution.lam.copy()
    kin = Kinematics(sm, q, v)
    pin.forwardKinematics(model, data, q, v, solution.a)
    pin.computeJointJacobians(model, data, q)
    row: dict[str, float] = {}
    unbalanced: dict[str, np.ndarray] = {}
    on_body, on_j = loop_wrenches(sm, lam)
    g = np.asarray(system.gravity, dtype=float)
    residual = np.zeros(model.nv)
    for b in system.bodies:
        f = sm.frame_of[b.name]
        pose, (velocity, omega) = kin.pose[b.name], kin.twist[b.name]
        acceleration = pin.getFrameClassicalAcceleration(model, data, f, ALIGNED)
        a, alpha = np.array(acceleration.linear), np.array(acceleration.angular)
        values = (*pose.translation, *matrix_to_quaternion(pose.rotation), *velocity, *omega, *a, *alpha)
        row.update({f"{b.name}.{name}": float(x) for name, x in zip(("x", "y", "z", "qw", "qx", "qy", "qz", "vx",
                    "vy", "vz", "wx", "wy", "wz", "ax", "ay", "az", "alphax", "alphay", "alphaz"), values)})
        # Newton–Euler about the centre of mass G, then about the origin
        arm = pose.rotation @ np.asarray(b.com, dtype=float)
        G = pose.translation + arm
        a_G = a + np.cross(alpha, arm) + np.cross(omega, np.cross(omega, arm))
        J = pose.rotation @ np.asarray(b.inertia, dtype=float) @ pose.rotation.T
        inertial = wrench(b.mass * a_G, J @ alpha + np.cross(omega, J @ omega), G)
        applied = wrench(b.mass * g, np.zeros(3), G) + solution.wrenches.get(b.name, 0.0) + on_body.get(b.name, 0.0)
        unbalanced[b.name] = inertial - applied
        residual += frame_jacobian(model, data, f, WORLD).T @ unbalanced[b.name]
    residual[dynamics.drive_coordinates] -= solution.efforts

    for cut in sm.cuts:
        point = kin.point(cut.joint.body_j, cut.joint.point_j)[0]
        row.update(reaction_columns(cut.joint.name, *about(on_j[cut.joint.name], point)))
    efforts = dict(zip((d.joint for d in system.drives), solution.efforts))
    for tj in sm.tree:
        w = sum(unbalanced[b] for b in sm.subtree[tj.child])
        parent_side = tj.side(tj.parent)
        child_point = kin.point(tj.child, tj.side(tj.child).translation)[0]
        if tj.joint.name in efforts:        # the drive's effort on the child is no reaction
            z = kin.axis(tj.parent, parent_side.rotation[:, 2])
            effort = efforts[tj.joint.name]
            w = w - (wrench(np.zeros(3), effort * z, child_point) if tj.joint.kind == "revolute"
                     else wrench(effort * z, np.zeros(3), child_point))
        w = w if tj.child == tj.joint.body_j else -w         # the load on body_j
        point = kin.point(tj.joint.body_j, tj.joint.point_j)[0]
        row.update(reaction_columns(tj.joint.name, *about(w, point)))
    for d, effort, sign in zip(system.drives, solution.efforts, dynamics.drive_signs):
        row[f"{d.name}.{'T' if system.joint(d.joint).kind == 'revolute' else 'F'}"] = float(sign * effort)
    for torque in system.torques:
        row[f"{torque.name}.T"] = float(torque.law.value(t))
    return row, float(np.abs(residual).max()) if model.nv else 0.0


def reaction_columns(name: str, force: np.ndarray, moment: np.ndarray) -> dict[str, float]:
    return {f"{name}.F{c}": float(x) for c, x in zip("xyz", force)} | \
        {f"{name}.M{c}": float(x) for c, x in zip("xyz", moment)}
