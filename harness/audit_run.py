"""Run the compiled-model audit (`mechval.records.audit`) of engines on scenarios:
the harness side, which knows the engine registry (as `baseline_run` does
for baselines). An audit builds each engine's model and reads it back; it
simulates nothing."""

from __future__ import annotations

import time
from typing import Any, Iterable, Mapping

from mechval.adapter import SPATIAL
from mechval.records.audit import AuditResult, format_audit
from mechval.engines.registry import adapter
from mechval.model.scenario import Scenario

from .plan import Plan, planned, prepare
from .preflight import chosen_engines, load_scenario


def audit_scenario(scenario: Scenario | Plan, engine: str, overrides: Mapping[str, Any] | None = None,
                   settings: Mapping[str, Any] | None = None) -> AuditResult:
    """The audit of `engine`'s model of `scenario` (or of its prepared
    `Plan`) at its default setting (plus overrides), or at `settings`
    resolved by the caller's plan (then nothing is derived here). Settings
    the scenario refuses raise ScenarioError; a scenario the engine cannot
    model gives a result with the error."""
    engine_adapter = adapter(engine)
    plan = planned(scenario, [] if settings is not None else [engine_adapter])
    scenario, mechanism = plan.scenario, plan.mechanism
    settings = dict(settings) if settings is not None else plan.settings(engine_adapter, overrides)
    if mechanism.spatial is not None and SPATIAL not in engine_adapter.features:
        return AuditResult(scenario.name, engine, error=f"{engine}: its adapter does not build spatial scenes")
    start = time.perf_counter()
    try:
        table = engine_adapter.audit(mechanism, scenario.time.t, settings)
    except NotImplementedError as exc:
        return AuditResult(scenario.name, engine, error=str(exc))
    except Exception as exc:           # e.g. a mechanism the engine cannot model: the report says so
        return AuditResult(scenario.name, engine, error=f"{type(exc).__name__}: {exc}")
    return AuditResult(scenario.name, engine, table, seconds=time.perf_counter() - start)


def audit_all(scenarios: Iterable[Scenario | Plan], engines: Iterable[str]) -> list[AuditResult]:
    """Every scenario (or prepared plan) × engine, in that order; each
    scene prepared once."""
    engines = list(engines)
    plans = (planned(scenario, engines) for scenario in scenarios)
    return [audit_scenario(plan, engine) for plan in plans for engine in engines]


def audit_command(scenario_name: str, engines: list[str] | None) -> int:
    """`mechval audit`: per engine, the verdict and the table of what its
    model holds against the scene; exit status 1 when one differs."""
    scenario = load_scenario(scenario_name)
    engines = chosen_engines(engines)
    plan = prepare(scenario, engines)
    status = 0
    for engine in engines:
        result = audit_scenario(plan, engine)
        verdict = result.error or (f"{result.failing} rows differ" if result.failing else "the model is the scene")
        print(f"== {scenario.name} × {engine}: {verdict}")
        if result.table is not None:
            print(format_audit(result.table))
        status = status or int(not result.ok)
    return status
