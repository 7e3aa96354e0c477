"""Exudyn on joints between two moving bodies: a torque law at a pin
between two moving links, and the couple of a slide (between two moving
links or on a ground guide).

Scene written here (no source): the falling four-bar of
docs/scenario-format.md with a torque law at its coupler–rocker pin.
"""

from __future__ import annotations

import tomllib

import pytest

from conftest import builtin_reference, builtin_scenario, engine_or_skip
from mechval.records.audit import failures
from mechval.judging.compare import compare, passed
from mechval.testing import discrepancy_table
from mechval.harness.simulate import simulate
from mechval.reference.linkages import build_mechanism
from mechval.model.mechanism import GROUND, Body, Joint, Mechanism
from mechval.scenarios import parse

pytestmark = pytest.mark.engine

#: The falling four-bar (docs/scenario-format.md), a rippling torque law at
#: its pin B between the coupler and the rocker, both moving.
ELBOW_TORQUE = """
name = "fourbar-elbow-torque"
mechanism = "planar"
[ground]
O2 = [0.0, 0.0]
O4 = [0.6, 0.0]
[[body]]
name = "crank"
mass = 12.5
length = 0.25
[[body]]
name = "coupler"
mass = 25.0
length = 0.5
[[body]]
name = "rocker"
mass = 25.0
length = 0.5
[[joint]]
name = "O2"
type = "revolute"
between = ["ground.O2", "crank.start"]
[[joint]]
name = "A"
type = "revolute"
between = ["crank.end", "coupler.start"]
[[joint]]
name = "B"
type = "revolute"
between = ["rocker.end", "coupler.end"]
[[joint]]
name = "O4"
type = "revolute"
between = ["ground.O4", "rocker.start"]
damping = 0.5
[[torque]]
joint = "B"
name = "elbow"
torque = 3.0
amplitude = 2.0
frequency = 1.5
[[initial]]
joint = "O2"
value = 0.3
[assembly]
crank = 0.3
coupler = 1.2
rocker = 2.1
[effects]
gravity = [0.0, -9.81]
[time]
end = 2.0
samples = 201
"""


@pytest.fixture(scope="module")
def adapter():
    return engine_or_skip("exudyn")


def test_a_torque_law_between_two_moving_links(adapter):
    """Two loads, T on the coupler and −T on the rocker, each under its own
    name (Exudyn refused the second load of the same name: "AddLoad …
    'torque law elbow' already exists"); the audit reads the law back; the
    run follows the forward-dynamics reference within the default bounds
    (measured worst ratio 0.052)."""
    scenario = parse(tomllib.loads(ELBOW_TORQUE), "fourbar-elbow-torque.toml")
    mechanism = build_mechanism(scenario)
    times = scenario.time.t
    settings = adapter.settings_for(scenario, mechanism)
    assert failures(adapter.audit(mechanism, times, settings)).empty
    records = compare(simulate(scenario, "reference"), simulate(scenario, adapter), scenario.tolerance_for("exudyn"),
                      scenario=scenario.name)
    assert passed(records), discrepancy_table(records, only_failures=True)
    assert "elbow.T" in set(records["signal"])


# --- the couple of a slide -------------------------------------------------------

@pytest.mark.parametrize("setting", ["default", "index3"])
@pytest.mark.parametrize("name, couple", [("hand-pump", "M43"), ("shaper-quick-return", "M43"),
                                          ("slider-driven-slider-crank", "guide.M")])
def test_a_slide_s_couple_is_compared(adapter, name, couple, setting):
    """Exudyn reports no couple of a slide; the adapter derives it from the
    balance of the slide's body (`exudyn.slide`), so it is compared like any
    signal instead of missing: within its bound on the built-ins with a
    slide between moving links (hand-pump, shaper-quick-return) and on a
    ground guide (slider-driven-slider-crank, with a damper, a spring and a
    body torque on the slider). Measured ratios default / index3: 6e-5 /
    8e-5, 0.25 / 0.0037, 6e-6 / 6e-14."""
    scenario = builtin_scenario(name)
    signals = simulate(scenario, adapter, adapter.variants[setting])
    records = compare(builtin_reference(name), signals, scenario.tolerance_for("exudyn"), scenario=name)
    row = records[records["signal"] == couple].iloc[0]
    assert couple not in signals.missing and row["verdict"] == "pass", discrepancy_table(records)
    assert "derived from the moment balance" in signals.info.facts["derived_reactions"]


def test_slides_whose_balances_cannot_tell_their_couples_apart_stay_missing():
    """Two slides between the ground and one block (a redundant guide): one
    body's balance cannot give two couples, so they are missing with the
    reason rather than split arbitrarily."""
    from mechval.engines.exudyn.slide import balance_bodies
    block = Body("block", 1.0, (0.0, 0.0), 1e-3)
    slides = (Joint("g1", "prismatic", GROUND, "block", (0.0, 0.0), (0.0, 0.0)),
              Joint("g2", "prismatic", GROUND, "block", (0.0, 0.1), (0.0, 0.1)))
    mechanism = Mechanism(name="two-guides", kind="planar", bodies=(block,), joints=slides, drive=None,
                          gravity=(0.0, 0.0), motion=None, signal_map={})
    assert balance_bodies(mechanism, slides) is None
    assert balance_bodies(mechanism, slides[:1]) == ["block"]
