"""Hard cases stay numerically stable: near-singular and toggle positions,
high speed, a 509-revolution run, extreme mass ratios and scales, a crank
that stops and reverses. Every engine must stay healthy (no NaN, no branch
flip, loop gap and drive error within the position and angle tolerances,
power balance within the torque tolerance) and accurate on each."""

from __future__ import annotations

import dataclasses
import functools

import pytest

from conftest import BUILTIN, CANNOT_RUN, ENGINES, builtin_scenario, engine_or_skip
from mechval.model.scenario import ScenarioError, TimeGrid
from mechval.scenarios import parse
from mechval.harness.simulate import simulate
from mechval.testing.scenes import slider_crank

#: The built-ins tagged hard, and the hard scenes kept out of the default
#: run in scenarios/planar-extra/ (an engine cannot run them or misses the
#: bounds: CANNOT_RUN, BEYOND).
HARD = [name for name in BUILTIN if "hard" in builtin_scenario(name).tags] + ["planar-extra/double-fourbar-falling"]
#: The long run (509 revolutions, ~1 min per engine) runs in full under
#: `-m slow`; by default its first tenth (51 revolutions) stands in for it.
LONG = "fourbar-long-run"
#: Engine × hard scene pairs an engine runs but not within the bounds, with
#: the figures measured (an engine finding, kept visible as an xfail).
BEYOND = {("pybullet", "planar-extra/double-fourbar-falling"): (
    "PyBullet on the free redundant double four-bar at its default step (4.2e-4 s): energy drift 5.3e-2 of the "
    "peak kinetic energy (bound 1e-2), c1.theta 0.059 rad off, coupler.y 0.058 m, c2.alpha 3.9 relative, power "
    "residual 1.25; at 1.04e-4 s: drift 9.4e-3, c1.theta 2.7e-3 rad; at 2.6e-5 s: drift 2.9e-4, angles 5e-6 rad, "
    "but c3.alpha still 5x its bound (the redundant pins' load split differs step to step, as on "
    "parallelogram-double-fourbar)"),
    # Drake 1.51.1 at its defaults (drive_stiffness 1e4); its misses at the
    # shared step rule on fourbar-millimetre and slider-crank-150 are met by
    # their files' `refine` (tests/test_drake.py).
    ("drake", LONG): "Drake: SAP fails to converge at t = 103.7 s of the 509-revolution run with the default "
                     "drive_stiffness 1e4 (at 100 it finishes, energy balance 49x its bound)"}
HARD_CASES = [pytest.param(name, marks=pytest.mark.slow) if name == LONG else name for name in HARD] + [
    f"{LONG}@tenth"]


@functools.lru_cache(maxsize=None)
def hard_case(name: str):
    """The named built-in, or the first tenth of the long run (one object
    per name, so that its reference is solved once)."""
    if name.endswith("@tenth"):
        scenario = builtin_scenario(name.split("@")[0])
        return dataclasses.replace(scenario, name=f"{scenario.name} (first tenth)",
                                   time=TimeGrid(scenario.time.end / 10, (scenario.time.samples - 1) // 10 + 1))
    return builtin_scenario(name)


def test_hard_scenarios_exist():
    tags = {name: builtin_scenario(name).tags for name in HARD}
    assert len(tags) >= 8, tags


@pytest.mark.hard
@pytest.mark.engine
@pytest.mark.parametrize("scenario_name", HARD_CASES)
@pytest.mark.parametrize("engine_name", ENGINES)
def test_engine_stable_and_accurate(engine_name, scenario_name, mechval_compare, request):
    """Every signal and health measure within its bound; a NaN or inf
    without a reason and an assembly-branch flip each fail their health
    row outright, and both rows are judged."""
    engine = engine_or_skip(engine_name)
    if (engine_name, scenario_name) in BEYOND:
        request.applymarker(pytest.mark.xfail(reason=BEYOND[engine_name, scenario_name], strict=True))
    scenario = hard_case(scenario_name)
    if (engine_name, scenario_name) in CANNOT_RUN:
        with pytest.raises(Exception, match=CANNOT_RUN[engine_name, scenario_name]):
            simulate(scenario, engine)
        return
    records = mechval_compare(scenario, engine)
    # Planar files have no assembly-branch check: the row is "missing" there.
    assert {"health.nonfinite", "health.assembly_flip"} <= set(records["signal"])


def test_reference_refuses_a_sample_at_a_singular_configuration():
    """Conrod = crank + offset + 1e-15 m with the crank at −90° at t = 0:
    the rod stands perpendicular to the guide (condition number ~2e7)."""
    data = slider_crank(geometry={"crank": 0.1, "conrod": 0.15 + 1e-15, "offset": 0.05},
                        drive={"phi0": -1.5707963267948966, "omega0": 0.0, "alpha": 0.0},
                        time={"end": 1.0, "samples": 3})
    with pytest.raises(ScenarioError) as info:
        parse(data, "toggle.toml")
    assert info.value.key == "geometry"
    assert "t = 0 s is too close to a singular configuration" in info.value.reason
    assert "condition number" in info.value.reason
