"""What a fresh worker process per engine run costs (the local pool's
isolation: `mechval.harness.executors.LocalExecutor`), against workers that
run task after task: the runs' own CPU time, the workers' CPU time in all
(forks, start-up, and the runs) and the parent's, in CPU time so that it
holds on a shared machine.

    .venv/bin/python tests/bench/worker_overhead_bench.py [SCENARIO...] [--workers N]

Without SCENARIO: five kinematic built-ins. The persistent pool is for this
measurement only: `mechval run` keeps a fresh process per run, so that a
crash, or an engine that corrupts its process without crashing, is charged
to the run that did it.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from unittest import mock

from mechval.harness import executors
from mechval.harness.plan import prepare
from mechval.harness.preflight import chosen_engines, load_scenario
from mechval.harness.runner import import_engines, run_tasks, tasks_for

SCENES = ["fourbar-seed", "slider-crank", "jansen-leg", "watt-six-bar", "hand-pump"]


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def measure(tasks, workers: int, persistent: bool) -> tuple[float, float, float]:
    """The runs' CPU time, the workers' and the parent's (s)."""
    pool = executors.ProcessPool
    fresh_or_not = (lambda **kw: pool(**{**kw, "max_tasks": 0})) if persistent else pool
    children, parent = _children_cpu(), time.process_time()
    with mock.patch.object(executors, "ProcessPool", fresh_or_not):
        outcomes = run_tasks(tasks, workers=workers, timeout=600.0)
    return sum(o.cpu_time for o in outcomes), _children_cpu() - children, time.process_time() - parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", default=SCENES)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    engines = chosen_engines(None)
    tasks = tasks_for([prepare(load_scenario(s), engines) for s in args.scenarios], engines)
    import_engines(engines)         # as `mechval run` does before its pool forks
    print(f"{len(tasks)} engine runs on {args.workers} workers")
    print(f"{'workers':<22} {'runs CPU [s]':>12} {'workers CPU [s]':>15} {'parent CPU [s]':>14}")
    for _ in range(2):
        for persistent in (False, True):
            runs, workers, parent = measure(tasks, args.workers, persistent)
            print(f"{'persistent' if persistent else 'fresh per run':<22} {runs:>12.2f} {workers:>15.2f} {parent:>14.2f}")


if __name__ == "__main__":
    sys.exit(main())
