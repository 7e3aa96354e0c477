"""Run engines on scenarios in worker processes, isolated from each other.

Each (scenario, engine, setting) is one task in its own worker process
(`executors.LocalExecutor`), so an engine that crashes, hangs past the timeout
or returns NaN fails its own comparison and nothing else. The parent
compares every result with the reference (computed once per scenario).
"""

from __future__ import annotations

import os
import time
from typing import Callable, Iterable, Mapping

import pandas as pd

from mechval.judging.compare import COLUMNS, compare
from mechval.engines.registry import REFERENCE, adapter
from mechval.records.outcome import Outcome, Task
from mechval.model.scenario import Scenario, require_unique_names
from mechval.records.signals import Signals

from .executors import Done, Executor, LocalExecutor
from .plan import Plan, planned, scenario_of
from .simulate import simulate


def simulate_task(task: Task) -> tuple[Signals, float, float]:
    """Worker body: the engine's canonical signals, the wall time and the
    worker's CPU time (all its threads; on a shared machine the steadier
    figure of what the run costs)."""
    start, cpu = time.perf_counter(), time.process_time()
    signals = simulate(task.scenario, task.engine, task.overrides, task.feed, task.settings)
    return signals, time.perf_counter() - start, time.process_time() - cpu


def tasks_for(scenarios: Iterable[Scenario | Plan], engines: Iterable[str]) -> list[Task]:
    """One task per scenario × engine × the engine's reported variants.

    Hard scenarios run at each engine's default setting only: they test
    stability, and the accuracy variants would multiply their long runs.
    Each scene is prepared once (`mechval.harness.plan`; pass the plans to
    share them with other phases); each task carries its resolved settings,
    so that its worker derives nothing.
    """
    engines, scenarios = list(engines), list(scenarios)
    require_unique_names([scenario_of(scene) for scene in scenarios])
    plans = [planned(scene, engines) for scene in scenarios]
    tasks = []
    for plan in plans:
        scenario = plan.scenario
        for engine in engines:
            engine_adapter = adapter(engine)
            variants = engine_adapter.variants
            if "hard" in scenario.tags:
                variants = {"default": variants["default"]}
            for setting, overrides in variants.items():
                # Bad [engines.NAME] settings are the user's input: refuse them
                # here, with file and key, rather than as a failed run.
                settings = plan.settings(engine_adapter, overrides)
                step = settings.get(engine_adapter.step_setting)
                steps = scenario.time.end / step if isinstance(step, float) and step > 0 else 0.0
                tasks.append(Task(scenario, engine, setting, dict(overrides), steps, settings=settings))
    return tasks


def run_tasks(tasks: list[Task], workers: int = 0, timeout: float = 900.0,
              on_done: Callable[[Outcome], None] = lambda outcome: None,
              body: Callable[[Task], tuple] = simulate_task, executor: Executor | None = None) -> list[Outcome]:
    """Run every task in a worker process (`body`: `simulate_task`, or one
    that returns its figures and each signal's sensitivity) of `executor`
    (default: a local pool of `workers`); failures become Outcomes, in the
    tasks' order. The runs with the most steps start first, so that no
    long run is left to finish alone while the other workers idle."""
    def outcome(task: Task, done: Done) -> Outcome:
        if done.error:
            return Outcome(task, None, done.error, worker=done.worker)
        signals, wall_time, cpu_time, *sensitivity = done.value
        return Outcome(task, signals, wall_time=wall_time, cpu_time=cpu_time,
                       sensitivity=sensitivity[0] if sensitivity else None, worker=done.worker)

    order = longest_first(tasks)
    results = (executor or LocalExecutor(workers or os.cpu_count() or 1, timeout)).run(
        body, [tasks[k] for k in order], lambda index, done: on_done(outcome(tasks[order[index]], done)))
    in_task_order = dict(zip(order, results))
    return [outcome(task, in_task_order[k]) for k, task in enumerate(tasks)]


def longest_first(tasks: list[Task]) -> list[int]:
    """Indices of `tasks`, the most steps first (ties in the given order)."""
    return sorted(range(len(tasks)), key=lambda k: -tasks[k].steps)


def discrepancies(outcomes: list[Outcome], references: Mapping[str, Signals]) -> pd.DataFrame:
    """Discrepancy records of every outcome; a failed run is one row."""
    frames = []
    for outcome in outcomes:
        task = outcome.task
        if outcome.signals is None:
            row = dict.fromkeys(COLUMNS)
            row.update(scenario=task.scenario.name, engine=task.engine, setting=task.setting, signal="(run)",
                       verdict="fail", reason=outcome.error, missing=0)
            frames.append(pd.DataFrame([row], columns=COLUMNS))
            continue
        frames.append(compare(references[task.scenario.name], outcome.signals,
                              task.scenario.tolerance_for(task.engine), task.scenario.name, task.engine,
                              task.setting))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=COLUMNS)


def references_for(scenarios: Iterable[Scenario | Plan]) -> dict[str, Signals]:
    """The reference per scenario name (names are refused unless unique),
    of scenarios or their prepared plans."""
    scenarios = list(scenarios)
    require_unique_names([scenario_of(scene) for scene in scenarios])
    plans = [planned(scene) for scene in scenarios]
    reference = adapter(REFERENCE)
    return {plan.scenario.name: simulate(plan, reference) for plan in plans}
