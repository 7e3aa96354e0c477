"""OpenSim on planar files beyond the four kinds (issue 14's scenes): the
shared planar contract (testing/planar_contract.py), and what the adapter
refuses up front. Figures: `.venv/bin/python tests/bench/planar_figures.py
--engine opensim` prints every scene's worst signals.
"""

from __future__ import annotations

import pytest

from conftest import engine_or_skip
from mechval.adapter import Unrepresentable
from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND, Body, Drive, Joint, Mechanism
from mechval.testing.planar_contract import PlanarContract

pytestmark = pytest.mark.engine     # every test here runs OpenSim


class TestPlanarContract(PlanarContract):
    engine = "opensim"
    # Nothing missing: every reaction is read from a mobilizer or a
    # point constraint (docs/engines.md).


def test_a_loop_only_a_slide_can_close_is_refused_naming_the_key():
    """A block on two crossed slides to the ground (x and y) is a loop with
    no pin: the adapter closes loops with point constraints at pins, so it
    refuses the scene, naming the joint key, before OpenSim runs."""
    adapter = engine_or_skip("opensim")
    from mechval.engines.opensim.model import spanning_tree
    block = Body("block", 1.0, (0.0, 0.0), 0.01)
    joints = (Joint("sx", "prismatic", GROUND, "block", (0.0, 0.0), (0.0, 0.0), axis=(1.0, 0.0)),
              Joint("sy", "prismatic", GROUND, "block", (0.0, 0.0), (0.0, 0.0), axis=(0.0, 1.0), angle=0.0))
    mechanism = Mechanism("two-slides", "planar", (block,), joints, Drive("sx", DriveLaw(0.0, 1.0)), (0.0, 0.0),
                          motion=lambda t: None, signal_map={})
    with pytest.raises(Unrepresentable) as caught:
        spanning_tree(mechanism)
    assert caught.value.key == "joint" and "sy" in caught.value.reason
    assert adapter.name == "opensim"
