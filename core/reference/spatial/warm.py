"""Compile the spatial reference's numba kernels into numba's cache once
(`make setup` runs `python -m mechval.reference.spatial.warm`), so that no
test worker or run pays the compilation (docs/conventions.md, "Spatial
systems"): one prescribed solve of a driven crank reaches every kernel
with the argument types every scene passes."""

from __future__ import annotations

import numpy as np

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.solver import SpatialSolver
from mechval.reference.spatial.system import SpatialBody, SpatialDrive, SpatialJoint, SpatialSystem


def crank() -> SpatialSystem:
    body = SpatialBody("crank", 1.0, (0.5, 0.0, 0.0), np.diag([1e-3, 1e-2, 1e-2]))
    joint = SpatialJoint("A", "revolute", GROUND, "crank", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    return SpatialSystem("warm-up crank", (body,), (joint,), (SpatialDrive("A", DriveLaw(0.0, 1.0, 0.0)),),
                         (0.0, 0.0, -9.81))


def main() -> None:
    SpatialSolver(crank()).solve(np.linspace(0.0, 1.0, 5))


if __name__ == "__main__":
    main()
