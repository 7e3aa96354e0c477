"""Torque-driven and free mechanisms for the forward-dynamics reference's
tests (mechval.dynamics), each with the initial values it starts from and,
where there is one, its closed-form motion. Built on the prescribed
mechanisms of tests/planar_mechanisms.py and tests/andrews.py with their
drives removed."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.special import ellipj, ellipk

import andrews as A
import planar_mechanisms as pm
from mechval.linkages import build_mechanism
from mechval.mechanism import GROUND, BodyPose, BodyTorque, InitialValue, Joint, Mechanism, SpringDamper, TorqueLaw
from mechval.planar_solver import default_pose
from mechval.scenarios import load


@dataclass(frozen=True)
class Case:
    """A mechanism (with its initial values at t = 0) and an assembly pose."""

    mech: Mechanism
    pose: dict[str, BodyPose]

    @property
    def initial(self) -> tuple[InitialValue, ...]:
        return self.mech.initial_values


def case(mech: Mechanism, initial: tuple[InitialValue, ...], pose) -> Case:
    return Case(dataclasses.replace(mech, initial_values=initial), dict(pose))


def _no_closed_form(t):
    raise NotImplementedError("no closed form: integrate with mechval.dynamics")


# -- closed forms -------------------------------------------------------------------------------

PENDULUM = dict(length=0.5, mass=2.0, g=9.81, swing=2.5)   # m, kg, m/s², rad from the bottom


def pendulum() -> Case:
    """A uniform bar pivoted at its end O under gravity, released from rest
    `swing` rad from hanging straight down (θ = −π/2)."""
    p = PENDULUM
    bar = pm.bar("bar", p["mass"], p["length"])
    theta0 = -np.pi / 2 + p["swing"]
    mech = Mechanism(name="pendulum", kind="planar", bodies=(bar,),
                     joints=(Joint("O", "revolute", GROUND, "bar", (0.0, 0.0), (0.0, 0.0)),),
                     drive=None, gravity=(0.0, -p["g"]), motion=_no_closed_form, signal_map={},
                     assembly_pose={"bar": BodyPose(round(theta0, 1))})
    return case(mech, (InitialValue("O", theta0, 0.0),), dict(mech.assembly_pose))


def pendulum_exact(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """θ(t), ω(t) of `pendulum`: with φ = θ + π/2 the angle from the
    bottom, k = sin(φ0/2), ω0² = m·g·d/I_O and K = K(k²), released from
    rest at φ0: φ = 2·arcsin(k·sn(K − ω0·t)), φ̇ = −2·k·ω0·cn(K − ω0·t)
    (Lawden, *Elliptic Functions and Applications*, 1989, §5.2; sn, cn of
    parameter m = k², scipy.special.ellipj)."""
    p = PENDULUM
    d = p["length"] / 2
    inertia = p["mass"] * p["length"] ** 2 / 3
    omega0 = np.sqrt(p["mass"] * p["g"] * d / inertia)
    k = np.sin(p["swing"] / 2)
    sn, cn, _, _ = ellipj(ellipk(k * k) - omega0 * t, k * k)
    return -np.pi / 2 + 2 * np.arcsin(k * sn), -2 * k * omega0 * cn


SPIN = dict(length=0.4, mass=1.5, torque=0.8, amplitude=0.5, frequency=1.3, phase=0.7, theta0=0.2, rate0=-1.0)


def spinning_crank() -> Case:
    """A bar pivoted at its end, no gravity, spun by the torque law
    T = T0 + A·sin(2π·f·t + φ) from θ0, ω0."""
    s = SPIN
    mech = Mechanism(name="spinning-crank", kind="planar", bodies=(pm.bar("crank", s["mass"], s["length"]),),
                     joints=(Joint("O", "revolute", GROUND, "crank", (0.0, 0.0), (0.0, 0.0)),),
                     drive=None, gravity=(0.0, 0.0), motion=_no_closed_form, signal_map={},
                     torque_drives=(TorqueLaw("O", s["torque"], s["amplitude"], s["frequency"], s["phase"]),),
                     assembly_pose={"crank": BodyPose(0.0)})
    return case(mech, (InitialValue("O", s["theta0"], s["rate0"]),), dict(mech.assembly_pose))


def spinning_exact(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """θ(t), ω(t) of `spinning_crank`: I·θ̈ = T0 + A·sin(Ωt + φ), I = m·l²/3,
    Ω = 2π·f, integrated twice: θ = θ0 + ω0·t + ½(T0/I)·t² +
    (A/I)·[(sin φ − sin(Ωt + φ))/Ω² + t·cos φ/Ω]."""
    s = SPIN
    inertia = s["mass"] * s["length"] ** 2 / 3
    big = 2 * np.pi * s["frequency"]
    a, phase = s["amplitude"] / inertia, s["phase"]
    theta = (s["theta0"] + s["rate0"] * t + 0.5 * s["torque"] / inertia * t * t
             + a * ((np.sin(phase) - np.sin(big * t + phase)) / big**2 + t * np.cos(phase) / big))
    omega = s["rate0"] + s["torque"] / inertia * t + a * (np.cos(phase) - np.cos(big * t + phase)) / big
    return theta, omega


# -- without a closed form ----------------------------------------------------------------------

def free_fourbar() -> Case:
    """The seed four-bar (a crank-rocker) with its drive removed, released
    from rest at its t = 0 pose under gravity: undamped, so its energy is
    constant."""
    mech = build_mechanism(load("fourbar-seed"))
    pose = default_pose(mech, 0.0)
    return case(dataclasses.replace(mech, drive=None), (InitialValue("O2", float(pose["crank"].theta), 0.0),), pose)


def motored_slider_crank() -> Case:
    """tests/planar_mechanisms.py's slider-crank (damped guide), its crank
    carrying a flywheel (izz 0.05 kg·m²: without one the light crank
    whips through each dead centre), driven by a motor torque T = 2 +
    0.5·sin(2π·1.5t + 0.3) N·m at the crank pivot, against gravity, a
    spring-damper from the slider to the ground, a damper at the crank pin
    and a torque on the conrod."""
    base = pm.slider_driven_slider_crank()
    joints = tuple(dataclasses.replace(j, damping=0.02) if j.name == "A" else j for j in base.joints)
    bodies = tuple(dataclasses.replace(b, izz=0.05) if b.name == "crank" else b for b in base.bodies)
    mech = dataclasses.replace(
        base, name="motored-slider-crank", drive=None, joints=joints, bodies=bodies,
        torque_drives=(TorqueLaw("O2", 2.0, 0.5, 1.5, 0.3, name="motor"),),
        forces=(SpringDamper("return", "slider", (0.0, 0.0), GROUND, (0.6, 0.0), 150.0, 0.25, 1.5),
                BodyTorque("twist", "conrod", 0.1)))
    crank = base.assembly_pose["crank"].theta
    return case(mech, (InitialValue("O2", crank, 3.0),), dict(base.assembly_pose))


def free_five_bar() -> Case:
    """tests/planar_mechanisms.py's five-bar with both drives removed: two
    degrees of freedom, started at its drives' t = 0 angles and rates."""
    base = pm.five_bar()
    mech = dataclasses.replace(base, drive=None, extra_drives=())
    initial = tuple(InitialValue(d.joint, d.law.phi0, d.law.omega0) for d in base.drives)
    return case(mech, initial, dict(base.assembly_pose))


def half_driven_five_bar() -> Case:
    """tests/planar_mechanisms.py's five-bar with its first crank still
    prescribed (φ1 = 0.5 + 2t) and the second free, started at its drive's
    t = 0 angle and rate: a rheonomic constraint in the forward dynamics."""
    base = pm.five_bar()
    second = base.extra_drives[0]
    mech = dataclasses.replace(base, extra_drives=())
    return case(mech, (InitialValue(second.joint, second.law.phi0, second.law.omega0),), dict(base.assembly_pose))


def free_parallelogram() -> Case:
    """The redundant parallelogram (three cranks, one coupler) swinging
    under gravity from rest at −0.5 rad: between −π + 0.5 and −0.5, clear
    of its change points at 0 and −π."""
    base = pm.parallelogram()
    pose = {name: BodyPose(-0.5 if name != "coupler" else 0.0) for name in base.assembly_pose}
    return case(dataclasses.replace(base, drive=None, assembly_pose=pose), (InitialValue("O1", -0.5, 0.0),), pose)


def motored_andrews() -> Case:
    """Andrews' squeezer under its motor torque mom at O and its spring,
    from the Test Set's consistent initial state (tests/andrews.py)."""
    mech = dataclasses.replace(A.andrews_mechanism(), drive=None, torque_drives=(TorqueLaw("O", A.mom),))
    return case(mech, (InitialValue("O", float(A.Q0[0]), float(A.QDOT0[0])),), A.pose_near(A.Q0))


CASES: dict[str, Callable[[], Case]] = {
    "pendulum": pendulum, "spinning-crank": spinning_crank, "free-fourbar": free_fourbar,
    "motored-slider-crank": motored_slider_crank, "free-five-bar": free_five_bar,
    "half-driven-five-bar": half_driven_five_bar,
    "free-parallelogram": free_parallelogram, "motored-andrews": motored_andrews,
}
