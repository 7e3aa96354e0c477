"""Cost of the model audit that `mechval run` adds: every built-in scenario ×
every installed engine, as the run does it (settings, build, read-back), in
one process. Prints per-engine and total wall time; asserts nothing.

    .venv/bin/python tests/bench/audit_bench.py
"""

from __future__ import annotations

import time

from mechval.harness.audit_run import audit_all
from mechval.engines.registry import availability
from mechval.scenarios import builtin_names, load


def main() -> None:
    scenarios = [load(name) for name in builtin_names()]
    engines = [name for name, reason in availability().items() if not reason]   # imports the engines
    total = 0.0
    for engine in engines:
        start = time.perf_counter()
        results = audit_all(scenarios, [engine])
        wall = time.perf_counter() - start
        total += wall
        build = sum(r.seconds for r in results)
        failing = sum(r.failing for r in results) + sum(r.table is None for r in results)
        worst = max((float(r.table["deviation"].max()), r.scenario) for r in results if r.table is not None)
        print(f"{engine:<9} {len(results)} scenarios: {wall:.2f} s wall ({build:.2f} s build + read-back, "
              f"the rest settings), {failing} failing rows/audits, largest deviation {worst[0]:.2g} ({worst[1]})")
    print(f"total     {total:.2f} s for {len(scenarios)} scenarios × {len(engines)} engines")


if __name__ == "__main__":
    main()
