"""The mechanism kinds mechval knows: each has a closed-form reference
module with the same small interface (geometry dataclass, LINKS, PINS,
check_closure, kinematics, body_motion, build_mechanism)."""

from __future__ import annotations

import dataclasses
from types import ModuleType

from . import fourbar, inverted_slider, slider_crank, slotted_lever
from .drive import DriveLaw
from .dynamic_scene import with_dynamics
from .mechanism import Mechanism
from .planar_scene import build_mechanism as build_planar
from .scenario import Scenario

LINKAGES: dict[str, ModuleType] = {"fourbar": fourbar, "slider_crank": slider_crank,
                                   "slotted_lever": slotted_lever, "inverted_slider": inverted_slider}


def linkage(kind: str) -> ModuleType:
    return LINKAGES[kind]


def build_mechanism(scenario: Scenario) -> Mechanism:
    """The generic `Mechanism` of a validated scenario (a planar file's
    from its bodies and joints, `mechval.planar_scene`; a torque-driven or
    free scene's with the integrated motion, `mechval.dynamic_scene`). The
    harness builds each scene's once per run (`mechval.harness.plan`)."""
    if scenario.mechanism == "planar":
        mechanism = build_planar(scenario)
    elif scenario.drive is None:    # a torque-driven or free crank: built at its initial angle and rate
        start = scenario.initial_values[0]
        stand_in = dataclasses.replace(scenario, drive=DriveLaw(start.value, start.rate))
        mechanism = LINKAGES[scenario.mechanism].build_mechanism(stand_in)
    else:
        mechanism = LINKAGES[scenario.mechanism].build_mechanism(scenario)
    if scenario.forward_dynamics:
        mechanism = with_dynamics(scenario, mechanism)
    return mechanism
