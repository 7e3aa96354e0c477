"""What a command works on and whether it may start, settled before any
engine work: the scenarios and engines chosen, the run limits, and the
output paths (one line naming what is wrong, exit status 2)."""

from __future__ import annotations

import datetime
import os
import sys
import tempfile
from pathlib import Path
from typing import Any, Iterable, Mapping

from mechval.engines.registry import REFERENCE, adapter, availability, engine_names
from mechval.records.outputs import not_a_regular_file
from mechval.model.scenario import Scenario
from mechval.scenarios import builtin_names, default_run_names, load
from mechval.scenarios.loader import spatial_builtin_names

from .defaults import Limits
from .run_limits import check_run


class UsageError(Exception):
    """A user error reported as one line, exit status 2."""


class EngineFailure(Exception):
    """An engine run that produced no usable result, exit status 1."""


#: The tag of built-ins that a run of all built-ins leaves out unless asked
#: (`mechval run --long`): scenes whose engine runs alone would take most
#: of the main job's minute (fourbar-long-run: 509 revolutions, about 85 s
#: of engine CPU time, tests/bench/run_bench.py).
LONG = "long"


def load_scenario(name: str) -> Scenario:
    """A scenario whose [engines.NAME] tables must name registered engines."""
    return load(name, engine_names())


def chosen_engines(names: list[str] | None) -> list[str]:
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


def chosen_scenarios(names: list[str] | None, skip_hard: bool, long: bool = True) -> list[Scenario]:
    if names:
        return [load_scenario(n) for n in names]
    loaded = [load_scenario(n) for n in default_run_names()]
    return [s for s in loaded if not (skip_hard and "hard" in s.tags) and (long or LONG not in s.tags)]


def left_out(names: list[str] | None, scenarios: list[Scenario]) -> list[str]:
    """The built-ins a run of all built-ins left out."""
    ran = {s.name for s in scenarios}
    every = builtin_names() + spatial_builtin_names()
    return [] if names else [n for n in every if n.rpartition("/")[2] not in ran]


def default_out_dir(kind: str = "run") -> Path:
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path("reports") / "out" / f"{kind}-{stamp}"


def check_dask_address(address: str | None) -> None:
    """--dask ADDRESS refused, before any work, unless it is a Dask
    scheduler's address (None: no cluster asked for)."""
    from .executors import dask_address_problem
    problem = "" if address is None else dask_address_problem(address)
    if problem:
        raise UsageError(f"--dask {address!r}: not a Dask scheduler address: {problem}")


def worker_count(count: int) -> int:
    """Worker processes: `count`, or one per core when 0."""
    return count or os.cpu_count() or 1


def check_runs(runs: Iterable[tuple[Scenario, str, Mapping[str, Any] | None]], limits: Limits) -> None:
    """Refuse, before any work, every (scenario, engine, settings) over the
    step or memory limit (mechval.harness.run_limits.check_run); the
    settings are those the run's plan resolved."""
    for scenario, engine, settings in runs:
        check_run(scenario, engine, limits=limits, settings=settings)


def check_writable(folder: Path, what: Path) -> None:
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


def check_out_dir(out: Path) -> None:
    """A report folder must not exist yet and its parent must take it."""
    if os.path.lexists(out):
        raise UsageError(f"{out} exists; choose another --out or remove it")
    check_writable(out.parent, out)


def check_csv(csv: Path) -> None:
    """A CSV is written by renaming over its path: refuse a path that is
    not a regular file (a device, a FIFO, a symlink, a folder) rather than
    replace it, and a folder that would not take it."""
    check_writable(csv.parent, csv)
    kind = not_a_regular_file(csv)
    if kind:
        raise UsageError(f"cannot write {csv}: it is {kind}, and mechval replaces only regular files")
