"""Benchmark: the Exudyn adapter at its default settings on every built-in
scenario — wall time per simulated second, and the adapter's overhead as
the ratio of a whole `simulate` (settings, model building, solve, reading
sensors, conversion) to the bare solver call on the same model and settings.

    .venv/bin/python tests/bench/exudyn_bench.py [--repeats N] [SCENARIO ...]

Prints the figures; it asserts nothing about time (a benchmark, not a test).
Each figure is the best of N runs.
"""

from __future__ import annotations

import time

from mechval.engines.exudyn.adapter import ExudynAdapter
from mechval.engines.exudyn.run import prepare
from mechval.engines.exudyn.model import SOLVERS
from mechval.reference.linkages import build_mechanism
from mechval.scenarios import load
from mechval.harness.simulate import simulate
from timing import best_times, scenario_arguments


def whole_run(adapter: ExudynAdapter, scenario) -> float:
    start = time.perf_counter()
    simulate(scenario, adapter)
    return time.perf_counter() - start


def bare_solve(adapter: ExudynAdapter, scenario) -> float:
    """Only the `SolveDynamic` call, on the model and settings the adapter
    would use (Exudyn's console output left on; it prints nothing at
    verboseMode 0)."""
    mechanism = build_mechanism(scenario)
    settings = adapter.settings_for(scenario, mechanism)
    model, simulation, _ = prepare(mechanism, scenario.time.t, settings)
    start = time.perf_counter()
    model.mbs.SolveDynamic(simulation, solverType=SOLVERS[settings["solver"]])
    return time.perf_counter() - start


def main() -> None:
    args = scenario_arguments(__doc__)

    adapter = ExudynAdapter()
    print(f"exudyn {ExudynAdapter.version()}, default settings, best of {args.repeats}")
    print(f"{'scenario':22s} {'sim s':>6s} {'steps':>6s} {'run s':>7s} {'s per sim s':>11s} "
          f"{'µs/step':>8s} {'bare s':>7s} {'overhead':>8s}")
    for name in args.scenarios:
        scenario = load(name)
        result = simulate(scenario, adapter)
        steps = result.info.steps
        run, bare = best_times(args.repeats, lambda: whole_run(adapter, scenario),
                               lambda: bare_solve(adapter, scenario))
        simulated = scenario.time.end
        print(f"{name:22s} {simulated:6.2f} {steps:6d} {run:7.3f} {run / simulated:11.3f} "
              f"{1e6 * bare / steps:8.1f} {bare:7.3f} {run / bare:8.2f}")


if __name__ == "__main__":
    main()
