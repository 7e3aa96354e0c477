"""How close the forward-dynamics reference (mechval.reference.dynamics, at its
default tolerance RTOL) comes to the motion it integrates, measured as the
comparison measures engines: per signal, max |reference − tighter run| over
the run, against the largest peak of the signal's class (angle, velocity,
acceleration, force, torque, …: mechval.records.signals.SIGNAL_CLASS). The tighter
run is the same integration at scipy's finest tolerance, TIGHTEST (its own
error, against a run whose steps are capped, is far below the bound:
tests/bench/dynamics_accuracy.py prints it).

The integrator bounds each step's error; over a run the steps' errors add
up, about in proportion to the turns the run makes, and a fast run's
accelerations and forces inherit the angles' absolute error times Ω². The
scene that found it (issue: "the integrated reference is 1e-7, not 1e-9"):
the seed four-bar spun by two sinusoidal torque laws, 15 turns to 135 rad/s
(`spun_fourbar`); at the former tolerance, 1e-10, it was 2.8e-7 of the
acceleration peak off. Held here: BOUND on every torque-driven and free
built-in scene and on the spun four-bar, a short run of it by default and
the whole 15 turns in the slow suite.
"""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from mechval.reference import dynamics
from mechval.reference.dynamics import RTOL, raw_dynamics
from mechval.reference.linkages import build_mechanism
from mechval.scenarios import load, parse
from mechval.records.signals import SIGNAL_CLASS, canonical_signals

#: The reference within this fraction of each class's peak (the goal: two
#: orders below the tightest tolerance a scene may ask of an engine).
BOUND = 1e-9
#: scipy's finest relative tolerance (100 ulp, rounded up: below it scipy
#: warns and takes 100 ulp).
TIGHTEST = 2.3e-14

SPUN_FOURBAR = """
name = "spun-fourbar"
mechanism = "planar"
description = "The seed four-bar spun up from rest by a sinusoidal motor torque at O2 against a sinusoidal torque at O4"

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
between = ["coupler.start", "crank.end"]

[[joint]]
name = "B"
type = "revolute"
between = ["rocker.end", "coupler.end"]

[[joint]]
name = "O4"
type = "revolute"
between = ["ground.O4", "rocker.start"]

[[torque]]
joint = "O2"
name = "motor"
torque = 80.0
amplitude = 60.0
frequency = 1.0

[[torque]]
joint = "O4"
name = "brake"
torque = 0.0
amplitude = 40.0
frequency = 1.5
phase = 0.5

[[initial]]
joint = "O2"
value = 0.0
rate = 0.0

[assembly]
crank = 0.0
coupler = 1.21
rocker = 1.93

[effects]
gravity = [0.0, -9.81]
"""


def spun_fourbar(end: float):
    """The spun four-bar over 0–end s at 200 samples a second (2.2 s: 15
    turns, up to 135 rad/s)."""
    doc = tomllib.loads(SPUN_FOURBAR)
    doc["time"] = {"end": end, "samples": int(round(200 * end)) + 1}
    return parse(doc, "spun-fourbar.toml")


def signals(scenario, rtol: float = RTOL):
    """The reference's canonical signals at tolerance rtol, and its facts."""
    mech = build_mechanism(scenario)
    solution = raw_dynamics(mech, scenario.time.t, rtol=rtol)
    return canonical_signals(mech, solution.frame, "reference", "", {}, solution.missing), solution.facts


def class_errors(run, tight) -> dict[str, tuple[float, str]]:
    """Per class: the largest max |run − tight| of its signals over the
    class's peak (of `tight`), and the signal it is at."""
    peaks: dict[str, float] = {}
    worst: dict[str, tuple[float, str]] = {}
    for name in tight.frame.columns[1:]:
        if name in tight.missing:
            continue
        cls = SIGNAL_CLASS[name]
        peaks[cls] = max(peaks.get(cls, 0.0), float(np.abs(tight[name]).max()))
        error = float(np.abs(run[name] - tight[name]).max())
        worst[cls] = max(worst.get(cls, (0.0, name)), (error, name))
    return {cls: (error / peaks[cls], name) for cls, (error, name) in worst.items()}


def check(run, tight) -> None:
    """Every class of `run` within BOUND of its peak in `tight`."""
    errors = class_errors(run, tight)
    assert {"angle", "velocity", "acceleration", "force"} <= set(errors)
    far = {cls: f"{error:.3g} at {name}" for cls, (error, name) in errors.items() if not error <= BOUND}
    assert not far, far


@pytest.mark.parametrize("name", ["andrews-squeezer-motor", "planar-extra/double-fourbar-falling",
                                  pytest.param("slider-crank-motor", marks=pytest.mark.slow),
                                  pytest.param("fourbar-falling", marks=pytest.mark.slow)])
def test_built_in_scenes_within_the_bound_of_a_tighter_run(name):
    scenario = load(name)
    check(signals(scenario)[0], signals(scenario, TIGHTEST)[0])


def test_the_spun_fourbar_within_the_bound_of_a_tighter_run():
    """Its first 1.2 s: 3.5 turns, to 57 rad/s (at 1e-10: 1.5e-8 of the acceleration peak)."""
    scenario = spun_fourbar(1.2)
    check(signals(scenario)[0], signals(scenario, TIGHTEST)[0])


@pytest.mark.slow
def test_fifteen_turns_of_the_spun_fourbar_within_the_bound_of_a_tighter_run(monkeypatch):
    """The whole run (at 1e-10: 2.8e-7 of the acceleration peak); at RTOL
    it fits the evaluation limit with a sixth to spare (the tighter run, a
    test device, may take more)."""
    scenario = spun_fourbar(2.2)
    run, facts = signals(scenario)
    assert facts["evaluations"] <= 5 / 6 * dynamics.MAX_EVALUATIONS, facts["evaluations"]
    monkeypatch.setattr(dynamics, "MAX_EVALUATIONS", 2 * dynamics.MAX_EVALUATIONS)
    check(run, signals(scenario, TIGHTEST)[0])
