"""Drake adapter: the shared contract suites (testing/contract.py,
testing/planar_contract.py) run on Drake's discrete SAP plant, with each
case Drake's first-order step cannot meet at the default settings kept as
a strict xfail with its measured figure (docs/engines.md, Drake)."""

from __future__ import annotations

import pytest

from mechval.testing.contract import DYNAMIC, AdapterContract
from mechval.testing.planar_contract import PlanarContract
from mechval.testing.planar_scenes import SCENES

pytestmark = pytest.mark.engine
pytest.importorskip("pydrake")

#: Measured on Drake 1.51.1 (timestep 6.06e-4 s by the step rule): the
#: falling four-bar's coupler.y is 19.9 × its bound at the default step,
#: 4.9 × at refine 4, 2.0 × at refine 10 — first order in the step.
FREE_FOURBAR = ("Drake's step is first order: the falling four-bar is 20x the position bound at the default step "
                "(4.9x at refine 4, 2.0x at refine 10)")
#: Planar scenes out of the default tolerances at the default settings,
#: measured on Drake 1.51.1 (worst signal, its error over its bound).
#: Drake's step is first order: each error halves with the step.
PLANAR_OUT = {
    "slider-driven": "conrod.ax 5.4x its bound at the last sample (a peak of 0.105 m/s²; 1.4x at refine 4)",
    "slider-driven-offset-com": "conrod.ax 5.4x its bound (as slider-driven)",
    "pin-driven-five-bar": "health.energy_balance 24x its bound, L3.ay 1.1x at t = 0, where it falls from 48 to "
                           "11 m/s² within 10 ms",
    "ground-second": "conrod.vy 1.0002x its bound (0.005001 against 0.005)",
}


class TestContract(AdapterContract):
    engine = "drake"

    @pytest.mark.parametrize("name", [pytest.param(n, marks=[pytest.mark.xfail(strict=True, reason=FREE_FOURBAR),
                                                                  pytest.mark.slow])
                                      if n == "free-fourbar" else n for n in DYNAMIC])
    def test_follows_the_forward_dynamics_reference(self, adapter, name):
        super().test_follows_the_forward_dynamics_reference(adapter, name)


class TestPlanarContract(PlanarContract):
    engine = "drake"

    @pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=PLANAR_OUT[n]))
                                      if n in PLANAR_OUT else n for n in SCENES])
    def test_meets_the_default_tolerances(self, adapter, name):
        super().test_meets_the_default_tolerances(adapter, name)


def test_a_ball_constraint_on_the_world_body_still_crashes_drake():
    """The finding (engines/drake/findings.py), measured on the installed
    Drake in a child process: this fails when a release fixes it, and then
    the topology's rule (no cut on a ground pin) can go."""
    from mechval.engines.drake.findings import BALL_ON_WORLD, probe_ball_on_world
    measured = probe_ball_on_world()
    assert measured.present, (f"fixed in Drake {measured.version}: update {BALL_ON_WORLD.key} (until=) and "
                              "let engines/drake/topology.py cut ground pins again")


def test_loops_are_cut_between_moving_bodies():
    """Every built-in four-bar is cut at a pin between two moving bodies,
    never at a ground pin (the finding above)."""
    from mechval.engines.drake.topology import topology
    from mechval.model.mechanism import GROUND
    from mechval.reference.linkages import build_mechanism
    from mechval.scenarios import load
    for name in ("fourbar-seed", "slider-crank", "shaper-quick-return", "hand-pump", "watt-six-bar", "jansen-leg"):
        cuts = topology(build_mechanism(load(name))).cuts
        assert cuts and all(GROUND not in (c.body_i, c.body_j) for c in cuts), name


def _wrong_revolute(damping: float = 0.0, limit: float | None = None):
    """A RevoluteJoint factory that gives joint "j1" (the four-bar's A, the
    first pin after the drive) a damper or a position limit."""
    from pydrake.multibody.tree import RevoluteJoint

    def make(name, parent, child, axis, default_damping):
        joint = RevoluteJoint(name, parent, child, axis, default_damping + (damping if name == "j1" else 0.0))
        if name == "j1" and limit is not None:
            joint.set_position_limits([-limit], [limit])
        return joint
    return make


@pytest.mark.parametrize("fault, rows", [
    ("damping", {("joint A", "damping")}),
    ("limit", {("scene", "joint limits")}),
])
def test_the_audit_catches_a_wrong_model(monkeypatch, fault, rows):
    """A plant built with one quantity wrong (a damper Drake adds at A, a
    position limit on A) fails exactly the rows that read it."""
    from mechval.engines.drake import model as drake_model
    from mechval.records.audit import failures
    from mechval.reference.linkages import build_mechanism
    from mechval.scenarios import load
    from mechval.engines.registry import adapter
    monkeypatch.setattr(drake_model, "RevoluteJoint", _wrong_revolute(**({"damping": 0.1} if fault == "damping"
                                                                        else {"limit": 100.0})))
    scenario = load("fourbar-seed")
    mech, engine = build_mechanism(scenario), adapter("drake")
    table = engine.audit(mech, scenario.time.t, engine.settings_for(scenario, mech))
    assert {(r.item, r.quantity) for r in failures(table).itertuples()} == rows


def test_a_quarter_of_the_step_is_four_times_as_accurate():
    """High accuracy is `refine = 4`: Drake's step is first order, so the
    worst error over its bound falls about fourfold (measured 0.69 → 0.17
    on slider-crank; at least threefold here)."""
    from mechval.harness.simulate import simulate
    from mechval.judging.compare import compare
    from mechval.scenarios import load
    scenario = load("slider-crank")
    reference = simulate(scenario, "reference")

    def worst(overrides):
        records = compare(reference, simulate(scenario, "drake", overrides), scenario.tolerance_for("drake"),
                          scenario.name, "drake")
        return float((records["max_error"] / records["bound"]).max())
    default, fine = worst({}), worst({"refine": 4})
    assert default <= 1.0 and fine <= default / 3, (default, fine)


@pytest.mark.parametrize("name", ["fourbar-millimetre", "slider-driven-slider-crank"])
def test_a_file_s_finer_step_meets_what_the_shared_step_rule_misses(name):
    """Six built-ins set Drake's `refine` ([engines.drake], with the
    figures): at refine 1 (the shared step rule) Drake misses their default
    tolerances (measured 1.97x and 5.4x), at the file's setting it meets
    them (0.12x, 0.34x). No bound is loosened; the step is finer."""
    from mechval.harness.simulate import simulate
    from mechval.judging.compare import compare
    from mechval.scenarios import load
    scenario = load(name)
    assert scenario.settings_for("drake")["refine"] > 1
    reference = simulate(scenario, "reference")

    def worst(overrides):
        records = compare(reference, simulate(scenario, "drake", overrides), scenario.tolerance_for("drake"),
                          scenario.name, "drake")
        return float((records["max_error"] / records["bound"]).max())
    assert worst({"refine": 1}) > 1.0 >= worst({})
