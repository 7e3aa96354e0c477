"""Systems of the IFToMM multibody benchmark library (the A Coruña
"Library of Computational Benchmark Problems", González, Dopico, Lugrís
& Cuadrado, *A benchmarking system for MBS simulation software: problem
standardization and performance measurement*, Multibody System Dynamics
16 (2006) 179–190; problem pages at lim.ii.udc.es/mbsbenchmark/dist/),
built for the spatial reference. As in tests/spatial_mechanisms.py every
body's frame is the world frame at the assembly, so joint points, axes
and centres of mass are written in world axes at that instant."""

from __future__ import annotations

import numpy as np

from mechval.model.mechanism import GROUND
from mechval.reference.spatial.system import SpatialBody, SpatialSystem, Spring
from spatial_mechanisms import revolute

G = 9.81


def bar_inertia(mass: float, length: float, side: float, direction) -> np.ndarray:
    """A uniform bar of square cross-section `side` along unit `direction`,
    about its centre of mass: m(ℓ² + a²)/12 across, m·a²/6 along."""
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    across, along = mass * (length ** 2 + side ** 2) / 12, mass * side ** 2 / 6
    return across * (np.eye(3) - np.outer(d, d)) + along * np.outer(d, d)


class Bricard:
    """Benchmark A04, Bricard's mechanism: five bars of 1 m and 1 kg and
    the ground closing the loop, six revolute joints; the two axes at the
    ends of each bar are perpendicular to each other and to the bar.
    Grübler–Kutzbach gives 6·5 − 5·6 = 0 degrees of freedom, the special
    axes give it 1 (one redundant constraint row). Gravity 9.81 m/s² along
    −y; released at rest from the published assembly; 10 s; no dissipation,
    so the benchmark's measure is the mechanical energy, which must hold.

    Joint points P0 … P5 and axes: the benchmark's figure, as its two
    public implementations read it (OpenSim: RehabEngGroup/
    MBSbenchmarksInOpenSim, src/A04-BricardsMechanism/createModel.cpp,
    square cross-section 0.1 m, all pins at angle 0 and speed 0; Exudyn:
    jgerstmayr/EXUDYN, main/pythonDev/TestModels/bricardMechanism.py,
    the same points and axes, cuboid bars 1 m × 0.1 m × 0.1 m of 1 kg).
    The library's own page (lim.ii.udc.es/mbsbenchmark/dist/A04/
    A04_specification.xml) was in our sources only as far as its header,
    so the start at rest rests on those two implementations."""

    length, mass, side = 1.0, 1.0, 0.1
    points = np.array([[0, 0, 0], [1, 0, 0], [1, -1, 0], [1, -1, 1], [0, -1, 1], [0, 0, 1]], dtype=float)
    axes = np.eye(3)[[1, 2, 0, 1, 2, 0]]        # y, z, x, y, z, x at P0 … P5

    def __init__(self):
        P = self.points * self.length
        names = [f"bar{k + 1}" for k in range(5)]
        bodies = tuple(SpatialBody(n, self.mass, tuple((P[k] + P[k + 1]) / 2),
                                   bar_inertia(self.mass, self.length, self.side, P[k + 1] - P[k]))
                       for k, n in enumerate(names))
        ends = [GROUND] + names + [GROUND]
        joints = tuple(revolute(f"P{k}", ends[k], ends[k + 1], P[k], self.axes[k]) for k in range(6))
        self.system = SpatialSystem("Bricard (A04)", bodies, joints, gravity=(0.0, -G, 0.0))


def with_point_mass(mass: float, centre, inertia: np.ndarray, point_mass: float, point) -> tuple[float, np.ndarray, np.ndarray]:
    """A body plus a point mass fixed to it: total mass, centre of mass and
    inertia about it (parallel-axis theorem)."""
    centre, point = np.asarray(centre, dtype=float), np.asarray(point, dtype=float)
    total = mass + point_mass
    com = (mass * centre + point_mass * point) / total
    shifted = inertia.copy()
    for m, p in ((mass, centre), (point_mass, point)):
        d = p - com
        shifted = shifted + m * (d @ d * np.eye(3) - np.outer(d, d))
    return total, com, shifted


class FlyballGovernor:
    """Benchmark A05, the stiff flyball governor: a vertical shaft
    (1 m × 0.01 m × 0.01 m) on a ground pin about z, a slider (0.1 m cube)
    on it, two rods (1 m × 0.01 m × 0.01 m) pinned to the shaft's top at
    ±0.05 m with a 5 kg point mass at each far end, hanging α = 30° below
    the horizontal; two spring-dampers (k = 8e5 N/m, c = 4e4 N·s/m, rest
    length 0.5 m) from the slider's sides (±0.05 m) to the rods' midpoints
    stand in for the coupler rods. Density 3000 kg/m³, gravity −z, slider
    at s = 0.5 m, shaft spinning at 2π rad/s, 10 s.

    Values: the benchmark's table as the OpenSim implementation states it
    (RehabEngGroup/MBSbenchmarksInOpenSim, help/benchmarks/
    A05_FlyballGovernor.rst and src/A05-FlyballGovernor/createModel.cpp,
    which also fixes the points and axes: pin axes ∥ y, the springs at
    their rest length in the published assembly)."""

    density, side, length = 3000.0, 0.01, 1.0
    cube, point_mass, alpha, s0, offset = 0.1, 5.0, np.radians(30.0), 0.5, 0.05
    stiffness, damping, rest = 8e5, 4e4, 0.5
    omega0 = 2 * np.pi

    def __init__(self, stiffness: float | None = None, damping: float | None = None):
        k = self.stiffness if stiffness is None else stiffness
        c = self.damping if damping is None else damping
        L, a = self.length, self.side
        m_bar = self.density * L * a * a
        z, y = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])
        bodies = [SpatialBody("shaft", m_bar, (0.0, 0.0, L / 2), bar_inertia(m_bar, L, a, z)),
                  SpatialBody("slider", self.density * self.cube ** 3, (0.0, 0.0, self.s0),
                              self.density * self.cube ** 5 / 6 * np.eye(3))]
        joints = [revolute("ground_pin", GROUND, "shaft", (0.0, 0.0, 0.0), z, (1.0, 0.0, 0.0)),
                  revolute("slide", "shaft", "slider", (0.0, 0.0, self.s0), z, (1.0, 0.0, 0.0), kind="prismatic")]
        springs = []
        self.tips = {}
        for side, name in ((1.0, "rod_right"), (-1.0, "rod_left")):
            pin = np.array([side * self.offset, 0.0, L])
            along = np.array([side * np.cos(self.alpha), 0.0, -np.sin(self.alpha)])
            mid, tip = pin + along * L / 2, pin + along * L
            mass, com, inertia = with_point_mass(m_bar, mid, bar_inertia(m_bar, L, a, along), self.point_mass, tip)
            bodies.append(SpatialBody(name, mass, tuple(com), inertia))
            joints.append(revolute(f"{name}_pin", "shaft", name, pin, y, (1.0, 0.0, 0.0)))
            springs.append(Spring(f"{name}_spring", "slider", (side * self.cube / 2, 0.0, self.s0), name, tuple(mid),
                                  k, self.rest, c))
            self.tips[name] = tip
        self.system = SpatialSystem("stiff flyball governor (A05)", tuple(bodies), tuple(joints),
                                    gravity=(0.0, 0.0, -G), springs=tuple(springs))

    @property
    def velocities(self) -> dict:
        """Every body turning with the shaft; body frames sit at the world
        origin on the spin axis, so their origins start at rest."""
        return {b.name: ((0.0, 0.0, 0.0), (0.0, 0.0, self.omega0)) for b in self.system.bodies}


def spring_energy(system: SpatialSystem, origins: dict, rotations: dict) -> np.ndarray:
    """½·k·(ℓ − ℓ0)² summed over the springs, per instant, from each body's
    frame origin (N, 3) and rotation (N, 3, 3); points are in body axes."""
    def world(body, point):
        if body == GROUND:
            return np.asarray(point, dtype=float)
        return origins[body] + rotations[body] @ np.asarray(point, dtype=float)
    total = 0.0
    for s in system.springs:
        length = np.linalg.norm(world(s.body_b, s.point_b) - world(s.body_a, s.point_a), axis=-1)
        total = total + 0.5 * s.stiffness * (length - s.free_length) ** 2
    return total
