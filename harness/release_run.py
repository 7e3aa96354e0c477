"""The engine runs of one release, inside that release's environment
(`mechval.harness.release_envs`): what `mechval matrix` starts there as

    ENV/bin/python -m mechval.harness.release_run ENGINE OUT SCENARIO... [--workers N] [--timeout S]
                                                  [--commit C]

Every scenario × the engine's variants runs through the same worker
isolation as `mechval baseline save` (`runner.run_tasks`, one process per
run, with each signal's sensitivity to its inputs), and each run's signals
are stored as a baseline under OUT (`baseline_store`: %.17g, exact). OUT/
result.json says what ran: the engine's version as imported, the versions
of the libraries beside it, and per run its files or the reason it failed;
an engine that cannot be imported is {"unavailable": REASON}. The parent
reads it back (`read_result`): the comparisons are made there.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import sys
from dataclasses import dataclass
from pathlib import Path

from mechval.engines.registry import EngineUnavailable, adapter
from mechval.records.signals import Signals
from mechval.reports.build import provenance

from . import baseline_store as store
from .baseline_run import run_metadata, sensitive_task
from .plan import prepare
from .preflight import load_scenario, worker_count
from .runner import run_tasks, tasks_for

RESULT = "result.json"
#: Libraries whose versions a release's row shows beside the engine's.
LIBRARIES = ("numpy", "scipy", "pandas")


@dataclass(frozen=True)
class ReleaseRun:
    """One run of a release, read back: its signals (a stored baseline) or
    why there are none."""

    scenario: str
    setting: str
    baseline: store.Baseline | None
    error: str = ""
    wall_time: float = 0.0
    cpu_time: float = 0.0


def run_release(engine: str, out: Path, scenarios: list[str], workers: int, timeout: float,
                commit: str = "") -> dict:
    """Run and store every task; the content of result.json. `commit`: the
    caller's (the installed wheel lies outside any checkout)."""
    try:
        adapter(engine)
    except EngineUnavailable as exc:
        return {"unavailable": str(exc)}
    engine_version = type(adapter(engine)).version()
    plans = [prepare(load_scenario(name), [engine]) for name in scenarios]
    tasks = tasks_for(plans, [engine])
    meta = {**provenance(), **({"commit": commit} if commit else {})}
    runs = []
    for outcome in run_tasks(tasks, workers=worker_count(workers), timeout=timeout, body=sensitive_task):
        task, row = outcome.task, {"scenario": outcome.task.scenario.name, "setting": outcome.task.setting,
                                   "wall_time": outcome.wall_time, "cpu_time": outcome.cpu_time}
        if outcome.signals is None:
            runs.append({**row, "error": outcome.error})
            continue
        path = store.baseline_path(out / "signals", engine, outcome.signals.version, task.scenario.name, task.setting)
        store.save(path, outcome.signals, run_metadata(task, outcome.signals, meta, outcome.sensitivity))
        runs.append({**row, "error": "", "path": str(path.relative_to(out))})
    return {"version": engine_version, "libraries": {name: _version(name) for name in LIBRARIES},
            "python": sys.version.split()[0], "runs": runs}


def _version(distribution: str) -> str:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return "(not installed)"


def read_result(out: Path) -> tuple[dict, list[ReleaseRun]]:
    """result.json and its runs, their signals loaded (a file that cannot
    be read makes that run a failure with the reason)."""
    result = json.loads((Path(out) / RESULT).read_text(encoding="utf-8"))
    runs = []
    for row in result.get("runs", []):
        baseline, error = None, row["error"]
        if not error:
            try:
                baseline = store.load(Path(out) / row["path"])
            except store.CorruptBaseline as exc:
                error = f"its signals cannot be read back: {exc}"
        runs.append(ReleaseRun(row["scenario"], row["setting"], baseline, error, row["wall_time"], row["cpu_time"]))
    return result, runs


def signals_of(run: ReleaseRun) -> Signals | None:
    return None if run.baseline is None else run.baseline.signals


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mechval.harness.release_run")
    parser.add_argument("engine")
    parser.add_argument("out", type=Path)
    parser.add_argument("scenarios", nargs="+")
    parser.add_argument("--workers", type=int, default=0)
    parser.add_argument("--timeout", type=float, default=900.0)
    parser.add_argument("--commit", default="")
    args = parser.parse_args(argv)
    result = run_release(args.engine, args.out, args.scenarios, args.workers, args.timeout, args.commit)
    (args.out / RESULT).write_text(json.dumps(result, indent=2), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
