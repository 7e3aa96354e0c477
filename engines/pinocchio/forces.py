"""The applied effects of a planar mechanism on its Pinocchio model, at one
state: joint dampers, torque laws, spring-dampers and body torques.

An effect at a tree joint (its damper, a torque law there) acts along the
joint's coordinate: a generalised force. Every other effect is a wrench on
the bodies it acts on (world axes, about the world origin, per Pinocchio
joint), mapped to generalised forces by the joints' world Jacobians
(τ = Jᵀ·w) for the dynamics and handed to `rnea` as external forces for
the reactions, so that each body's balance holds them. None of them is part
of a reaction or a drive effort (docs/conventions.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from mechval.model.mechanism import GROUND, BodyTorque, Joint, Mechanism, SpringDamper, TorqueLaw

from mechval.engines.pinocchio.model import PinocchioModel, vec3


@dataclass(frozen=True)
class Effects:
    """Which effects a mechanism has, sorted once for the integration loop."""

    tree_dampers: tuple[tuple[int, float], ...]          # (coordinate, damping)
    tree_laws: tuple[tuple[int, float, TorqueLaw], ...]  # (coordinate, tree sign, law)
    cut_dampers: tuple[Joint, ...]                       # loop-closing pins with a damper
    cut_laws: tuple[tuple[Joint, TorqueLaw], ...]        # laws at loop-closing pins
    springs: tuple[SpringDamper, ...]
    torques: tuple[BodyTorque, ...]

    @property
    def wrenches(self) -> bool:
        return bool(self.cut_dampers or self.cut_laws or self.springs or self.torques)


def effects(pm: PinocchioModel, mech: Mechanism) -> Effects:
    """The mechanism's applied effects, each where the model applies it."""
    tree_dampers, cut_dampers = [], []
    for joint in mech.damped_joints:
        tj = pm.tree_joint(joint.name)
        if tj is None:
            cut_dampers.append(joint)
        else:
            tree_dampers.append((tj.coordinate, joint.damping))
    tree_laws, cut_laws = [], []
    for law in mech.torque_drives:
        tj = pm.tree_joint(law.joint)
        if tj is None:
            cut_laws.append((mech.joint(law.joint), law))
        else:
            tree_laws.append((tj.coordinate, tj.sign, law))
    springs = tuple(f for f in mech.forces if isinstance(f, SpringDamper))
    torques = tuple(f for f in mech.forces if isinstance(f, BodyTorque))
    return Effects(tuple(tree_dampers), tuple(tree_laws), tuple(cut_dampers), tuple(cut_laws), springs, torques)


def point_state(pm: PinocchioModel, body: str, point) -> tuple[np.ndarray, np.ndarray]:
    """World position and velocity of a body-fixed point (kinematics of the
    current q, v already computed in pm.data)."""
    if body == GROUND:
        return vec3(point), np.zeros(3)
    joint = pm.joint_of[body]
    local = pm.placement(body, point).translation
    placement, velocity = pm.data.oMi[joint], pm.data.v[joint]
    return placement.act(local), placement.rotation @ (velocity.linear + np.cross(velocity.angular, local))


def omega(pm: PinocchioModel, body: str) -> float:
    return 0.0 if body == GROUND else float(pm.data.v[pm.joint_of[body]].angular[2])


def body_wrenches(pm: PinocchioModel, fx: Effects, t: float) -> dict[int, np.ndarray]:
    """World wrenches [f; m about the origin] per Pinocchio joint of the
    effects that are not along a tree coordinate (kinematics of q, v
    computed in pm.data)."""
    wrenches: dict[int, np.ndarray] = {}

    def add(body: str, force=(0.0, 0.0, 0.0), at=(0.0, 0.0, 0.0), torque: float = 0.0) -> None:
        if body == GROUND:
            return
        w = wrenches.setdefault(pm.joint_of[body], np.zeros(6))
        w[:3] += force
        w[3:] += np.cross(at, force)
        w[5] += torque

    for joint in fx.cut_dampers:          # −c(ω_j − ω_i) on body_j, the opposite on body_i
        couple = -joint.damping * (omega(pm, joint.body_j) - omega(pm, joint.body_i))
        add(joint.body_j, torque=couple)
        add(joint.body_i, torque=-couple)
    for joint, law in fx.cut_laws:        # T on body_j, −T on body_i
        value = float(law.value(t))
        add(joint.body_j, torque=value)
        add(joint.body_i, torque=-value)
    for spring in fx.springs:             # tension pulls the points together
        (pa, va), (pb, vb) = point_state(pm, spring.body_a, spring.point_a), point_state(pm, spring.body_b, spring.point_b)
        d = pb - pa
        length = float(np.linalg.norm(d))
        e = d / length
        tension = spring.stiffness * (length - spring.free_length) + spring.damping * float((vb - va) @ e)
        add(spring.body_a, tension * e, pa)
        add(spring.body_b, -tension * e, pb)
    for torque in fx.torques:
        add(torque.body, torque=torque.torque)
    return wrenches


def generalised(pm: PinocchioModel, fx: Effects, q: np.ndarray, v: np.ndarray, t: float
                ) -> tuple[np.ndarray, np.ndarray, dict[int, np.ndarray]]:
    """The generalised forces of the applied effects at (q, v, t): those
    along tree coordinates, those of the body wrenches (Jᵀw), and the
    wrenches."""
    tau = np.zeros(pm.model.nv)
    for k, c in fx.tree_dampers:
        tau[k] -= c * v[k]
    for k, sign, law in fx.tree_laws:
        tau[k] += sign * float(law.value(t))
    on_bodies = np.zeros(pm.model.nv)
    if not fx.wrenches:
        return tau, on_bodies, {}
    pin.forwardKinematics(pm.model, pm.data, q, v)
    wrenches = body_wrenches(pm, fx, t)
    pin.computeJointJacobians(pm.model, pm.data, q)
    for joint, w in wrenches.items():
        on_bodies += pin.getJointJacobian(pm.model, pm.data, joint, pin.WORLD).T @ w
    return tau, on_bodies, wrenches


def external_forces(pm: PinocchioModel, wrenches: dict[int, np.ndarray]) -> list[pin.Force]:
    """World wrenches as `rnea`'s external forces (each joint's local frame;
    kinematics computed in pm.data)."""
    fext = [pin.Force.Zero() for _ in range(pm.model.njoints)]
    for joint, w in wrenches.items():
        fext[joint] = fext[joint] + pm.data.oMi[joint].actInv(pin.Force(w[:3], w[3:]))
    return fext
