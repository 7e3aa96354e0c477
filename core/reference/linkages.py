"""The one path from a scenario's scene to its `Mechanism`, and the closed
forms of the four kinds mechval knows: each kind's module has the same small
interface (Geometry dataclass, LINKS, PINS, SIGNAL_MAP, scene_parts,
check_closure, kinematics, body_motion, assembly_indicator, analysis,
jacobian_condition).

A scene with a closed form takes its motion, canonical signal names and
assembly-branch indicator from it (the reference is then the closed form);
a scene without one is solved by the general reference
(`mechval.reference.planar.solver`); a torque-driven or free scene's motion is
integrated (`mechval.reference.dynamic_scene`). Nothing else differs: the bodies,
joints, drives and forces are the scene's.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from types import ModuleType
from typing import Callable, Mapping

import numpy as np
import pandas as pd

from mechval.reference.closed_forms import fourbar, inverted_slider, slider_crank, slotted_lever
from mechval.model.drive import DriveLaw
from mechval.reference.dynamic_scene import with_dynamics
from mechval.model.mechanism import Drive, Mechanism
from mechval.reference.planar.scene import SolvedMotion, has_redundant_constraints
from mechval.reference.planar.solver import default_pose
from mechval.reference.resultants import RESULTANT_SIGNALS
from mechval.reference.spatial.mechanism import spatial_mechanism
from mechval.reference.spatial.system import SpatialSystem
from mechval.model.scenario import Scenario
from mechval.model.scene import signal_map as scene_signal_map

LINKAGES: dict[str, ModuleType] = {"fourbar": fourbar, "slider_crank": slider_crank,
                                   "slotted_lever": slotted_lever, "inverted_slider": inverted_slider}
#: The crank's pivot joint in every closed-form kind's scene.
CRANK_PIVOT = "O2"
#: `Mechanism.kind` of a scene without a closed form.
GENERAL = "planar"

Geometry = (fourbar.FourBarGeometry | slider_crank.SliderCrankGeometry
            | slotted_lever.SlottedLeverGeometry | inverted_slider.InvertedSliderGeometry)


@dataclass(frozen=True)
class ClosedForm:
    """A kind's closed-form motion of its scene: the crank at O2 follows
    `law` (a torque-driven or free crank's stand-in: its initial angle and
    rate, which picks the branch its integrated motion starts on)."""

    kind: str
    geometry: Geometry
    law: DriveLaw

    @property
    def module(self) -> ModuleType:
        return LINKAGES[self.kind]

    @property
    def signal_map(self) -> Mapping[str, str]:
        """Canonical signal (theta2, F12x, …) → raw column."""
        return self.module.SIGNAL_MAP

    def kinematics(self, t: np.ndarray) -> dict[str, np.ndarray]:
        return self.module.kinematics(self.geometry, self.law, t)

    def motion(self, t: np.ndarray) -> pd.DataFrame:
        return self.module.body_motion(self.geometry, self.law, np.asarray(t, dtype=float))

    def jacobian_condition(self, k: dict[str, np.ndarray]) -> np.ndarray:
        """2-norm condition number of the loop's velocity Jacobian at each
        instant of the kinematics k, columns scaled to the same units
        (distance to singularity)."""
        return self.module.jacobian_condition(self.geometry, k)

    def assembly(self) -> Callable[[Mapping[str, np.ndarray]], np.ndarray] | None:
        return self.module.assembly_indicator(self.geometry)

    def check_closure(self, t: np.ndarray, source, key: str = "geometry") -> None:
        self.module.check_closure(self.geometry, self.law, t, source, key=key)


def build_mechanism(scenario: Scenario) -> Mechanism:
    """The generic `Mechanism` of a validated scenario, from its scene. The
    harness builds each scene's once per run (`mechval.harness.plan`)."""
    if isinstance(scenario.scene, SpatialSystem):
        return spatial_mechanism(scenario.scene, scenario.name)
    return _built(scenario)


def _built(scenario: Scenario) -> Mechanism:
    scene, closed = scenario.scene, scenario.closed_form
    solved = SolvedMotion()      # it needs the mechanism it belongs to
    mechanism = Mechanism(
        name=scenario.name, kind=closed.kind if closed else GENERAL, bodies=scene.bodies, joints=scene.joints,
        drive=scene.drives[0] if scene.drives else None, extra_drives=scene.drives[1:], gravity=scene.gravity,
        motion=closed.motion if closed else solved,
        signal_map=dict(closed.signal_map) if closed else scene_signal_map(scene),
        assembly=closed.assembly() if closed else None, forces=scene.forces, assembly_pose=dict(scene.pose))
    solved.mechanism = mechanism
    if closed is None and has_redundant_constraints(mechanism):
        # Reactions not unique: each body's resultant is (docs/conventions.md).
        mechanism.signal_map.update({f"{b.name}.{q}": f"{b.name}.{suffix}" for b in scene.bodies
                                     for q, suffix in RESULTANT_SIGNALS.items()})
    return with_dynamics(scenario.source, scene, mechanism) if scene.forward_dynamics else mechanism


def without_closed_form(scenario: Scenario) -> Scenario:
    """The same scene for the general reference: its closed form's pose at
    t = 0 as the assembly pose (it picks the branch). The cross-check of
    every closed form (tests/test_planar_scenarios.py)."""
    pose = {**default_pose(build_mechanism(scenario), 0.0), **scenario.scene.pose}
    scene = dataclasses.replace(scenario.scene, pose=pose)
    return dataclasses.replace(scenario, scene=scene, closed_form=None)


def crank_drive(law: DriveLaw) -> Drive:
    """The prescribed crank of a closed-form kind."""
    return Drive(CRANK_PIVOT, law)
