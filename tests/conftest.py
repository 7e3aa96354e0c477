"""Shared fixtures: scenarios, the cached reference, engine adapters."""

from __future__ import annotations

import functools

import pytest

from mechval.engines.registry import ENGINE_NAMES, EngineUnavailable, adapter
from mechval.reference import simulate_reference
from mechval.scenarios import builtin_names, load

BUILTIN = builtin_names()


@functools.lru_cache(maxsize=None)
def builtin_scenario(name: str):
    return load(name)


#: Built-ins of the four closed-form kinds (each has a planar twin); the
#: planar built-ins have no closed form (tests/test_new_scenes.py), nor
#: have torque-driven and free scenes (integrated: tests/test_dynamic_scenes.py).
CLOSED_FORM = [name for name in BUILTIN if builtin_scenario(name).mechanism != "planar"
               and not builtin_scenario(name).forward_dynamics]
#: Built-in × engine pairs the engine cannot run at all, with the refusal the
#: harness gives up front (the engine's failure is the finding, see the
#: scene's file; tests/test_exudyn_planar.py runs the engine on it anyway
#: and fails when the engine starts to run it, so that the note gets updated).
CANNOT_RUN = {("exudyn", "planar-extra/parallelogram-double-fourbar"):
              "parallelogram-double-fourbar.toml: joint: exudyn: cannot run redundant constraints",
              ("exudyn", "planar-extra/double-fourbar-falling"):
              "double-fourbar-falling.toml: joint: exudyn: cannot run redundant constraints"}


@functools.lru_cache(maxsize=None)
def builtin_reference(name: str):
    return simulate_reference(builtin_scenario(name))


def engine_or_skip(name: str):
    """The named adapter, or skip the test with the reason it is unavailable."""
    try:
        return adapter(name)
    except EngineUnavailable as exc:
        pytest.skip(str(exc))


@pytest.fixture(params=ENGINE_NAMES)
def engine(request):
    return engine_or_skip(request.param)


# --- pytest --mechval-report DIR: the same report, written from a test session.

COMPARISONS: list = []      # (Outcome, records) of every comparison test that ran


def pytest_addoption(parser):
    parser.addoption("--mechval-report", metavar="DIR", default=None,
                     help="write the discrepancy report of the session's comparison tests to DIR")


@pytest.fixture
def record_comparison():
    """Tests call record_comparison(scenario, engine, signals, records,
    wall_time) so that --mechval-report can show their results."""
    from mechval.outcome import Outcome, Task

    def record(scenario, engine, signals, records, wall_time=0.0, setting="default"):
        COMPARISONS.append((Outcome(Task(scenario, engine, setting), signals, wall_time=wall_time), records))
    return record


def pytest_sessionfinish(session, exitstatus):
    out = session.config.getoption("--mechval-report", default=None)
    if not out or not COMPARISONS:
        return
    import pandas as pd
    from pathlib import Path
    from mechval.reports.build import write_report
    from mechval.reports.stability import stability_section
    outcomes = [o for o, _ in COMPARISONS]
    scenarios = list({o.task.scenario.name: o.task.scenario for o in outcomes}.values())
    references = {s.name: simulate_reference(s) for s in scenarios}
    records = pd.concat([r for _, r in COMPARISONS], ignore_index=True)
    sections = [s for s in (stability_section(records, scenarios),) if s]
    path = write_report(Path(out), scenarios, references, outcomes, records, sections)
    session.config.get_terminal_writer().line(f"mechval report: {path / 'index.html'}")
