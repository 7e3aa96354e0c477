"""The `mechval` command line (README.md, "Command line": stable; scripts outside call it)."""

from __future__ import annotations

import argparse
import contextlib
import datetime
import os
import sys
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, ContextManager

import pandas as pd
from tqdm import tqdm

from mechval.reference.analysis import analyse, format_analysis
from mechval.records.audit import format_audit
from mechval.judging.compare import passed
from mechval.judging.cost_tables import cheapest, convergence, format_tables
from mechval.engines.findings import measure_findings
from mechval.engines.registry import REFERENCE, EngineUnavailable, UnknownEngine, adapter, availability, engine_names
from mechval.reports.build import provenance, summary_markdown, write_report
from mechval.reports.cost_report import cost_section, write_cost_report, write_table
from mechval.reports.audit import audit_section
from mechval.reports.findings import findings_section
from mechval.reports.stability import stability_section
from mechval.records.outcome import Outcome
from mechval.records.outputs import not_a_regular_file
from mechval.model.scenario import Scenario, ScenarioError, one_line
from mechval.scenarios import builtin_names, builtin_path, load
from mechval.scenarios.export import planar_file
from mechval.records.signals import SIGNAL_CLASS, Signals

from .audit_run import audit_all, audit_scenario
from .baseline import LinkInside, UnsafeName
from .baseline_run import BaselinesExist, check_command, save_command
from .cost import points_for, sweep
from .plan import prepare
from .executors import DASK_CONNECT_TIMEOUT, LocalExecutor, SchedulerUnreachable, dask_address_problem, executor_for
from .interrupts import Interrupted, stop_on_signals
from .listing import scenario_header
from .runner import discrepancies, references_for, run_tasks, tasks_for
from .simulate import simulate
from .run_limits import DEFAULT_MAX_MEMORY, DEFAULT_MAX_STEPS, Limits, check_run


class UsageError(Exception):
    """A user error reported as one line, exit status 2."""


def _count(text: str) -> int:
    """argparse type: a whole number ≥ 0."""
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {value}")
    return value


def _positive(text: str) -> float:
    """argparse type: a finite number > 0."""
    value = float(text)
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
    return value


def _positive_int(text: str) -> int:
    """argparse type: a whole number ≥ 1."""
    value = _count(text)
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1")
    return value


class EngineFailure(Exception):
    """An engine run that produced no usable result, exit status 1."""


def _load(name: str):
    """A scenario whose [engines.NAME] tables must name registered engines."""
    return load(name, engine_names())


def _limits(args) -> Limits:
    return Limits(args.max_steps, args.max_memory * 2**30)


def _check_runs(runs, limits: Limits) -> None:
    """Refuse, before any work, every (scenario, engine, settings) over the
    step or memory limit (mechval.harness.run_limits.check_run); the
    settings are those the run's plan resolved."""
    for scenario, engine, settings in runs:
        check_run(scenario, engine, limits=limits, settings=settings)


def _check_writable(folder: Path, what: Path) -> None:
    """Refuse, before any work, to run when `what` could not be written into
    `folder` (or into the folder it would be created in)."""
    existing = folder.absolute()
    while not os.path.lexists(existing) and existing != existing.parent:
        existing = existing.parent
    try:
        os.stat(existing)       # a symlink that loops or leads nowhere: refused now, not after the engines ran
        if not existing.is_dir():
            raise NotADirectoryError(20, "not a folder", str(existing))
        with tempfile.TemporaryFile(dir=existing):      # a real try: permissions, read-only file systems
            pass
    except OSError as exc:
        raise UsageError(f"cannot write {what}: {existing}: {exc.strerror or exc}") from None


def _check_out_dir(out: Path) -> None:
    """A report folder must not exist yet and its parent must take it."""
    if os.path.lexists(out):
        raise UsageError(f"{out} exists; choose another --out or remove it")
    _check_writable(out.parent, out)


def _check_csv(csv: Path) -> None:
    """A CSV is written by renaming over its path: refuse a path that is
    not a regular file (a device, a FIFO, a symlink, a folder) rather than
    replace it, and a folder that would not take it."""
    _check_writable(csv.parent, csv)
    kind = not_a_regular_file(csv)
    if kind:
        raise UsageError(f"cannot write {csv}: it is {kind}, and mechval replaces only regular files")


def cmd_list(args) -> int:
    """The built-in scenarios from their files' headers (name, kind, tags,
    description), read without building or solving anything (a scene is
    checked when it is loaded to run), and the engines found."""
    print("scenarios:")
    for name in builtin_names():
        s = scenario_header(builtin_path(name))
        tags = f" [{', '.join(s.tags)}]" if s.tags else ""
        print(one_line(f"  {name:<28} {s.mechanism:<13}{tags} {s.description}"))
    print("engines:")
    print(f"  {'reference':<12} available (analytic)")
    for engine, reason in availability().items():
        print(f"  {engine:<12} {'available' if not reason else 'unavailable: ' + reason}")
    return 0


def cmd_simulate(args) -> int:
    scenario = _load(args.scenario)
    _check_csv(args.csv)
    plan = prepare(scenario, [args.engine])
    settings = plan.settings(args.engine)
    _check_runs([(scenario, args.engine, settings)], _limits(args))
    try:
        signals = simulate(plan, args.engine, settings=settings)
    except (ScenarioError, EngineUnavailable, UnknownEngine, KeyboardInterrupt):
        raise
    except Exception as exc:    # the engine's own failure (a solver that gives up): one line, exit 1
        raise EngineFailure(f"{args.engine} on {scenario.source or scenario.name}: {type(exc).__name__}: "
                            f"{one_line(str(exc))}; nothing written to {args.csv}") from None
    unexplained = signals.unexplained_gaps()
    if unexplained:
        # An engine that blew up must not leave a CSV that looks like data.
        raise EngineFailure(f"{args.engine} returned non-finite values without a reason "
                            f"({'; '.join(unexplained)}); nothing written to {args.csv}")
    signals.to_csv(args.csv)
    for name, reason in signals.missing.items():
        print(f"note: {name}: missing values ({reason})", file=sys.stderr)
    print(f"wrote {args.csv}: {len(signals.frame)} samples × {signals.frame.shape[1]} columns "
          f"({args.engine} {signals.version})")
    return 0


def _engines(names: list[str] | None) -> list[str]:
    """The requested engines (all installed ones by default); a requested
    engine that is not installed is an error, an unrequested one is skipped
    with its reason."""
    if names and REFERENCE in names:
        raise UsageError("'reference' is the analytic solution every engine is compared with, not an engine "
                         "to run here (use it with `mechval simulate`)")
    if names:
        for name in names:
            adapter(name)       # raises UnknownEngine / EngineUnavailable
        return list(dict.fromkeys(names))
    engines = []
    for name, reason in availability().items():
        if reason:
            print(f"note: skipping {reason}", file=sys.stderr)
        else:
            engines.append(name)
    return engines


#: The tag of built-ins that a run of all built-ins leaves out unless asked
#: (`mechval run --long`): scenes whose engine runs alone would take most
#: of the main job's minute (fourbar-long-run: 509 revolutions, about 85 s
#: of engine CPU time, tests/bench/run_bench.py).
LONG = "long"


def _scenarios(names: list[str] | None, skip_hard: bool, long: bool = True):
    if names:
        return [_load(n) for n in names]
    loaded = [_load(n) for n in builtin_names()]
    return [s for s in loaded if not (skip_hard and "hard" in s.tags) and (long or LONG not in s.tags)]


def _left_out(names: list[str] | None, scenarios: list[Scenario]) -> list[str]:
    """The built-ins a run of all built-ins left out."""
    ran = {s.name for s in scenarios}
    return [] if names else [n for n in builtin_names() if n not in ran]


def default_out_dir(kind: str = "run") -> Path:
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path("reports") / "out" / f"{kind}-{stamp}"


def _workers(args) -> int:
    return args.workers or os.cpu_count() or 1


def _cost_sweep(scenarios, engines, executor, quick: bool, repeats: int, quiet: bool):
    """The cost table, observed orders and cheapest settings (mechval.harness.cost)."""
    with tqdm(desc="cost points", unit="point", file=sys.stderr, disable=quiet) as bar:
        def done(point, outcome):
            bar.set_postfix_str(f"{point.engine} {point.variant} dt {point.step:.3g}"
                                + (" FAILED" if outcome.error else ""), refresh=False)
            bar.update()
        table = sweep(scenarios, engines, executor, quick=quick, repeats=repeats, on_done=done)
    return table, convergence(table), cheapest(table)


def cmd_cost(args) -> int:
    if args.repeats < 1:
        raise UsageError("--repeats must be at least 1")
    problem = "" if args.dask is None else dask_address_problem(args.dask)
    if problem:
        raise UsageError(f"--dask {args.dask!r}: not a Dask scheduler address: {problem}")
    scenarios = [_load(name) for name in args.scenarios]
    engines = _engines(args.engine)
    plans = [prepare(s, engines) for s in scenarios]
    _check_runs([(p.scenario, p.engine, p.settings) for plan in plans for e in engines
                 for p in points_for(plan, e, args.quick)], _limits(args))
    out = args.out or default_out_dir("cost")
    _check_out_dir(out)
    executor = executor_for(args.dask, _workers(args), args.timeout, args.dask_connect_timeout)
    table, orders, cheap = _cost_sweep(plans, engines, executor, args.quick, args.repeats, args.quiet)
    write_cost_report(out, table, orders, cheap)
    print(format_tables(table, orders, cheap))
    print(f"report: {out / 'index.html'}")
    return 0


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


def run_and_report(args, phase: Callable[[str], ContextManager] = _untimed) -> RunReport:
    """`mechval run`'s work, phase by phase (tests/bench/run_bench.py passes
    `phase` to time each one)."""
    with phase("load scenarios and engines"):
        scenarios = _scenarios(args.scenarios, args.skip_hard, args.long)
        engines = _engines(args.engine)
    with phase("plan runs: settings, limits"):
        plans = [prepare(s, engines) for s in scenarios]       # each scene prepared once for every phase
        tasks = tasks_for(plans, engines)
        _check_runs([(t.scenario, t.engine, t.settings) for t in tasks], _limits(args))
        if args.cost:
            _check_runs([(p.scenario, p.engine, p.settings) for plan in plans for e in engines
                         for p in points_for(plan, e)], _limits(args))
        out = args.out or default_out_dir()
        _check_out_dir(out)
    with phase("reference"):
        references = references_for(plans)
    with phase("engine runs"), tqdm(total=len(tasks), desc="engine runs", unit="run", file=sys.stderr,
                                    disable=args.quiet) as bar:
        def done(outcome):
            bar.set_postfix_str(one_line(outcome.task.label, 80) + (" FAILED" if outcome.error else ""),
                                refresh=False)
            bar.update()
        outcomes = run_tasks(tasks, workers=_workers(args), timeout=args.timeout, on_done=done)
    with phase("comparison"):
        records = discrepancies(outcomes, references)
    # The report: stability of the hard cases, the engine findings measured
    # on the installed versions, the model audit (which builds the models
    # again and simulates nothing), then the page and its files.
    with phase("report: stability, findings"):
        sections = [stability_section(records, scenarios), findings_section(measure_findings(engines))]
    with phase("report: model audit"):
        sections.append(audit_section(audit_all(plans, engines)))
    sections, files = [s for s in sections if s], None
    if args.cost:
        with phase("cost sweep"):
            table, orders, cheap = _cost_sweep(plans, engines, LocalExecutor(_workers(args), args.timeout),
                                               quick=False, repeats=3, quiet=args.quiet)
            sections.append(cost_section(table, orders, cheap))
            files = {"cost.csv": lambda path: write_table(table, path)}
    with phase("report: page and files"):
        write_report(out, scenarios, references, outcomes, records, sections, files)
    return RunReport(scenarios, references, outcomes, records, out, _left_out(args.scenarios, scenarios))


def cmd_run(args) -> int:
    run = run_and_report(args)
    print(summary_markdown(run.records, run.scenarios, provenance(), run.references))
    if run.left_out:
        print(f"left out: {', '.join(run.left_out)} (built-ins tagged 'long', run with --long, or 'hard', left out "
              f"by --skip-hard; naming a scene runs it)")
    print(f"report: {run.folder / 'index.html'}")
    return 0 if passed(run.records) else 1


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



def cmd_baseline(args) -> int:
    engines = _engines(args.engine)
    plans = [prepare(s, engines) for s in _scenarios(args.scenarios, skip_hard=True)]
    _check_runs([(t.scenario, t.engine, t.settings) for t in tasks_for(plans, engines)], _limits(args))
    if args.action == "save":
        _check_writable(args.dir, args.dir)
        return save_command(plans, engines, args.dir, args.force, _workers(args))
    return check_command(plans, engines, args.dir, args.rtol, parse_signal_rtol(args.signal_rtol),
                         _workers(args))


def cmd_audit(args) -> int:
    scenario = _load(args.scenario)
    engines = _engines(args.engine)
    plan = prepare(scenario, engines)
    status = 0
    for engine in engines:
        result = audit_scenario(plan, engine)
        verdict = result.error or (f"{result.failing} rows differ" if result.failing else "the model is the scene")
        print(f"== {scenario.name} × {engine}: {verdict}")
        if result.table is not None:
            print(format_audit(result.table))
        status = status or int(not result.ok)
    return status


def cmd_analyse(args) -> int:
    print(format_analysis(analyse(_load(args.scenario))))
    return 0


def cmd_export(args) -> int:
    sys.stdout.write(planar_file(_load(args.scenario)))
    return 0


def _add_limits(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--max-steps", type=_positive_int, default=DEFAULT_MAX_STEPS, metavar="N",
                        help=f"refuse an engine run of more steps (default {DEFAULT_MAX_STEPS:.0e}; README: Limits)")
    parser.add_argument("--max-memory", type=_positive, default=DEFAULT_MAX_MEMORY / 2**30, metavar="GIB",
                        help=f"refuse an engine run estimated to need more GiB (default: 3/4 of this machine, {DEFAULT_MAX_MEMORY / 2**30:.3g})")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mechval", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="scenarios and engines found").set_defaults(func=cmd_list)
    p = sub.add_parser("simulate", help="canonical signals at the scenario's samples")
    p.add_argument("scenario", help="built-in scenario name or path to a .toml file")
    p.add_argument("--engine", default="reference", help="reference|mujoco|pybullet|exudyn")
    p.add_argument("--csv", required=True, type=Path, help="output CSV file")
    _add_limits(p)
    p.set_defaults(func=cmd_simulate)
    p = sub.add_parser("run", help="compare engines with the reference and write the report")
    p.add_argument("scenarios", nargs="*", metavar="SCENARIO", help="built-in names or .toml paths (default: all)")
    p.add_argument("--engine", action="append", help="engine to run (repeatable; default: all installed)")
    p.add_argument("--out", type=Path, help="report folder (default: a new folder under reports/out/)")
    p.add_argument("--workers", type=_count, default=0, help="worker processes (default: one per core)")
    p.add_argument("--timeout", type=_positive, default=900.0, help="seconds before an engine run is killed")
    p.add_argument("--skip-hard", action="store_true",
                   help="leave out the built-in scenarios tagged 'hard' (long runs, singular neighbourhoods)")
    p.add_argument("--long", action="store_true",
                   help="also run the built-ins tagged 'long' (fourbar-long-run: 509 revolutions, about a minute "
                        "and a half of engine CPU time), which a run of all built-ins leaves out by default")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--cost", action="store_true", help="add the work-precision sweep (as `mechval cost`; slow)")
    _add_limits(p)
    p.set_defaults(func=cmd_run)
    p = sub.add_parser("cost", help="work-precision sweep: error against wall time per engine setting")
    p.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="built-in names or .toml paths")
    p.add_argument("--engine", action="append", help="engine to sweep (repeatable; default: all installed)")
    p.add_argument("--out", type=Path, help="report folder (default: a new folder under reports/out/)")
    p.add_argument("--dask", metavar="ADDRESS",
                   help="run the points on the Dask scheduler at ADDRESS (tcp://HOST:PORT) instead of locally")
    p.add_argument("--dask-connect-timeout", type=_positive, default=DASK_CONNECT_TIMEOUT, metavar="SECONDS",
                   help=f"seconds to wait for the Dask scheduler to answer (default {DASK_CONNECT_TIMEOUT:g})")
    p.add_argument("--repeats", type=_positive_int, default=3, help="timed runs per point (median; default 3)")
    p.add_argument("--quick", action="store_true", help="two points per engine: the default step and ~10x coarser")
    p.add_argument("--workers", type=_count, default=0, help="local worker processes (default: one per core)")
    p.add_argument("--timeout", type=_positive, default=900.0, help="seconds before a point is given up")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_limits(p)
    p.set_defaults(func=cmd_cost)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("scenarios", nargs="*", metavar="SCENARIO",
                        help="built-in names or .toml paths (default: all not tagged 'hard')")
    common.add_argument("--engine", action="append", help="engine (repeatable; default: all installed)")
    common.add_argument("--dir", required=True, type=Path, help="baseline folder, e.g. baselines/")
    common.add_argument("--workers", type=_count, default=0, help="worker processes (default: one per core)")
    _add_limits(common)
    p = sub.add_parser("baseline", help="engine regression checks against stored signals per engine version")
    actions = p.add_subparsers(dest="action", required=True)
    q = actions.add_parser("save", parents=[common], help="store baselines (never overwrites without --force)")
    q.add_argument("--force", action="store_true", help="overwrite existing baselines")
    q = actions.add_parser("check", parents=[common], help="re-run and compare with the stored baselines")
    q.add_argument("--rtol", type=_positive, help="max |change| / peak of a signal (default 1e-9)")
    q.add_argument("--signal-rtol", action="append", metavar="NAME=R", help="per-signal rtol (repeatable)")
    p.set_defaults(func=cmd_baseline)
    p = sub.add_parser("audit", help="read back what each engine's model holds and compare it with the scene")
    p.add_argument("scenario", help="built-in scenario name or path to a .toml file")
    p.add_argument("--engine", action="append", help="engine to audit (repeatable; default: all installed)")
    p.set_defaults(func=cmd_audit)
    p = sub.add_parser("analyse", help="engineering analysis: Grashof, transmission angle, toggles")
    p.add_argument("scenario")
    p.set_defaults(func=cmd_analyse)
    p = sub.add_parser("export", help="print the scenario's scene as a planar file (TOML)")
    p.add_argument("scenario")
    p.set_defaults(func=cmd_export)
    return parser


def _registry_warnings() -> None:
    """Read the engine registry once, saying on one line each engine name
    two installed distributions register and which one is used."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        engine_names()
    for warning in said:
        print(one_line(f"mechval: warning: {warning.message}"), file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    _registry_warnings()
    try:
        with stop_on_signals():
            return args.func(args)
    except (ScenarioError, UnknownEngine, UsageError, BaselinesExist, UnsafeName, LinkInside) as exc:
        print(f"mechval: error: {exc}", file=sys.stderr)
        return 2
    except EngineUnavailable as exc:
        print(f"mechval: engine unavailable: {exc}", file=sys.stderr)
        return 3
    except SchedulerUnreachable as exc:
        print(f"mechval: error: {exc}", file=sys.stderr)
        return 3
    except EngineFailure as exc:
        print(f"mechval: engine failed: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:         # output piped into `head` and the like
        sys.stderr.close()
        return 0
    except OSError as exc:          # e.g. an output path that is a folder
        where = f"cannot write {exc.filename}: " if exc.filename else ""
        print(f"mechval: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except Interrupted as exc:      # the workers are stopped, no folder is left
        print(f"mechval: stopped by {exc}", file=sys.stderr)
        return exc.exit_status
    except KeyboardInterrupt:
        print("mechval: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
