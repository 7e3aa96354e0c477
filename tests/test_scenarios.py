"""Scenario files: every built-in loads; bad input is refused with the
file, the key and the reason."""

from __future__ import annotations

import pytest

from conftest import BUILTIN, ENGINES
from mechval.model.scenario import ScenarioError
from mechval.scenarios import load, parse
from mechval.testing.scenes import fourbar, slider_crank
from mechval.testing.twins import twin_document


@pytest.mark.parametrize("name", BUILTIN)
def test_builtin_loads(name):
    scenario = load(name)
    assert scenario.name == name
    assert scenario.time.t[-1] == scenario.time.end


def test_defaults_for_omitted_tables():
    scenario = parse(fourbar(effects=None), "defaults")
    scene = scenario.scene
    assert scene.gravity == (0.0, 0.0) and all(j.damping == 0.0 for j in scene.joints) and not scene.forces
    assert scenario.tolerance["angle"] == 1e-3 and scenario.tolerance["force"] == 1e-2
    rocker = next(b for b in scene.bodies if b.name == "rocker")
    assert rocker.com == pytest.approx((0.25, 0.0)) and rocker.izz == pytest.approx(25.0 * 0.5**2 / 12)


def test_engine_tolerance_override():
    scenario = parse(fourbar(engines={"mujoco": {"timestep": 1e-4, "tolerance": {"force": 2e-2}}}), "x")
    assert scenario.tolerance_for("mujoco")["force"] == 2e-2
    assert scenario.tolerance_for("exudyn")["force"] == 1e-2
    assert scenario.settings_for("mujoco") == {"timestep": 1e-4}


def test_engine_tolerance_override_with_its_reason():
    """{ bound =, reason = } carries the reason; the plain number stays valid
    (docs/scenario-format.md) and has none."""
    reason = "MuJoCo's soft constraints: measured 1.4 % on this scene"
    scenario = parse(fourbar(engines={"mujoco": {"tolerance": {"force": {"bound": 2e-2, "reason": reason},
                                                               "torque": 3e-2}}}), "x")
    assert scenario.tolerance_for("mujoco")["force"] == 2e-2 and scenario.tolerance_for("mujoco")["torque"] == 3e-2
    assert scenario.engines["mujoco"].reasons == {"force": reason}


@pytest.mark.parametrize("name", BUILTIN)
def test_builtin_tolerance_overrides_state_their_reason(name):
    scenario = load(name)
    for engine, table in scenario.engines.items():
        assert set(table.reasons) == set(table.tolerance), f"{name}: [engines.{engine}.tolerance] without a reason"


BAD = [
    (fourbar(geometry={"coupler": 0.2}), "geometry", "cannot close at t = 1.1439 s (θ2 = 1.79815 rad)"),
    (fourbar(geometry={"crank": 0.6}), "geometry.crank", "crank equals ground"),
    (slider_crank(geometry={"offset": 0.35}), "geometry", "cannot close"),
    (fourbar(geometry={"rocker": -0.5}), "geometry.rocker", "must be positive"),
    (fourbar(geometry={"rocker": 0}), "geometry.rocker", "must be positive"),
    (fourbar(mass={"crank": 0.0}), "mass.crank", "must be positive"),
    (fourbar(mass={"crank": 1e300}), "mass.crank", "exceeds"),
    (fourbar(drive={"alpha": 5e152}), "drive.alpha", "exceeds"),
    (fourbar(mass={"coupler": {"mass": 2.0, "izz": -1.0}}), "mass.coupler.izz", "must be positive"),
    (fourbar(mass={"coupler": {"izz": 1.0}}), "mass.coupler.mass", "missing value"),
    (fourbar(mass={"coupler": None}), "mass.coupler", "missing value"),
    (slider_crank(mass={"slider": {"mass": 1.0, "com": 0.1}}), "mass.slider.com", "unknown key"),
    (fourbar(time={"samples": 1}), "time.samples", "at least 2"),
    (fourbar(time={"samples": 10.5}), "time.samples", "whole number"),
    (fourbar(time={"end": -1.0}), "time.end", "must be positive"),
    (fourbar(colour="red"), "colour", "unknown key"),
    (fourbar(geometry={"lenght": 0.3}), "geometry.lenght", "unknown key"),
    (fourbar(effects={"damping": {"C": 1.0}}), "effects.damping.C", "unknown key"),
    (fourbar(effects={"damping": {"A": -1.0}}), "effects.damping.A", "must not be negative"),
    (fourbar(effects={"gravity": [0.0, -9.81, 0.0]}), "effects.gravity", "two finite numbers"),
    (fourbar(effects={"gravity": "down"}), "effects.gravity", "two finite numbers"),
    (fourbar(drive={"omega0": "fast"}), "drive.omega0", "expected a number"),
    (fourbar(drive={"omega0": True}), "drive.omega0", "expected a number"),
    (fourbar(drive={"omega0": None}), "drive.omega0", "missing value"),
    (fourbar(drive=None), "drive", "missing table"),
    (fourbar(time=None), "time", "missing table"),
    (fourbar(geometry={"branch": "upside"}), "geometry.branch", "must be one of"),
    (fourbar(mechanism="sixbar"), "mechanism", "must be one of"),
    (fourbar(name=None), "name", "missing value"),
    (fourbar(tolerance={"force": 0.0}), "tolerance.force", "must be positive"),
    (fourbar(tolerance={"speed": 1.0}), "tolerance.speed", "unknown key"),
    (fourbar(engines={"bullet": {}}), "engines.bullet", "unknown key"),
    (fourbar(engines={"mujoco": {"tolerance": {"force": "big"}}}), "engines.mujoco.tolerance.force",
     "expected a number"),
    (fourbar(engines={"mujoco": {"tolerance": {"force": {"bound": 2e-2}}}}), "engines.mujoco.tolerance.force.reason",
     "missing value"),
    (fourbar(engines={"mujoco": {"tolerance": {"force": {"bound": 2e-2, "reason": " "}}}}),
     "engines.mujoco.tolerance.force.reason", "must not be empty"),
    (fourbar(engines={"mujoco": {"tolerance": {"force": {"bound": 2e-2, "reason": 3}}}}),
     "engines.mujoco.tolerance.force.reason", "expected a string"),
    (fourbar(engines={"mujoco": {"tolerance": {"force": {"bound": -1.0, "reason": "x"}}}}),
     "engines.mujoco.tolerance.force.bound", "must be positive"),
    (fourbar(engines={"mujoco": {"tolerance": {"force": {"value": 2e-2, "reason": "x"}}}}),
     "engines.mujoco.tolerance.force.value", "unknown key"),
    (fourbar(tolerance={"force": {"bound": 2e-2, "reason": "x"}}), "tolerance.force", "expected a number"),
    # The crank of this double-crank turns fully; from a triple-rocker's
    # reachable range it cannot: refused at the first instant it leaves it.
    (fourbar(geometry={"ground": 0.6, "crank": 0.5, "coupler": 0.3, "rocker": 0.45}), "geometry",
     "cannot close at t ="),
]


@pytest.mark.parametrize("data,key,reason", BAD, ids=[b[1] + ":" + b[2] for b in BAD])
def test_bad_input_refused(data, key, reason):
    with pytest.raises(ScenarioError) as info:
        parse(data, "bad.toml", ENGINES)
    assert info.value.source == "bad.toml"
    assert info.value.key == key
    assert reason in info.value.reason


def test_closure_message_names_time_and_lengths():
    with pytest.raises(ScenarioError) as info:
        parse(fourbar(geometry={"coupler": 0.3, "rocker": 0.45}, drive={"phi0": 0.0, "omega0": 1.0, "alpha": 0.0}),
              "f.toml")
    message = str(info.value)
    assert message.startswith("f.toml: geometry: the loop cannot close at t = ")
    assert "coupler + rocker = 0.75 m" in message and "ground 0.6, crank 0.25" in message


def test_closure_checked_between_samples():
    """A violation that lies between two samples is still found: crank angle
    π is reached only between the samples t = 0 and t = 2 s."""
    data = fourbar(geometry={"ground": 0.6, "crank": 0.25, "coupler": 0.3, "rocker": 0.45},
                   drive={"phi0": -1.0, "omega0": 1.6, "alpha": 0.0}, time={"end": 4.0, "samples": 3})
    with pytest.raises(ScenarioError, match="cannot close"):
        parse(data, "between.toml")


def test_unreadable_file(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("name = [unclosed\n")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load(path)
    with pytest.raises(ScenarioError, match="no such scenario"):
        load(tmp_path / "absent.toml")


# -- one parser of the tables both formats share (issue 24) --------------------------------------

LONG_TEXT = "x" * 3000


@pytest.mark.parametrize("key, edit, shown", [
    ("time.samples", lambda doc: doc["time"].update(samples=LONG_TEXT), "'xxxxxxxxxxxx"),
    ("time.samples", lambda doc: doc["time"].update(samples=-10**3999), "-~1e3999"),
    ("time.samples", lambda doc: doc["time"].update(samples=1), "must be at least 2, got 1"),
    ("tags", lambda doc: doc.update(tags=[LONG_TEXT, 1]), "expected a list of strings"),
])
def test_both_formats_refuse_shared_tables_alike(key, edit, shown):
    """A 3,000-character `samples` was quoted in ~100 characters by one
    format and 2,000 by the other, a 4,000-digit one as -~1e3999 by one and
    in full by the other: both now read the shared tables with one parser,
    so the refusal is the same, one short line."""
    reasons = []
    for doc in (fourbar(), twin_document("fourbar-seed")):
        edit(doc)
        with pytest.raises(ScenarioError) as refused:
            parse(doc, "scene.toml")
        assert refused.value.key == key
        reasons.append(refused.value.reason)
    assert reasons[0] == reasons[1] and shown in reasons[0] and len(reasons[0]) < 120, reasons
