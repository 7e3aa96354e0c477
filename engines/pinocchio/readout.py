"""One sample's read-out of the Pinocchio model, in mechval's conventions
(raw columns, `mechval.model.mechanism`).

- Motion: each body's frame (a Pinocchio `Frame` at the body's origin):
  position from `oMf`, velocity and classical acceleration of its origin
  in world axes (`LOCAL_WORLD_ALIGNED`), ω and α their z components; θ is
  the sum of the tree's coordinates down to the body (continuous, and the
  reference's angle at the start, since q was taken from it).
- Reactions: the loops' forces λ (Pinocchio's `lambda_c`, in the first
  constraint frame's axes) act as +λ on the constraint's first body and
  −λ on its second; with them and the applied effects' wrenches as
  external forces, `rnea` at the computed accelerations gives each tree
  joint's transmitted wrench `data.f` (by the parent on the child, in the
  child joint's frame, about the joint point). Its part along the joint's
  motion (the drive effort, a torque law, a damper: none of them a
  reaction) is removed; the rest, turned to world axes, is the reaction,
  by body_i on body_j when the child is body_j, else the opposite with the
  couple moved to body_j's point. `rnea`'s τ must equal the forces the
  dynamics applied, so the passive joints' torques come out 0: its
  largest deviation is recorded as the run fact `rnea_residual_max` (a
  check of λ's sign, tests/test_pinocchio.py).
- Drive efforts: the computed effort on the drive's coordinate, times the
  tree joint's sign (T or F on body_j).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from mechval.model.mechanism import Mechanism

from mechval.engines.pinocchio.dynamics import Dynamics
from mechval.engines.pinocchio.forces import external_forces, point_state
from mechval.engines.pinocchio.model import PinocchioModel, TreeJoint

#: λ acts on the constraint's first frame with this sign (measured:
#: the passive joints' rnea torques vanish with it, `rnea_residual_max`).
LAMBDA_ON_FIRST = 1.0


def body_angles(pm: PinocchioModel, q: np.ndarray) -> dict[str, float]:
    """θ of every body from the tree's coordinates (parents come first)."""
    theta = {"ground": 0.0}
    for tj in pm.tree:
        turn = q[tj.coordinate] if tj.joint.kind == "revolute" else tj.turn
        theta[tj.child] = theta[tj.parent] + turn
    return theta


def sample(pm: PinocchioModel, dynamics: Dynamics, mech: Mechanism, t: float, q: np.ndarray, v: np.ndarray
           ) -> tuple[dict[str, float], float]:
    """Raw columns at one instant and rnea's largest torque residual."""
    model, data = pm.model, pm.data
    solution = dynamics.solve(t, q, v, final=True)
    lam = solution.lam.copy()
    pin.forwardKinematics(model, data, q, v, solution.a)
    pin.updateFramePlacements(model, data)
    row: dict[str, float] = {}
    theta = body_angles(pm, q)
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    for body in mech.bodies:
        frame = pm.frame_of[body.name]
        position = data.oMf[frame].translation
        velocity = pin.getFrameVelocity(model, data, frame, world)
        acceleration = pin.getFrameClassicalAcceleration(model, data, frame, world)
        row.update({f"{body.name}.x": position[0], f"{body.name}.y": position[1], f"{body.name}.theta": theta[body.name],
                    f"{body.name}.vx": velocity.linear[0], f"{body.name}.vy": velocity.linear[1],
                    f"{body.name}.omega": velocity.angular[2],
                    f"{body.name}.ax": acceleration.linear[0], f"{body.name}.ay": acceleration.linear[1],
                    f"{body.name}.alpha": acceleration.angular[2]})

    fext = external_forces(pm, solution.wrenches)
    for k, loop in enumerate(pm.loops):
        c1 = pm.constraint_data[k].oMc1
        force = LAMBDA_ON_FIRST * (c1.rotation @ lam[3 * k:3 * k + 3])
        row[f"{loop.joint.name}.Fx"], row[f"{loop.joint.name}.Fy"] = loop.sign * force[:2]
        wrench = pin.Force(force, np.cross(c1.translation, force))
        for body, side in ((loop.first, 1.0), (loop.second, -1.0)):
            if body in pm.frame_of:
                joint = pm.joint_of[body]
                fext[joint] = fext[joint] + data.oMi[joint].actInv(wrench * side)
    tau = pin.rnea(model, data, q, v, solution.a, fext)
    residual = float(np.max(np.abs(tau - solution.tau_joints))) if model.nv else 0.0
    for tj in pm.tree:
        row.update(_tree_reaction(pm, tj))
    for drive, effort, sign in zip(mech.drives, solution.efforts, dynamics.drive_signs):
        row[drive.effort_column(mech.joint(drive.joint).kind)] = sign * effort
    for law in mech.torque_drives:
        row[f"{law.name}.T"] = float(law.value(t))
    return row, residual


def _tree_reaction(pm: PinocchioModel, tj: TreeJoint) -> dict[str, float]:
    """The reaction of a tree joint from rnea's transmitted wrench."""
    data, joint = pm.data, tj.joint
    f = data.f[tj.index]
    linear, angular = np.array(f.linear), np.array(f.angular)
    if joint.kind == "revolute":
        angular[2] = 0.0
    else:
        axis = pm.axes[tj.index]            # the slide's direction in the joint's frame
        linear -= (linear @ axis) * axis
    placement = data.oMi[tj.index]
    force, moment = placement.rotation @ linear, placement.rotation @ angular
    name = joint.name
    if tj.sign > 0:
        out = {f"{name}.Fx": force[0], f"{name}.Fy": force[1]}
        if joint.kind == "prismatic":
            out[f"{name}.M"] = moment[2]
        return out
    out = {f"{name}.Fx": -force[0], f"{name}.Fy": -force[1]}
    if joint.kind == "prismatic":
        p_i = placement.translation
        p_j = point_state(pm, tj.parent, tj.point_parent)[0]
        out[f"{name}.M"] = -moment[2] + float(np.cross(p_i - p_j, -force)[2])
    return out

