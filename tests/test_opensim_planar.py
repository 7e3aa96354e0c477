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


def test_audit_catches_faults_injected_into_the_built_model(monkeypatch):
    """One fault per kind of element, injected into OpenSim's model after
    the adapter's build: exactly those rows differ (the audit reads the
    model, not what the adapter meant to build)."""
    engine_or_skip("opensim")
    import opensim as osim
    from mechval.engines.opensim import audit as opensim_audit
    from mechval.harness.audit_run import audit_scenario
    from mechval.records.audit import failures
    from mechval.testing.planar_scenes import scene
    prepare = opensim_audit.prepare

    def faulty(mechanism, times, settings):
        prepared = prepare(mechanism, times, settings)
        for force in prepared.built.model.getForceSet():
            kind = force.getConcreteClassName()
            if kind == "ExpressionBasedPointToPointForce":
                spring = osim.ExpressionBasedPointToPointForce.safeDownCast(force)
                spring.setExpression(spring.get_expression().replace("*(d-", "1*(d-", 1))    # k → 10·k + 1
            elif kind == "PrescribedForce":
                osim.PrescribedForce.safeDownCast(force).setTorqueFunctions(
                    osim.Constant(0.0), osim.Constant(0.0), osim.Constant(-29.0))
        for coordinate in prepared.built.model.getCoordinateSet():
            if coordinate.getDefaultIsPrescribed():
                coordinate.setPrescribedFunction(osim.PolynomialFunction(osim.Vector([0.0, 2.0, 0.5])))
        return prepared
    monkeypatch.setattr(opensim_audit, "prepare", faulty)

    def failing(name):
        result = audit_scenario(scene(name), "opensim")
        assert result.table is not None, result.error
        return {(r.item, r.quantity) for r in failures(result.table).itertuples()}

    drive = {("drive", "phi0"), ("drive", "omega0"), ("drive", "alpha")}
    assert failing("spring") == drive | {("spring tie", "stiffness")}
    assert failing("torque") == drive | {("torque twist", "torque"), ("torque brake", "torque")}
