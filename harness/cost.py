"""Work-precision sweeps: what accuracy costs in wall time, per engine.

Every engine runs its ladder of time steps (the adapter's `cost_ladder`,
rotations per step at the run's peak rate Ω, each snapped to the sample
interval divided by a 1-2-5 count, so the step divides the interval as
every adapter requires), crossed with its `cost_variants`, plus its default
step. One point (one setting) is one task (`mechval.records.outcome.Task`, as a
comparison run's): its timing repeats stay on one
worker, and every task goes through the same `Executor` (a local process
pool or a Dask cluster), so the errors do not depend on where it ran.

Time is measured inside the worker: the whole `simulate` call (integration,
reading the signals out, mapping them) minus the adapter's `build_time_s`,
median of the repeats, per simulated second. The adapters' own
`wall_time_s` (differently scoped: MuJoCo's is the rollout alone) is kept
as `engine_s_per_sim_s`. The reference is timed the same way (the
same `simulate` call, its adapter's) and every time is also given as a ratio to it.

Errors are those of `mechval.judging.compare.compare`, the largest per signal
class: relative to the signal's peak for relative classes, absolute (rad,
m) for angle and position; "force+torque" is the larger of the two
relative classes. Failures (an exception, a crashed or hung worker,
non-finite values, an assembly-branch flip) are data in the `failure`
column; their points take no part in orders and cheapest settings.
"""

from __future__ import annotations

import functools
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Sequence

import numpy as np
import pandas as pd
from tqdm import tqdm

from mechval.judging.compare import compare
from mechval.judging.cost_tables import CLASS_ORDER, COLUMNS, HEADLINE, REFERENCE, cheapest, convergence, format_tables
from mechval.engines.base import peak_rates
from mechval.engines.registry import adapter
from mechval.records.outcome import Task
from mechval.model.scenario import Scenario, Tolerance, require_unique_names
from mechval.reports.cost_report import write_cost_report
from mechval.records.signals import SIGNAL_CLASS, Signals

from .defaults import DASK_CONNECT_TIMEOUT, Limits
from .executors import Done, Executor, executor_for
from .plan import Plan, planned, prepare, scenario_of
from .preflight import (UsageError, check_dask_address, check_out_dir, check_runs, chosen_engines, default_out_dir,
                        load_scenario, worker_count)
from .simulate import simulate



@dataclass(frozen=True)
class Measurement:
    """A point's signals (first repeat) and per-repeat times (s)."""

    signals: Signals
    run_s: tuple[float, ...]
    build_s: tuple[float, ...]
    engine_s: tuple[float, ...]


def measure_point(point: Task, repeats: int = 3) -> Measurement:
    """Worker body: simulate the point `repeats` times, timing each call."""
    engine = adapter(point.engine)     # imports the engine before any timing
    first, run_s, build_s, engine_s = None, [], [], []
    for _ in range(repeats):
        start = time.perf_counter()
        signals = simulate(point.scenario, engine, point.overrides, settings=point.settings)
        total = time.perf_counter() - start
        first = signals if first is None else first
        build = signals.info.build_time_s or 0.0
        run_s.append(total - build)
        build_s.append(build)
        engine_s.append(np.nan if signals.info.wall_time_s is None else signals.info.wall_time_s)
    return Measurement(first, tuple(run_s), tuple(build_s), tuple(engine_s))


def nice_count(ratio: float) -> int:
    """The smallest count in the 1-2-5 series (1, 2, 5, 10, 20, …) ≥ ratio."""
    decade = 1
    while True:
        for m in (1, 2, 5):
            if m * decade >= ratio - 1e-9:
                return m * decade
        decade *= 10


def points_for(scene: Scenario | Plan, engine: str, quick: bool = False) -> list[Task]:
    """The sweep of one engine on a scenario (or its prepared plan): its
    variants × its ladder and default step (the adapter's step for the
    scenario, as interval / k), each with its resolved settings. Quick: the
    default variant at the default step and one ~10× coarser. An adapter
    with no time step (`step_setting` empty) has one point: its defaults.
    The ladder's Ω is the plan's peak rates (`PeakRates.rate`). An engine
    that declares it cannot build the scene has no points."""
    adapter_ = adapter(engine)
    plan = planned(scene, [adapter_])
    scenario = plan.scenario
    if plan.refusal(adapter_):      # declared up front: no points (the run's table says why)
        return []
    if not adapter_.step_setting:
        return [Task(scenario, engine, "default", {}, settings=plan.settings(adapter_), default=True)]
    times = scenario.time.t
    interval = float(times[1] - times[0])
    default = float(plan.settings(adapter_)[adapter_.step_setting])
    k_default = max(1, round(interval / default))
    if quick:
        coarse = nice_count(k_default / 10)
        counts = {k_default, coarse if coarse != k_default else nice_count(10 * k_default)}
        variants = {name: o for name, o in adapter_.cost_variants.items() if not o}
    else:
        rate = (plan.rates if plan.rates is not None else peak_rates(plan.mechanism, times)).rate
        counts = {nice_count(interval * rate / rad) for rad in adapter_.cost_ladder} | {k_default}
        variants = adapter_.cost_variants
    points = []
    for name, overrides in variants.items():
        for k in sorted(counts):
            chosen = {**overrides, adapter_.step_setting: interval / k}
            points.append(Task(scenario, engine, name, chosen, settings=plan.settings(adapter_, chosen), step=interval / k,
                               default=not overrides and k == k_default))
    return points


def sweep(scenarios: Sequence[Scenario | Plan], engines: Iterable[str], executor: Executor, quick: bool = False,
          repeats: int = 3, on_done: Callable[[Task, Done], None] = lambda point, done: None) -> pd.DataFrame:
    """The cost table (COLUMNS) of every engine on every scenario (or its
    prepared plan), plus one reference row per scenario (its own cost;
    class and error empty)."""
    require_unique_names([scenario_of(s) for s in scenarios])     # the references below are keyed by name
    engines = list(engines)
    plans = [planned(s, engines) for s in scenarios]
    points = [Task(plan.scenario, REFERENCE, "closed form") for plan in plans]
    points += [p for plan in plans for e in engines for p in points_for(plan, e, quick)]
    # Finest steps first: the longest tasks start early and the pool drains
    # evenly. The table keeps the points' own order.
    order = sorted(range(len(points)), key=lambda k: (points[k].engine != REFERENCE, points[k].step))
    ran = executor.run(functools.partial(measure_point, repeats=repeats), [points[k] for k in order],
                       lambda index, done: on_done(points[order[index]], done))
    dones: list[Done] = [Done()] * len(points)
    for k, done in zip(order, ran):
        dones[k] = done
    rows = []
    references: dict[str, tuple[Signals, float]] = {}
    for point, done in zip(points, dones):
        if point.engine == REFERENCE:
            if done.error:
                raise RuntimeError(f"{point.scenario.name}: the reference failed: {done.error}")
            seconds = _per_sim_second(point.scenario, done.value.run_s)
            references[point.scenario.name] = (done.value.signals, seconds)
            rows.append(dict(_point_columns(point, repeats), version=done.value.signals.version,
                             **_timing(point.scenario, done.value, seconds), failure=""))
            continue
        rows += _point_rows(point, repeats, done, *references[point.scenario.name])
    return pd.DataFrame(rows, columns=COLUMNS)


def cost_sweep(scenarios: Sequence[Scenario | Plan], engines: Iterable[str], executor: Executor, quick: bool,
               repeats: int, quiet: bool) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """The cost table, observed orders and cheapest settings
    (`mechval.judging.cost_tables`), with a progress bar on stderr unless `quiet`."""
    with tqdm(desc="cost points", unit="point", file=sys.stderr, disable=quiet) as bar:
        def done(point, outcome):
            bar.set_postfix_str(f"{point.engine} {point.setting} dt {point.step:.3g}"
                                + (" FAILED" if outcome.error else ""), refresh=False)
            bar.update()
        table = sweep(scenarios, engines, executor, quick=quick, repeats=repeats, on_done=done)
    return table, convergence(table), cheapest(table)


def cost_command(scenarios: list[str], engines: list[str] | None, out: Path | None, *, dask: str | None = None,
                 dask_connect_timeout: float = DASK_CONNECT_TIMEOUT, workers: int = 0, timeout: float = 900.0, quick: bool = False,
                 repeats: int = 3, quiet: bool = False, limits: Limits = Limits()) -> int:
    """`mechval cost`: every refusal before any work, then the sweep, its
    report folder and its tables printed."""
    if repeats < 1:
        raise UsageError("--repeats must be at least 1")
    check_dask_address(dask)
    chosen = [load_scenario(name) for name in scenarios]
    engines = chosen_engines(engines)
    plans = [prepare(s, engines) for s in chosen]
    check_runs([(p.scenario, p.engine, p.settings) for plan in plans for e in engines
                for p in points_for(plan, e, quick)], limits)
    out = out or default_out_dir("cost")
    check_out_dir(out)
    with executor_for(dask, worker_count(workers), timeout, dask_connect_timeout) as executor:
        table, orders, cheap = cost_sweep(plans, engines, executor, quick, repeats, quiet)
    write_cost_report(out, table, orders, cheap)
    print(format_tables(table, orders, cheap))
    print(f"report: {out / 'index.html'}")
    return 0


def _per_sim_second(scenario: Scenario, seconds: Sequence[float]) -> float:
    return float(np.median(seconds)) / float(scenario.time.end - scenario.time.t[0])


def _point_columns(point: Task, repeats: int) -> dict:
    interval = float(point.scenario.time.t[1] - point.scenario.time.t[0])
    return dict(scenario=point.scenario.name, engine=point.engine, variant=point.setting, step_s=point.step,
                steps_per_sample=round(interval / point.step) if np.isfinite(point.step) else np.nan,
                default=point.default, repeats=repeats)


def _timing(scenario: Scenario, m: Measurement, reference_s: float) -> dict:
    per_s = [_per_sim_second(scenario, [r]) for r in m.run_s]
    median = _per_sim_second(scenario, m.run_s)
    return dict(s_per_sim_s=median, s_per_sim_s_min=min(per_s), s_per_sim_s_max=max(per_s),
                vs_reference=median / reference_s if reference_s > 0 else np.nan,
                build_s=float(np.median(m.build_s)), engine_s_per_sim_s=_per_sim_second(scenario, m.engine_s))


def _point_rows(point: Task, repeats: int, done: Done, reference: Signals, reference_s: float) -> list[dict]:
    """One row per signal class (and the headline) of one point."""
    scenario, base = point.scenario, _point_columns(point, repeats)
    tolerance = scenario.tolerance_for(point.engine)
    classes = [c for c in CLASS_ORDER if c == HEADLINE or c in _classes(reference)]
    if done.error:
        return [dict(base, **{"class": c}, error_kind=_kind(tolerance, c), failure=done.error) for c in classes]
    records = compare(reference, done.value.signals, tolerance, scenario.name, point.engine, point.setting)
    errors, failure = class_errors(records, tolerance), failure_of(records)
    timing = _timing(scenario, done.value, reference_s)
    return [dict(base, version=done.value.signals.version, **timing, **{"class": c},
                 error_kind=_kind(tolerance, c), failure=failure, **errors.get(c, {})) for c in classes]


def _classes(signals: Signals) -> set[str]:
    return {SIGNAL_CLASS[c] for c in signals.frame.columns if c != "t"}


def _kind(tolerance: Tolerance, cls: str) -> str:
    if cls == HEADLINE or tolerance.is_relative(cls):
        return "relative"
    return "absolute (rad)" if cls == "angle" else "absolute (m)"


def class_errors(records: pd.DataFrame, tolerance: Tolerance) -> dict[str, dict]:
    """Per class: the largest error among its signals ({error, worst_signal});
    non-finite errors are left out (the point's failure says why), as are
    signals the engine reports as missing with a reason."""
    signals = records[records["class"] != "health"]
    relative = signals["class"].map(lambda c: tolerance.is_relative(c)).to_numpy(dtype=bool)
    value = np.where(relative, signals["relative_error"].to_numpy(dtype=float),
                     signals["max_error"].to_numpy(dtype=float))
    signals = signals.assign(value=value)
    signals = signals[np.isfinite(signals["value"])]
    result = {}
    for cls, group in signals.groupby("class"):
        worst = group.loc[group["value"].idxmax()]
        result[cls] = dict(error=float(worst["value"]), worst_signal=worst["signal"])
    headline = [result[c] for c in ("force", "torque") if c in result]
    if headline:
        result[HEADLINE] = max(headline, key=lambda r: r["error"])
    return result


def failure_of(records: pd.DataFrame) -> str:
    """Why a point's results are unusable ("" if they are usable): values
    that are NaN or inf without a reason, or an assembly-branch flip."""
    problems = []
    signals = records[records["class"] != "health"]
    nonfinite = signals[(signals["max_error"] == np.inf) | (signals["reason"] == "no finite value")]
    health = records.set_index("signal")["max_error"]
    if len(nonfinite) or health.get("health.nonfinite", 0) > 0:
        names = ", ".join(nonfinite["signal"]) or "raw columns"
        problems.append(f"non-finite values ({names})")
    if health.get("health.assembly_flip", 0) > 0:
        problems.append("assembly branch flip")
    return "; ".join(problems)
