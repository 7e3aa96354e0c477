"""Comparison checks for pytest: run an engine on a scene, judge it against
the reference by the comparison rule, and fail with the discrepancy table.

The pytest plugin's `mechval_compare` fixture (`mechval.testing.plugin`)
calls `compare_with_reference` and records the comparison for
`--mechval-report`; a test that wants the records without the fixture calls
it directly, and `assert_within_tolerance(records)` fails the way the
fixture does.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import pandas as pd
import pytest

from mechval.adapter import EngineAdapter
from mechval.judging.compare import compare
from mechval.engines.registry import REFERENCE, EngineUnavailable, adapter, engine_names
from mechval.harness.simulate import simulate
from mechval.model.scenario import Scenario, ScenarioError
from mechval.scenarios import load
from mechval.records.signals import Signals

#: The columns of the failure table, most telling first.
TABLE_COLUMNS = ["scenario", "engine", "setting", "signal", "max_error", "t_max", "relative_error", "bound", "ratio",
                 "verdict", "reason"]


@dataclass(frozen=True)
class Comparison:
    """One engine run on one scene, judged against the reference."""

    scenario: Scenario
    engine: str
    setting: str
    signals: Signals
    reference: Signals
    records: pd.DataFrame
    wall_time: float


def engine_or_skip(name: str) -> EngineAdapter:
    """The named adapter, or skip the test with the reason it is unavailable
    (its engine library is not installed). An unknown name fails."""
    try:
        return adapter(name)
    except EngineUnavailable as exc:
        pytest.skip(str(exc))


def scenario_of(scene: Scenario | str | Path) -> Scenario:
    """A scenario, a scenario file's path or a built-in's name, loaded; a
    bad file fails the test with the one line naming file, key and reason."""
    if isinstance(scene, Scenario):
        return scene
    try:
        return _load(str(scene))
    except ScenarioError as exc:
        pytest.fail(str(exc), pytrace=False)


@functools.lru_cache(maxsize=None)
def _load(name_or_path: str) -> Scenario:
    """Each file loaded once per session, so that its reference is too."""
    return load(name_or_path, engine_names())


#: The reference per scenario object, kept with it (a scenario's identity
#: is its key: the same scene compared with several engines is solved once).
_references: dict[int, tuple[Scenario, Signals]] = {}


def reference_of(scenario: Scenario) -> Signals:
    """The reference's signals on the scenario, solved once per scenario
    object in a session (`simulate(scenario, "reference")`)."""
    kept = _references.get(id(scenario))
    if kept is None or kept[0] is not scenario:
        kept = _references[id(scenario)] = (scenario, simulate(scenario, REFERENCE))
    return kept[1]


def compare_with_reference(scene: Scenario | str | Path, engine: str | EngineAdapter,
                           overrides: Mapping[str, Any] | None = None, setting: str = "default") -> Comparison:
    """Run `engine` (a registered name, skipped when unavailable, or an
    adapter) on the scene with its settings (and `overrides`), and compare
    it with the reference within the scene's tolerances for that engine."""
    scenario = scenario_of(scene)
    engine_adapter = engine_or_skip(engine) if isinstance(engine, str) else engine
    reference = reference_of(scenario)
    start = time.perf_counter()
    try:
        signals = simulate(scenario, engine_adapter, overrides)
    except ScenarioError as exc:
        pytest.fail(str(exc), pytrace=False)
    wall_time = time.perf_counter() - start
    records = compare(reference, signals, scenario.tolerance_for(engine_adapter.name), scenario.name,
                      engine_adapter.name, setting)
    return Comparison(scenario, engine_adapter.name, setting, signals, reference, records, wall_time)


def discrepancy_table(records: pd.DataFrame, only_failures: bool = False) -> str:
    """A fixed-width table of discrepancy records, worst ratio first."""
    shown = records[records["verdict"] == "fail"] if only_failures else records
    shown = shown.sort_values("ratio", ascending=False, na_position="first")
    return shown[TABLE_COLUMNS].to_string(index=False, float_format=lambda v: f"{v:.3g}")


def assert_within_tolerance(records: pd.DataFrame) -> None:
    """Fail the test, with the records as a table (worst first), when any
    is out of tolerance (a missing value with a reason does not fail)."""
    failed = records[records["verdict"] == "fail"]
    if not failed.empty:
        pytest.fail(f"{len(failed)} of {len(records)} signals out of tolerance:\n" + discrepancy_table(records),
                    pytrace=False)
