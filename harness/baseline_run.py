"""`mechval baseline save|check`: run engines in worker processes, store
their signals as baselines, or compare a new run with the stored one and say
what changed (the rule itself is `mechval.harness.baseline.compare_to_baseline`).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any, Mapping

import pandas as pd

from mechval.engines.registry import adapter, adapter_class
from mechval.linkages import build_mechanism
from mechval.outcome import Outcome, Task
from mechval.reports.build import provenance
from mechval.signals import Signals

from . import baseline as bl
from .runner import references_for, run_tasks, tasks_for

class BaselinesExist(Exception):
    """`save` without --force found baselines it would overwrite."""


#: Seconds before an engine run is killed (as `mechval run`'s default).
TIMEOUT = 900.0


def save_command(scenarios: list, engines: list[str], root: Path, force: bool, workers: int) -> int:
    """Store a baseline per scenario × engine × variant; refuse, before
    running anything, when any of them exists and `force` is not given."""
    tasks = tasks_for(scenarios, engines)
    targets = [bl.baseline_path(root, t.engine, adapter_class(t.engine).version(), t.scenario.name, t.setting)
               for t in tasks]
    existing = [p for p in targets if p.exists() or p.with_suffix(".json").exists()]
    if existing and not force:
        listing = "\n".join(f"  {p}" for p in existing)
        raise BaselinesExist(f"{len(existing)} baseline(s) exist and were left as they are:\n{listing}\n"
                         "regenerate them with the same command plus --force, or name only the "
                         "scenarios/engines that have none")
    meta = provenance()
    failures = 0

    def store(outcome: Outcome) -> None:
        nonlocal failures
        if outcome.signals is None:
            failures += 1
            print(f"FAILED {outcome.task.label}: {outcome.error} (no baseline written)", file=sys.stderr)
            return
        path = bl.baseline_path(root, outcome.task.engine, outcome.signals.version, outcome.task.scenario.name,
                                outcome.task.setting)
        bl.save(path, outcome.signals, run_metadata(outcome.task, outcome.signals, meta))
        print(f"saved {path}")

    run_tasks(tasks, workers=workers, timeout=TIMEOUT, on_done=store)
    return 1 if failures else 0


def run_metadata(task: Task, signals: Signals, provenance: Mapping[str, str]) -> dict[str, Any]:
    """`baseline.metadata` of a finished task; which recorded settings are
    inputs (not facts of the run) is what the adapter resolves for it."""
    keys = set(adapter(task.engine).settings_for(task.scenario, build_mechanism(task.scenario), task.overrides))
    return bl.metadata(task.scenario, task.setting, task.overrides, signals, keys, provenance)


def check_run(root: Path, task: Task, signals: Signals, reference: Signals, provenance: Mapping[str, str],
              rtol: float = bl.DEFAULT_RTOL, signal_rtol: Mapping[str, float] | None = None) -> tuple[str, str]:
    """Compare one run with its baseline: (verdict, text to print). The
    verdict is "ok", "regression" or "no baseline"."""
    base = bl.find(root, task.engine, signals.version, task.scenario.name, task.setting)
    if base is None:
        return "no baseline", (f"{task.label}: no baseline in {root}; create one with\n"
                               f"  mechval baseline save {task.scenario.name} --engine {task.engine} --dir {root}")
    provenance_old = base.meta["provenance"]
    lines = [f"{task.label}: baseline {base.path} ({base.meta['engine']} {base.meta['version']}, "
             f"saved {provenance_old['date']}, commit {provenance_old['commit']})"]
    lines += [f"  note: {change}" for change in
              bl.context_changes(base.meta, run_metadata(task, signals, provenance))]
    rows = bl.compare_to_baseline(base.signals, signals, rtol, signal_rtol)
    changed = rows[rows["verdict"] != "identical"]
    if changed.empty:
        lines.append(f"  signals: all {len(rows)} bit-identical")
    else:
        lines.append(f"  signals: {len(rows) - len(changed)} of {len(rows)} bit-identical; changed:")
        lines += ["    " + line for line in _table(changed.drop(columns=["class", "rtol"])).splitlines()]
    accuracy = bl.accuracy_change(reference, base.signals, signals, task.scenario.tolerance_for(task.engine))
    lines.append("  accuracy vs reference, max |error| / peak per class (old → new):")
    lines += ["    " + line for line in _table(accuracy.set_index("class").T, index=True).splitlines()]
    if not bl.regressed(rows):
        return "ok", "\n".join(lines + ["  verdict: OK"])
    force = " --force" if base.meta["version"] == signals.version else ""
    lines.append(f"  verdict: REGRESSION (if the change is intended, record it: mechval baseline save "
                 f"{task.scenario.name} --engine {task.engine} --dir {root}{force})")
    return "regression", "\n".join(lines)


def check_command(scenarios: list, engines: list[str], root: Path, rtol: float | None,
                  signal_rtol: Mapping[str, float], workers: int) -> int:
    """Re-run and compare with the stored baselines (rtol None: the
    default); non-zero exit status on a regression, a run that failed or a
    missing baseline."""
    rtol = bl.DEFAULT_RTOL if rtol is None else rtol
    meta = provenance()
    references = references_for(scenarios)
    verdicts: dict[str, int] = {}

    def judge(outcome: Outcome) -> None:
        if outcome.signals is None:
            verdict, text = "run failed", f"{outcome.task.label}: run failed: {outcome.error}"
        else:
            verdict, text = check_run(root, outcome.task, outcome.signals,
                                      references[outcome.task.scenario.name], meta, rtol, signal_rtol)
        verdicts[verdict] = verdicts.get(verdict, 0) + 1
        print(text + "\n", flush=True)

    run_tasks(tasks_for(scenarios, engines), workers=workers, timeout=TIMEOUT, on_done=judge)
    print("baseline check: " + ", ".join(f"{v}: {n}" for v, n in sorted(verdicts.items())))
    return 0 if set(verdicts) <= {"ok"} else 1


def _table(frame: pd.DataFrame, index: bool = False) -> str:
    return frame.to_string(index=index, float_format=lambda v: f"{v:.3g}", na_rep="")
