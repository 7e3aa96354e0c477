"""The `mechval` command line (README.md, "Command line": stable; scripts
outside call it): the arguments parsed, and each command dispatched to the
module that does its work, imported only when that command runs (so that
`mechval list` imports nothing heavy, harness/listing.py):

    list      harness/listing.py      list_command
    simulate  harness/simulate.py     simulate_command
    run       harness/run.py          run_and_report, print_summary
    cost      harness/cost.py         cost_command
    baseline  harness/baseline_run.py baseline_command
    audit     harness/audit_run.py    audit_command
    matrix    harness/matrix.py       matrix_command
    analyse   mechval.reference.analysis; export: mechval.scenarios.export
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from mechval.engines.registry import EngineUnavailable, UnknownEngine, engine_names

from .defaults import DASK_CONNECT_TIMEOUT, DEFAULT_MAX_MEMORY, DEFAULT_MAX_STEPS, Limits
from .interrupts import Interrupted, stop_on_signals
from .listing import one_line


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


def _limits(args) -> Limits:
    return Limits(args.max_steps, args.max_memory * 2**30)


def cmd_list(args) -> int:
    from .listing import list_command
    return list_command()


def cmd_simulate(args) -> int:
    from .simulate import simulate_command
    return simulate_command(args.scenario, args.engine, args.csv, _limits(args))


def cmd_run(args) -> int:
    from .run import print_summary, run_and_report
    return print_summary(run_and_report(**run_options(args)))


def run_options(args) -> dict:
    """`run_and_report`'s arguments from `mechval run`'s."""
    return dict(scenarios=args.scenarios, engines=args.engine, out=args.out, workers=args.workers,
                timeout=args.timeout, skip_hard=args.skip_hard, long=args.long, quiet=args.quiet, cost=args.cost,
                limits=_limits(args), dask=args.dask, dask_connect_timeout=args.dask_connect_timeout)


def cmd_cost(args) -> int:
    from .cost import cost_command
    return cost_command(args.scenarios, args.engine, args.out, dask=args.dask,
                        dask_connect_timeout=args.dask_connect_timeout, workers=args.workers, timeout=args.timeout,
                        quick=args.quick, repeats=args.repeats, quiet=args.quiet, limits=_limits(args))


def cmd_baseline(args) -> int:
    from .baseline_run import baseline_command
    check = args.action == "check"
    return baseline_command(args.action, args.scenarios, args.engine, args.dir, force=getattr(args, "force", False),
                            rtol=args.rtol if check else None, signal_rtol=args.signal_rtol if check else None,
                            workers=args.workers, limits=_limits(args))


def cmd_matrix(args) -> int:
    from .matrix import matrix_command
    return matrix_command(args.engine, args.items, args.out, args.envs, workers=args.workers, timeout=args.timeout,
                          dask=args.dask, dask_connect_timeout=args.dask_connect_timeout, find_links=args.find_links,
                          rtol=args.rtol)


def cmd_audit(args) -> int:
    from .audit_run import audit_command
    return audit_command(args.scenario, args.engine)


def cmd_analyse(args) -> int:
    from mechval.reference.analysis import analyse, format_analysis
    from .preflight import load_scenario
    print(format_analysis(analyse(load_scenario(args.scenario))))
    return 0


def cmd_export(args) -> int:
    from mechval.scenarios.export import planar_file
    from .preflight import load_scenario
    sys.stdout.write(planar_file(load_scenario(args.scenario)))
    return 0


def _add_limits(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--max-steps", type=_positive_int, default=DEFAULT_MAX_STEPS, metavar="N",
                        help=f"refuse an engine run of more steps (default {DEFAULT_MAX_STEPS:.0e}; README: Limits)")
    parser.add_argument("--max-memory", type=_positive, default=DEFAULT_MAX_MEMORY / 2**30, metavar="GIB",
                        help=f"refuse an engine run estimated to need more GiB (default: 3/4 of this machine, {DEFAULT_MAX_MEMORY / 2**30:.3g})")


def _add_dask(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--dask", metavar="ADDRESS",
                        help=f"run {what} on the Dask scheduler at ADDRESS (tcp://HOST:PORT) instead of locally")
    parser.add_argument("--dask-connect-timeout", type=_positive, default=DASK_CONNECT_TIMEOUT, metavar="SECONDS",
                        help=f"seconds to wait for the Dask scheduler to answer (default {DASK_CONNECT_TIMEOUT:g})")


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
    _add_dask(p, "the engine runs")
    _add_limits(p)
    p.set_defaults(func=cmd_run)
    p = sub.add_parser("cost", help="work-precision sweep: error against wall time per engine setting")
    p.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="built-in names or .toml paths")
    p.add_argument("--engine", action="append", help="engine to sweep (repeatable; default: all installed)")
    p.add_argument("--out", type=Path, help="report folder (default: a new folder under reports/out/)")
    _add_dask(p, "the points")
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
    p = sub.add_parser("matrix", usage="mechval matrix ENGINE VERSION... [SCENARIO...] [options]", help="the suite against several releases of one engine, each in its own "
                                      "environment, and what each release changed")
    p.add_argument("engine", metavar="ENGINE")
    p.add_argument("items", nargs="+", metavar="VERSION|SCENARIO",
                   help="releases (oldest first), then built-in names or .toml paths (default: the built-ins "
                        "not tagged 'hard' or 'long')")
    p.add_argument("--out", type=Path, help="report folder (default: a new folder under reports/out/)")
    p.add_argument("--envs", type=Path, metavar="DIR",
                   help="where the releases' environments are kept (default: ~/.cache/mechval/envs)")
    p.add_argument("--find-links", action="append", metavar="DIR_OR_URL",
                   help="also look for the releases there (pip --find-links; repeatable)")
    p.add_argument("--rtol", type=_positive, help="max |change| / peak counted as within (default 1e-9)")
    p.add_argument("--workers", type=_count, default=0, help="worker processes per release (default: one per core)")
    p.add_argument("--timeout", type=_positive, default=900.0, help="seconds before an engine run is killed")
    p.add_argument("--dask", metavar="ADDRESS", help="run each release's job on the Dask scheduler at ADDRESS")
    p.add_argument("--dask-connect-timeout", type=_positive, default=DASK_CONNECT_TIMEOUT, metavar="SECONDS",
                   help=f"seconds to wait for the Dask scheduler to answer (default {DASK_CONNECT_TIMEOUT:g})")
    p.set_defaults(func=cmd_matrix)
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


def _error(exc: Exception) -> tuple[int, str] | None:
    """The exit status and message of an error the command reports on one
    line (None: a bug, shown with its traceback). Their modules are
    imported here, not before: a command imports what it uses."""
    from mechval.model.scenario import ScenarioError
    from .baseline_store import LinkInside, UnsafeName
    from .baseline_run import BaselinesExist
    from .executors import SchedulerUnreachable
    from .preflight import EngineFailure, UsageError
    if isinstance(exc, (ScenarioError, UnknownEngine, UsageError, BaselinesExist, UnsafeName, LinkInside,
                        SchedulerUnreachable)):
        return (3 if isinstance(exc, SchedulerUnreachable) else 2), f"mechval: error: {exc}"
    if isinstance(exc, EngineUnavailable):
        return 3, f"mechval: engine unavailable: {exc}"
    if isinstance(exc, EngineFailure):
        return 1, f"mechval: engine failed: {exc}"
    return None


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    _registry_warnings()
    try:
        with stop_on_signals():
            return args.func(args)
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
    except Exception as exc:
        known = _error(exc)
        if known is None:
            raise
        status, message = known
        print(message, file=sys.stderr)
        return status


if __name__ == "__main__":
    sys.exit(main())
