"""The adapter contract as one test suite that every engine's tests subclass
(as xarray's backend tests do):

    class TestContract(AdapterContract):
        engine = "mujoco"

A new adapter (Drake, MuJoCo Warp, a plug-in from the `mechval.engines`
entry-point group) gets the same checks by subclassing it once. Each check
stays short: a few hundred samples at most.

Expected values are independent of the engine: signs from physics stated
in each test (power balance, statics), the rest from the analytic
reference, which passes the same contract (tests/test_reference_contract.py).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pytest

from conftest import engine_or_skip
from mechval.compare import compare
from mechval.linkages import build_mechanism
from mechval.reference import simulate_reference
from mechval.scenario import ScenarioError
from mechval.scenarios import parse
from mechval.signals import signal_names
from mechval.harness.simulate import simulate
from scenario_data import fourbar, slider_crank

G = 9.81
#: A slotted lever (a slide between two moving links) and a four-bar (a
#: closed loop of pins), each short enough for a quick default run.
MOVING_SLIDE = {
    "name": "contract-slotted-lever", "mechanism": "slotted_lever",
    "geometry": {"ground": 0.30, "crank": 0.10, "lever": 0.50},
    "mass": {"crank": 2.0, "block": {"mass": 0.5, "izz": 1e-4}, "lever": 4.0},
    "drive": {"phi0": 0.0, "omega0": 6.0, "alpha": 0.0},
    "effects": {"gravity": [0.0, -G]},
    "time": {"end": 0.5, "samples": 101},
}
CLOSED_LOOP = fourbar(time={"end": 1.0, "samples": 101}, name="contract-fourbar")


@pytest.mark.engine
class AdapterContract:
    """What every adapter promises (docs/adapters.md)."""

    engine: ClassVar[str]

    @pytest.fixture
    def adapter(self):
        return engine_or_skip(self.engine)

    def simulate(self, adapter, data: dict, **overrides):
        return simulate(parse(data, f"{data['name']}.toml"), adapter, overrides or None)

    # -- sign conventions -------------------------------------------------

    def test_ground_carries_the_weight(self, adapter):
        """Statics, independent of any reference: a slider-crank held still
        under gravity −y; the ground's vertical forces on the crank (F12y)
        and on the slider (F14y) carry the whole weight, upwards."""
        data = slider_crank(drive={"phi0": 1.0, "omega0": 0.0, "alpha": 0.0}, time={"end": 0.1, "samples": 11})
        result = self.simulate(adapter, data)
        weight = G * sum(data["mass"].values())
        np.testing.assert_allclose(result["F12y"] + result["F14y"], weight, rtol=1e-6)

    def test_drive_torque_does_the_work(self, adapter):
        """Power balance: spun up from rest with no gravity and no damper,
        T12·ω2 = dKE/dt > 0, so T12 > 0 for a counter-clockwise drive, and
        T12 flips with the drive's direction."""
        spin = dict(drive={"phi0": 0.0, "omega0": 0.0, "alpha": 20.0}, effects=None,
                    time={"end": 0.2, "samples": 21})
        ccw = self.simulate(adapter, slider_crank(**spin))
        cw = self.simulate(adapter, slider_crank(**{**spin, "drive": {"phi0": 0.0, "omega0": 0.0,
                                                                        "alpha": -20.0}}))
        assert np.all(ccw["T12"][1:] > 0) and np.all(cw["T12"][1:] < 0)

    # -- signals, missing values, provenance --------------------------------

    def test_canonical_columns_and_missing_values_have_reasons(self, adapter):
        result = self.simulate(adapter, CLOSED_LOOP)
        assert tuple(result.frame.columns) == signal_names("fourbar")
        assert result.source == self.engine and result.version
        assert not result.unexplained_gaps()
        for name, reason in result.missing.items():
            assert name in result.frame.columns and reason.strip(), name

    def test_a_single_instant(self, adapter):
        """The reference state itself at one instant, with finite values
        or stated gaps."""
        scenario = parse(CLOSED_LOOP, "one.toml")
        mechanism = build_mechanism(scenario)
        settings = adapter.settings_for(scenario, mechanism)
        raw = adapter.run(mechanism, scenario.time.t[:1], settings)
        assert len(raw.frame) == 1
        finite = np.isfinite(raw.frame.to_numpy(dtype=float))
        assert all(finite[:, k].all() or column in raw.missing for k, column in enumerate(raw.frame.columns))

    # -- settings -----------------------------------------------------------

    def test_settings_are_recorded_and_overridable(self, adapter):
        scenario = parse(CLOSED_LOOP, "s.toml")
        defaults = adapter.settings_for(scenario, build_mechanism(scenario))
        step = adapter.step_setting
        interval = float(scenario.time.t[1] - scenario.time.t[0])
        finer = interval / (round(interval / defaults[step]) * 2)
        result = self.simulate(adapter, CLOSED_LOOP, **{step: finer})
        assert result.settings[step] == finer
        for key in defaults:
            assert key in result.settings, key

    @pytest.mark.parametrize("key, value, reason", [
        ("no_such_setting", 1.0, "unknown setting"),
        (None, "text", "expected"),        # the step setting, given a string
        (None, -1e-3, "positive"),
    ])
    def test_bad_settings_are_refused_with_file_and_key(self, adapter, key, value, reason):
        key = key or adapter.step_setting
        data = {**CLOSED_LOOP, "engines": {self.engine: {key: value}}}
        with pytest.raises(ScenarioError) as info:
            self.simulate(adapter, data)
        assert info.value.key == f"engines.{self.engine}.{key}"
        assert info.value.source.endswith(".toml") and reason in info.value.reason

    # -- mechanisms ----------------------------------------------------------

    @pytest.mark.parametrize("data", [CLOSED_LOOP, MOVING_SLIDE], ids=["closed-loop", "moving-slide"])
    def test_meets_the_default_tolerances(self, adapter, data):
        scenario = parse(data, f"{data['name']}.toml")
        records = compare(simulate_reference(scenario), simulate(scenario, adapter),
                          scenario.tolerance_for(self.engine), scenario.name, self.engine)
        failed = records[records["verdict"] == "fail"]
        assert failed.empty, failed[["signal", "max_error", "bound", "reason"]].to_string()
