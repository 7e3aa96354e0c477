"""`mechval matrix ENGINE VERSION... [SCENARIO...]`: the suite run against
several releases of one engine, each in an environment of its own
(`release_envs`), and what each release changed (docs/comparison.md,
"The release matrix").

Per release: its environment is made ready (created once, cached), the
engine runs happen in it (`release_run`, through the usual worker
isolation), and their signals come back here, where each is compared with
the reference (computed once, by this mechval) and with the previous
release that ran it, by the rule of `mechval baseline check`
(`baseline.compare_to_baseline` and `baseline.accuracy_change`). A release
that cannot be installed or imported is a row with the reason. With
`--dask`, each release's job (its environment and its runs) is one task on
the cluster, made ready on the worker that takes it.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from packaging.version import InvalidVersion, Version

from mechval.judging.compare import compare
from mechval.model.scenario import Scenario
from mechval.engines.registry import REFERENCE, UnknownEngine, engine_names
from mechval.scenarios import builtin_path
from mechval.records.signals import Signals
from mechval.reports.build import provenance

from . import baseline as bl
from . import baseline_store as store
from . import release_envs as envs
from .defaults import DASK_CONNECT_TIMEOUT
from .executors import Done, dask_address_problem, executor_for
from .preflight import UsageError, check_out_dir, chosen_scenarios, worker_count
from .release_run import ReleaseRun, read_result
from .runner import references_for

#: The most variants an engine's runs of one scene are counted for when
#: bounding a release's job on Dask (mechval's engines have two).
VARIANTS = 4
#: A cell's change verdicts, by the rule of `baseline check`.
IDENTICAL, WITHIN, CHANGED = "bit-identical", "within", "changed"


@dataclass(frozen=True)
class ScenarioFile:
    """A scenario as the release's job carries it: a built-in by name, any
    other as its file's text (a Dask worker may not have the file)."""

    name: str
    file_name: str = ""
    text: str = ""


@dataclass(frozen=True)
class ReleaseJob:
    """Everything one release's job needs, wherever it runs."""

    engine: str
    release: envs.Release
    envs_dir: str
    wheel: bytes
    digest: str
    scenarios: tuple[ScenarioFile, ...]
    workers: int
    timeout: float
    #: This mechval's commit, recorded with every run.
    commit: str = ""


@dataclass(frozen=True)
class ReleaseResult:
    """What one release gave: its runs, or the reason there are none."""

    version: str
    error: str = ""
    facts: dict = field(default_factory=dict)
    runs: tuple[ReleaseRun, ...] = ()


def parse_items(items: list[str]) -> tuple[list[str], list[str]]:
    """VERSION... [SCENARIO...]: the leading items that start with a digit
    are versions (each a valid release number, PEP 440), the rest scenarios."""
    versions = []
    for item in items:
        if not item[:1].isdigit():
            break
        try:
            Version(item)
        except InvalidVersion:
            raise UsageError(f"version {item!r}: not a release number (e.g. 3.3.7)") from None
        versions.append(item)
    if not versions:
        raise UsageError("name at least one release (e.g. mechval matrix mujoco 3.3.7 4.0.0)")
    if len(set(versions)) != len(versions):
        twice = dict.fromkeys(v for v in versions if versions.count(v) > 1)
        raise UsageError(f"release given twice: {', '.join(twice)}")
    return versions, items[len(versions):]


def release_job(job: ReleaseJob) -> ReleaseResult:
    """Make the release's environment ready and run the suite in it (on
    this machine or a Dask worker); every failure is the result's reason."""
    version = job.release.version
    with tempfile.TemporaryDirectory(prefix="mechval-release-") as tmp:
        wheel = Path(tmp) / "mechval-0-py3-none-any.whl"
        wheel.write_bytes(job.wheel)
        try:
            env = envs.ensure_env(Path(job.envs_dir), job.release, wheel, job.digest)
        except envs.ReleaseUnavailable as exc:
            return ReleaseResult(version, f"not installed: {exc}")
        names = []
        for k, scenario in enumerate(job.scenarios):
            if scenario.text:       # a folder each: two files of one name from two folders stay apart
                path = Path(tmp, "scenarios", str(k), scenario.file_name)
                path.parent.mkdir(parents=True)
                path.write_text(scenario.text, encoding="utf-8")
                names.append(str(path))
            else:
                names.append(scenario.name)
        out = Path(tmp) / "out"
        out.mkdir()
        command = [str(envs.python_of(env)), "-m", "mechval.harness.release_run", job.engine, str(out), *names,
                   "--workers", str(job.workers), "--timeout", str(job.timeout), "--commit", job.commit]
        done = subprocess.run(command, capture_output=True, text=True, env=envs.clean_environ(), cwd=tmp)
        if done.returncode != 0 or not (out / "result.json").exists():
            reason = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
            return ReleaseResult(version, f"the run in its environment failed: {reason}")
        result, runs = read_result(out)
    if "unavailable" in result:
        return ReleaseResult(version, f"not importable: {result['unavailable']}")
    facts = {"imported": result["version"], "python": result["python"], **result["libraries"], "environment": str(env)}
    if Version(result["version"]) != Version(version):     # 4.0 is 4.0.0
        return ReleaseResult(version, f"the environment imports {job.engine} {result['version']}, not {version}", facts)
    return ReleaseResult(version, "", facts, tuple(runs))


def accuracy_rows(result: ReleaseResult, references: dict[str, Signals], scenarios: dict[str, Scenario],
                  engine: str) -> list[dict]:
    """Per run and signal class of a release: the largest relative error
    against the reference (max |error| / peak) and whether every signal of
    the class is within its tolerance."""
    rows = []
    for run in result.runs:
        base = dict(version=result.version, scenario=run.scenario, setting=run.setting)
        if run.baseline is None:
            rows.append(dict(base, **{"class": "(run)"}, error=np.nan, verdict="fail", reason=run.error))
            continue
        scenario = scenarios[run.scenario]
        records = compare(references[run.scenario], run.baseline.signals, scenario.tolerance_for(engine))
        for cls, group in records[records["class"] != "health"].groupby("class", sort=False):
            failed = group[group["verdict"] == "fail"]
            rows.append(dict(base, **{"class": cls}, error=float(group["relative_error"].max()),
                             verdict="fail" if len(failed) else "pass",
                             reason="; ".join(failed["signal"].astype(str))))
    return rows


def change_rows(old: ReleaseResult, new: ReleaseResult, references: dict[str, Signals],
                scenarios: dict[str, Scenario], engine: str, rtol: float) -> list[dict]:
    """Per run that both releases made: the change from `old` to `new` by
    `baseline check`'s rule (threshold from the old run's recorded
    sensitivity), its size (the largest |change| / peak, and where) and the
    accuracy verdict per class (improved, worsened, unchanged)."""
    before = {(r.scenario, r.setting): r for r in old.runs}
    rows = []
    for run in new.runs:
        base = dict(old=old.version, new=new.version, scenario=run.scenario, setting=run.setting)
        previous = before.get((run.scenario, run.setting))
        if previous is None or previous.baseline is None or run.baseline is None:
            why = run.error or (f"{old.version}: {previous.error}" if previous is not None
                                else f"no run in {old.version}")
            rows.append(dict(base, verdict="failed" if run.error else "n/a", reason=why))
            continue
        signals = bl.compare_to_baseline(previous.baseline.signals, run.baseline.signals, rtol,
                                         sensitivity=previous.baseline.sensitivity)
        moved = signals[signals["verdict"] != "identical"]
        verdict = IDENTICAL if moved.empty else CHANGED if bl.regressed(signals) else WITHIN
        size = moved["relative"].astype(float)
        worst = moved.loc[size.idxmax()] if size.notna().any() else None
        accuracy = bl.accuracy_change(references[run.scenario], previous.baseline.signals, run.baseline.signals,
                                      scenarios[run.scenario].tolerance_for(engine))
        rows.append(dict(base, verdict=verdict, size=float(size.max()) if worst is not None else 0.0,
                         signal="" if worst is None else worst["signal"],
                         t=np.nan if worst is None else float(worst["t_max"]),
                         changed_signals=len(moved), signals=len(signals),
                         accuracy=accuracy_summary(accuracy),
                         reason="; ".join(r for r in moved["reason"] if r),
                         **{f"{row['class']}": f"{row['old']:.3g} → {row['new']:.3g} ({row['verdict']})"
                            for _, row in accuracy.iterrows()}))
    return rows


def accuracy_summary(accuracy: pd.DataFrame) -> str:
    """One word for the accuracy verdicts of a run's classes: better,
    worse, mixed, unchanged (or n/a)."""
    verdicts = set(accuracy["verdict"]) - {"n/a"}
    if not verdicts:
        return "n/a"
    if verdicts <= {"unchanged"}:
        return "unchanged"
    if "improved" in verdicts and "worsened" in verdicts:
        return "mixed"
    return "better" if "improved" in verdicts else "worse"


def _scenario_file(scenario: Scenario) -> ScenarioFile:
    source = scenario.source
    if source is None or Path(source).resolve() == builtin_path(scenario.name).resolve():
        return ScenarioFile(scenario.name)
    return ScenarioFile(scenario.name, Path(source).name, Path(source).read_text(encoding="utf-8"))


def matrix_command(engine: str, items: list[str], out: Path | None, envs_dir: Path | None, *, workers: int = 0,
                   timeout: float = 900.0, dask: str | None = None, dask_connect_timeout: float = DASK_CONNECT_TIMEOUT,
                   find_links: list[str] | None = None, rtol: float | None = None) -> int:
    """`mechval matrix`: every refusal before any work, then one job per
    release, the comparisons, the report folder and the summary. Exit
    status 0 when every release ran every run, 1 otherwise."""
    from mechval.reports.matrix_report import summary_markdown, write_matrix_report
    from .preflight import default_out_dir
    if engine == REFERENCE or engine not in engine_names():
        raise UnknownEngine(engine)
    versions, names = parse_items(items)
    problem = "" if dask is None else dask_address_problem(dask)
    if problem:
        raise UsageError(f"--dask {dask!r}: not a Dask scheduler address: {problem}")
    chosen = chosen_scenarios(names or None, skip_hard=True, long=False)
    out = out or default_out_dir("matrix")
    check_out_dir(out)
    envs_dir = (envs_dir or envs.default_envs_dir()).absolute()
    _check_envs_dir(envs_dir)
    requirements = tuple(envs.pinned_requirements() + [r for r in [envs.plugin_requirement(engine)] if r])
    distribution = envs.engine_distribution(engine)
    references = references_for(chosen)
    with tempfile.TemporaryDirectory(prefix="mechval-wheel-") as tmp:
        try:
            wheel = envs.build_wheel(Path(tmp))
        except envs.ReleaseUnavailable as exc:      # e.g. a mechval installed from a wheel: no source to build
            raise UsageError(f"cannot make this mechval installable into the releases' environments: {exc}") from None
        wheel_bytes, digest = wheel.read_bytes(), envs.wheel_digest(wheel)
    jobs = [ReleaseJob(engine, envs.Release(distribution, v, requirements, tuple(find_links or ())),
                       str(envs_dir), wheel_bytes, digest, tuple(_scenario_file(s) for s in chosen),
                       worker_count(workers), timeout, provenance()["commit"]) for v in versions]
    results = run_jobs(jobs, dask, dask_connect_timeout, timeout)
    by_name = {s.name: s for s in chosen}
    accuracy = pd.DataFrame([row for r in results for row in accuracy_rows(r, references, by_name, engine)])
    ran = [r for r in results if not r.error]
    changes = pd.DataFrame([row for old, new in zip(ran, ran[1:])
                            for row in change_rows(old, new, references, by_name, engine, rtol or bl.DEFAULT_RTOL)])
    releases = releases_table(results)
    rule = dict(margin=bl.SENSITIVITY_MARGIN, floor=bl.ABSOLUTE_FLOOR, accuracy_change=bl.ACCURACY_CHANGE)
    write_matrix_report(out, engine, versions, releases, accuracy, changes, envs_dir, rule,
                        lambda folder: store_signals(folder / "signals", results))
    print(summary_markdown(engine, releases, changes))
    print(f"report: {out / 'index.html'}")
    failed = any(r.error for r in results) or any(run.error for r in results for run in r.runs)
    return 1 if failed else 0


def store_signals(root: Path, results: list[ReleaseResult]) -> None:
    """Every run's signals and record under `root`, as baselines of their
    release (DIR/engine/version/scenario/setting.csv and .json)."""
    for result in results:
        for run in result.runs:
            if run.baseline is not None:
                meta = run.baseline.meta
                store.save(store.baseline_path(root, meta["engine"], meta["version"], run.scenario, run.setting),
                           run.baseline.signals, meta)


def releases_table(results: list[ReleaseResult]) -> pd.DataFrame:
    """One row per release: ok or the reason it did not run, its runs and
    failed runs, and what its environment held."""
    return pd.DataFrame([dict(version=r.version, status=r.error or "ok", runs=len(r.runs),
                              failed=sum(1 for run in r.runs if run.error),
                              facts=", ".join(f"{k} {v}" for k, v in r.facts.items())) for r in results],
                        columns=["version", "status", "runs", "failed", "facts"])


def run_jobs(jobs: list[ReleaseJob], dask: str | None, connect_timeout: float, timeout: float) -> list[ReleaseResult]:
    """Each release's job: here, one after the other (each uses every
    worker), or as tasks on the Dask cluster."""
    if dask is None:
        results = []
        for job in jobs:
            print(f"release {job.release.version}: environment and runs …", file=sys.stderr, flush=True)
            results.append(release_job(job))
        return results
    # A release's job installs, then runs every scene at each of the
    # engine's variants (the caller may not import the adapter to count
    # them): it is given pip's time and the runs' at up to VARIANTS each.
    executor = executor_for(dask, 1, envs.INSTALL_TIMEOUT + timeout * VARIANTS * len(jobs[0].scenarios),
                            connect_timeout)
    done: list[Done] = executor.run(release_job, jobs)
    return [d.value if not d.error else ReleaseResult(job.release.version, f"its job failed: {d.error}")
            for job, d in zip(jobs, done)]


def _check_envs_dir(folder: Path) -> None:
    """The environments' folder must be (or become) a writable folder."""
    from .preflight import check_writable
    check_writable(folder, folder)
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"--envs {folder}: not a folder")
