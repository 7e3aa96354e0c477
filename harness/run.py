"""`mechval run` as a function a script can call (docs/comparison.md,
"mechval run"): plan the runs (settings, limits, output folder; each
scene's peak rates solved by the workers), run the engines and, on the
same workers alongside them, the references, the model audit, the
drawings and the engine findings, compare each run as it arrives, write
the report (stability, findings, audit, and the cost sweep when asked),
and say what it found. The workers are a local pool or, with `dask`, a
Dask cluster's. The command line only parses its arguments into
`run_and_report`.
"""

from __future__ import annotations

import contextlib
import functools
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, ContextManager

import pandas as pd
from tqdm import tqdm

from mechval.judging.compare import passed
from mechval.engines.findings import measure_findings
from mechval.engines.registry import REFERENCE
from mechval.records.outcome import Outcome
from mechval.reports.audit import audit_section
from mechval.reports.build import write_report
from mechval.reports.cost_report import cost_section, write_table
from mechval.reports.findings import findings_section
from mechval.reports.stability import stability_section
from mechval.reports.workers import version_section, version_warnings
from mechval.model.scenario import Scenario, one_line
from mechval.records.signals import Signals

from .audit_run import audit_all
from .cost import cost_sweep, points_for
from .defaults import DASK_CONNECT_TIMEOUT, Limits
from .executors import Done, LocalExecutor, executor_for
from .plan import Plan
from .preflight import (check_dask_address, check_out_dir, check_runs, chosen_engines, chosen_scenarios,
                        default_out_dir, left_out, worker_count)
from .runner import import_engines, joined, outcome_records, prepare_and_run
from .simulate import simulate


def _untimed(name: str):
    return contextlib.nullcontext()


@dataclass(frozen=True)
class RunReport:
    """What `mechval run` did: its scenarios and their references, the
    engine runs' outcomes, their discrepancy records and the report folder
    written."""

    scenarios: list[Scenario]
    references: dict[str, Signals]
    outcomes: list[Outcome]
    records: pd.DataFrame
    folder: Path
    #: Built-ins a run of all of them left out (--skip-hard, no --long).
    left_out: list[str]
    #: CPU time (s) of the work done alongside the engine runs: the
    #: references, the model audit, the findings.
    alongside_cpu_time: float = 0.0

    @property
    def passed(self) -> bool:
        return passed(self.records)


def run_and_report(scenarios: list[str] | None = None, engines: list[str] | None = None, out: Path | None = None,
                   *, workers: int = 0, timeout: float = 900.0, skip_hard: bool = False, long: bool = False,
                   quiet: bool = False, cost: bool = False, limits: Limits = Limits(), dask: str | None = None,
                   dask_connect_timeout: float = DASK_CONNECT_TIMEOUT,
                   phase: Callable[[str], ContextManager] = _untimed) -> RunReport:
    """`mechval run SCENARIO… --engine E… --out OUT`: built-in names or .toml
    paths (None: every built-in, less 'hard' ones with `skip_hard` and
    'long' ones without `long`), engines (None: all installed), the report
    folder (None: a new one under reports/out/), the options of the same
    names (`workers`: --workers; `dask`: --dask, the engine runs and the
    cost sweep on that Dask scheduler's workers, connected to before any
    work). Raises what the command reports as
    errors (`mechval.harness.cli.main`). tests/bench/run_bench.py passes
    `phase` to time each phase."""
    check_dask_address(dask)
    with executor_for(dask, worker_count(workers), timeout, dask_connect_timeout) as executor:
        return _run_and_report(scenarios, engines, out, executor, skip_hard=skip_hard, long=long, quiet=quiet,
                               cost=cost, limits=limits, phase=phase)


def _run_and_report(scenarios, engines, out, executor, *, skip_hard, long, quiet, cost, limits, phase) -> RunReport:
    with phase("load scenarios and engines"):
        chosen = chosen_scenarios(scenarios, skip_hard, long)
        engines = chosen_engines(engines)
    with phase("plan runs: engines, output folder"):
        if isinstance(executor, LocalExecutor):
            import_engines(engines)
        out = out or default_out_dir()
        check_out_dir(out)

    def check(plans: list[Plan], tasks: list) -> None:
        """The limits, once every scene is prepared and before any engine runs."""
        check_runs([(t.scenario, t.engine, t.settings) for t in tasks if not t.refused], limits)
        if cost:
            check_runs([(t.scenario, t.engine, t.settings) for plan in plans for e in engines
                        for t in points_for(plan, e)], limits)

    # One batch on the workers: each scene's preparation (its peak rates and
    # every engine's defaults); as each arrives, the scene's reference, model
    # audit (which builds the models again and simulates nothing) and
    # drawing; the engine findings measured on the installed versions; and,
    # once every scene is prepared and the limits pass, the engine runs.
    # The main job's own work overlaps the engine runs. Each run is compared
    # as it arrives, once its scene's reference has.
    arrived: dict[str, Signals] = {}
    compared: dict[int, pd.DataFrame] = {}                 # id(task) → its records
    waiting: dict[str, list[Outcome]] = {}
    with phase("engine runs"), tqdm(total=None, desc="engine runs", unit="run", file=sys.stderr,
                                    disable=quiet) as bar:
        def done(outcome):
            bar.set_postfix_str(one_line(outcome.task.label, 80) + (" FAILED" if outcome.error else ""),
                                refresh=False)
            bar.update()
            name = outcome.task.scenario.name
            if outcome.signals is None or name in arrived:
                compared[id(outcome.task)] = outcome_records(outcome, arrived.get(name))
            else:
                waiting.setdefault(name, []).append(outcome)

        def scene_done(index, job):
            if not job.error:
                name = chosen[index].name
                arrived[name] = job.value[0][0]
                for outcome in waiting.pop(name, []):
                    compared[id(outcome.task)] = outcome_records(outcome, arrived[name])

        def counted(tasks):
            bar.total = len(tasks)
            bar.refresh()

        batch = prepare_and_run(executor, chosen, engines, check, done, scene_done, counted,
                                functools.partial(measure_findings, engines))
        plans, outcomes, side = batch.plans, batch.outcomes, batch.side
    with phase("comparison"):
        references, audits, findings, drawings, alongside_cpu = _side_results(plans, engines, side)
        alongside_cpu += batch.preparation_cpu
        records = joined([compared[id(o.task)] if id(o.task) in compared
                          else outcome_records(o, references[o.task.scenario.name]) for o in outcomes])
    with phase("report: sections"):
        sections = [version_section(outcomes), stability_section(records, chosen), findings_section(findings),
                    audit_section(audits)]
    sections, files = [s for s in sections if s], None
    if cost:
        with phase("cost sweep"):
            table, orders, cheap = cost_sweep(plans, engines, executor, quick=False, repeats=3, quiet=quiet)
            sections.append(cost_section(table, orders, cheap))
            files = {"cost.csv": lambda path: write_table(table, path)}
    with phase("report: page and files"):
        write_report(out, chosen, references, outcomes, records, sections, files, drawings)
    return RunReport(chosen, references, outcomes, records, out, left_out(scenarios, chosen), alongside_cpu)


def _side_results(plans: list[Plan], engines: list[str], side: list[Done]) -> tuple[dict, list, list, dict, float]:
    """The references, audits, findings and drawings of the linkages (scene
    name → figure) the workers computed alongside
    the engine runs. A job that failed there is done again here, so that
    its error is raised as it would be in one process (a scene refused as
    bad input is exit status 2, not a lost report). And the workers' CPU
    time (s) for them."""
    references, audits, drawings = {}, [], {}
    for plan, done in zip(plans, side):
        if done.error:
            references[plan.scenario.name] = simulate(plan, REFERENCE)
            audits += audit_all([plan], engines)
            continue
        references[plan.scenario.name], audit, drawings[plan.scenario.name] = done.value[0]
        audits += audit
    findings = side[-1].value[0] if not side[-1].error else measure_findings(engines)
    return references, audits, findings, drawings, sum(done.value[1] for done in side if not done.error)


def print_summary(run: RunReport) -> int:
    """What `mechval run` prints once the report is written; its exit status
    (0: every comparison passed, 1: one failed)."""
    print((run.folder / "summary.md").read_text(encoding="utf-8"), end="")
    for warning in version_warnings(run.outcomes):
        print(f"warning: {warning}")
    if run.left_out:
        print(f"left out: {', '.join(run.left_out)} (built-ins tagged 'long', run with --long, or 'hard', left out "
              f"by --skip-hard, or spatial ones tagged 'extra', which an engine cannot meet (docs/engines.md); "
              f"naming a scene runs it)")
    print(f"report: {run.folder / 'index.html'}")
    return 0 if run.passed else 1
