"""Run engines on scenarios in worker processes, isolated from each other.

Each (scenario, engine, setting) is one task in its own worker process
(`executors.LocalExecutor`), so an engine that crashes, hangs past the timeout
or returns NaN fails its own comparison and nothing else. The parent
compares every result with the reference (computed once per scenario).
"""

from __future__ import annotations

import functools
import importlib
import os
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Mapping, Sequence

import pandas as pd

from mechval.adapter import PeakRates
from mechval.judging.compare import COLUMNS, compare
from mechval.engines.registry import REFERENCE, adapter
from mechval.records.outcome import Outcome, Task
from mechval.model.scenario import Scenario, require_unique_names
from mechval.records.signals import Signals
from mechval.reference.linkages import build_mechanism

from .executors import Done, Executor, LocalExecutor
from .plan import Plan, planned, prepare, scenario_of
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
            refused = plan.refusal(engine_adapter)
            if refused:         # declared up front: a row that says so, not a failed run
                tasks.append(Task(scenario, engine, refused=refused))
                continue
            variants = engine_adapter.variants
            if "hard" in scenario.tags:
                variants = {"default": variants["default"]}
            for setting, overrides in variants.items():
                # Bad [engines.NAME] settings are the user's input: refuse them
                # here, with file and key, rather than as a failed run.
                settings = plan.settings(engine_adapter, overrides)
                # The declared run size (a refined step, a pre-roll count too):
                # what `longest_first` orders by.
                per_interval, preroll = engine_adapter.planned_steps(scenario.time.t, settings)
                steps = per_interval * max(len(scenario.time.t) - 1, 1) + preroll
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
    outcomes, _ = run_alongside(tasks, (), executor or LocalExecutor(workers or os.cpu_count() or 1, timeout),
                                on_done, body)
    return outcomes


def run_alongside(tasks: list[Task], jobs: Sequence[Callable[[], Any]], executor: Executor,
                  on_done: Callable[[Outcome], None] = lambda outcome: None,
                  body: Callable[[Task], tuple] = simulate_task,
                  on_job: Callable[[int, Done], None] = lambda index, done: None) -> tuple[list[Outcome], list[Done]]:
    """`run_tasks`, with other work (`jobs`: calls without arguments, e.g.
    `functools.partial(scene_job, plan, engines)`) run by the same workers
    in the same batch, so that it overlaps the engine runs rather than
    waiting for them or keeping them waiting. The jobs go first (they are
    short, and what they give is needed once the runs end), then the
    runs, the most steps first: no long run is left to finish alone while
    the other workers idle. The outcomes in the tasks' order, and one
    Done per job, its value (what the job returned, its worker's CPU time
    in s); on_job(index, done) as each job ends. A task the engine
    refused up front (`Task.refused`) is not run: its outcome is the
    refusal."""
    order = _runnable(tasks, on_done)
    items = [functools.partial(_timed, job) for job in jobs] + [functools.partial(body, tasks[k]) for k in order]

    def done(index: int, result: Done) -> None:
        if index >= len(jobs):
            on_done(_outcome(tasks[order[index - len(jobs)]], result))
        else:
            on_job(index, result)

    results = executor.run(_call, items, done)
    return _in_task_order(tasks, dict(zip(order, results[len(jobs):]))), results[:len(jobs)]


def _runnable(tasks: list[Task], on_done: Callable[[Outcome], None]) -> list[int]:
    """The indices of the tasks to run, the most steps first; each task
    the engine refused up front is an outcome now (on_done), not a run."""
    for task in tasks:
        if task.refused:
            on_done(Outcome(task, None, task.refused))
    return [k for k in longest_first(tasks) if not tasks[k].refused]


def _in_task_order(tasks: list[Task], ran: Mapping[int, Done]) -> list[Outcome]:
    """Every task's outcome (ran: task index → its run's Done)."""
    return [Outcome(task, None, task.refused) if task.refused else _outcome(task, ran[k])
            for k, task in enumerate(tasks)]


def _outcome(task: Task, done: Done) -> Outcome:
    """A run's outcome from its worker's Done."""
    if done.error:
        return Outcome(task, None, done.error, worker=done.worker)
    signals, wall_time, cpu_time, *sensitivity = done.value
    return Outcome(task, signals, wall_time=wall_time, cpu_time=cpu_time,
                   sensitivity=sensitivity[0] if sensitivity else None, worker=done.worker)


@dataclass
class Prepared:
    """What `prepare_and_run` did: the scenes' plans, their engine runs
    (tasks) and the runs' outcomes in the tasks' order, one Done per side
    job (each scene's `scene_job`, then the findings, as `run_alongside`'s
    jobs) and the workers' CPU time (s) for the preparations."""

    plans: list[Plan]
    tasks: list[Task]
    outcomes: list[Outcome]
    side: list[Done]
    preparation_cpu: float


def prepare_and_run(executor: Executor, scenarios: Sequence[Scenario], engines: Sequence[str],
                    check: Callable[[list[Plan], list[Task]], None],
                    on_done: Callable[[Outcome], None] = lambda outcome: None,
                    on_scene: Callable[[int, Done], None] = lambda index, done: None,
                    on_tasks: Callable[[list[Task]], None] = lambda tasks: None,
                    findings: Callable[[], Any] | None = None) -> Prepared:
    """`mechval run`'s work as one batch of the executor's workers, so that
    they go from one phase to the next without the batch ending: each
    scene's preparation (`preparation_job`, as `prepared_on`; its plan is
    built here as it arrives), then the findings; once every scene is
    prepared, `check(plans, tasks)` (the limits: it raises before any
    reference or engine runs, and the batch stops), on_tasks(tasks), and
    each scene's job (`scene_job`: reference, audit, drawing) and the
    engine runs join, the most steps first. on_scene(k, done) as scene
    k's job ends, on_done(outcome) as each run does. A preparation that
    fails on a worker is done again here, so that its error is raised as
    it would be in one process."""
    engines = list(engines)
    plans: list[Plan | None] = [None] * len(scenarios)
    side: list[Done | None] = [None] * (len(scenarios) + 1)
    tasks: list[Task] = []
    ran: dict[int, Done] = {}
    kinds: list[tuple[str, int]] = []         # per item of the batch: what it is, and which
    cpu = [0.0]
    remote = _solved_ahead(engines)

    def item(kind: str, k: int, job: Callable[[], Any]) -> Callable[[], Any]:
        kinds.append((kind, k))
        return job

    def scene_item(k: int) -> Callable[[], Any]:
        plan = plans[k]
        settings = {e: plan.settings(e) for e in engines if not plan.refusal(e)}
        return item("scene", k, functools.partial(_timed, functools.partial(scene_job, plan.scenario, settings)))

    def checked_work() -> list[Callable[[], Any]]:
        """Once every scene is prepared: the limits, then the scene jobs
        and the engine runs."""
        tasks.extend(tasks_for(plans, engines))
        check(plans, tasks)
        on_tasks(tasks)
        return [scene_item(k) for k in range(len(plans))] + [
            item("run", k, functools.partial(simulate_task, tasks[k])) for k in _runnable(tasks, on_done)]

    def done(index: int, result: Done) -> list[Callable[[], Any]]:
        kind, k = kinds[index]
        if kind == "prepare":
            if result.error:
                plans[k] = prepare(scenarios[k], engines)
            else:
                plans[k], cpu[0] = _plan_from(scenarios[k], result.value[0]), cpu[0] + result.value[1]
            return checked_work() if all(plan is not None for plan in plans) else []
        if kind == "run":
            ran[k] = result
            on_done(_outcome(tasks[k], result))
        else:
            side[k] = result
            if kind == "scene":
                on_scene(k, result)
        return []

    if remote:
        first = [item("prepare", k, functools.partial(_timed, functools.partial(preparation_job, scenario, engines)))
                 for k, scenario in enumerate(scenarios)]
    else:           # nothing to solve ahead: prepared here
        plans[:] = [prepare(scenario, engines) for scenario in scenarios]
        first = []
    # the findings fill the workers the last preparations leave idle
    first.append(item("findings", len(scenarios), functools.partial(_timed, findings or (lambda: None))))
    if not remote:
        first += checked_work()
    executor.run(_call, first, done)
    return Prepared(plans, tasks, _in_task_order(tasks, ran), side, cpu[0])


def prepared_on(executor: Executor, scenarios: Sequence[Scenario], engines: Sequence[str]) -> list[Plan]:
    """Each scene prepared for `engines` (`mechval.harness.plan.prepare`) by
    the executor's workers, in parallel: the solve of its peak rates (a
    dense solve of its motion; for a torque-driven or free scene an
    integration of the forward-dynamics reference, the longer part) and
    each engine's defaults from them (some solve again: Exudyn's force
    scale). The rates and defaults come back (arrays, numbers and names);
    the mechanism is built here again (it solves nothing). A scene whose
    preparation fails there is prepared here, so that its error is
    raised as it would be in one process."""
    if not _solved_ahead(engines):
        return [prepare(scenario, engines) for scenario in scenarios]
    plans: dict[int, Plan] = {}

    def arrived(index: int, done: Done) -> None:       # while the workers prepare the scenes after it
        if not done.error:
            plans[index] = _plan_from(scenarios[index], done.value)

    executor.run(functools.partial(preparation_job, engines=list(engines)), list(scenarios), arrived)
    return [plans[k] if k in plans else prepare(scenario, engines) for k, scenario in enumerate(scenarios)]


def _solved_ahead(engines: Sequence[str]) -> bool:
    """Whether some engine reads peak rates: then the scenes' preparations
    are solves, done by the workers (else a plan solves nothing)."""
    return any(adapter(engine).uses_peak_rates for engine in engines)


def _plan_from(scenario: Scenario, prepared: tuple[PeakRates | None, dict]) -> Plan:
    """A scene's plan from what its `preparation_job` sent back: the
    mechanism built here again (it solves nothing)."""
    return Plan(scenario, build_mechanism(scenario), *prepared)


def preparation_job(scenario: Scenario, engines: Sequence[str]) -> tuple[PeakRates | None, dict]:
    """A worker's part of a scene's preparation: its peak rates and every
    engine's defaults."""
    plan = prepare(scenario, engines)
    return plan.rates, dict(plan.defaults)


def import_engines(engines: Iterable[str]) -> None:
    """Import each engine's adapter and library here, once: the local
    pool's workers are forked from this process (for each task, so that
    no engine state leaks from one into the next) and start with them
    imported, instead of each paying for the imports in its run (measured
    25 ms of CPU per run on average, tests/bench/run_bench.py)."""
    for engine in engines:
        importlib.import_module(adapter(engine).library)


def _call(job: Callable[[], Any]) -> Any:
    return job()


def _timed(job: Callable[[], Any]) -> tuple[Any, float]:
    cpu = time.process_time()
    return job(), time.process_time() - cpu


def scene_job(scenario: Scenario, settings: Mapping[str, Mapping[str, Any]]) -> tuple[Signals, list, dict]:
    """A scene's own work, run by a worker alongside the engine runs: the
    reference's run, the model audit of each engine at its default
    `settings` (engine → settings, resolved by the plan;
    `mechval.harness.audit_run.audit_scenario`: it simulates nothing) and
    the page's drawing of the linkage (`mechval.reports.plots.
    mechanism_figure`, whose motion, for a torque-driven or free scene, is
    the reference's integrated run: done here, it is not integrated again).
    It carries the scene, not its `Plan` (whose solved rates are large
    and hold closures that do not pickle): the worker builds the
    mechanism again, which solves nothing, and the reference needs no
    peak rates."""
    from mechval.reports.plots import mechanism_figure
    from .audit_run import audit_scenario
    plan = prepare(scenario)
    reference = simulate(plan, adapter(REFERENCE))
    return (reference, [audit_scenario(plan, engine, settings=values) for engine, values in settings.items()],
            mechanism_figure(plan.mechanism, scenario.time.t))


def longest_first(tasks: list[Task]) -> list[int]:
    """Indices of `tasks`, the most steps first (ties in the given order)."""
    return sorted(range(len(tasks)), key=lambda k: -tasks[k].steps)


def discrepancies(outcomes: list[Outcome], references: Mapping[str, Signals]) -> pd.DataFrame:
    """Discrepancy records of every outcome; a failed run is one row."""
    return joined([outcome_records(o, references.get(o.task.scenario.name)) for o in outcomes])


def outcome_records(outcome: Outcome, reference: Signals | None) -> pd.DataFrame:
    """The discrepancy records of one outcome (`reference`: its scene's;
    None only for a failed run, which is one row)."""
    task = outcome.task
    if task.refused:
        row = dict.fromkeys(COLUMNS)
        row.update(scenario=task.scenario.name, engine=task.engine, setting=task.setting, signal="(run)",
                   verdict="missing", reason=f"not built: {task.refused}", missing=0)
        return pd.DataFrame([row], columns=COLUMNS)
    if outcome.signals is None:
        row = dict.fromkeys(COLUMNS)
        row.update(scenario=task.scenario.name, engine=task.engine, setting=task.setting, signal="(run)",
                   verdict="fail", reason=outcome.error, missing=0)
        return pd.DataFrame([row], columns=COLUMNS)
    return compare(reference, outcome.signals, task.scenario.tolerance_for(task.engine), task.scenario.name,
                   task.engine, task.setting)


def joined(frames: list[pd.DataFrame]) -> pd.DataFrame:
    """Outcomes' records as one table, in the given order."""
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=COLUMNS)


def references_for(scenarios: Iterable[Scenario | Plan]) -> dict[str, Signals]:
    """The reference per scenario name (names are refused unless unique),
    of scenarios or their prepared plans."""
    scenarios = list(scenarios)
    require_unique_names([scenario_of(scene) for scene in scenarios])
    plans = [planned(scene) for scene in scenarios]
    reference = adapter(REFERENCE)
    return {plan.scenario.name: simulate(plan, reference) for plan in plans}
