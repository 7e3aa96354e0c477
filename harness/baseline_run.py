"""`mechval baseline save|check`: run engines in worker processes, store
their signals as baselines, or compare a new run with the stored one and say
what changed (the rule itself is `mechval.harness.baseline.compare_to_baseline`).
"""

from __future__ import annotations

import dataclasses
import shlex
import sys
from pathlib import Path
from typing import Any, Mapping

import pandas as pd

from mechval.records.engine_inputs import Feed, InputsNotRecorded
from mechval.engines.registry import adapter_class
from mechval.records.outcome import Outcome, Task
from mechval.reports.build import provenance
from mechval.model.scenario import ScenarioError
from mechval.scenarios import builtin_path
from mechval.records.signals import SIGNAL_CLASS, Signals

from . import baseline as bl
from . import baseline_store as store
from .defaults import Limits
from .plan import prepare
from .preflight import UsageError, check_runs, check_writable, chosen_engines, chosen_scenarios, worker_count
from .runner import references_for, run_tasks, simulate_task, tasks_for
from .simulate import simulate


class BaselinesExist(Exception):
    """`save` without --force found baselines it would overwrite."""


#: Seconds before an engine run is killed (as `mechval run`'s default).
TIMEOUT = 900.0


def save_command(scenarios: list, engines: list[str], root: Path, force: bool, workers: int) -> int:
    """Store a baseline per scenario × engine × variant, with what each run
    was fed and how far its signals move when that moves by an ulp
    (`sensitive_task`); refuse, before running anything, when any of them
    exists and `force` is not given, or lies behind a symbolic link."""
    tasks = tasks_for(scenarios, engines)
    versions = checked_path_names(tasks)
    targets = [store.baseline_path(root, t.engine, versions[t.engine], t.scenario.name, t.setting) for t in tasks]
    for target in targets:
        store.refuse_links(target, root)
        store.remove_stale_temporaries(target.parent)
    existing = [p for p in targets if p.exists() or p.with_suffix(".json").exists()]
    if existing and not force:
        listing = "\n".join(f"  {p}" for p in existing)
        raise BaselinesExist(f"{len(existing)} baseline(s) exist and were left as they are:\n{listing}\n"
                         "regenerate them with the same command plus --force, or name only the "
                         "scenarios/engines that have none")
    meta = provenance()
    failures = 0

    def record(outcome: Outcome) -> None:
        nonlocal failures
        signals, task = outcome.signals, outcome.task
        error = outcome.error
        gaps = signals.unexplained_gaps() if signals is not None else []
        if gaps:
            error = f"non-finite values without a reason ({'; '.join(gaps)})"
        elif signals is not None and signals.version != versions[task.engine]:
            error = f"the worker ran {task.engine} {signals.version}, not {versions[task.engine]}"
        path = None if error else store.baseline_path(root, task.engine, signals.version, task.scenario.name,
                                                      task.setting)
        if path is not None:
            try:
                store.save(path, signals, run_metadata(task, signals, meta, outcome.sensitivity), overwrite=force)
            except (store.BaselineAppeared, store.LinkInside) as exc:
                error = str(exc)
            except OSError as exc:
                error = f"cannot write {exc.filename or path}: {exc.strerror or exc}"
        if error:
            failures += 1
            print(f"FAILED {task.label}: {error} (no baseline written)", file=sys.stderr)
            return
        store.obtained_path(path).unlink(missing_ok=True)      # a regression's new signals, now recorded
        print(f"saved {path}")

    run_tasks(tasks, workers=workers, timeout=TIMEOUT, on_done=record, body=sensitive_task)
    return 1 if failures else 0


#: The input moves of the sensitivity runs, in units in the last place.
NUDGES = (1, -1)


def sensitive_task(task: Task) -> tuple[Signals, float, float, dict[str, float]]:
    """Worker body of `save`: the run (`simulate_task`, which records what
    it was fed), then the same run fed those inputs moved by ±1 ulp, and
    each signal's largest move among them (`baseline.sensitivity`)."""
    signals, wall_time, cpu_time = simulate_task(task)
    moved = [simulate(task.scenario, task.engine, task.overrides, Feed(signals.settings, signals.inputs.nudged(ulps)))
             for ulps in NUDGES] if signals.inputs is not None else []
    return signals, wall_time, cpu_time, bl.sensitivity(signals, moved)


def checked_path_names(tasks: list[Task]) -> dict[str, str]:
    """The installed version per engine, after checking that every scenario
    name and version can be one folder name under --dir (refused before
    anything runs: a name like "../../x" must not write outside it)."""
    for task in tasks:
        try:
            store.checked_name(task.scenario.name, "scenario name")
        except store.UnsafeName as exc:
            raise ScenarioError(task.scenario.source, "name", str(exc)) from None
    versions = {}
    for engine in dict.fromkeys(t.engine for t in tasks):
        versions[engine] = adapter_class(engine).version()
        try:
            store.checked_name(versions[engine], f"{engine} version")
        except store.UnsafeName as exc:
            raise store.UnsafeName(f"the installed {engine} library: {exc}") from None
    return versions


def save_command_line(task: Task, root: Path, force: bool = False) -> str:
    """The command that records this task's baseline (a built-in scenario
    by name, any other by its file)."""
    source = task.scenario.source
    builtin = source is not None and Path(source).resolve() == builtin_path(task.scenario.name).resolve()
    scenario = task.scenario.name if builtin or source is None else str(source)
    words = ["mechval", "baseline", "save", scenario, "--engine", task.engine, "--dir", str(root)]
    return shlex.join(words + (["--force"] if force else []))


def run_metadata(task: Task, signals: Signals, provenance: Mapping[str, str],
                 sensitivity: Mapping[str, float] | None = None) -> dict[str, Any]:
    """`baseline.metadata` of a finished task."""
    return bl.metadata(task.scenario, task.setting, task.overrides, signals, provenance, sensitivity)


def check_run(root: Path, task: Task, signals: Signals, reference: Signals, provenance: Mapping[str, str],
              rtol: float = bl.DEFAULT_RTOL, signal_rtol: Mapping[str, float] | None = None,
              obtained_root: Path | None = None) -> tuple[str, str]:
    """Compare one run with the baseline of the installed engine version:
    (verdict, text to print). The verdict is "ok", "regression", "no
    baseline" (a comparison with the newest other stored version follows
    for information) or "corrupt baseline". On a regression the new signals
    go to SETTING.obtained.csv beside the baseline, or under
    `obtained_root` in the same layout (pytest: its temporary folder); a
    check that passes removes a stale one."""
    name, version = task.scenario.name, signals.version
    versions = store.stored_versions(root, task.engine, name, task.setting)
    if version not in versions:
        lines = [f"{task.label}: no baseline for the installed {task.engine} {version} in {root}"]
        if versions:
            lines.append(f"  for information only, the newest stored version ({task.engine} {versions[-1]}):")
            try:
                other = store.load(store.baseline_path(root, task.engine, versions[-1], name, task.setting))
                lines += ["  " + line for line in _comparison(task, other, signals, reference, provenance, rtol,
                                                               signal_rtol)[0]]
            except store.CorruptBaseline as exc:
                lines.append(f"    unreadable: {exc}")
        lines.append(f"  verdict: NO BASELINE; record it with\n    {save_command_line(task, root)}")
        return "no baseline", "\n".join(lines)
    path = store.baseline_path(root, task.engine, version, name, task.setting)
    try:
        base = store.load(path)
    except store.CorruptBaseline as exc:
        return "corrupt baseline", (f"{task.label}: corrupt baseline {exc}\n"
                                    "  verdict: CORRUPT BASELINE; restore it from version control, or record "
                                    f"it again with\n    {save_command_line(task, root, force=True)}")
    lines, regression = _comparison(task, base, signals, reference, provenance, rtol, signal_rtol)
    lines[0] = f"{task.label}: {lines[0]}"
    lines[2:2] = [f"  note: {note}" for note in derived_now(task)]
    lines.insert(1, "  inputs: " + (
        f"fed the recorded settings and {len(task.feed.reads)} reference read(s), as saved"
        if task.feed is not None else
        f"NOT fed ({feed_of(base, task)[1] or 'the check ran without them'}): derived again on this machine, "
        "whose floating point may move the engine's signals beyond the threshold"))
    obtained = store.obtained_path(store.baseline_path(obtained_root or root, task.engine, version, name, task.setting))
    if not regression:
        obtained.unlink(missing_ok=True)
        return "ok", "\n".join(lines + ["  verdict: OK"])
    try:
        store.refuse_links(obtained, obtained_root or root)
        signals.to_csv(obtained)
        lines.append(f"  new signals written to {obtained} (diff it with the baseline)")
    except store.LinkInside as exc:
        lines.append(f"  new signals not written: {exc}")
    except OSError as exc:      # e.g. a read-only checkout: the verdict stands without the file
        lines.append(f"  new signals not written to {obtained}: {exc.strerror or exc}")
    lines.append(f"  verdict: REGRESSION (if the change is intended, record it: "
                 f"{save_command_line(task, root, force=True)})")
    return "regression", "\n".join(lines)


def _comparison(task: Task, base: store.Baseline, signals: Signals, reference: Signals,
                provenance: Mapping[str, str], rtol: float,
                signal_rtol: Mapping[str, float] | None) -> tuple[list[str], bool]:
    """The lines describing a run against a stored baseline (the first
    names the baseline), and whether a signal regressed."""
    provenance_old = base.meta["provenance"]
    lines = [f"baseline {base.path} ({base.meta['engine']} {base.meta['version']}, "
             f"saved {provenance_old.get('date', '(no date)')}, commit {provenance_old.get('commit', '(none)')})"]
    lines += [f"  note: {change}" for change in
              bl.context_changes(base.meta, run_metadata(task, signals, provenance))]
    rows = bl.compare_to_baseline(base.signals, signals, rtol, signal_rtol, base.sensitivity)
    changed = rows[rows["verdict"] != "identical"]
    if changed.empty:
        lines.append(f"  signals: all {len(rows)} bit-identical")
    else:
        lines.append(f"  signals: {len(rows) - len(changed)} of {len(rows)} bit-identical; changed:")
        lines += ["    " + line for line in _table(changed.drop(columns=["class", "rtol"])).splitlines()]
    accuracy = bl.accuracy_change(reference, base.signals, signals, task.scenario.tolerance_for(task.engine))
    lines.append("  accuracy vs reference, max |error| / peak per class (old → new):")
    lines += ["    " + line for line in _table(accuracy.set_index("class").T, index=True).splitlines()]
    return lines, bl.regressed(rows)


def check_command(scenarios: list, engines: list[str], root: Path, rtol: float | None,
                  signal_rtol: Mapping[str, float], workers: int) -> int:
    """Re-run and compare with the stored baselines (rtol None: the
    default); non-zero exit status on a regression, a run that failed, a
    missing or a corrupt baseline. Each task gets its own verdict."""
    rtol = bl.DEFAULT_RTOL if rtol is None else rtol
    meta = provenance()
    tasks = tasks_for(scenarios, engines)
    versions = checked_path_names(tasks)
    tasks = [fed(root, task, versions[task.engine]) for task in tasks]
    references = references_for(scenarios)
    verdicts: dict[str, int] = {}

    def judge(outcome: Outcome) -> None:
        task = outcome.task
        if outcome.signals is None and outcome.error.startswith(InputsNotRecorded.__name__):
            verdict, text = "inputs changed", (
                f"{task.label}: {outcome.error.partition(': ')[2]}\n  verdict: INPUTS CHANGED (the adapter starts "
                f"its runs differently since the baseline was saved); record it again with\n"
                f"    {save_command_line(task, root, force=True)}")
        elif outcome.signals is None:
            verdict, text = "run failed", f"{task.label}: run failed: {outcome.error}"
        else:
            verdict, text = check_run(root, outcome.task, outcome.signals,
                                      references[outcome.task.scenario.name], meta, rtol, signal_rtol)
        verdicts[verdict] = verdicts.get(verdict, 0) + 1
        print(text + "\n", flush=True)

    run_tasks(tasks, workers=workers, timeout=TIMEOUT, on_done=judge)
    print("baseline check: " + ", ".join(f"{v}: {n}" for v, n in sorted(verdicts.items())))
    return 0 if set(verdicts) <= {"ok"} else 1


def fed(root: Path, task: Task, version: str) -> Task:
    """The task with the feed of its stored baseline (the installed
    version's, `feed_of`), so that the check runs the engine on exactly
    what it was fed then; as it is where there is none."""
    path = store.baseline_path(root, task.engine, version, task.scenario.name, task.setting)
    try:
        feed, _ = feed_of(store.load(path), task)
    except store.CorruptBaseline:
        return task
    return task if feed is None else dataclasses.replace(task, feed=feed)


def derived_now(task: Task) -> list[str]:
    """Where this mechval would derive other settings than the fed ones
    (beyond their last bits, which another machine moves): the check ran
    the recorded ones."""
    if task.feed is None:
        return []
    now = task.settings if task.settings is not None else prepare(task.scenario, [task.engine]).settings(
        task.engine, task.overrides)
    notes = []
    for key in sorted(set(now) | set(task.feed.settings)):
        old, new = task.feed.settings.get(key, "(absent)"), now.get(key, "(absent)")
        same = (old == new or isinstance(old, float) and isinstance(new, float)
                and abs(new - old) <= 1e-12 * max(abs(old), abs(new)))
        if not same:
            notes.append(f"this mechval derives setting {key} = {new} where the baseline recorded {old} "
                         "(the recorded value was fed)")
    return notes


def feed_of(base: store.Baseline, task: Task) -> tuple[Feed | None, str]:
    """The baseline's feed for this task, or None and why it cannot be fed:
    it records no inputs, the scenario changed since (old inputs would not
    fit it), or the adapter no longer takes the recorded settings."""
    feed, why = base.feed()
    if feed is None:
        return None, why
    if base.meta["scenario_hash"] != bl.scenario_hash(task.scenario, task.engine):
        return None, "the scenario changed since the baseline was saved"
    spec = adapter_class(task.engine).settings_spec
    if set(feed.settings) != set(spec):
        added, gone = sorted(set(spec) - set(feed.settings)), sorted(set(feed.settings) - set(spec))
        return None, (f"the adapter's settings changed since (new: {', '.join(added) or 'none'}; "
                      f"gone: {', '.join(gone) or 'none'})")
    for key, value in feed.settings.items():
        try:
            spec[key].parse(value)
        except ValueError as exc:
            return None, f"the recorded setting {key} = {value!r} is refused now ({exc})"
    return feed, ""


def _table(frame: pd.DataFrame, index: bool = False) -> str:
    return frame.to_string(index=index, float_format=lambda v: f"{v:.3g}", na_rep="")


def parse_signal_rtol(items: list[str] | None) -> dict[str, float]:
    """NAME=R pairs of --signal-rtol; NAME is a canonical signal (or t)."""
    result = {}
    for item in items or []:
        name, _, value = item.partition("=")
        if name not in SIGNAL_CLASS and name != "t":
            raise UsageError(f"--signal-rtol {item}: unknown signal {name!r}")
        try:
            result[name] = float(value)
        except ValueError:
            raise UsageError(f"--signal-rtol {item}: expected NAME=NUMBER") from None
        if not 0 <= result[name] < float("inf"):
            raise UsageError(f"--signal-rtol {item}: must be a finite number ≥ 0")
    return result


def baseline_command(action: str, scenarios: list[str] | None, engines: list[str] | None, root: Path, *,
                     force: bool = False, rtol: float | None = None, signal_rtol: list[str] | None = None,
                     workers: int = 0, limits: Limits = Limits()) -> int:
    """`mechval baseline save|check`: the scenarios (default: the built-ins
    not tagged 'hard') planned and checked against the limits before any
    run, then `save_command` or `check_command`."""
    engines = chosen_engines(engines)
    plans = [prepare(s, engines) for s in chosen_scenarios(scenarios, skip_hard=True)]
    check_runs([(t.scenario, t.engine, t.settings) for t in tasks_for(plans, engines)], limits)
    if action == "save":
        check_writable(root, root)
        return save_command(plans, engines, root, force, worker_count(workers))
    return check_command(plans, engines, root, rtol, parse_signal_rtol(signal_rtol), worker_count(workers))
