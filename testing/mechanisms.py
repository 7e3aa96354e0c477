"""The torque-driven and free mechanisms of the contract suite, each with
the initial values it starts from and, where there is one, its closed-form
motion: a pendulum and a crank under a torque law (closed forms), the seed
four-bar falling from rest, a motored slider-crank with a spring-damper,
joint dampers and a body torque. Built as `Mechanism`s directly (planar
files say the same in TOML); each assembly pose is worked out by hand and
rounded, never by the solver under test."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.special import ellipj, ellipk

from mechval.model.drive import DriveLaw
from mechval.reference.linkages import build_mechanism
from mechval.model.mechanism import (GROUND, Body, BodyPose, BodyTorque, Drive, InitialValue, Joint, Mechanism,
                               SpringDamper, TorqueLaw)
from mechval.reference.planar.solver import default_pose
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


def no_closed_form(t):
    raise NotImplementedError("no closed form: solve with mechval.reference.planar.solver or mechval.reference.dynamics")


def bar(name: str, mass: float, length: float) -> Body:
    """A uniform bar along its frame's x axis from the origin."""
    return Body(name, mass, (length / 2, 0.0), mass * length**2 / 12)


# -- closed forms -------------------------------------------------------------------------------

PENDULUM = dict(length=0.5, mass=2.0, g=9.81, swing=2.5)   # m, kg, m/s², rad from the bottom


def pendulum() -> Case:
    """A uniform bar pivoted at its end O under gravity, released from rest
    `swing` rad from hanging straight down (θ = −π/2)."""
    p = PENDULUM
    theta0 = -np.pi / 2 + p["swing"]
    mech = Mechanism(name="pendulum", kind="planar", bodies=(bar("bar", p["mass"], p["length"]),),
                     joints=(Joint("O", "revolute", GROUND, "bar", (0.0, 0.0), (0.0, 0.0)),),
                     drive=None, gravity=(0.0, -p["g"]), motion=no_closed_form, signal_map={},
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
    mech = Mechanism(name="spinning-crank", kind="planar", bodies=(bar("crank", s["mass"], s["length"]),),
                     joints=(Joint("O", "revolute", GROUND, "crank", (0.0, 0.0), (0.0, 0.0)),),
                     drive=None, gravity=(0.0, 0.0), motion=no_closed_form, signal_map={},
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


SLIDER = dict(crank=0.1, conrod=0.3)


def slider_driven_slider_crank(law: DriveLaw = DriveLaw(0.35, -0.12, 0.0)) -> Mechanism:
    """The slider-crank driven by its slider: the guide (ground, slider) is
    a prismatic drive along x through O, x_B = s(t); the crank follows on
    its upper branch. Closed form: r² + x² − 2·r·x·cosθ2 = l²."""
    r, l = SLIDER["crank"], SLIDER["conrod"]
    bodies = (bar("crank", 1.0, r), bar("conrod", 2.0, l), Body("slider", 3.0, (0.0, 0.0), 1e-3))
    joints = (
        Joint("O2", "revolute", GROUND, "crank", (0.0, 0.0), (0.0, 0.0)),
        Joint("A", "revolute", "conrod", "crank", (0.0, 0.0), (r, 0.0)),
        Joint("B", "revolute", "slider", "conrod", (0.0, 0.0), (l, 0.0)),
        Joint("guide", "prismatic", GROUND, "slider", (0.0, 0.0), (0.0, 0.0), axis=(1.0, 0.0), damping=4.0),
    )
    x = law.phi0
    th2 = np.arccos((r * r + x * x - l * l) / (2 * r * x))
    a = r * np.array([np.cos(th2), np.sin(th2)])
    th3 = float(np.arctan2(-a[1], x - a[0]))
    return Mechanism(
        name="slider-driven", kind="planar", bodies=bodies, joints=joints, drive=Drive("guide", law),
        gravity=(0.0, -9.81), motion=no_closed_form, signal_map={},
        assembly_pose={"crank": BodyPose(round(float(th2), 1)), "conrod": BodyPose(round(th3, 1)),
                       "slider": BodyPose(0.0)},
    )


def motored_slider_crank() -> Case:
    """`slider_driven_slider_crank` (damped guide), its crank carrying a
    flywheel (izz 0.05 kg·m²: without one the light crank whips through
    each dead centre), driven by a motor torque T = 2 + 0.5·sin(2π·1.5t +
    0.3) N·m at the crank pivot instead of its slider drive, against
    gravity, a spring-damper from the slider to the ground, a damper at
    the crank pin and a torque on the conrod."""
    base = slider_driven_slider_crank()
    joints = tuple(dataclasses.replace(j, damping=0.02) if j.name == "A" else j for j in base.joints)
    bodies = tuple(dataclasses.replace(b, izz=0.05) if b.name == "crank" else b for b in base.bodies)
    mech = dataclasses.replace(
        base, name="motored-slider-crank", drive=None, joints=joints, bodies=bodies,
        torque_drives=(TorqueLaw("O2", 2.0, 0.5, 1.5, 0.3, name="motor"),),
        forces=(SpringDamper("return", "slider", (0.0, 0.0), GROUND, (0.6, 0.0), 150.0, 0.25, 1.5),
                BodyTorque("twist", "conrod", 0.1)))
    crank = base.assembly_pose["crank"].theta
    return case(mech, (InitialValue("O2", crank, 3.0),), dict(base.assembly_pose))


#: The contract suite's cases by name.
CASES = {"pendulum": pendulum, "spinning-crank": spinning_crank, "free-fourbar": free_fourbar,
         "motored-slider-crank": motored_slider_crank}
