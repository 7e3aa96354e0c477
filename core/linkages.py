"""The mechanism kinds mechval knows: each has a closed-form reference
module with the same small interface (geometry dataclass, LINKS, PINS,
check_closure, kinematics, body_motion, build_mechanism)."""

from __future__ import annotations

import dataclasses
from collections import OrderedDict
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


#: The mechanisms of the last scenarios built, by the scenario's identity
#: (a Scenario holds dicts, so it has no hash; the entry keeps it alive, so
#: its id is not reused while it is here). Planning, the limits check and
#: the model audit of one run all ask for the same scenario's mechanism,
#: and what is derived from it (`Mechanism.derived`) is then computed once.
_BUILT: OrderedDict[int, tuple[Scenario, Mechanism]] = OrderedDict()
_BUILT_KEPT = 64


def build_mechanism(scenario: Scenario) -> Mechanism:
    """The generic `Mechanism` of a validated scenario (a planar file's
    from its bodies and joints, `mechval.planar_scene`; a torque-driven or
    free scene's with the integrated motion, `mechval.dynamic_scene`); the
    same object for the same scenario object while it is among the last
    built."""
    kept = _BUILT.get(id(scenario))
    if kept is not None and kept[0] is scenario:
        _BUILT.move_to_end(id(scenario))
        return kept[1]
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
    _BUILT[id(scenario)] = (scenario, mechanism)
    if len(_BUILT) > _BUILT_KEPT:
        _BUILT.popitem(last=False)
    return mechanism
