"""The size of one engine run, checked before any work: its steps and the
memory it would take, from the adapter's resolved settings and its declared
run size (`EngineAdapter.planned_steps`, `output_copies`, `bytes_per_step`).
A run over `--max-steps` or `--max-memory` is refused naming the file, the
key that sets its size and how much it would take (README.md, "Limits")."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from mechval.adapter import EngineAdapter, as_float
from mechval.engines.registry import adapter
from mechval.model.scenario import Scenario, ScenarioError
from mechval.reference.limits import signal_count

from .defaults import DEFAULT_MAX_MEMORY, DEFAULT_MAX_STEPS, Limits  # noqa: F401 (also imported from here)
from .plan import prepare

@dataclass(frozen=True)
class RunSize:
    """What one engine run would take. Floats, so that an absurd setting
    gives inf rather than an overflow."""

    engine: str
    steps: float        # pre-roll included
    pre_roll: float
    step: float         # s
    table_bytes: float  # the output tables (samples × signals)
    step_bytes: float   # what the engine keeps per step

    @property
    def memory(self) -> float:
        return self.table_bytes + self.step_bytes


def run_size(scenario: Scenario, engine: EngineAdapter | str, settings: Mapping[str, Any]) -> RunSize:
    """The step count and memory of the engine with its resolved `settings`
    (`adapter.settings_for`) on the scenario."""
    engine = adapter(engine) if isinstance(engine, str) else engine
    samples = scenario.time.samples
    table = as_float(samples) * signal_count(scenario) * 8 * engine.output_copies
    per_sample, pre_roll = engine.planned_steps(scenario.time.t[:2], settings)
    if per_sample == 0:
        return RunSize(engine.name, 0.0, 0.0, math.nan, table, 0.0)
    steps = pre_roll + (samples - 1) * per_sample
    interval = scenario.time.end / (samples - 1)
    return RunSize(engine.name, steps, pre_roll, interval / per_sample, table, steps * engine.bytes_per_step)


def check_run(scenario: Scenario, engine: str, overrides: Mapping[str, Any] | None = None,
              limits: Limits = Limits(), settings: Mapping[str, Any] | None = None) -> RunSize:
    """Refuse an engine run over the step or memory limit, saying what it
    would take. The key named is the file's step setting if it has one,
    else time.end (steps) or time.samples (memory of the output tables).
    `settings`: the run's, resolved by its plan (else resolved here, with
    `overrides`)."""
    engine_adapter = adapter(engine)
    if settings is None:
        settings = prepare(scenario, [engine_adapter]).settings(engine_adapter, overrides)
    size = run_size(scenario, engine_adapter, settings)
    in_file = [key for key in engine_adapter.step_settings if key in scenario.settings_for(engine)]
    step_key = f"engines.{engine}.{in_file[0]}" if in_file else "time.end"
    if size.steps > limits.max_steps:
        raise ScenarioError(scenario.source, step_key,
                            f"one {engine} run would take {size.steps:.3g} steps ({size.pre_roll:.3g} pre-roll, then "
                            f"steps of {size.step:.3g} s up to t = {scenario.time.end:g} s), more than the limit of "
                            f"{limits.max_steps:.3g} (--max-steps)")
    if size.memory > limits.max_memory:
        key = step_key if size.step_bytes > size.table_bytes else "time.samples"
        raise ScenarioError(scenario.source, key,
                            f"one {engine} run would need about {gib(size.memory)} GiB ({scenario.time.samples:,} "
                            f"samples, {size.steps:.3g} steps), more than the limit of {gib(limits.max_memory)} GiB "
                            "(--max-memory)")
    return size


def gib(size: float) -> str:
    return f"{size / 2**30:.3g}" if size < 2**30 * 1e6 else "over a million"
