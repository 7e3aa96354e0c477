"""PyBullet on planar files that use what the built-in kinds cannot: two
drives, a prismatic drive, spring-dampers, body torques, two closed loops.
Each scene is compared with the general reference at the default
tolerances (`mechval.compare.compare`, as tests/contract.py does); short
runs (≤ 1 s, ≤ 101 samples) keep the tests fast.

How PyBullet builds each feature (engines/pybullet_run.py, pybullet_model.py):
every drive is a position-controlled multibody joint (a leaf of the split
layout), its effort read from the joint's applied motor torque or force;
spring-dampers and body torques are external loads set before every step
(PyBullet has no spring element between bodies)."""

from __future__ import annotations

import tomllib

import pytest

from conftest import engine_or_skip
from mechval.audit import failures, force_item, format_audit
from mechval.compare import compare
from mechval.linkages import build_mechanism
from mechval.scenarios import parse
from mechval.harness.simulate import simulate

pytestmark = pytest.mark.engine

#: Seed four-bar (crank-rocker of the published 9×9 study, as
#: scenarios/planar-twins/fourbar-seed.toml), 1 s of it; the scenes below
#: add to it.
SEED_FOURBAR = """
[ground]
O2 = [0.0, 0.0]
O4 = [0.6, 0.0]
{ground_points}
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
{rocker_points}

[[joint]]
name = "O2"
type = "revolute"
between = ["ground.O2", "crank.start"]

[[joint]]
name = "A"
type = "revolute"
between = ["coupler.start", "crank.end"]

[[joint]]
name = "B"
type = "revolute"
between = ["rocker.end", "coupler.end"]

[[joint]]
name = "O4"
type = "revolute"
between = ["ground.O4", "rocker.start"]

[[drive]]
joint = "O2"
phi0 = 0.0
omega0 = 1.0
alpha = 1.0

[effects]
gravity = [0.0, -9.81]

[time]
end = 1.0
samples = 101
"""

FOURBAR_POSE = """
[assembly]
crank = 0.0
coupler = 1.21
rocker = 1.93
"""

#: A spring-damper between two moving links (crank end to rocker middle)
#: under gravity.
FOURBAR_SPRING = 'name = "pb-fourbar-spring"\nmechanism = "planar"\n' + SEED_FOURBAR.format(
    ground_points="", rocker_points="points = { mid = [0.25, 0.0] }") + """
[[force]]
type = "spring"
name = "tie"
between = ["crank.end", "rocker.mid"]
stiffness = 2000.0
free_length = 0.3
damping = 40.0
""" + FOURBAR_POSE

#: A constant torque on the rocker (and one on the coupler) of the seed four-bar.
FOURBAR_TORQUE = 'name = "pb-fourbar-torque"\nmechanism = "planar"\n' + SEED_FOURBAR.format(
    ground_points="", rocker_points="") + """
[[force]]
type = "torque"
name = "brake"
body = "rocker"
torque = -40.0

[[force]]
type = "torque"
name = "twist"
body = "coupler"
torque = 15.0
""" + FOURBAR_POSE

#: Watt II six-bar: the seed four-bar, its rocker a ternary link (point C)
#: driving a second four-bar (rocker–link5–link6–ground, pivot O6). The
#: second loop's lengths are derived here, not taken from a source: C at
#: 0.32 m from O4, |C − O6| ≈ 0.43 m at t = 0 between link5 = 0.4 m and
#: link6 = 0.3 m, so the loop closes over the rocker's swing (the reference
#: assembles and follows it over the run, or the file is refused on load).
WATT_II = 'name = "pb-watt-ii"\nmechanism = "planar"\n' + SEED_FOURBAR.format(
    ground_points="O6 = [1.0, 0.0]", rocker_points="points = { C = [0.25, -0.2] }") + """
[[body]]
name = "link5"
mass = 8.0
length = 0.4

[[body]]
name = "link6"
mass = 6.0
length = 0.3

[[joint]]
name = "C"
type = "revolute"
between = ["rocker.C", "link5.start"]

[[joint]]
name = "D"
type = "revolute"
between = ["link6.end", "link5.end"]
damping = 0.5

[[joint]]
name = "O6"
type = "revolute"
between = ["ground.O6", "link6.start"]

[assembly]
crank = 0.0
coupler = 1.21
rocker = 1.93
link5 = -0.05
link6 = 1.23
"""

#: Two-drive five-bar (tests/planar_mechanisms.py's `five_bar` without its
#: force elements): cranks at O1 (φ1 = 0.5 + 2t) and O4 (φ4 = 2 + 1.5t +
#: 0.5t²), couplers meeting at P; gravity, dampers at A and P.
FIVE_BAR = """
name = "pb-five-bar"
mechanism = "planar"

[ground]
O1 = [0.0, 0.0]
O4 = [0.3, 0.0]

[[body]]
name = "L1"
mass = 1.0
length = 0.15

[[body]]
name = "L2"
mass = 1.5
length = 0.3

[[body]]
name = "L3"
mass = 1.5
length = 0.3

[[body]]
name = "L4"
mass = 1.0
length = 0.15

[[joint]]
name = "O1"
type = "revolute"
between = ["ground.O1", "L1.start"]

[[joint]]
name = "A"
type = "revolute"
between = ["L1.end", "L2.start"]
damping = 0.05

[[joint]]
name = "P"
type = "revolute"
between = ["L2.end", "L3.end"]
damping = 0.05

[[joint]]
name = "B"
type = "revolute"
between = ["L4.end", "L3.start"]

[[joint]]
name = "O4"
type = "revolute"
between = ["ground.O4", "L4.start"]

[[drive]]
joint = "O1"
phi0 = 0.5
omega0 = 2.0

[[drive]]
joint = "O4"
phi0 = 2.0
omega0 = 1.5
alpha = 1.0

[assembly]
L1 = 0.5
L2 = -0.8
L3 = -1.2
L4 = 2.0

[effects]
gravity = [0.0, -9.81]

[time]
end = 1.0
samples = 101
"""

#: The slider-driven slider-crank of docs/scenario-format.md ("Planar
#: files"): the guide is a prismatic drive, s = 0.35 − 0.12t + 0.15t²; a
#: damper on the guide and a return spring from the slider to the wall.
#: Unlike the docs' file, the guide is tilted (axis [1, 0.2]) and the drive
#: accelerates: on a level guide at constant speed the slider's vy, ay and
#: ax are zero, and the reference's rounding noise there (~1e-17) makes
#: their relative bound ~1e-19 (the comparison scales only an exactly zero
#: signal by its class), which no engine can meet.
SLIDER_DRIVEN = """
name = "pb-slider-driven"
mechanism = "planar"

[ground]
O = [0.0, 0.0]
wall = [0.6, 0.1]

[[body]]
name = "crank"
mass = 1.0
length = 0.1

[[body]]
name = "conrod"
mass = 2.0
length = 0.3

[[body]]
name = "slider"
mass = 3.0
com = [0.0, 0.0]
izz = 1e-3
points = { pin = [0.0, 0.0] }

[[joint]]
name = "O2"
type = "revolute"
between = ["ground.O", "crank.start"]

[[joint]]
name = "A"
type = "revolute"
between = ["conrod.start", "crank.end"]

[[joint]]
name = "B"
type = "revolute"
between = ["slider.pin", "conrod.end"]

[[joint]]
name = "guide"
type = "prismatic"
between = ["ground.O", "slider.pin"]
axis = [1.0, 0.2]
damping = 4.0

[[drive]]
joint = "guide"
phi0 = 0.35
omega0 = -0.12
alpha = 0.3

[[force]]
type = "spring"
between = ["slider.pin", "ground.wall"]
stiffness = 50.0
free_length = 0.2

[assembly]
crank = 1.1
conrod = -0.1
slider = 0.2

[effects]
gravity = [0.0, -9.81]

[time]
end = 1.0
samples = 101
"""

SCENES = {"five-bar": FIVE_BAR, "slider-driven": SLIDER_DRIVEN, "fourbar-spring": FOURBAR_SPRING,
          "fourbar-torque": FOURBAR_TORQUE, "watt-ii": WATT_II}


def scene(name: str):
    data = tomllib.loads(SCENES[name])
    return parse(data, f"{data['name']}.toml")


@pytest.fixture(scope="module")
def adapter():
    return engine_or_skip("pybullet")


@pytest.mark.parametrize("name", list(SCENES))
def test_meets_the_default_tolerances(adapter, name):
    """Every signal within the scene's bounds of the general reference."""
    scenario = scene(name)
    records = compare(simulate(scenario, "reference"), simulate(scenario, adapter),
                      scenario.tolerance_for("pybullet"), scenario.name, "pybullet")
    failed = records[records["verdict"] == "fail"]
    assert failed.empty, failed[["signal", "max_error", "bound", "reason"]].to_string()


@pytest.mark.parametrize("name", list(SCENES))
def test_the_model_holds_only_the_scene(adapter, name):
    """The model audit covers every drive and force element too."""
    scenario = scene(name)
    mechanism = build_mechanism(scenario)
    table = adapter.audit(mechanism, scenario.time.t, adapter.settings_for(scenario, mechanism))
    assert failures(table).empty, "\n" + format_audit(failures(table))
    audited = set(table["item"])
    assert {force_item(f) for f in mechanism.forces} <= audited
    assert {f"drive {d.name}" for d in mechanism.extra_drives} <= audited
