"""MuJoCo builds every planar feature (issue 14): several drives, a
prismatic drive, spring-dampers, body torques, several closed loops; each
scene agrees with the general reference at the default tolerances, and the
audit reads every new element back."""

from __future__ import annotations

import tomllib

import pytest

from mechval.audit import failures, format_audit
from mechval.compare import compare
from mechval.harness.simulate import simulate
from mechval.linkages import build_mechanism
from mechval.scenarios import parse

pytestmark = pytest.mark.engine
mujoco = pytest.importorskip("mujoco")

FOURBAR = """
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
points = { middle = [0.25, 0.0] }

[[body]]
name = "rocker"
mass = 25.0
length = 0.5
points = { middle = [0.25, 0.0] }

[[joint]]
name = "O2"
type = "revolute"
between = ["ground.O2", "crank.start"]

[[joint]]
name = "A"
type = "revolute"
between = ["coupler.start", "crank.end"]
damping = 0.5

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
omega0 = 4.0
alpha = 1.0

[assembly]
crank = 0.0
coupler = 1.21
rocker = 1.93

[effects]
gravity = [0.0, -9.81]

[time]
end = 0.5
samples = 101
"""

#: The seed four-bar (fourbar-seed) with a spring-damper from the coupler's
#: middle to the rocker's middle, both moving.
SPRING_FOURBAR = FOURBAR + """
[[force]]
name = "coupler_rocker"
type = "spring"
between = ["coupler.middle", "rocker.middle"]
stiffness = 2000.0
free_length = 0.2
damping = 30.0
"""

#: The seed four-bar with constant torques on the coupler and the rocker.
TORQUE_FOURBAR = FOURBAR + """
[[force]]
name = "on_coupler"
type = "torque"
body = "coupler"
torque = 15.0

[[force]]
name = "on_rocker"
type = "torque"
body = "rocker"
torque = -40.0
"""

#: A two-drive five-bar: both cranks driven at the ground (derived; the
#: reference closes the loop over the whole run).
FIVEBAR = """
[ground]
O1 = [0.0, 0.0]
O2 = [0.3, 0.0]

[[body]]
name = "crank1"
mass = 1.0
length = 0.1

[[body]]
name = "crank2"
mass = 1.2
length = 0.1

[[body]]
name = "link3"
mass = 2.0
length = 0.3

[[body]]
name = "link4"
mass = 2.5
length = 0.3

[[joint]]
name = "O1"
type = "revolute"
between = ["ground.O1", "crank1.start"]

[[joint]]
name = "O2"
type = "revolute"
between = ["ground.O2", "crank2.start"]

[[joint]]
name = "A"
type = "revolute"
between = ["crank1.end", "link3.start"]
damping = 0.05

[[joint]]
name = "B"
type = "revolute"
between = ["crank2.end", "link4.start"]

[[joint]]
name = "P"
type = "revolute"
between = ["link3.end", "link4.end"]
damping = 0.02

[[drive]]
joint = "O1"
phi0 = 1.2
omega0 = 1.5
alpha = 2.0

[[drive]]
joint = "O2"
phi0 = 1.9
omega0 = -1.0

[assembly]
crank1 = 1.2
crank2 = 1.9
link3 = 1.17
link4 = 1.97

[effects]
gravity = [0.0, -9.81]

[time]
end = 0.5
samples = 101
"""

#: The seed textbook's slider-driven slider-crank (docs/scenario-format.md,
#: "Planar files"): the slide is prescribed, a return spring from the
#: slider to the wall, a damped guide, and a torque on the slider block
#: (which the guide's couple M carries). Unlike the docs' example, the
#: guide is tilted and the slide accelerates: on a level guide at constant
#: rate the reference's slider.vy and slider.ax are rounding noise
#: (~1e-17), and the comparison's bound, relative to a signal's own peak,
#: would then be ~1e-19 (a limit of the comparison rule, not of MuJoCo).
SLIDER_DRIVEN = """
[ground]
O = [0.0, 0.0]
wall = [0.6, 0.0]

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
axis = [0.96, 0.28]
damping = 4.0

[[drive]]
joint = "guide"
phi0 = 0.35
omega0 = -0.12
alpha = -0.1

[[force]]
type = "spring"
between = ["slider.pin", "ground.wall"]
stiffness = 50.0
free_length = 0.2

[[force]]
type = "torque"
body = "slider"
torque = 2.0

[assembly]
crank = 0.9
conrod = 0.05
slider = 0.2838

[effects]
gravity = [0.0, -9.81]

[time]
end = 0.8
samples = 161
"""

#: A Watt II six-bar: a crank-rocker four-bar (O2, A, B, O4) whose rocker is
#: a ternary link driving a second four-bar (C, D, O6). Link lengths
#: derived here (Grashof crank-rocker first loop: 0.1 + 0.4 < 0.35 + 0.3);
#: the reference closes both loops over the whole run.
WATT_II = """
[ground]
O2 = [0.0, 0.0]
O4 = [0.4, 0.0]
O6 = [0.75, 0.15]

[[body]]
name = "crank"
mass = 1.0
length = 0.1

[[body]]
name = "coupler"
mass = 2.0
length = 0.35

[[body]]
name = "rocker"
mass = 3.0
com = [0.1, 0.05]
izz = 0.03
points = { pivot = [0.0, 0.0], B = [0.3, 0.0], C = [0.1, 0.2] }

[[body]]
name = "coupler2"
mass = 1.5
length = 0.35

[[body]]
name = "rocker2"
mass = 1.5
length = 0.3

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
between = ["coupler.end", "rocker.B"]
damping = 0.1

[[joint]]
name = "O4"
type = "revolute"
between = ["ground.O4", "rocker.pivot"]

[[joint]]
name = "C"
type = "revolute"
between = ["rocker.C", "coupler2.start"]

[[joint]]
name = "D"
type = "revolute"
between = ["coupler2.end", "rocker2.end"]
damping = 0.05

[[joint]]
name = "O6"
type = "revolute"
between = ["ground.O6", "rocker2.start"]

[[drive]]
joint = "O2"
phi0 = 0.0
omega0 = 6.0

[assembly]
crank = 0.0
coupler = 1.3
rocker = 1.9
coupler2 = 0.0
rocker2 = 2.0

[effects]
gravity = [0.0, -9.81]

[time]
end = 1.0
samples = 201
"""

SCENES = {
    "two-drive-fivebar": FIVEBAR,
    "slider-driven-slider-crank": SLIDER_DRIVEN,
    "fourbar-spring-damper": SPRING_FOURBAR,
    "fourbar-body-torques": TORQUE_FOURBAR,
    "watt-ii-sixbar": WATT_II,
}


def scene(name: str):
    data = {"name": name, "mechanism": "planar", "description": "test scene", **tomllib.loads(SCENES[name])}
    return parse(data, f"{name}.toml")


@pytest.mark.parametrize("name", SCENES)
def test_meets_the_default_tolerances(name):
    scenario = scene(name)
    records = compare(simulate(scenario, "reference"), simulate(scenario, "mujoco"),
                      scenario.tolerance_for("mujoco"), scenario.name, "mujoco")
    failed = records[records["verdict"] == "fail"]
    assert not records.empty and failed.empty, failed[["signal", "max_error", "bound", "reason"]].to_string()


#: Inverse mode evaluates the same equations as the reference at the same
#: state: only rounding separates them (measured ≤ 5e-14 of each peak here).
INVERSE_AGREEMENT = 1e-9


@pytest.mark.parametrize("name", SCENES)
def test_inverse_mode_reproduces_the_reference(name):
    """Inverse dynamics at the reference state (no time integration) checks
    frames and signs of the new elements alone: each drive's effort read
    from its own column, every loop's force, the spring-dampers' and body
    torques' loads (none may land in a reaction)."""
    scenario = scene(name)
    records = compare(simulate(scenario, "reference"), simulate(scenario, "mujoco", {"mode": "inverse"}),
                      scenario.tolerance_for("mujoco"), scenario.name, "mujoco")
    signals = records[records["class"] != "health"]
    off = signals[~(signals["max_error"] <= INVERSE_AGREEMENT * signals["peak"])]
    assert len(signals) and off.empty, off[["signal", "max_error", "peak"]].to_string()


@pytest.mark.parametrize("name", SCENES)
def test_the_model_holds_the_new_elements(name):
    """The audit reads back every drive, spring-damper and body torque (and
    finds no other spring, damper, motor or constraint)."""
    from mechval.engines.mujoco import MujocoAdapter
    scenario = scene(name)
    adapter = MujocoAdapter()
    mechanism = build_mechanism(scenario)
    table = adapter.audit(mechanism, scenario.time.t, adapter.settings_for(scenario, mechanism))
    assert failures(table).empty, "\n" + format_audit(failures(table))
    items = set(table["item"])
    assert {f"spring {f.name}" if hasattr(f, "stiffness") else f"torque {f.name}" for f in mechanism.forces} <= items
    assert all(item in items for item in ["drive"] + [f"drive {d.name}" for d in mechanism.extra_drives])


@pytest.mark.parametrize("name, element, quantity", [
    ("fourbar-spring-damper", "stiffness", "stiffness"), ("fourbar-spring-damper", "springlength", "free length"),
    ("fourbar-spring-damper", "damping", "damping"), ("fourbar-body-torques", "torque", "torque"),
    ("two-drive-fivebar", "clock force", "alpha")])
def test_the_audit_reads_the_new_elements_back(name, element, quantity):
    """A changed value in the compiled model (not in the Mechanism) shows
    as "differs" in that element's row: the audit reads MuJoCo's numbers."""
    from mechval.audit import audit, expected_model
    from mechval.engines.mujoco import MujocoAdapter
    from mechval.engines.mujoco_run import Model
    from mechval.engines.mujoco_audit import Reader
    scenario = scene(name)
    mechanism = build_mechanism(scenario)
    model = Model(mechanism, scenario.time.t, MujocoAdapter().settings_for(scenario, mechanism))
    model.initial_state()
    mujoco.mj_fwdPosition(model.m, model.d)
    m, last = model.m, len(mechanism.forces) - 1
    if element == "stiffness":
        m.tendon_stiffness[model.tendon[last]] *= 1.5
    elif element == "springlength":
        m.tendon_lengthspring[model.tendon[last]] += 0.01
    elif element == "damping":
        m.tendon_damping[model.tendon[last]] *= 1.5
    elif element == "torque":
        m.actuator_biasprm[model.actuator[last], 0] *= 1.5
    else:                                        # the second drive's clock
        m.actuator_biasprm[m.actuator(model.clocks[1]).id, 0] += 1e6
    table = audit(expected_model(mechanism), Reader(model).readings())
    bad = failures(table)
    # One element differs (a clock's force also shifts φ0, ω0 read back at t = 0).
    assert quantity in set(bad["quantity"]) and bad["item"].nunique() == 1, format_audit(bad)
    assert bad["item"].iloc[0].startswith(("spring", "torque", "drive ")), format_audit(bad)


def test_declares_every_feature_and_the_harness_still_refuses_undeclared_ones():
    """MuJoCo declares all FEATURES; a MuJoCo adapter that declared none
    would still be refused each, naming the key (the refusal is the
    harness's, not the adapter's)."""
    from mechval.adapter import FEATURES
    from mechval.engines.mujoco import MujocoAdapter
    from mechval.scenario import ScenarioError
    assert MujocoAdapter.features == frozenset(FEATURES)

    class Undeclared(MujocoAdapter):
        features = frozenset()

    with pytest.raises(ScenarioError, match="two-drive-fivebar.toml: drive: mujoco: its adapter does not build "
                                            "several drives yet"):
        simulate(scene("two-drive-fivebar"), Undeclared())
