"""A spatial multibody system as the spatial reference reads it.

Frames (docs/conventions.md, extended to three dimensions): world axes
x, y, z; each body has a frame, its pose the world position of the frame's
origin and the rotation matrix A from body axes to world axes. The centre
of mass `com` and joint points are in body axes; the inertia tensor is
about the centre of mass, in body axes. The body named `GROUND` is the
world frame.

A joint joins body_i to body_j at point_i (on body_i) and point_j (on
body_j); its joint frames, `frame_i` on body_i and `frame_j` on body_j
(rotation matrices in body axes, built by `rotation.frame_from_axis`),
carry its axes: z is the joint axis; x the reference from which a
revolute drive measures its angle. Per kind (rows in
`mechval.reference.spatial.joints`):

- spherical: Pj = Pi;
- revolute: Pj = Pi, zj ∥ zi; angle from xi to xj about zi;
- prismatic: frames parallel, Pj − Pi along zi; slide s = zi·(Pj − Pi);
- cylindrical: zj ∥ zi, Pj − Pi along zi;
- universal: Pj = Pi, zi ⊥ zj (the cross's two pins are zi and zj);
- planar: zj ∥ zi, zi·(Pj − Pi) = 0 (body_j slides and turns in the plane);
- fixed: Pj = Pi, frames parallel.

A joint's reaction is the load BY body_i ON body_j (`Fij`): force F and
moment M about Pj, world axes. A drive prescribes a revolute joint's angle
or a prismatic joint's slide; its effort T (about zi) or F (along zi) acts
on body_j, the opposite on body_i, as in the planar model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, Mapping, Protocol

import numpy as np

from mechval.model.mechanism import GROUND
from mechval.reference.planar.constraints import MechanismError

JOINT_KINDS = ("revolute", "prismatic", "cylindrical", "spherical", "universal", "planar", "fixed")
DRIVEN_KINDS = ("revolute", "prismatic")
IDENTITY = np.eye(3)


class Law(Protocol):
    """A prescribed coordinate φ(t) with its first two derivatives."""

    def angle(self, t: np.ndarray) -> np.ndarray: ...
    def rate(self, t: np.ndarray) -> np.ndarray: ...
    def acceleration(self, t: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class SpatialBody:
    """A rigid body: mass (kg), centre of mass (m, body axes), inertia
    tensor about it (kg·m², body axes), and an approximate pose that picks
    the assembly branch: frame origin (m, world) and rotation matrix."""

    name: str
    mass: float
    com: tuple[float, float, float]
    inertia: np.ndarray
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: np.ndarray = field(default_factory=lambda: IDENTITY.copy())


@dataclass(frozen=True, eq=False)
class SpatialJoint:
    name: str
    kind: Literal["revolute", "prismatic", "cylindrical", "spherical", "universal", "planar", "fixed"]
    body_i: str
    body_j: str
    point_i: tuple[float, float, float]
    point_j: tuple[float, float, float]
    frame_i: np.ndarray = field(default_factory=lambda: IDENTITY.copy())
    frame_j: np.ndarray = field(default_factory=lambda: IDENTITY.copy())
    #: Viscous damping on the relative rotation about zi (revolute,
    #: N·m·s/rad) or translation along zi (prismatic, N·s/m).
    damping: float = 0.0


@dataclass(frozen=True, eq=False)
class SpatialDrive:
    """The prescribed angle (revolute) or slide (prismatic) of `joint`."""

    joint: str
    law: Law
    name: str = "drive"


@dataclass(frozen=True, eq=False)
class JointTorque:
    """An applied torque T(t) about a revolute joint's axis zi (N·m): T on
    body_j, −T on body_i. `law` has a `value(t)` (as `TorqueLaw`)."""

    joint: str
    law: object
    name: str = "torque"


@dataclass(frozen=True, eq=False)
class Spring:
    """A linear spring-damper between point_a of body_a and point_b of body_b:
    tension k·(ℓ − ℓ0) + c·ℓ̇ pulling the points together (N/m, m, N·s/m)."""

    name: str
    body_a: str
    point_a: tuple[float, float, float]
    body_b: str
    point_b: tuple[float, float, float]
    stiffness: float
    free_length: float
    damping: float = 0.0


@dataclass(frozen=True, eq=False)
class BodyLoad:
    """A constant force at the centre of mass and torque (world axes; N, N·m)."""

    name: str
    body: str
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True, eq=False)
class SpatialSystem:
    name: str
    bodies: tuple[SpatialBody, ...]
    joints: tuple[SpatialJoint, ...]
    drives: tuple[SpatialDrive, ...] = ()
    gravity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    springs: tuple[Spring, ...] = ()
    loads: tuple[BodyLoad, ...] = ()
    torques: tuple[JointTorque, ...] = ()
    #: Where a torque-driven or free run starts, per body name: (velocity of
    #: the frame origin, angular velocity), world axes; bodies not named
    #: start at rest. The reference projects them onto the constraints.
    velocities: Mapping[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = \
        field(default_factory=dict)

    def __post_init__(self) -> None:
        check(self)

    @property
    def forward_dynamics(self) -> bool:
        """True when the motion is integrated (`mechval.reference.spatial.
        dynamics`): no drives, torque laws, or a stated initial state."""
        return not self.drives or bool(self.torques) or bool(self.velocities)

    def body(self, name: str) -> SpatialBody:
        return next(b for b in self.bodies if b.name == name)

    def joint(self, name: str) -> SpatialJoint:
        return next(j for j in self.joints if j.name == name)

    def motion_columns(self) -> list[str]:
        return [f"{b.name}.{q}" for b in self.bodies for q in MOTION]

    def reaction_columns(self) -> list[str]:
        columns = [f"{j.name}.{q}" for j in self.joints for q in REACTION]
        for d in self.drives:
            columns.append(f"{d.name}.{'T' if self.joint(d.joint).kind == 'revolute' else 'F'}")
        return columns + [f"{t.name}.T" for t in self.torques]


#: Per body: frame origin, attitude (unit quaternion w ≥ 0), origin's
#: velocity, angular velocity, origin's acceleration, angular acceleration;
#: all in world axes.
MOTION = ("x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz",
          "ax", "ay", "az", "alphax", "alphay", "alphaz")
#: Per joint: force by body_i on body_j and its moment about Pj (world axes).
REACTION = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


def _is_rotation(R: np.ndarray) -> bool:
    R = np.asarray(R, dtype=float)
    return R.shape == (3, 3) and np.isfinite(R).all() and np.allclose(R.T @ R, IDENTITY, atol=1e-9) \
        and np.linalg.det(R) > 0


def check_inertia(key: str, mass: float, inertia) -> None:
    """Refuse a tensor that is not symmetric positive semi-definite with
    principal moments obeying the triangle inequality (any real mass
    distribution does: I1 + I2 ≥ I3), or a negative mass."""
    I = np.asarray(inertia, dtype=float)
    if not (np.isfinite(mass) and mass >= 0):
        raise MechanismError(key.rsplit(".", 1)[0] + ".mass", f"mass {mass} must be finite and non-negative")
    if I.shape != (3, 3) or not np.isfinite(I).all() or not np.allclose(I, I.T, rtol=0, atol=1e-12 * max(1, abs(I).max())):
        raise MechanismError(key, "the inertia tensor must be a symmetric 3×3 matrix of finite numbers")
    principal = np.linalg.eigvalsh(I)
    slack = 1e-12 * max(principal.max(), 0.0)
    if principal.min() < -slack:
        raise MechanismError(key, f"the inertia tensor is not positive definite (principal moments {principal})")
    if principal[0] + principal[1] < principal[2] - slack:
        raise MechanismError(key, f"principal moments {principal} break the triangle inequality I1 + I2 ≥ I3: "
                                  "no mass distribution has them")


def check(system: SpatialSystem) -> None:
    """Refuse unknown names, repeated names, a degenerate joint frame, a
    drive on a joint kind that has no angle or slide, bad inertia."""
    names = [b.name for b in system.bodies]
    if len(set(names)) != len(names) or GROUND in names:
        raise MechanismError("body", f"body names must be unique and not {GROUND!r}: {names}")
    known = set(names) | {GROUND}
    for b in system.bodies:
        check_inertia(f"body.{b.name}.inertia", b.mass, b.inertia)
        if not _is_rotation(b.rotation):
            raise MechanismError(f"body.{b.name}.rotation", "is not a rotation matrix")
    joint_names = [j.name for j in system.joints]
    if len(set(joint_names)) != len(joint_names):
        raise MechanismError("joint", f"two joints share a name: {joint_names}")
    for j in system.joints:
        if j.kind not in JOINT_KINDS:
            raise MechanismError(f"joint.{j.name}.kind", f"unknown kind {j.kind!r} (kinds: {', '.join(JOINT_KINDS)})")
        for body in (j.body_i, j.body_j):
            if body not in known:
                raise MechanismError(f"joint.{j.name}", f"unknown body {body!r} (bodies: {', '.join(sorted(known))})")
        if j.body_i == j.body_j:
            raise MechanismError(f"joint.{j.name}", f"joins {j.body_i!r} to itself")
        for side in ("frame_i", "frame_j"):
            if not _is_rotation(getattr(j, side)):
                raise MechanismError(f"joint.{j.name}.{side}", "is not a rotation matrix (a degenerate axis?)")
    for d in system.drives:
        if d.joint not in joint_names:
            raise MechanismError(f"drive.{d.name}", f"unknown joint {d.joint!r}")
        if system.joint(d.joint).kind not in DRIVEN_KINDS:
            raise MechanismError(f"drive.{d.name}", f"drives act on revolute or prismatic joints, not "
                                                    f"{system.joint(d.joint).kind}")
    for t in system.torques:
        if t.joint not in joint_names or system.joint(t.joint).kind != "revolute":
            raise MechanismError(f"torque.{t.name}", f"needs a revolute joint, not {t.joint!r}")
    drive_names = [d.name for d in system.drives] + [t.name for t in system.torques]
    if len(set(drive_names)) != len(drive_names):
        raise MechanismError("drive", f"two drives share a name: {drive_names}")
    for element in (*system.springs, *system.loads):
        for body in (getattr(element, "body", None), getattr(element, "body_a", None), getattr(element, "body_b", None)):
            if body is not None and body not in known:
                raise MechanismError(f"force.{element.name}", f"unknown body {body!r}")
