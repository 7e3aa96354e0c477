"""Comparison runs: every installed engine × every built-in scenario at the
engine's default settings, every signal within the scenario's tolerances
(with the scenario file's per-engine overrides, each of which states its
reason and measured figure)."""

from __future__ import annotations

import time

import pytest

from conftest import BUILTIN, builtin_reference, builtin_scenario, engine_or_skip
from mechval.compare import compare, format_records, passed
from mechval.engines.registry import ENGINE_NAMES


@pytest.mark.engine
@pytest.mark.parametrize("scenario_name", [n for n in BUILTIN if "hard" not in builtin_scenario(n).tags])
@pytest.mark.parametrize("engine_name", ENGINE_NAMES)
def test_engine_matches_reference(engine_name, scenario_name, record_comparison):
    engine = engine_or_skip(engine_name)
    scenario = builtin_scenario(scenario_name)
    start = time.perf_counter()
    result = engine.simulate(scenario)
    wall_time = time.perf_counter() - start
    records = compare(builtin_reference(scenario_name), result, scenario.tolerance_for(engine_name),
                      scenario=scenario_name)
    record_comparison(scenario, engine_name, result, records, wall_time)
    assert passed(records), "\n" + format_records(records)
