"""PyBullet on planar files beyond the four kinds (issue 14): the shared
planar contract (tests/planar_contract.py) on the scenes of
tests/planar_scenes.py, at the default tolerances.

How PyBullet builds each feature (engines/pybullet_run.py, pybullet_model.py):
every drive is a position-controlled multibody joint (a leaf of the split
layout), its effort read from the joint's applied motor torque or force;
spring-dampers and body torques are external loads set before every step
(PyBullet has no spring element between bodies)."""

from __future__ import annotations

import pytest

from planar_contract import PlanarContract

pytestmark = pytest.mark.engine


class TestPlanarContract(PlanarContract):
    engine = "pybullet"
