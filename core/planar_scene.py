"""The `Mechanism` of a planar file (`mechanism = "planar"`,
docs/scenario-format.md#planar-files): its bodies, joints, drives, force
elements and assembly pose as the file gives them, solved by the general
reference (`mechval.planar_solver`).

Canonical signals (docs/conventions.md): per body B its angle and its
centre of mass's motion, B.theta, B.omega, B.alpha, B.x, B.y, B.vx, B.vy,
B.ax, B.ay; per joint J its reaction (the force by its first body on its
second, world axes), J.Fx, J.Fy, and for a prismatic joint its normal force
J.N and couple J.M; per drive, named after its joint, its torque J.T
(revolute) or force J.F (prismatic); per torque law N (`[[torque]]`) the
torque it applies, N.T. The first drive's raw column stays
"drive.T" (or "drive.F"), the name every adapter writes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
import pandas as pd

from .mechanism import Body, BodyPose, BodyTorque, Drive, Joint, Mechanism, SpringDamper, TorqueLaw
from .planar_constraints import MechanismError
from .planar_solver import raw_planar, redundant_constraints
from .resultants import RESULTANT_SIGNALS
from .scenario import Scenario

BODY_SIGNALS = ("theta", "omega", "alpha")
COM_SIGNALS = ("x", "y", "vx", "vy", "ax", "ay")


@dataclass(frozen=True)
class PlanarScene:
    """What a planar file describes, validated (SI units)."""

    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    drives: tuple[Drive, ...]
    forces: tuple[SpringDamper | BodyTorque, ...] = ()
    pose: Mapping[str, BodyPose] = field(default_factory=dict)
    gravity: tuple[float, float] = (0.0, 0.0)
    #: Applied joint torque laws (`[[torque]]`); the initial values of a
    #: torque-driven or free run are the scenario's (`[[initial]]`).
    torques: tuple[TorqueLaw, ...] = ()


def signal_map(scene: PlanarScene) -> dict[str, str]:
    """Canonical signal → raw column, in the order signals are listed."""
    names: dict[str, str] = {}
    for body in scene.bodies:
        names.update({f"{body.name}.{q}": f"{body.name}.{q}" for q in BODY_SIGNALS})
        names.update({f"{body.name}.{q}": f"{body.name}.G.{q}" for q in COM_SIGNALS})
    for joint in scene.joints:
        quantities = ("Fx", "Fy") + (("N", "M") if joint.kind == "prismatic" else ())
        names.update({f"{joint.name}.{q}": f"{joint.name}.{q}" for q in quantities})
    kinds = {j.name: j.kind for j in scene.joints}
    for drive in scene.drives:
        kind = kinds[drive.joint]
        names[f"{drive.joint}.{'T' if kind == 'revolute' else 'F'}"] = drive.effort_column(kind)
    for law in scene.torques:
        names[f"{law.name}.T"] = f"{law.name}.T"
    return names


def has_redundant_constraints(mechanism: Mechanism) -> bool:
    """Whether the joints' Jacobian is rank-deficient at the assembly pose;
    a pose that does not assemble is refused later, where it always was."""
    try:
        return bool(redundant_constraints(mechanism))
    except MechanismError:
        return False


class SolvedMotion:
    """A planar mechanism's `motion`: the raw motion columns of its frames,
    from the general reference (the four kinds have closed forms instead)."""

    def __init__(self, mechanism: Mechanism | None = None):
        self.mechanism = mechanism

    def __call__(self, t: np.ndarray) -> pd.DataFrame:
        frame = raw_planar(self.mechanism, np.asarray(t, dtype=float)).frame
        return frame[["t"] + self.mechanism.motion_columns()]


def build_mechanism(scenario: Scenario) -> Mechanism:
    """The generic `Mechanism` of a planar scenario (its torque laws and
    initial values are added by `mechval.dynamic_scene`)."""
    scene: PlanarScene = scenario.planar
    motion = SolvedMotion()      # it needs the mechanism it belongs to
    mechanism = Mechanism(
        name=scenario.name, kind="planar", bodies=scene.bodies, joints=scene.joints,
        drive=scene.drives[0] if scene.drives else None,
        extra_drives=scene.drives[1:], gravity=scene.gravity, motion=motion, signal_map=signal_map(scene),
        forces=scene.forces, assembly_pose=dict(scene.pose),
    )
    motion.mechanism = mechanism
    if has_redundant_constraints(mechanism):
        # Reactions not unique: each body's resultant is (docs/conventions.md).
        mechanism.signal_map.update({f"{b.name}.{q}": f"{b.name}.{suffix}" for b in scene.bodies
                                     for q, suffix in RESULTANT_SIGNALS.items()})
    return mechanism
