"""MuJoCo on planar files beyond the four kinds (issue 14): the shared
planar contract (testing/planar_contract.py) on the scenes of
testing/planar_scenes.py, and what only MuJoCo has: its inverse mode
reproduces the reference, the audit reads each new element's numbers from
the compiled model, and every feature is declared."""

from __future__ import annotations

import pytest

from mechval.records.audit import failures, format_audit
from mechval.judging.compare import compare
from mechval.harness.simulate import simulate
from mechval.reference.linkages import build_mechanism
from mechval.testing.planar_contract import PlanarContract
from mechval.testing.planar_scenes import SCENES, scene

pytestmark = pytest.mark.engine
mujoco = pytest.importorskip("mujoco")


class TestPlanarContract(PlanarContract):
    engine = "mujoco"


#: Inverse mode evaluates the same equations as the reference at the same
#: state: only rounding separates them (measured ≤ 5e-14 of each peak here).
INVERSE_AGREEMENT = 1e-9


@pytest.mark.parametrize("name", SCENES)
def test_inverse_mode_reproduces_the_reference(name):
    """Inverse dynamics at the reference state (no time integration) checks
    frames and signs of the new elements alone: each drive's effort read
    from its own column, every loop's force, the spring-dampers' and body
    torques' loads (none may land in a reaction)."""
    scenario = scene(name)
    records = compare(simulate(scenario, "reference"), simulate(scenario, "mujoco", {"mode": "inverse"}),
                      scenario.tolerance_for("mujoco"), scenario.name, "mujoco")
    signals = records[records["class"] != "health"]
    off = signals[~(signals["max_error"] <= INVERSE_AGREEMENT * signals["peak"])]
    assert len(signals) and off.empty, off[["signal", "max_error", "peak"]].to_string()


@pytest.mark.parametrize("name, element, quantity", [
    ("spring", "stiffness", "stiffness"), ("spring", "springlength", "free length"),
    ("spring", "damping", "damping"), ("torque", "torque", "torque"),
    ("five-bar", "clock force", "alpha")])
def test_the_audit_reads_the_new_elements_back(name, element, quantity):
    """A changed value in the compiled model (not in the Mechanism) shows
    as "differs" in that element's row: the audit reads MuJoCo's numbers."""
    from mechval.records.audit import audit, expected_model
    from mechval.engines.mujoco.adapter import MujocoAdapter
    from mechval.engines.mujoco.run import Model
    from mechval.engines.mujoco.audit import Reader
    scenario = scene(name)
    mechanism = build_mechanism(scenario)
    model = Model(mechanism, scenario.time.t, MujocoAdapter().settings_for(scenario, mechanism))
    model.initial_state()
    mujoco.mj_fwdPosition(model.m, model.d)
    m, last = model.m, len(mechanism.forces) - 1
    if element == "stiffness":
        m.tendon_stiffness[model.tendon[last]] *= 1.5
    elif element == "springlength":
        m.tendon_lengthspring[model.tendon[last]] += 0.01
    elif element == "damping":
        m.tendon_damping[model.tendon[last]] *= 1.5
    elif element == "torque":
        m.actuator_biasprm[model.actuator[last], 0] *= 1.5
    else:                                        # the second drive's clock
        m.actuator_biasprm[m.actuator(model.clocks[1]).id, 0] += 1e6
    table = audit(expected_model(mechanism), Reader(model).readings())
    bad = failures(table)
    # One element differs (a clock's force also shifts φ0, ω0 read back at t = 0).
    assert quantity in set(bad["quantity"]) and bad["item"].nunique() == 1, format_audit(bad)
    assert bad["item"].iloc[0].startswith(("spring", "torque", "drive ")), format_audit(bad)


def test_declares_every_feature_and_the_harness_still_refuses_undeclared_ones():
    """MuJoCo declares all FEATURES and spatial scenes; a MuJoCo adapter that declared none
    would still be refused each, naming the key (the refusal is the
    harness's, not the adapter's)."""
    from mechval.adapter import FEATURES, SPATIAL
    from mechval.engines.mujoco.adapter import MujocoAdapter
    from mechval.model.scenario import ScenarioError
    assert MujocoAdapter.features == frozenset(FEATURES) | {SPATIAL}

    class Undeclared(MujocoAdapter):
        features = frozenset()

    with pytest.raises(ScenarioError, match="five-bar.toml: drive: mujoco: its adapter does not build "
                                            "several drives yet"):
        simulate(scene("five-bar"), Undeclared())
