"""`mechval run` as a function a script can call (docs/comparison.md,
"mechval run"): plan the runs (settings, limits, output folder), compute
the references, run the engines, compare, write the report (stability,
engine findings, model audit, and the cost sweep when asked), and say what
it found. The command line only parses its arguments into `run_and_report`.
"""

from __future__ import annotations

import contextlib
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, ContextManager

import pandas as pd
from tqdm import tqdm

from mechval.judging.compare import passed
from mechval.engines.findings import measure_findings
from mechval.records.outcome import Outcome
from mechval.reports.audit import audit_section
from mechval.reports.build import provenance, summary_markdown, write_report
from mechval.reports.cost_report import cost_section, write_table
from mechval.reports.findings import findings_section
from mechval.reports.stability import stability_section
from mechval.reports.workers import version_section, version_warnings
from mechval.model.scenario import Scenario, one_line
from mechval.records.signals import Signals

from .audit_run import audit_all
from .cost import cost_sweep, points_for
from .defaults import DASK_CONNECT_TIMEOUT, Limits
from .executors import executor_for
from .plan import prepare
from .preflight import (check_dask_address, check_out_dir, check_runs, chosen_engines, chosen_scenarios,
                        default_out_dir, left_out, worker_count)
from .runner import discrepancies, references_for, run_tasks, tasks_for


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
    with phase("plan runs: settings, limits"):
        plans = [prepare(s, engines) for s in chosen]       # each scene prepared once for every phase
        tasks = tasks_for(plans, engines)
        check_runs([(t.scenario, t.engine, t.settings) for t in tasks], limits)
        if cost:
            check_runs([(t.scenario, t.engine, t.settings) for plan in plans for e in engines
                        for t in points_for(plan, e)], limits)
        out = out or default_out_dir()
        check_out_dir(out)
    with phase("reference"):
        references = references_for(plans)
    with phase("engine runs"), tqdm(total=len(tasks), desc="engine runs", unit="run", file=sys.stderr,
                                    disable=quiet) as bar:
        def done(outcome):
            bar.set_postfix_str(one_line(outcome.task.label, 80) + (" FAILED" if outcome.error else ""),
                                refresh=False)
            bar.update()
        outcomes = run_tasks(tasks, on_done=done, executor=executor)
    with phase("comparison"):
        records = discrepancies(outcomes, references)
    # The report: stability of the hard cases, the engine findings measured
    # on the installed versions, the model audit (which builds the models
    # again and simulates nothing), then the page and its files.
    with phase("report: stability, findings"):
        sections = [version_section(outcomes), stability_section(records, chosen),
                    findings_section(measure_findings(engines))]
    with phase("report: model audit"):
        sections.append(audit_section(audit_all(plans, engines)))
    sections, files = [s for s in sections if s], None
    if cost:
        with phase("cost sweep"):
            table, orders, cheap = cost_sweep(plans, engines, executor, quick=False, repeats=3, quiet=quiet)
            sections.append(cost_section(table, orders, cheap))
            files = {"cost.csv": lambda path: write_table(table, path)}
    with phase("report: page and files"):
        write_report(out, chosen, references, outcomes, records, sections, files)
    return RunReport(chosen, references, outcomes, records, out, left_out(scenarios, chosen))


def print_summary(run: RunReport) -> int:
    """What `mechval run` prints once the report is written; its exit status
    (0: every comparison passed, 1: one failed)."""
    print(summary_markdown(run.records, run.scenarios, provenance(), run.references))
    for warning in version_warnings(run.outcomes):
        print(f"warning: {warning}")
    if run.left_out:
        print(f"left out: {', '.join(run.left_out)} (built-ins tagged 'long', run with --long, or 'hard', left out "
              f"by --skip-hard; naming a scene runs it)")
    print(f"report: {run.folder / 'index.html'}")
    return 0 if run.passed else 1
