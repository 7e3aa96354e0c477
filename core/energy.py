"""Energy of a planar mechanism and the power of what is not conservative,
from raw motion columns alone (any engine's, or the reference's).

- kinetic: Σ ½·m·|v_G|² + ½·izz·ω² (centre-of-mass velocity from the body
  frame's motion, `mechval.mechanism.point_motion`);
- potential: gravity −Σ m·g·r_G, and each spring ½·k·(ℓ − ℓ0)²;
- applied power (the rest): torque laws and prescribed drives (their effort
  columns times the joint's relative rate), body torques τ·ω, and the
  dampers' losses −c·(rate)² (joint dampers, spring-dampers' dℓ/dt).

The energy balance: E(t) − E(t0) = ∫ applied power dt, with E = kinetic +
potential (Norton, *Design of Machinery*, §11.2, the energy method; for a
constrained system the ideal joints do no work, Haug 1989, §11.1).
"""

from __future__ import annotations

import numpy as np

from .health import slide_rate
from .kinematics import point_motion
from .mechanism import GROUND, BodyTorque, Joint, Mechanism, SpringDamper


def kinetic_energy(mech: Mechanism, raw) -> np.ndarray:
    """Σ ½·m·|v_G|² + ½·izz·ω² at each sample (J)."""
    energy = 0.0
    for body in mech.bodies:
        G = point_motion(raw, body.name, body.com)
        w = np.asarray(raw[f"{body.name}.omega"])
        energy = energy + 0.5 * body.mass * (G["vx"] ** 2 + G["vy"] ** 2) + 0.5 * body.izz * w * w
    return energy + np.zeros(len(raw["t"]))


def _stretch(raw, spring: SpringDamper) -> tuple[np.ndarray, np.ndarray]:
    """A spring's length ℓ and its rate dℓ/dt."""
    a = point_motion(raw, spring.body_a, spring.point_a)
    b = point_motion(raw, spring.body_b, spring.point_b)
    dx, dy = b["x"] - a["x"], b["y"] - a["y"]
    length = np.hypot(dx, dy)
    return length, (dx * (b["vx"] - a["vx"]) + dy * (b["vy"] - a["vy"])) / length


def potential_energy(mech: Mechanism, raw) -> np.ndarray:
    """Gravity's −Σ m·g·r_G plus the springs' ½·k·(ℓ − ℓ0)² (J); zero for
    gravity at the world origin."""
    gx, gy = mech.gravity
    energy = 0.0
    for body in mech.bodies:
        G = point_motion(raw, body.name, body.com)
        energy = energy - body.mass * (gx * G["x"] + gy * G["y"])
    for element in mech.forces:
        if isinstance(element, SpringDamper):
            length, _ = _stretch(raw, element)
            energy = energy + 0.5 * element.stiffness * (length - element.free_length) ** 2
    return energy + np.zeros(len(raw["t"]))


def joint_rate(raw, joint: Joint) -> np.ndarray:
    """ωj − ωi of a revolute joint, the sliding speed of a prismatic one."""
    if joint.kind == "prismatic":
        return slide_rate(raw, joint)
    omega = lambda name: 0.0 if name == GROUND else np.asarray(raw[f"{name}.omega"])
    return omega(joint.body_j) - omega(joint.body_i)


def applied_power(mech: Mechanism, raw) -> np.ndarray:
    """Power of the torque laws, prescribed drives and body torques, plus
    the dampers' (negative) power, at each sample (W)."""
    power = 0.0
    for drive in mech.drives:
        joint = mech.joint(drive.joint)
        power = power + np.asarray(raw[drive.effort_column(joint.kind)]) * joint_rate(raw, joint)
    for law in mech.torque_drives:
        power = power + np.asarray(raw[f"{law.name}.T"]) * joint_rate(raw, mech.joint(law.joint))
    for joint in mech.damped_joints:
        power = power - joint.damping * joint_rate(raw, joint) ** 2
    for element in mech.forces:
        if isinstance(element, BodyTorque):
            power = power + element.torque * np.asarray(raw[f"{element.body}.omega"])
        elif element.damping:
            power = power - element.damping * _stretch(raw, element)[1] ** 2
    return power + np.zeros(len(raw["t"]))
