"""Exudyn on joints between two moving bodies: a torque law at a pin
between two moving links, and the couple of a slide.

Scenes written here (no source): the falling four-bar of
docs/scenario-format.md with a torque law at its coupler–rocker pin.
"""

from __future__ import annotations

import tomllib

import pytest

from conftest import engine_or_skip
from mechval.audit import failures
from mechval.compare import compare, format_records, passed
from mechval.harness.simulate import simulate
from mechval.linkages import build_mechanism
from mechval.reference import simulate_reference
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
    records = compare(simulate_reference(scenario), simulate(scenario, adapter), scenario.tolerance_for("exudyn"),
                      scenario=scenario.name)
    assert passed(records), format_records(records, only_failures=True)
    assert "elbow.T" in set(records["signal"])
