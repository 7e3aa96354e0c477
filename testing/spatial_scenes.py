"""Small spatial scenes with closed forms, for the spatial contract
(`mechval.testing.spatial_contract`). Each is a `Scenario` whose scene is
a `SpatialSystem`, and each gives its expected signals at instants t from
physics alone (statics, steady conical motion, Euler's equations at
constant ω, free flight), never from the reference."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND
from mechval.model.scenario import Scenario, TimeGrid, Tolerance
from mechval.reference.spatial.rotation import frame_from_axis
from mechval.reference.spatial.system import SpatialBody, SpatialDrive, SpatialJoint, SpatialSystem

G = 9.81
ORIGIN = (0.0, 0.0, 0.0)


def turned(axis, angle: float) -> np.ndarray:
    """The rotation by `angle` about the unit `axis` (Rodrigues)."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


#: A full inertia tensor (kg·m²) with products of inertia: principal
#: moments 0.02, 0.03, 0.04 on axes turned off the body's.
TILTED_INERTIA = turned((1.0, 2.0, 3.0), 0.7) @ np.diag([0.02, 0.03, 0.04]) @ turned((1.0, 2.0, 3.0), 0.7).T
#: Which way gravity and the whole scene are turned in the "oblique" cases.
OBLIQUE = turned((0.3, -1.0, 0.4), 1.1)


def scenario(name: str, system: SpatialSystem, end: float, samples: int = 101) -> Scenario:
    return Scenario(name=name, description=f"spatial contract: {name}", scene=system,
                    time=TimeGrid(end, samples), tolerance=Tolerance())


@dataclass(frozen=True)
class ConicalPendulum:
    """A body on a spherical joint at the origin, its centre of mass at L
    from the pivot, tilted β from the downward vertical, circling the
    vertical at Ω² = g/(L·cos β): with an isotropic inertia about the centre
    of mass the motion is a steady rotation about the vertical, so the
    pivot's force on the body is m·(a_G − g), a_G the centripetal
    acceleration −Ω²·r_horizontal, and its moment about the pivot zero
    (a spherical joint). `turn` turns the whole scene (gravity included)."""

    mass: float = 2.0
    length: float = 0.5
    tilt: float = 0.6
    izz: float = 0.01
    turn: np.ndarray = field(default_factory=lambda: np.eye(3))

    @property
    def rate(self) -> float:
        return float(np.sqrt(G / (self.length * np.cos(self.tilt))))

    @property
    def vertical(self) -> np.ndarray:
        return self.turn @ np.array([0.0, 0.0, 1.0])

    def system(self) -> SpatialSystem:
        com = self.turn @ (self.length * np.array([np.sin(self.tilt), 0.0, -np.cos(self.tilt)]))
        bob = SpatialBody("bob", self.mass, tuple(com), self.izz * np.eye(3))
        pivot = SpatialJoint("pivot", "spherical", GROUND, "bob", ORIGIN, ORIGIN)
        return SpatialSystem("conical-pendulum", (bob,), (pivot,), gravity=tuple(-G * self.vertical),
                             velocities={"bob": (ORIGIN, tuple(self.rate * self.vertical))})

    def attitude(self, t: np.ndarray) -> np.ndarray:
        """The body's rotation matrices (N, 3, 3)."""
        return np.array([turned(self.vertical, self.rate * tk) for tk in t])

    def pivot_force(self, t: np.ndarray) -> np.ndarray:
        """Force by the ground on the body (N, 3), world axes."""
        com0 = np.array(self.system().body("bob").com)
        horizontal = com0 - (com0 @ self.vertical) * self.vertical
        a_G = -self.rate ** 2 * np.einsum("nij,j->ni", self.attitude(t), horizontal)
        return self.mass * (a_G + G * self.vertical)


@dataclass(frozen=True)
class SpinningRotor:
    """A rotor driven at a constant rate Ω about a fixed axis u through its
    centre of mass, no gravity: ω = Ω·u is constant, so the ground's moment
    on it is dH/dt = ω × (I(t)·ω) (Euler's equations), I(t) = R·I·Rᵀ its
    world inertia, R the turn Ω·t about u; the force is zero and so is the
    drive torque u·(ω × I·ω). A rotor whose axis is not principal needs this
    gyroscopic moment from its bearing."""

    mass: float = 3.0
    rate: float = 12.0
    axis: tuple[float, float, float] = (0.3, -0.5, 0.8)

    @property
    def u(self) -> np.ndarray:
        return np.asarray(self.axis) / np.linalg.norm(self.axis)

    def system(self) -> SpatialSystem:
        rotor = SpatialBody("rotor", self.mass, ORIGIN, TILTED_INERTIA)
        frame = frame_from_axis(self.u)
        bearing = SpatialJoint("bearing", "revolute", GROUND, "rotor", ORIGIN, ORIGIN, frame, frame)
        return SpatialSystem("spinning-rotor", (rotor,), (bearing,),
                             drives=(SpatialDrive("bearing", DriveLaw(0.0, self.rate, 0.0), "spin"),))

    def moment(self, t: np.ndarray) -> np.ndarray:
        w = self.rate * self.u
        R = np.array([turned(self.u, self.rate * tk) for tk in t])
        inertia = R @ TILTED_INERTIA @ np.swapaxes(R, 1, 2)
        return np.cross(w, np.einsum("nij,j->ni", inertia, w))


@dataclass(frozen=True)
class FreeBrick:
    """A free body thrown spinning about no principal axis, under gravity:
    its centre of mass flies on a parabola (m·v_G = m·v_G0 + m·g·t) and its
    angular momentum about the centre of mass, I(t)·ω(t), keeps its value."""

    mass: float = 1.5
    com: tuple[float, float, float] = (0.1, 0.0, 0.05)
    velocity: tuple[float, float, float] = (1.0, 0.5, 2.0)
    spin: tuple[float, float, float] = (3.0, 5.0, -2.0)
    gravity: tuple[float, float, float] = (0.0, -3.0, -G)

    def system(self) -> SpatialSystem:
        brick = SpatialBody("brick", self.mass, self.com, TILTED_INERTIA)
        return SpatialSystem("free-brick", (brick,), (), gravity=self.gravity,
                             velocities={"brick": (self.velocity, self.spin)})

    def com_velocity(self, t: np.ndarray) -> np.ndarray:
        v0 = np.asarray(self.velocity) + np.cross(self.spin, self.com)     # the origin is at the body frame's
        return v0 + np.outer(t, self.gravity)

    def com_position(self, t: np.ndarray) -> np.ndarray:
        v0 = self.com_velocity(np.zeros(1))[0]
        return np.asarray(self.com) + np.outer(t, v0) + 0.5 * np.outer(t * t, self.gravity)


def hanging(turn: np.ndarray = OBLIQUE) -> SpatialSystem:
    """A body at rest on a spherical joint, its centre of mass straight
    "below" the pivot along a gravity turned off every axis: statics, the
    pivot carries the weight, F = −m·g."""
    down = turn @ np.array([0.0, 0.0, -1.0])
    body = SpatialBody("weight", 4.0, tuple(0.3 * down), TILTED_INERTIA)
    pivot = SpatialJoint("pivot", "spherical", GROUND, "weight", ORIGIN, ORIGIN)
    return SpatialSystem("hanging", (body,), (pivot,), gravity=tuple(G * down), velocities={"weight": (ORIGIN, ORIGIN)})

