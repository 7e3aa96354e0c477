"""Run the compiled-model audit (`mechval.audit`) of engines on scenarios:
the harness side, which knows the engine registry (as `baseline_run` does
for baselines). An audit builds each engine's model and reads it back; it
simulates nothing."""

from __future__ import annotations

import time
from typing import Any, Iterable, Mapping

from mechval.audit import AuditResult
from mechval.engines.registry import adapter
from mechval.linkages import build_mechanism
from mechval.scenario import Scenario


def audit_scenario(scenario: Scenario, engine: str, overrides: Mapping[str, Any] | None = None) -> AuditResult:
    """The audit of `engine`'s model of `scenario` at its default setting
    (plus overrides). Settings the scenario refuses raise ScenarioError; a
    scenario the engine cannot model gives a result with the error."""
    engine_adapter = adapter(engine)
    mechanism = build_mechanism(scenario)
    settings = engine_adapter.settings_for(scenario, mechanism, overrides)
    start = time.perf_counter()
    try:
        table = engine_adapter.audit(mechanism, scenario.time.t, settings)
    except NotImplementedError as exc:
        return AuditResult(scenario.name, engine, error=str(exc))
    except Exception as exc:           # e.g. a mechanism the engine cannot model: the report says so
        return AuditResult(scenario.name, engine, error=f"{type(exc).__name__}: {exc}")
    return AuditResult(scenario.name, engine, table, seconds=time.perf_counter() - start)


def audit_all(scenarios: Iterable[Scenario], engines: Iterable[str]) -> list[AuditResult]:
    """Every scenario × engine, in that order."""
    engines = list(engines)
    return [audit_scenario(scenario, engine) for scenario in scenarios for engine in engines]
