"""Energy of a planar mechanism and the power of what is not conservative,
from raw motion columns alone (any engine's, or the reference's).

- kinetic: Σ ½·m·|v_G|² + ½·izz·ω² (centre-of-mass velocity from the body
  frame's motion, `mechval.model.kinematics.point_motion`);
- potential: gravity −Σ m·g·r_G, and each spring ½·k·(ℓ − ℓ0)²;
- its rate dE/dt from the accelerations (`energy_rate`);
- applied power (the rest): torque laws and prescribed drives (their effort
  columns times the joint's relative rate, `input_power`), body torques
  τ·ω, and the dampers' losses −c·(rate)² (joint dampers, spring-dampers'
  dℓ/dt);
- the work of the applied power since the first sample (`work`).

The energy balance: E(t) − E(t0) = ∫ applied power dt, with E = kinetic +
potential (Norton, *Design of Machinery*, §11.2, the energy method; for a
constrained system the ideal joints do no work, Haug 1989, §11.1). A
mechanism with no drive, torque law, body torque or damper conserves E
(`conservative`).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_simpson

from mechval.model.kinematics import point_motion, slide_rate
from mechval.model.mechanism import GROUND, BodyTorque, Joint, Mechanism, SpringDamper


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


def _potential(mech: Mechanism, raw) -> tuple[np.ndarray, np.ndarray]:
    """The potential energy V (J) and its rate dV/dt (W) at each sample:
    gravity's −Σ m·g·r_G and the springs' ½·k·(ℓ − ℓ0)², and their rates."""
    gx, gy = mech.gravity
    energy = rate = 0.0
    for body in mech.bodies:
        G = point_motion(raw, body.name, body.com)
        energy = energy - body.mass * (gx * G["x"] + gy * G["y"])
        rate = rate - body.mass * (gx * G["vx"] + gy * G["vy"])
    for element in mech.forces:
        if isinstance(element, SpringDamper):
            length, stretch = _stretch(raw, element)
            energy = energy + 0.5 * element.stiffness * (length - element.free_length) ** 2
            rate = rate + element.stiffness * (length - element.free_length) * stretch
    zero = np.zeros(len(raw["t"]))
    return energy + zero, rate + zero


def potential_energy(mech: Mechanism, raw) -> np.ndarray:
    """Gravity's −Σ m·g·r_G plus the springs' ½·k·(ℓ − ℓ0)² (J); zero for
    gravity at the world origin."""
    return _potential(mech, raw)[0]


def joint_rate(raw, joint: Joint) -> np.ndarray:
    """ωj − ωi of a revolute joint, the sliding speed of a prismatic one."""
    if joint.kind == "prismatic":
        return slide_rate(raw, joint)
    omega = lambda name: 0.0 if name == GROUND else np.asarray(raw[f"{name}.omega"])
    return omega(joint.body_j) - omega(joint.body_i)


def kinetic_rate(mech: Mechanism, raw) -> np.ndarray:
    """dK/dt at each sample (W): Σ m·v_G·a_G + izz·ω·α."""
    rate = 0.0
    for body in mech.bodies:
        G = point_motion(raw, body.name, body.com)
        w, al = np.asarray(raw[f"{body.name}.omega"]), np.asarray(raw[f"{body.name}.alpha"])
        rate = rate + body.mass * (G["vx"] * G["ax"] + G["vy"] * G["ay"]) + body.izz * w * al
    return rate + np.zeros(len(raw["t"]))


def energy_rate(mech: Mechanism, raw) -> np.ndarray:
    """dE/dt at each sample (W), from the velocities and accelerations:
    dK/dt − Σ m·g·v_G + Σ springs k·(ℓ − ℓ0)·dℓ/dt."""
    return kinetic_rate(mech, raw) + _potential(mech, raw)[1]


def input_power(mech: Mechanism, raw) -> np.ndarray:
    """Power of the prescribed drives and torque laws, T·ω (or F·ṡ), at
    each sample (W): what motors put in."""
    power = 0.0
    for drive in mech.drives:
        joint = mech.joint(drive.joint)
        power = power + np.asarray(raw[drive.effort_column(joint.kind)]) * joint_rate(raw, joint)
    for law in mech.torque_drives:
        power = power + np.asarray(raw[f"{law.name}.T"]) * joint_rate(raw, mech.joint(law.joint))
    return power + np.zeros(len(raw["t"]))


def conservative(mech: Mechanism) -> bool:
    """True when nothing does work on the mechanism but gravity and springs
    (no drive, torque law, body torque, joint damper or damped spring): its
    energy is then constant."""
    return not (mech.drives or mech.torque_drives or mech.damped_joints
                or any(isinstance(f, BodyTorque) or f.damping for f in mech.forces))


def applied_power(mech: Mechanism, raw) -> np.ndarray:
    """Power of the torque laws, prescribed drives and body torques, plus
    the dampers' (negative) power, at each sample (W)."""
    power = input_power(mech, raw)
    for joint in mech.damped_joints:
        power = power - joint.damping * joint_rate(raw, joint) ** 2
    for element in mech.forces:
        if isinstance(element, BodyTorque):
            power = power + element.torque * np.asarray(raw[f"{element.body}.omega"])
        elif element.damping:
            power = power - element.damping * _stretch(raw, element)[1] ** 2
    return power + np.zeros(len(raw["t"]))


def work(t: np.ndarray, power: np.ndarray) -> np.ndarray:
    """∫ power dt from the first sample to each (J): cumulative Simpson
    (scipy.integrate.cumulative_simpson, a quadratic through each sample
    and its neighbours; its error falls as h⁴ with the sample interval h,
    measured ÷16 per halving on a smooth power)."""
    if len(t) < 3:      # Simpson needs three samples; two: the trapezoid is exact for a line
        return np.concatenate([[0.0], np.cumsum(np.diff(t) * (power[1:] + power[:-1]) / 2)])[:len(t)]
    return cumulative_simpson(power, x=t, initial=0.0)


def work_error(t: np.ndarray, power: np.ndarray) -> np.ndarray:
    """An estimate of `work`'s quadrature error at each sample (J): by
    Richardson, |W_h − W_2h| / 15 at the even samples (W_2h from every
    second sample; the error is fourth order), held to the next sample."""
    if len(t) < 5:
        return np.zeros(len(t))
    fine, coarse = work(t, power)[::2], work(t[::2], power[::2])
    return np.repeat(np.abs(fine - coarse) / 15.0, 2)[:len(t)]
