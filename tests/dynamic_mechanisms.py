"""Torque-driven and free mechanisms for the forward-dynamics reference's
tests (mechval.reference.dynamics), each with the initial values it starts from and,
where there is one, its closed-form motion: the contract suite's four
(`mechval.testing.mechanisms`: a pendulum, a crank under a torque law, the
seed four-bar falling, a motored slider-crank) and more, built on the
prescribed mechanisms of tests/planar_mechanisms.py and tests/andrews.py
with their drives removed."""

from __future__ import annotations

import dataclasses
from typing import Callable

import andrews as A
import planar_mechanisms as pm
from mechval.model.mechanism import BodyPose, InitialValue, TorqueLaw
from mechval.testing.mechanisms import (Case, case, free_fourbar, motored_slider_crank,  # noqa: F401
                                        pendulum, pendulum_exact, spinning_crank, spinning_exact)


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
