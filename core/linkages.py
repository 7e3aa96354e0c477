"""The mechanism kinds mechval knows: each has a closed-form reference
module with the same small interface (geometry dataclass, LINKS, PINS,
check_closure, kinematics, body_motion, build_mechanism)."""

from __future__ import annotations

from types import ModuleType

from . import fourbar, inverted_slider, slider_crank, slotted_lever
from .mechanism import Mechanism
from .planar_scene import build_mechanism as build_planar
from .scenario import Scenario

LINKAGES: dict[str, ModuleType] = {"fourbar": fourbar, "slider_crank": slider_crank,
                                   "slotted_lever": slotted_lever, "inverted_slider": inverted_slider}


def linkage(kind: str) -> ModuleType:
    return LINKAGES[kind]


def build_mechanism(scenario: Scenario) -> Mechanism:
    """The generic `Mechanism` of a validated scenario (a planar file's
    from its bodies and joints, `mechval.planar_scene`)."""
    if scenario.mechanism == "planar":
        return build_planar(scenario)
    return LINKAGES[scenario.mechanism].build_mechanism(scenario)
