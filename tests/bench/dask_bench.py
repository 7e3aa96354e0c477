"""`mechval run --dask` throughput: engine runs per minute on a Dask
cluster of 1 and of 2 worker processes (one thread each) on this machine,
and the scaling between them.

    .venv/bin/python tests/bench/dask_bench.py [SCENARIO...] [--engine NAME...] [--max-workers N]

Without SCENARIO: every built-in less the hard ones (as `mechval run
--skip-hard`). Each cluster is a `distributed.LocalCluster` of processes,
started before the clock runs and warmed by one run of each engine (its
workers import the engines once, as a long-lived cluster's do). The tasks
are those of `mechval run` (`mechval.harness.runner.tasks_for`, longest
first) through the same `DaskExecutor`. The machine may be shared: the
load average is printed, and the runs' CPU time beside the wall time.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from mechval.harness.executors import DaskExecutor
from mechval.harness.plan import prepare
from mechval.harness.preflight import chosen_engines, chosen_scenarios
from mechval.harness.runner import run_tasks, tasks_for


def throughput(tasks, workers: int) -> tuple[float, float, int]:
    """Wall time (s) and the runs' CPU time (s) of `tasks` on a cluster of
    `workers` processes, and how many failed."""
    from distributed import LocalCluster
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            DaskExecutor(cluster.scheduler_address, timeout=900.0) as executor:
        warm = list({t.engine: t for t in sorted(tasks, key=lambda t: t.steps)}.values())
        for _ in range(workers):        # each worker imports each engine before the clock runs
            run_tasks(warm, executor=executor)
        start = time.perf_counter()
        outcomes = run_tasks(tasks, executor=executor)
        wall = time.perf_counter() - start
    return wall, sum(o.cpu_time for o in outcomes), sum(bool(o.error) for o in outcomes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*")
    parser.add_argument("--engine", action="append")
    parser.add_argument("--max-workers", type=int, default=2)
    args = parser.parse_args()
    engines = chosen_engines(args.engine)
    scenes = chosen_scenarios(args.scenarios or None, skip_hard=not args.scenarios, long=False)
    tasks = tasks_for([prepare(s, engines) for s in scenes], engines)
    print(f"{len(tasks)} engine runs ({len(scenes)} scenes × {', '.join(engines)}); "
          f"load average (1 min) {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"{'workers':>7} {'wall [s]':>9} {'CPU [s]':>8} {'runs/min':>9} {'CPU/wall':>9} {'failed':>6}")
    rates = {}
    for workers in range(1, args.max_workers + 1):
        wall, cpu, failed = throughput(tasks, workers)
        rates[workers] = 60 * len(tasks) / wall
        print(f"{workers:>7} {wall:>9.2f} {cpu:>8.2f} {rates[workers]:>9.1f} {cpu / wall:>9.2f} {failed:>6}")
    for workers in range(2, args.max_workers + 1):
        print(f"scaling 1 → {workers} workers: {rates[workers] / rates[1]:.2f}× (ideal {workers}×)")
    print(f"load average (1 min) after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    sys.exit(main())
