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
from mechval.reference.spatial.system import SpatialBody, SpatialSystem
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
    the same points and axes, cuboid bars 1 m × 0.1 m × 0.1 m of 1 kg)."""

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
