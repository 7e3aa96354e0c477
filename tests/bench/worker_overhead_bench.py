"""What a fresh worker process per engine run costs (the local pool's
isolation: `mechval.harness.executors.LocalExecutor`), against workers that
run task after task: the runs' own CPU time, the workers' CPU time in all
(forks, start-up, and the runs) and the parent's, in CPU time so that it
holds on a shared machine; and the slots' idle time per run, with pebble's
pool polled at `pool_host.POLL` and at pebble's own 0.1 s.

    .venv/bin/python tests/bench/worker_overhead_bench.py [SCENARIO...] [--workers N]

Without SCENARIO: five kinematic built-ins. The persistent pool is for this
measurement only: `mechval run` keeps a fresh process per run, so that a
crash, or an engine that corrupts its process without crashing, is charged
to the run that did it.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from unittest import mock

from mechval.harness import pool_host
from mechval.harness.plan import prepare
from mechval.harness.preflight import chosen_engines, load_scenario
from mechval.harness.runner import import_engines, run_tasks, tasks_for

SCENES = ["fourbar-seed", "slider-crank", "jansen-leg", "watt-six-bar", "hand-pump"]


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def measure(tasks, workers: int, persistent: bool, poll: float) -> tuple[float, float, float, float]:
    """The runs' CPU time, the workers' and the parent's (s), and each
    run's share of the slots' idle time (workers × wall − the runs' walls)
    in ms: on a loaded machine the runs' walls stretch too, so it stays
    meaningful where the wall time is not."""
    pool = pool_host.ProcessPool       # patched here, before the batch forks the pool's host
    fresh_or_not = (lambda **kw: pool(**{**kw, "max_tasks": 0})) if persistent else pool
    children, parent, wall = _children_cpu(), time.process_time(), time.perf_counter()
    with mock.patch.object(pool_host, "ProcessPool", fresh_or_not), mock.patch.object(pool_host, "POLL", poll):
        outcomes = run_tasks(tasks, workers=workers, timeout=600.0)
    idle = (workers * (time.perf_counter() - wall) - sum(o.wall_time for o in outcomes)) / len(outcomes)
    return (sum(o.cpu_time for o in outcomes), _children_cpu() - children, time.process_time() - parent,
            1000 * idle)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", default=SCENES)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    engines = chosen_engines(None)
    tasks = tasks_for([prepare(load_scenario(s), engines) for s in args.scenarios], engines)
    import_engines(engines)         # as `mechval run` does before its pool forks
    print(f"{len(tasks)} engine runs on {args.workers} workers")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'workers':<34} {'runs CPU [s]':>12} {'workers CPU [s]':>15} {'parent CPU [s]':>14} "
          f"{'idle per run [ms]':>17}")
    for _ in range(2):
        for persistent, poll in ((False, pool_host.POLL), (False, 0.1), (True, pool_host.POLL)):
            runs, workers, parent, idle = measure(tasks, args.workers, persistent, poll)
            name = f"{'persistent' if persistent else 'fresh per run'}, pool polled every {poll:g} s"
            print(f"{name:<34} {runs:>12.2f} {workers:>15.2f} {parent:>14.2f} {idle:>17.0f}")


if __name__ == "__main__":
    sys.exit(main())
