"""The scene model every scenario becomes (docs/scene-model.md): rigid
bodies, joints between them, drives, applied torque laws, the initial values
a torque-driven or free run starts from, force elements, gravity and an
approximate assembly pose, all in SI units.

A planar file states its scene directly (`mechval.scenarios.planar`); each
of the four closed-form kinds expands its few numbers into one
(`mechval.scenarios.kinds`) and supplies its closed form beside it
(`mechval.reference.linkages.ClosedForm`). The `Mechanism` adapters see is built from
the scene alone (`mechval.reference.linkages.build_mechanism`).

Canonical signals of a scene without a closed form (docs/conventions.md):
per body B its angle and its centre of mass's motion, B.theta, B.omega,
B.alpha, B.x, B.y, B.vx, B.vy, B.ax, B.ay; per joint J its reaction (the
force by its first body on its second, world axes), J.Fx, J.Fy, and for a
prismatic joint its normal force J.N and couple J.M; per drive, named after
its joint, its torque J.T (revolute) or force J.F (prismatic); per torque
law N the torque it applies, N.T. The first drive's raw column stays
"drive.T" (or "drive.F"), the name every adapter writes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

from mechval.model.mechanism import Body, BodyPose, BodyTorque, Drive, InitialValue, Joint, SpringDamper, TorqueLaw

BODY_SIGNALS = ("theta", "omega", "alpha")
COM_SIGNALS = ("x", "y", "vx", "vy", "ax", "ay")


@dataclass(frozen=True)
class Scene:
    """A validated scene (SI units; frames as `mechval.model.mechanism` states)."""

    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    #: Prescribed joint motions; the first one's effort is "drive.T" / "drive.F".
    drives: tuple[Drive, ...] = ()
    forces: tuple[SpringDamper | BodyTorque, ...] = ()
    #: Approximate pose per body at t = 0: picks the assembly branch where
    #: no closed form does (empty: the closed form's own pose at t = 0).
    pose: Mapping[str, BodyPose] = field(default_factory=dict)
    gravity: tuple[float, float] = (0.0, 0.0)
    #: Applied joint torque laws, which prescribe no motion.
    torques: tuple[TorqueLaw, ...] = ()
    #: Where a torque-driven or free run starts: one joint value per degree
    #: of freedom the drives leave.
    initial: tuple[InitialValue, ...] = ()

    @property
    def forward_dynamics(self) -> bool:
        """True when the motion is integrated rather than prescribed
        (`Mechanism.forward_dynamics`)."""
        return not self.drives or bool(self.torques) or bool(self.initial)


def signal_map(scene: Scene) -> dict[str, str]:
    """Canonical signal → raw column of a scene without a closed form, in
    the order signals are listed."""
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
