"""Exudyn on planar files beyond the four kinds (issue 14): the shared
planar contract (testing/planar_contract.py) on the scenes of
testing/planar_scenes.py, and the audit catching a fault injected into each
new element of Exudyn's compiled model. Figures:
`.venv/bin/python tests/bench/planar_figures.py --engine exudyn` prints every
scene's worst signals.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from conftest import builtin_scenario, engine_or_skip
from mechval.adapter import mechanism_features
from mechval.records.audit import failures
from mechval.harness.audit_run import audit_scenario
from mechval.harness.simulate import simulate
from mechval.reference.linkages import build_mechanism
from mechval.model.scenario import ScenarioError
from mechval.testing.planar_contract import PlanarContract
from mechval.testing.planar_scenes import scene

pytestmark = pytest.mark.engine     # every test here runs Exudyn


class TestPlanarContract(PlanarContract):
    engine = "exudyn"
    # Nothing missing: the slide's couple, which Exudyn does not report, is
    # derived from the slider's balance (docs/engines.md).


def test_audit_catches_wrong_force_elements_and_drives(monkeypatch):
    """One fault per kind of new element, injected after the adapter's build
    into every element of that kind: exactly those elements' rows differ."""
    engine_or_skip("exudyn")
    from mechval.engines.exudyn import audit as exudyn_audit
    prepare = exudyn_audit.prepare

    def objects_of(mbs):
        return [mbs.GetObject(i) for i in range(mbs.systemData.NumberOfObjects())]

    def faulty(mechanism, times, settings):
        model, simulation, t0 = prepare(mechanism, times, settings)
        mbs = model.mbs
        for number, o in enumerate(objects_of(mbs)):
            if o["objectType"] == "ConnectorSpringDamper":
                mbs.SetObjectParameter(number, "stiffness", o["stiffness"] * 1.001)
                mbs.SetObjectParameter(number, "velocityOffset", 0.01)
        for number in range(mbs.systemData.NumberOfLoads()):
            if mbs.GetLoad(number)["loadType"] == "TorqueVector":
                mbs.SetLoadParameter(number, "loadVector", [0.0, 0.0, -29.0])
        for number in range(mbs.systemData.NumberOfMarkers()):
            if mbs.GetMarker(number)["markerType"] == "BodiesRelativeTranslationCoordinate":
                mbs.SetMarkerParameter(number, "localPosition1", [0.0, 0.001, 0.0])
        second = int(mbs.GetSensor(list(model.drive_sensors.values())[-1])["objectNumber"])
        if len(model.drive_sensors) > 1:
            mbs.SetObjectParameter(second, "factor1", 2.0)
        return model, simulation, t0
    monkeypatch.setattr(exudyn_audit, "prepare", faulty)

    def failing(name):
        result = audit_scenario(scene(name), "exudyn")
        assert result.table is not None, result.error
        return {(r.item, r.quantity) for r in failures(result.table).itertuples()}

    assert failing("spring") == {("spring tie", "stiffness"), ("spring tie", "extras")}
    assert failing("torque") == {("torque twist", "torque"), ("torque brake", "torque")}
    # The drive's marker now measures the slide of another point: no joint's
    # slide, so its law is not read either; the scene's spring and torque
    # take their faults too.
    assert failing("slider-driven") == {("drive", "joint"), ("drive", "phi0"), ("drive", "omega0"),
                                        ("drive", "alpha"), ("spring return", "stiffness"),
                                        ("spring return", "extras"), ("torque block", "torque")}
    assert failing("five-bar") == {("drive O4", "ratio")}


PARALLELOGRAM = "planar-extra/parallelogram-double-fourbar"


def test_redundant_constraints_are_refused_up_front_with_the_reason():
    """The parallelogram's third crank makes one joint equation redundant:
    the harness refuses Exudyn there in one line (file, key, engine and
    why) before Exudyn runs, rather than a solver error at its first step."""
    adapter = engine_or_skip("exudyn")
    scenario = builtin_scenario(PARALLELOGRAM)
    assert mechanism_features(build_mechanism(scenario))["redundant constraints"] == "joint"
    assert "redundant constraints" not in adapter.features
    with pytest.raises(ScenarioError) as caught:
        simulate(scenario, adapter)
    error = caught.value
    assert (Path(error.source).name, error.key) == ("parallelogram-double-fourbar.toml", "joint")
    assert error.reason.startswith("exudyn: cannot run redundant constraints: its solver stops at the first step")


@pytest.mark.parametrize("solver, stop", [("index2", "System Jacobian seems to be singular"),
                                          ("index3", "SolveDynamic terminated")])
def test_exudyn_still_stops_on_redundant_constraints(solver, stop):
    """The refusal's reason, measured: Exudyn itself, run past the refusal,
    stops at its first step with either solver. Fails when an Exudyn
    release runs redundant constraints, so the refusal can be lifted."""
    adapter = engine_or_skip("exudyn")
    scenario = builtin_scenario(PARALLELOGRAM)
    mechanism = build_mechanism(scenario)
    settings = adapter.settings_for(scenario, mechanism, {} if solver == "index2" else {"solver": solver})
    with pytest.raises(Exception, match=stop):
        adapter.run(mechanism, scenario.time.t, settings)
