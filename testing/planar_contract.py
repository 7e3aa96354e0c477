"""What every engine must do on planar files beyond the four kinds (issue
14), as one suite each engine's planar tests subclass, like
`mechval.testing.AdapterContract` (a plug-in's tests too):

    class TestPlanarContract(PlanarContract):
        engine = "mujoco"

On each scene of testing/planar_scenes.py (two drives, a prismatic drive,
one with the slider's centre of mass off its joint point, a spring-damper
between moving links, body torques, a two-loop six-bar, a five-bar driven
at a pin between moving links, a Scotch yoke, a ground pin written with
the ground second):
- every signal is within the scene's default tolerances of the general
  reference (no per-engine bound), and a signal is missing only where the
  adapter says it cannot report it (`missing`, with the reason's words);
- the model audit finds the compiled model is the scene, and reads back
  every drive and force element (none silently dropped);
- a joint that lists the ground second reports the force on the ground
  (the reference's is minus that of the joint written the usual way).
Engine-specific checks (MuJoCo's inverse mode, fault injection into each
engine's compiled model) stay in tests/test_<engine>_planar.py.
"""

from __future__ import annotations

import dataclasses
import tomllib
from typing import ClassVar, Mapping

import numpy as np
import pytest

from mechval.testing.comparison import engine_or_skip
from mechval.records.audit import failures, force_item, format_audit
from mechval.judging.compare import compare
from mechval.harness.simulate import simulate
from mechval.reference.linkages import build_mechanism
from .planar_scenes import SCENES, TWIN, scene
from mechval.scenarios import parse


class PlanarContract:
    engine: ClassVar[str]
    #: Signals the adapter reports missing on these scenes → words its
    #: reason must contain (docs/engines.md says why for each).
    missing: ClassVar[Mapping[str, str]] = {}

    @pytest.fixture
    def adapter(self):
        return engine_or_skip(self.engine)

    @pytest.mark.parametrize("name", SCENES)
    def test_meets_the_default_tolerances(self, adapter, name):
        scenario = scene(name)
        records = compare(simulate(scenario, "reference"), simulate(scenario, adapter),
                          scenario.tolerance_for(self.engine), scenario.name, self.engine)
        failed = records[records["verdict"] == "fail"]
        assert not records.empty and failed.empty, failed[["signal", "max_error", "bound", "reason"]].to_string()
        missing = records[records["missing"] > 0]
        assert set(missing["signal"]) <= set(self.missing), missing[["signal", "reason"]].to_string()
        for signal, reason in zip(missing["signal"], missing["reason"]):
            assert self.missing[signal] in reason, (signal, reason)

    @pytest.mark.parametrize("name", SCENES)
    def test_the_model_holds_the_scene_and_its_new_elements(self, adapter, name):
        """The audit reads back every drive, spring-damper and body torque,
        and finds no other spring, damper, motor or constraint."""
        scenario = scene(name)
        mechanism = build_mechanism(scenario)
        table = adapter.audit(mechanism, scenario.time.t, adapter.settings_for(scenario, mechanism))
        assert failures(table).empty, "\n" + format_audit(failures(table))
        audited = set(table["item"])
        assert {force_item(f) for f in mechanism.forces} <= audited
        assert {"drive"} | {f"drive {d.name}" for d in mechanism.extra_drives} <= audited

    def test_a_joint_listing_the_ground_second_acts_on_the_ground(self, adapter):
        """Scene "ground-second": the slider-crank twin's pin O2 written
        `["crank.start", "ground.O2"]` (drive reversed, same motion). Its
        reaction is the crank's force on the ground and its T the torque on
        the ground: minus the twin's (Newton's third law). The reference's
        to rounding; the engine's within the default tolerances of minus
        the twin's reference."""
        reversed_, twin = scene("ground-second"), tomllib.loads(TWIN)
        twin["time"] = {"end": reversed_.time.end, "samples": reversed_.time.samples}
        ours, theirs = simulate(reversed_, "reference"), simulate(parse(twin, "twin.toml"), "reference")
        names = ["O2.Fx", "O2.Fy", "O2.T"]
        for name in names:
            np.testing.assert_allclose(ours[name], -theirs[name], rtol=0, atol=1e-9 * np.abs(theirs[name]).max())
        opposite = dataclasses.replace(theirs, frame=theirs.frame.assign(**{n: -theirs.frame[n] for n in names}))
        records = compare(opposite, simulate(reversed_, adapter), reversed_.tolerance_for(self.engine),
                          reversed_.name, self.engine)
        records = records[records["signal"].isin(names)]
        assert len(records) == 3 and (records["verdict"] == "pass").all(), records.to_string()
