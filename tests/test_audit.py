"""The compiled-model audit: the comparison rule, every built-in scene's
model in every installed engine is the scene, a wrong model is caught (one
deliberate fault per engine), the command and the report section."""

from __future__ import annotations

import importlib
import inspect

import numpy as np
import pandas as pd
import pytest

from conftest import BUILTIN, builtin_scenario, engine_or_skip
from mechval.harness import cli
from mechval.records.audit import (ABSENT_EFFECTS, AUDIT_RTOL, AS_SET, DIFFERS, MATCH, MISSING, NOTE, SCENE, Expectation,
                           Reading, audit, expected_model, failures, format_audit)
from mechval.records.audit import AuditResult, ModelReader
from mechval.harness.audit_run import audit_scenario
from mechval.reference.linkages import build_mechanism
from mechval.reports.audit import audit_section
from mechval.harness.simulate import simulate

ENGINES = ("mujoco", "pybullet", "exudyn", "pinocchio", "opensim", "drake")


# -- the comparison rule (no engine) ---------------------------------------------

def perfect_readings(expected):
    return [Reading(e.item, e.quantity, e.value) for e in expected]


def verdicts(table) -> dict[tuple[str, str], str]:
    return {(r.item, r.quantity): r.verdict for r in table.itertuples()}


def test_expected_model_lists_the_scene():
    mech = build_mechanism(builtin_scenario("slider-crank-damped"))
    expected = {(e.item, e.quantity): e for e in expected_model(mech)}
    assert expected[("body conrod", "mass")].value == 0.7
    assert expected[("body conrod", "com x")].value == 0.1
    assert expected[("joint guide", "kind")].value == "prismatic"
    assert expected[("joint guide", "point on ground y")].value == -0.01
    assert expected[("joint guide", "damping")].value == 2.0 and expected[("joint guide", "damping")].unit == "N·s/m"
    assert expected[("joint O2", "damping")].value == 0.01
    assert (expected[("scene", "gravity y")].value, expected[("scene", "gravity z")].value) == (0.0, 0.0)
    assert expected[("drive", "omega0")].value == 30.0
    assert all(expected[(SCENE, effect)].value == absent for effect, absent in ABSENT_EFFECTS.items())


def test_audit_verdicts():
    expected = [Expectation("body b", "mass", 2.0, "kg", 2.0), Expectation("joint j", "damping", 0.0, "N·s/m", 0.0),
                Expectation("body b", "com x", 0.0, "m", 0.5), Expectation(SCENE, "contacts", "off"),
                Expectation("drive", "phi0", 1.0, "rad", 1.0)]
    readings = [Reading("body b", "mass", 2.0 * (1 + 0.5 * AUDIT_RTOL)),       # rounding: match
                Reading("joint j", "damping", 1e-300),                          # must be exactly 0
                Reading("body b", "com x", 0.4 * AUDIT_RTOL, source="set"),     # within rtol of the 0.5 m scale
                Reading(SCENE, "contacts", "on"),
                Reading("engine", "clock", "1e12 kg", "artificial", "note"),
                Reading("joint extra", "kind", "revolute")]                     # not in the Mechanism
    table = audit(expected, readings)
    assert list(table.columns) == ["item", "quantity", "expected", "actual", "unit", "verdict", "deviation", "note"]
    assert verdicts(table) == {("body b", "mass"): MATCH, ("joint j", "damping"): DIFFERS,
                               ("body b", "com x"): AS_SET, (SCENE, "contacts"): DIFFERS,
                               ("drive", "phi0"): MISSING, ("engine", "clock"): NOTE,
                               ("joint extra", "kind"): DIFFERS}
    assert set(failures(table)["quantity"]) == {"damping", "contacts", "phi0", "kind"}
    assert "not in the Mechanism" in table.set_index("item").loc["joint extra", "note"]
    assert "phi0" in format_audit(table)
    with pytest.raises(ValueError, match="two readings"):
        audit(expected, [Reading("body b", "mass", 2.0)] * 2)


def test_rtol_is_relative_to_the_scale():
    expected = [Expectation("body b", "com x", 0.0, "m", 0.5)]
    assert audit(expected, [Reading("body b", "com x", 2 * AUDIT_RTOL)])["verdict"].item() == DIFFERS


# -- every built-in scene, every installed engine -------------------------------------

@pytest.mark.engine
@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("name", BUILTIN)
def test_built_in_models_are_the_scene(engine, name):
    """Audits build models only (tens of ms each), so the hard scenes are
    cheap here too."""
    engine_or_skip(engine)
    result = audit_scenario(builtin_scenario(name), engine)
    assert result.table is not None, result.error
    assert result.ok, "\n" + format_audit(failures(result.table))
    assert set(result.table["verdict"]) <= {MATCH, AS_SET, NOTE}
    assert (result.table["deviation"].dropna() <= AUDIT_RTOL).all()


# -- a wrong model is caught ----------------------------------------------------------

def failing_rows(result: AuditResult) -> set[tuple[str, str]]:
    assert result.table is not None, result.error
    return {(r.item, r.quantity) for r in failures(result.table).itertuples()}


def clock_dof(model):
    from mechval.engines.mujoco.model import CLOCK
    return model.m.jnt_dofadr[model.jid[CLOCK]]


#: A change to the compiled model of fourbar-seed (cut at O4) and the rows
#: that must then differ, and no other.
MUJOCO_FAULTS = {
    "crank mass": (lambda model: model.m.body_mass.__setitem__(model.bid["crank"], 12.5 * (1 + 1e-9)),
                   {("body crank", "mass")}),
    "coupler com": (lambda model: model.m.body_ipos.__setitem__((model.bid["coupler"], 0), 0.25 + 1e-6),
                    {("body coupler", "com x")}),
    "dof damping": (lambda model: model.m.dof_damping.__setitem__(model.m.jnt_dofadr[model.jid["A"]], 0.1),
                    {("joint A", "damping")}),
    "clock damping": (lambda model: model.m.dof_damping.__setitem__(clock_dof(model), 1.0),
                      {(SCENE, "other dampers")}),
    "gravity z": (lambda model: model.m.opt.gravity.__setitem__(2, -0.5),          # also accelerates the clock
                  {(SCENE, "gravity z"), ("drive", "phi0"), ("drive", "omega0"), ("drive", "alpha")}),
    "joint limit": (lambda model: model.m.jnt_limited.__setitem__(model.jid["B"], 1), {(SCENE, "joint limits")}),
    "gravity compensation": (lambda model: model.m.body_gravcomp.__setitem__(model.bid["rocker"], 1.0),
                             {(SCENE, "other loads")}),
    "fluid": (lambda model: setattr(model.m.opt, "density", 1.2), {(SCENE, "fluid forces")}),
}


@pytest.mark.engine
@pytest.mark.parametrize("engine", ENGINES)
def test_every_engine_reads_its_model_through_one_protocol(engine):
    """Each engine's audit reader is a `ModelReader`: the protocol's
    methods, with the protocol's signatures (issue 24: three readers once
    had the same method names with different signatures)."""
    engine_or_skip(engine)
    reader = importlib.import_module(f"mechval.engines.{engine}.audit").Reader
    assert issubclass(reader, ModelReader) and not inspect.isabstract(reader)
    for name in ModelReader.__abstractmethods__ | {"table"}:
        assert inspect.signature(getattr(reader, name)) == inspect.signature(getattr(ModelReader, name)), name


@pytest.mark.engine
@pytest.mark.parametrize("fault", MUJOCO_FAULTS)
def test_mujoco_audit_catches_a_wrong_model(monkeypatch, fault):
    engine_or_skip("mujoco")
    from mechval.engines.mujoco import adapter as adapter_module
    change, rows = MUJOCO_FAULTS[fault]
    build = adapter_module.Model.__init__

    def faulty(self, *args, **kwargs):
        build(self, *args, **kwargs)
        change(self)
    monkeypatch.setattr(adapter_module.Model, "__init__", faulty)
    assert failing_rows(audit_scenario(builtin_scenario("fourbar-seed"), "mujoco")) == rows


@pytest.mark.engine
def test_pybullet_audit_catches_defaults_left_on(monkeypatch):
    """Without `disarm_defaults` PyBullet keeps its body damping 0.04, its
    default velocity motors (friction) and gives shapeless links zero
    inertia: the audit must say so."""
    engine_or_skip("pybullet")
    from mechval.engines.pybullet import model as pybullet_model
    monkeypatch.setattr(pybullet_model, "disarm_defaults", lambda mechanism, model: None)
    rows = failing_rows(audit_scenario(builtin_scenario("fourbar-seed"), "pybullet"))
    assert rows == {(SCENE, "velocity damping of bodies"), (SCENE, "motors other than the drive"),
                    ("body crank", "izz"), ("body coupler", "izz"), ("body rocker", "izz")}


@pytest.mark.engine
def test_pybullet_audit_reads_back_what_the_build_changed(monkeypatch):
    engine_or_skip("pybullet")
    from mechval.engines.pybullet import audit as pybullet_audit
    from mechval.engines.pybullet.model import p
    build = pybullet_audit.build

    def faulty(mechanism, *args):
        model = build(mechanism, *args)
        crank = model.bodies["crank"]
        p.changeDynamics(crank.uid, crank.link, mass=13.0, physicsClientId=model.client)
        p.changeDynamics(crank.uid, crank.link, jointDamping=0.2, physicsClientId=model.client)
        p.setGravity(0.0, -9.81, 1.0, physicsClientId=model.client)
        return model
    monkeypatch.setattr(pybullet_audit, "build", faulty)
    rows = failing_rows(audit_scenario(builtin_scenario("fourbar-seed"), "pybullet"))
    # changeDynamics(mass=...) without localInertiaDiagonal recomputes the
    # inertia from the collision shapes: a shapeless link gets 0 (measured).
    assert rows == {("body crank", "mass"), ("body crank", "izz"), ("joint O2", "damping"), (SCENE, "gravity z")}


@pytest.mark.engine
def test_exudyn_audit_catches_a_wrong_model(monkeypatch):
    engine_or_skip("exudyn")
    import exudyn.itemInterface as eii
    from mechval.engines.exudyn import audit as exudyn_audit
    prepare = exudyn_audit.prepare

    def faulty(mechanism, times, settings):
        model, simulation, t0 = prepare(mechanism, times, settings)
        mbs = model.mbs
        objects = [mbs.GetObject(i) for i in range(mbs.systemData.NumberOfObjects())]
        bodies = [i for i, o in enumerate(objects) if o["objectType"] == "RigidBody2D"]
        mbs.SetObjectParameter(bodies[1], "inertia", objects[bodies[1]]["inertia"] * 1.001)
        rotations = [mbs.AddMarker(eii.MarkerNodeCoordinate(nodeNumber=objects[b]["nodeNumber"], coordinate=2))
                     for b in bodies[:2]]
        mbs.AddObject(eii.ObjectConnectorCoordinateSpringDamper(markerNumbers=rotations, stiffness=5.0, damping=0.3))
        mass = mbs.AddMarker(eii.MarkerBodyMass(bodyNumber=bodies[2]))
        mbs.AddLoad(eii.LoadMassProportional(markerNumber=mass, loadVector=[0.0, -9.81, 0.0]))
        return model, simulation, t0
    monkeypatch.setattr(exudyn_audit, "prepare", faulty)
    # slider-crank-damped has no gravity; bodies crank, conrod, slider; A joins crank and conrod.
    rows = failing_rows(audit_scenario(builtin_scenario("slider-crank-damped"), "exudyn"))
    assert rows == {("body conrod", "izz"), ("joint A", "damping"), (SCENE, "joint springs"),
                    (SCENE, "gravity y"), (SCENE, "other loads")}


@pytest.mark.engine
def test_pybullet_tree_layout_refuses_a_loop_closed_at_a_slide():
    """Found by the audit: layout 'tree' closed the shaper's loop at its slot
    with a point-to-point constraint, a pin (kind 'revolute', no axis), and
    the locked linkage ran into the 1e12 N force cap."""
    adapter = engine_or_skip("pybullet")
    scenario = builtin_scenario("shaper-quick-return")
    assert "layout 'tree' would close the loop at the prismatic joint 'slot'" in \
        audit_scenario(scenario, "pybullet", {"layout": "tree"}).error
    with pytest.raises(ValueError, match="use layout 'split'"):
        simulate(scenario, adapter, {"layout": "tree"})
    assert audit_scenario(builtin_scenario("slider-crank"), "pybullet", {"layout": "tree"}).ok


# -- command and report -----------------------------------------------------------------

@pytest.mark.engine
def test_audit_command(capsys):
    engine_or_skip("exudyn")
    assert cli.main(["audit", "slider-crank", "--engine", "exudyn"]) == 0
    out = capsys.readouterr().out
    assert "slider-crank × exudyn: the model is the scene" in out and "velocity damping of bodies" in out


def test_audit_section_opens_only_what_differs():
    table = audit(expected_model(build_mechanism(builtin_scenario("slider-crank"))), [])
    good = pd.DataFrame({"item": ["body crank"], "quantity": ["mass"], "expected": [1.0], "actual": [1.0],
                         "unit": ["kg"], "verdict": [MATCH], "deviation": [0.0], "note": ["<b>"]})
    results = [AuditResult("slider-crank", "mujoco", good), AuditResult("slider-crank", "exudyn", table),
               AuditResult("slider-crank", "faithful", error="faithful: no model audit")]
    html = str(audit_section(results).html)
    assert html.count("<details") == 3 and html.count("<details") - html.count(" open>") == 1
    assert f"{len(table)} of {len(table)} rows differ" in html and "no audit: faithful: no model audit" in html
    assert "&lt;b&gt;" in html and "<b>" not in html
    assert audit_section([]) is None
    assert np.isnan(table["deviation"]).all()
