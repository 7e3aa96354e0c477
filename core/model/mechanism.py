"""The generic planar mechanism that adapters build engine models from.

A `Mechanism` is all an engine adapter may look at: rigid bodies, joints,
the drive, gravity, and the reference motion of every body (used only to
start a simulation from a consistent state). It never says "four-bar": a new
linkage needs a `Mechanism` builder and a reference, not new engine models.

Frames and conventions (docs/conventions.md):
- World: planar x–y, joint axes along +z, angles counter-clockwise from +x.
- Each body has a frame; its pose is (x, y, theta) of the frame origin in
  world. Centre of mass `com` and joint points are given in that body frame.
  The ground is the body named `GROUND`, whose frame is the world frame.
- A joint's reaction is the force exerted BY `body_i` ON `body_j`, in world
  axes, at the joint point (a prismatic joint adds a couple `M` on body_j).
  Builders order (body_i, body_j) so that this is the canonical `Fij`.
- The drive acts at a revolute joint; its torque `T` acts on that joint's
  body_j (the crank) and −T on body_i.

The general reference (`mechval.reference.planar.solver`) also reads what the four
closed-form kinds leave at their defaults: further drives (a revolute drive
prescribes the relative angle θj − θi, a prismatic drive the slide s along
the axis, both by a `DriveLaw`; a prismatic drive's effort is a force `F`
along the axis on body_j), force elements (`SpringDamper`, `BodyTorque`)
and an approximate assembly pose that picks the branch. The
forward-dynamics reference (`mechval.reference.dynamics`) reads torque-driven and
free mechanisms: no prescribed `drive` (None) or fewer drives than the
mobility, applied `TorqueLaw`s, and the `InitialValue`s a run starts from.

Raw columns (`motion_columns`, `reaction_columns`) name what adapters and
the reference report: "crank.theta", "A.Fx", "drive.T", ...
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Literal, Mapping

import numpy as np
import pandas as pd

from mechval.model.drive import DriveLaw

GROUND = "ground"
MOTION_QUANTITIES = ("x", "y", "theta", "vx", "vy", "omega", "ax", "ay", "alpha")
DRIVE_TORQUE = "drive.T"

Vec2 = tuple[float, float]


@dataclass(frozen=True)
class Body:
    """A rigid body: mass (kg), centre of mass in its frame (m), izz about
    the centre of mass (kg·m²)."""

    name: str
    mass: float
    com: Vec2
    izz: float


@dataclass(frozen=True)
class Joint:
    """A revolute or prismatic joint between body_i and body_j.

    `point_i`/`point_j` are the joint point in each body's frame (world for
    the ground). A prismatic joint lets body_j translate along `axis` (a unit
    vector in body_i's frame, through point_i) with no relative rotation.
    `damping` is viscous: N·m·s/rad on the relative rotation (revolute) or
    N·s/m on the relative translation (prismatic); 0 means no damper.
    """

    name: str
    kind: Literal["revolute", "prismatic"]
    body_i: str
    body_j: str
    point_i: Vec2
    point_j: Vec2
    axis: Vec2 = (1.0, 0.0)
    damping: float = 0.0
    #: Prismatic only: the relative angle θj − θi the joint holds (rad).
    #: None: the angle of `axis` in body_i's frame, i.e. body_j's x axis
    #: lies along the slide (as every closed-form builder sets its frames).
    angle: float | None = None

    @property
    def held_angle(self) -> float:
        """θj − θi of a prismatic joint (see `angle`)."""
        return float(np.arctan2(self.axis[1], self.axis[0])) if self.angle is None else self.angle


@dataclass(frozen=True)
class Drive:
    """The prescribed motion of `joint` (body_j relative to body_i): the
    relative angle θj − θi of a revolute joint, or the slide s = (Pj − Pi)·u
    of a prismatic one (u the axis in world axes), equal to `law`'s φ(t).

    Its effort, torque T (revolute) or force F along u (prismatic) on body_j
    and the opposite on body_i, is the raw column "NAME.T" or "NAME.F".
    """

    joint: str
    law: DriveLaw
    name: str = "drive"

    def effort_column(self, kind: str) -> str:
        return f"{self.name}.T" if kind == "revolute" else f"{self.name}.F"


@dataclass(frozen=True)
class TorqueLaw:
    """An applied torque at a revolute joint, T(t) = torque + amplitude·
    sin(2π·frequency·t + phase) (N·m, N·m, Hz, rad): T on body_j and −T on
    body_i, about +z. Unlike a `Drive` it prescribes no motion (forward
    dynamics, `mechval.reference.dynamics`); its value is the raw column "NAME.T"."""

    joint: str
    torque: float = 0.0
    amplitude: float = 0.0
    frequency: float = 0.0
    phase: float = 0.0
    name: str = "drive"

    def value(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return self.torque + self.amplitude * np.sin(2 * np.pi * self.frequency * t + self.phase)


@dataclass(frozen=True)
class InitialValue:
    """A joint's coordinate at the start of a torque-driven or free run and
    its rate: relative angle θj − θi (rad, rad/s) of a revolute joint, or
    slide (m, m/s) of a prismatic one (`mechval.reference.initial_state`)."""

    joint: str
    value: float
    rate: float = 0.0


@dataclass(frozen=True)
class SpringDamper:
    """A linear spring-damper between point_a of body_a and point_b of
    body_b (body frames; world for the ground): tension
    stiffness·(ℓ − free_length) + damping·dℓ/dt along the line between
    them (N/m, m, N·s/m), pulling the points together when positive."""

    name: str
    body_a: str
    point_a: Vec2
    body_b: str
    point_b: Vec2
    stiffness: float
    free_length: float
    damping: float = 0.0


@dataclass(frozen=True)
class BodyTorque:
    """A constant torque (N·m, about +z) on a body."""

    name: str
    body: str
    torque: float


@dataclass(frozen=True)
class BodyPose:
    """An approximate pose of a body's frame at t = 0: its angle (rad) and,
    optionally, its origin (m). It only picks the assembly branch."""

    theta: float
    x: float | None = None
    y: float | None = None


@dataclass(frozen=True)
class Mechanism:
    """Generic planar mechanism; see the module docstring for frames."""

    name: str
    kind: str
    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    #: None: no prescribed drive (torque-driven or free; `mechval.reference.dynamics`).
    drive: Drive | None
    gravity: Vec2
    #: Reference motion of every body frame at the given instants, as raw
    #: motion columns ("crank.theta", ...). Adapters use it to start from a
    #: consistent state; it may refuse instants where the loop cannot close.
    motion: Callable[[np.ndarray], pd.DataFrame] = field(repr=False, compare=False)
    #: Canonical signal name -> raw column ("F32x" -> "A.Fx").
    signal_map: Mapping[str, str] = field(repr=False, compare=False)
    #: Assembly-branch indicator from raw motion columns: its sign is
    #: constant on one branch and flips only when the loop changes branch.
    assembly: Callable[[Mapping[str, np.ndarray]], np.ndarray] | None = field(
        default=None, repr=False, compare=False)
    #: Drives after the first (`drive`), for mechanisms of several degrees
    #: of freedom; each needs its own `name`.
    extra_drives: tuple[Drive, ...] = ()
    #: Force elements besides gravity and joint dampers.
    forces: tuple[SpringDamper | BodyTorque, ...] = ()
    #: Approximate pose per body at t = 0 (picks the assembly branch).
    assembly_pose: Mapping[str, BodyPose] = field(default_factory=dict, repr=False, compare=False)
    #: Applied joint torques (motor laws) that prescribe no motion.
    torque_drives: tuple[TorqueLaw, ...] = ()
    #: Where a torque-driven or free run starts: one joint value per degree
    #: of freedom the drives leave.
    initial_values: tuple[InitialValue, ...] = ()
    #: A spatial scene (`mechval.reference.spatial.system.SpatialSystem`),
    #: or None for a planar one. A spatial mechanism has kind "spatial", no
    #: planar bodies or joints, and its `motion` is the spatial reference's.
    spatial: Any = field(default=None, repr=False, compare=False)

    def body(self, name: str) -> Body:
        return next(b for b in self.bodies if b.name == name)

    def joint(self, name: str) -> Joint:
        return next(j for j in self.joints if j.name == name)

    @property
    def drives(self) -> tuple[Drive, ...]:
        return tuple(d for d in (self.drive, *self.extra_drives) if d is not None)

    @property
    def forward_dynamics(self) -> bool:
        """True when the motion is not all prescribed (torque laws, free
        degrees of freedom or stated initial values): it is then integrated
        from the consistent initial state at the first instant
        (`mechval.reference.dynamics`), and an engine starts there with no pre-roll."""
        if self.spatial is not None:
            return self.spatial.forward_dynamics
        return self.drive is None or bool(self.torque_drives) or bool(self.initial_values)

    @property
    def has_gravity(self) -> bool:
        return any(g != 0.0 for g in self.gravity)

    @property
    def damped_joints(self) -> tuple[Joint, ...]:
        return tuple(j for j in self.joints if j.damping != 0.0)

    def motion_columns(self) -> list[str]:
        return [f"{b.name}.{q}" for b in self.bodies for q in MOTION_QUANTITIES]

    def reaction_columns(self) -> list[str]:
        columns = []
        for j in self.joints:
            columns += [f"{j.name}.Fx", f"{j.name}.Fy"]
            if j.kind == "prismatic":
                columns.append(f"{j.name}.M")
        return (columns + [d.effort_column(self.joint(d.joint).kind) for d in self.drives]
                + [f"{law.name}.T" for law in self.torque_drives])

