"""Exudyn on planar files beyond the four kinds (issue 14): the shared
planar contract (tests/planar_contract.py) on the scenes of
tests/planar_scenes.py, and the audit catching a fault injected into each
new element of Exudyn's compiled model. Figures:
`.venv/bin/python tests/bench/planar_figures.py --engine exudyn` prints every
scene's worst signals.
"""

from __future__ import annotations

import pytest

from conftest import engine_or_skip
from mechval.audit import failures
from mechval.harness.audit_run import audit_scenario
from planar_contract import PlanarContract
from planar_scenes import scene

pytestmark = pytest.mark.engine     # every test here runs Exudyn


class TestPlanarContract(PlanarContract):
    engine = "exudyn"
    #: Exudyn's prismatic joint reports no couple (docs/engines.md).
    missing = {"guide.M": "no couple"}


def test_audit_catches_wrong_force_elements_and_drives(monkeypatch):
    """One fault per kind of new element, injected after the adapter's build
    into every element of that kind: exactly those elements' rows differ."""
    engine_or_skip("exudyn")
    from mechval.engines import exudyn_audit
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
