"""The adapter contract as one test suite that every engine's tests subclass
(as xarray's backend tests do), in mechval's own tests and in a plug-in's:

    from mechval.testing import AdapterContract

    class TestContract(AdapterContract):
        engine = "mujoco"

A new adapter (Drake, MuJoCo Warp, a plug-in from the `mechval.engines`
entry-point group) gets the same checks by subclassing it once, against an
installed mechval (docs/adapters.md, "Testing an adapter"). Each check
stays short: a few hundred samples at most.

Expected values are independent of the engine: signs from physics stated
in each test (power balance, statics), the rest from the analytic
reference, which passes the same contract (mechval's
tests/test_reference_contract.py). An adapter without a time step, without
a model to audit or without forward dynamics says why in a class
attribute, and the tests that need one skip with that reason.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import ClassVar

import numpy as np
import pytest

from mechval.records.audit import failures, format_audit
from mechval.judging.compare import HEALTH_BOUNDS, compare
from mechval.reference.dynamics import raw_dynamics
from mechval.harness.simulate import simulate
from mechval.reference.linkages import build_mechanism
from mechval.model.scenario import ScenarioError
from mechval.scenarios import parse
from mechval.records.signals import canonical_signals, signal_names

from . import mechanisms as dm
from .comparison import assert_within_tolerance, compare_with_reference, engine_or_skip
from .scenes import fourbar, slider_crank

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
#: The closed loop with nothing but the drive acting, and with gravity and a
#: damper at every pin (the loop-closing one included).
FREE_LOOP = fourbar(effects=None, time={"end": 1.0, "samples": 101}, name="contract-fourbar-free")
DAMPED_LOOP = fourbar(effects={"gravity": [0.0, -G], "damping": {"O2": 0.5, "A": 0.2, "B": 0.3, "O4": 0.4}},
                      time={"end": 1.0, "samples": 101}, name="contract-fourbar-damped")
MECHANISMS = pytest.mark.parametrize("data", [CLOSED_LOOP, MOVING_SLIDE], ids=["closed-loop", "moving-slide"])
#: Torque-driven and free mechanisms (`mechval.testing.mechanisms`) and how
#: long each runs (s): a pendulum and a crank under a torque law with closed
#: forms, the seed four-bar falling from rest, a motored slider-crank with a
#: spring-damper, joint dampers and a body torque.
DYNAMIC = {"pendulum": 2.0, "spinning-crank": 1.0, "free-fourbar": 2.0, "motored-slider-crank": 1.0}
#: The default tolerances of a scene (docs/scenario-format.md): angle (rad)
#: and position (m) absolute, force relative to the column's peak.
ANGLE, POSITION, FORCE = 1e-3, 1e-4, 1e-2


def dynamic_mechanism(name: str):
    """The mechanism of a dynamic case, carrying its assembly pose and
    initial values (all an adapter may look at), and its output instants."""
    case = dm.CASES[name]()
    mech = dataclasses.replace(case.mech, assembly_pose=case.pose)
    return mech, np.linspace(0.0, DYNAMIC[name], 101)


@functools.lru_cache(maxsize=None)
def dynamic_reference(name: str):
    """The forward-dynamics reference of a dynamic case at its output
    instants, solved once per test session (DOP853 at its RTOL takes
    seconds, and every engine's suite compares with the same frame)."""
    mech, times = dynamic_mechanism(name)
    return raw_dynamics(mech, times).frame


def dynamic_errors(mech, reference, result) -> dict[str, float]:
    """Per raw column, the error as a fraction of its default bound (> 1
    fails): body angles and positions absolute, reactions and efforts
    relative to the reference column's peak."""
    ratios = {}
    for body in mech.bodies:
        for q, bound in (("theta", ANGLE), ("x", POSITION), ("y", POSITION)):
            column = f"{body.name}.{q}"
            ratios[column] = float(np.max(np.abs(result[column] - reference[column]))) / bound
    for column in mech.reaction_columns():
        peak = float(np.max(np.abs(reference[column])))
        if peak > 0:
            ratios[column] = float(np.max(np.abs(result[column] - reference[column]))) / (FORCE * peak)
    return ratios


@pytest.mark.engine
class AdapterContract:
    """What every adapter promises (docs/adapters.md)."""

    engine: ClassVar[str]
    #: Why the adapter has no time-step setting ("" when it has one, named
    #: by its `step_setting`): the tests of the step skip with this reason.
    without_time_step: ClassVar[str] = ""
    #: Why the adapter builds no engine model to audit ("" when `audit` reads
    #: its model back): the audit test skips with this reason.
    without_model_audit: ClassVar[str] = ""
    #: Why the adapter runs no torque-driven or free mechanism ("" when it
    #: declares the features "torque laws" and "free motion"): the tests of
    #: forward dynamics skip with this reason.
    without_forward_dynamics: ClassVar[str] = ""

    @pytest.fixture
    def adapter(self):
        return engine_or_skip(self.engine)

    def skip_without_time_step(self, adapter) -> None:
        """Skip with the stated reason if the adapter has no time step (and
        check that it indeed declares none)."""
        if self.without_time_step:
            assert not adapter.step_setting, f"{self.engine} declares step_setting {adapter.step_setting!r}"
            pytest.skip(self.without_time_step)
        assert adapter.step_setting in adapter.settings_spec

    def simulate(self, adapter, data: dict, **overrides):
        return simulate(parse(data, f"{data['name']}.toml"), adapter, overrides or None)

    # -- sign conventions -------------------------------------------------

    def test_ground_carries_the_weight(self, adapter):
        """Statics, independent of any reference: a slider-crank held still
        under gravity −y; the ground's vertical forces on the crank (F12y)
        and on the slider (F14y) carry the whole weight, upwards. Under
        gravity +y they pull down, and the holding torque T12 turns round."""
        still = dict(drive={"phi0": 1.0, "omega0": 0.0, "alpha": 0.0}, time={"end": 0.1, "samples": 11})
        down = slider_crank(**still)
        up = slider_crank(**still, effects={"gravity": [0.0, G]})
        weight = G * sum(down["mass"].values())
        held_down, held_up = self.simulate(adapter, down), self.simulate(adapter, up)
        np.testing.assert_allclose(held_down["F12y"] + held_down["F14y"], weight, rtol=1e-6)
        np.testing.assert_allclose(held_up["F12y"] + held_up["F14y"], -weight, rtol=1e-6)
        assert np.all(np.sign(held_up["T12"]) == -np.sign(held_down["T12"])) and np.all(held_down["T12"] != 0)

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

    @MECHANISMS
    def test_canonical_columns_and_missing_values_have_reasons(self, adapter, data):
        """Every canonical signal of the kind, in order; a value the engine
        cannot give is NaN with a stated reason (e.g. a slide's couple), and
        no other value is NaN."""
        result = self.simulate(adapter, data)
        assert tuple(result.frame.columns) == signal_names(data["mechanism"])
        assert result.source == self.engine and result.version
        assert not result.unexplained_gaps()
        for name, reason in result.missing.items():
            assert name in result.frame.columns and reason.strip(), name

    @MECHANISMS
    def test_a_single_instant(self, adapter, data):
        """A run of one instant (no sample interval) gives the reference
        state at that instant: finite values or stated gaps, each within the
        bound the comparison rule sets for the whole run."""
        scenario = parse(data, "one.toml")
        mechanism = build_mechanism(scenario)
        settings = adapter.settings_for(scenario, mechanism)
        raw = adapter.run(mechanism, scenario.time.t[:1], settings)
        assert len(raw.frame) == 1
        finite = np.isfinite(raw.frame.to_numpy(dtype=float))
        assert all(finite[:, k].all() or column in raw.missing for k, column in enumerate(raw.frame.columns))
        # The bounds: the reference compared with itself over the whole run.
        reference = simulate(scenario, "reference")
        bounds = compare(reference, reference, scenario.tolerance_for(self.engine)).set_index("signal")["bound"]
        result = canonical_signals(mechanism, raw.frame, self.engine, missing=raw.missing)
        errors = {name: abs(result[name][0] - reference[name][0]) for name in signal_names(data["mechanism"])[1:]
                  if name not in result.missing}
        assert {name: error for name, error in errors.items() if not error <= bounds[name]} == {}

    # -- settings -----------------------------------------------------------

    def test_settings_are_declared_and_recorded(self, adapter):
        """The derived defaults hold exactly the declared settings, and a
        run records every one of them."""
        scenario = parse(CLOSED_LOOP, "s.toml")
        defaults = adapter.settings_for(scenario, build_mechanism(scenario))
        assert set(defaults) == set(adapter.settings_spec)
        result = self.simulate(adapter, CLOSED_LOOP)
        assert dict(result.settings) == defaults

    def test_the_step_is_overridable(self, adapter):
        """Half the default step, as an override: recorded, and used (an
        adapter that ignored it would give the default run's numbers)."""
        self.skip_without_time_step(adapter)
        scenario = parse(CLOSED_LOOP, "s.toml")
        defaults = adapter.settings_for(scenario, build_mechanism(scenario))
        step = adapter.step_setting
        interval = float(scenario.time.t[1] - scenario.time.t[0])
        finer = interval / (round(interval / defaults[step]) * 2)
        result = self.simulate(adapter, CLOSED_LOOP, **{step: finer})
        assert dict(result.settings) == {**defaults, step: finer}
        assert not np.array_equal(result.frame.to_numpy(), self.simulate(adapter, CLOSED_LOOP).frame.to_numpy())

    @pytest.mark.parametrize("origin", ["file", "override"])
    def test_an_unknown_setting_is_refused_with_its_origin_and_key(self, adapter, origin):
        """In the scenario file: the file and `engines.NAME.KEY`; as an
        explicit override (variants, the cost ladder): 'settings override'."""
        with pytest.raises(ScenarioError) as info:
            if origin == "file":
                self.simulate(adapter, {**CLOSED_LOOP, "engines": {self.engine: {"no_such_setting": 1.0}}})
            else:
                self.simulate(adapter, CLOSED_LOOP, no_such_setting=1.0)
        assert info.value.key == f"engines.{self.engine}.no_such_setting"
        assert "unknown setting" in info.value.reason
        assert info.value.source == ("contract-fourbar.toml" if origin == "file" else "settings override")

    @pytest.mark.parametrize("value, reason", [
        ("text", "expected"),
        (-1e-3, "positive"),
        (0.0, "positive"),
        (float("nan"), "finite"),
        (3e-3, "does not divide the sample interval"),     # the interval is 0.01 s
    ])
    def test_a_bad_step_is_refused_with_file_and_key(self, adapter, value, reason):
        self.skip_without_time_step(adapter)
        key = adapter.step_setting
        data = {**CLOSED_LOOP, "engines": {self.engine: {key: value}}}
        with pytest.raises(ScenarioError) as info:
            self.simulate(adapter, data)
        assert info.value.key == f"engines.{self.engine}.{key}"
        assert info.value.source.endswith(".toml") and reason in info.value.reason

    # -- mechanisms ----------------------------------------------------------

    @pytest.mark.parametrize("data", [CLOSED_LOOP, MOVING_SLIDE], ids=["closed-loop", "moving-slide"])
    def test_meets_the_default_tolerances(self, adapter, data):
        scenario = parse(data, f"{data['name']}.toml")
        assert_within_tolerance(compare_with_reference(scenario, adapter).records)

    # -- no unrequested effects ------------------------------------------------

    @pytest.mark.parametrize("data", [FREE_LOOP, DAMPED_LOOP], ids=["free", "gravity-and-dampers"])
    def test_the_model_holds_only_the_scene(self, adapter, data):
        """The compiled-model audit (`mechval.records.audit`): every mass, point,
        damper, the drive and gravity as the scene says, and no contact,
        limit, motor, body damping or other effect it does not ask for."""
        scenario = parse(data, f"{data['name']}.toml")
        mechanism = build_mechanism(scenario)
        settings = adapter.settings_for(scenario, mechanism)
        if self.without_model_audit:
            with pytest.raises(NotImplementedError):       # and it indeed has none
                adapter.audit(mechanism, scenario.time.t, settings)
            pytest.skip(self.without_model_audit)
        table = adapter.audit(mechanism, scenario.time.t, settings)
        assert failures(table).empty, "\n" + format_audit(failures(table))

    def test_power_balances_with_nothing_but_the_drive(self, adapter):
        """With no gravity and no damper, the drive's power is the rate of
        kinetic energy (health `power_residual`, from the engine's own
        motion and torque). An effect the scene does not ask for (a hidden
        damper, body damping, a joint motor) breaks the balance. Bound: the
        one the comparison rule holds the residual to (`HEALTH_BOUNDS`)."""
        scenario = parse(FREE_LOOP, "free.toml")
        result = simulate(scenario, adapter)
        bound = scenario.tolerance_for(self.engine)[HEALTH_BOUNDS["power_residual"]]
        assert float(np.max(result.health["power_residual"])) <= bound


    # -- torque-driven and free motion -------------------------------------------

    def run_dynamic(self, adapter, name: str):
        """Skip with the stated reason if the adapter builds no forward
        dynamics (and check that it indeed declares neither feature)."""
        if self.without_forward_dynamics:
            assert not {"torque laws", "free motion"} & adapter.features, adapter.features
            pytest.skip(self.without_forward_dynamics)
        assert {"torque laws", "free motion"} <= adapter.features
        mech, times = dynamic_mechanism(name)
        raw = adapter.run(mech, times, adapter.default_settings(mech, times))
        return mech, times, raw.frame

    @pytest.mark.parametrize("name", list(DYNAMIC))
    def test_follows_the_forward_dynamics_reference(self, adapter, name):
        """From the same consistent initial state at t = 0 (no pre-roll, no
        prescribed motion), the engine integrates the mechanism's own
        dynamics; body angles, positions, reactions and efforts stay within
        the default tolerances of the forward-dynamics reference
        (`mechval.reference.dynamics`, DOP853 at its RTOL) at the engine's default
        setting."""
        mech, times, frame = self.run_dynamic(adapter, name)
        reference = dynamic_reference(name)
        ratios = dynamic_errors(mech, reference, frame)
        assert {column: ratio for column, ratio in ratios.items() if not ratio <= 1.0} == {}

    @pytest.mark.parametrize("name", ["free-fourbar", "motored-slider-crank"])
    def test_the_dynamic_model_holds_only_the_scene(self, adapter, name):
        """The compiled-model audit of a free and a motored mechanism: each
        torque law as stated, nothing prescribing a joint that is
        integrated from its initial value, no other effect."""
        mech, times = dynamic_mechanism(name)
        if self.without_forward_dynamics:
            pytest.skip(self.without_forward_dynamics)
        if self.without_model_audit:
            pytest.skip(self.without_model_audit)
        table = adapter.audit(mech, times, adapter.default_settings(mech, times))
        assert failures(table).empty, "\n" + format_audit(failures(table))
        assert {"prescribed motion"} <= set(table["quantity"])
        if mech.torque_drives:
            assert any(item.startswith("torque law") for item in table["item"])

    def test_a_torque_law_is_an_applied_joint_torque(self, adapter):
        """The crank under T(t) = T0 + a·sin(2πft + φ) (`mechval.testing.mechanisms`
        SPIN): its effort column is the law itself, not a servo's
        response, and its motion follows the closed form."""
        mech, times, frame = self.run_dynamic(adapter, "spinning-crank")
        law = mech.torque_drives[0]
        np.testing.assert_allclose(frame[f"{law.name}.T"], law.value(times), rtol=1e-12, atol=1e-12)
        theta, _ = dm.spinning_exact(times)
        assert float(np.max(np.abs(frame["crank.theta"] - theta))) <= ANGLE

    def test_a_free_pendulum_swings_as_its_closed_form(self, adapter):
        """A bar released from rest 2.5 rad from hanging: its angle against
        the elliptic-function closed form (dm.pendulum_exact)."""
        mech, times, frame = self.run_dynamic(adapter, "pendulum")
        theta, _ = dm.pendulum_exact(times)
        assert float(np.max(np.abs(frame["bar.theta"] - theta))) <= ANGLE
