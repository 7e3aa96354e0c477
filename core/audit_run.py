"""Run the compiled-model audit (`mechval.audit`) of engines on scenarios:
the harness side, which knows the engine registry (as `baseline_run` does
for baselines). An audit builds each engine's model and reads it back; it
simulates nothing."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

import pandas as pd

from .audit import failures
from .linkages import build_mechanism
from .scenario import Scenario


@dataclass(frozen=True)
class AuditResult:
    """One engine's audit table on one scenario, or why there is none."""

    scenario: str
    engine: str
    table: pd.DataFrame | None = field(default=None, compare=False)
    error: str = ""
    seconds: float = 0.0

    @property
    def failing(self) -> int:
        return len(failures(self.table)) if self.table is not None else 0

    @property
    def ok(self) -> bool:
        return self.table is not None and self.failing == 0


def audit_scenario(scenario: Scenario, engine: str, overrides: Mapping[str, Any] | None = None) -> AuditResult:
    """The audit of `engine`'s model of `scenario` at its default setting
    (plus overrides). Settings the scenario refuses raise ScenarioError; a
    scenario the engine cannot model gives a result with the error."""
    from mechval.engines.registry import adapter
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
