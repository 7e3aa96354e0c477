"""`mechval run` phase by phase: what the engine runs, the reference and the
report cost, in wall time and CPU time (the machine may be shared: CPU time
is the steadier figure), the page's size and how fast it opens.

    .venv/bin/python tests/bench/run_bench.py [SCENARIO...] [--workers N] [--long] [--browser]

Without SCENARIO: the built-ins `mechval run` runs by default (`--long`
adds those tagged long). Prints one line per engine run (its own wall time
from inside the worker), then the phases, the engine phase's efficiency
(sum of run times / (workers × phase wall time)), the page size and, with
--browser, the time headless Chromium takes to open the page and to draw
the first scenario's plots.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

from mechval.harness.cli import _engines, _scenarios, report_sections
from mechval.reports.build import write_report
from mechval.harness.runner import discrepancies, references_for, run_tasks, tasks_for


class Phase:
    """Wall time, this process's CPU time and its finished children's CPU
    time (the engine workers) over a `with` block."""

    def __init__(self, name: str, rows: list):
        self.name, self.rows = name, rows

    def __enter__(self):
        self.wall, self.cpu, self.children = time.perf_counter(), time.process_time(), _children_cpu()
        return self

    def __exit__(self, *exc):
        self.rows.append((self.name, time.perf_counter() - self.wall, time.process_time() - self.cpu,
                          _children_cpu() - self.children))


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def open_in_chromium(page: Path) -> tuple[float, float]:
    """Seconds until the page's load event, and until the plots of the first
    scenario (opened through its link) are drawn."""
    from playwright.sync_api import sync_playwright
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox", "--disable-gpu"])
        try:
            tab = browser.new_page(viewport={"width": 1400, "height": 1000})
            start = time.perf_counter()
            tab.goto(page.as_uri(), wait_until="load")
            loaded = time.perf_counter() - start
            first = tab.locator("#scenario-list a").first
            first.click()
            section = first.get_attribute("href")
            tab.wait_for_function(f"[...document.querySelectorAll('{section} .plot')].slice(0, 2)"
                                  ".every(p => p.dataset.drawn === 'true')", timeout=120_000)
            drawn = time.perf_counter() - start
        finally:
            browser.close()
    return loaded, drawn


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--long", action="store_true", help="include the built-ins tagged long")
    parser.add_argument("--browser", action="store_true", help="also time opening the page in Chromium")
    args = parser.parse_args()

    phases: list = []
    with Phase("load scenarios, engines, tasks", phases):
        scenarios = _scenarios(args.scenarios or None, skip_hard=False)
        engines = _engines(None)
        tasks = tasks_for(scenarios, engines)
    with Phase("reference", phases):
        references = references_for(scenarios)
    with Phase("engine runs", phases):
        outcomes = run_tasks(tasks, workers=args.workers, timeout=900.0)
    with Phase("comparison", phases):
        records = discrepancies(outcomes, references)
    out = Path(tempfile.mkdtemp(prefix="mechval-bench-")) / "report"
    with Phase("report build", phases):
        write_report(out, scenarios, references, outcomes, records, report_sections(records, scenarios, engines))

    print(f"{'scenario':<24} {'engine':<24} {'run wall [s]':>12}")
    for o in sorted(outcomes, key=lambda o: -o.wall_time):
        setting = "" if o.task.setting == "default" else f" [{o.task.setting}]"
        print(f"{o.task.scenario.name:<24} {o.task.engine + setting:<24} {o.wall_time:>12.2f}"
              + (f"  FAILED: {o.error}" if o.error else ""))
    print()
    print(f"{'phase':<32} {'wall [s]':>9} {'CPU here [s]':>13} {'CPU workers [s]':>16}")
    for name, wall, cpu, children in phases:
        print(f"{name:<32} {wall:>9.2f} {cpu:>13.2f} {children:>16.2f}")
    total = sum(wall for _, wall, _, _ in phases)
    print(f"{'total':<32} {total:>9.2f}")
    engine_wall = next(wall for name, wall, _, _ in phases if name == "engine runs")
    busy = sum(o.wall_time for o in outcomes)
    print(f"\n{len(outcomes)} engine runs on {args.workers} workers: sum of run times {busy:.1f} s, "
          f"efficiency {busy / (args.workers * engine_wall):.0%} (longest run {max(o.wall_time for o in outcomes):.1f} s)")
    page = out / "index.html"
    print(f"page: {page.stat().st_size / 1e6:.2f} MB ({page})")
    if args.browser:
        loaded, drawn = open_in_chromium(page)
        print(f"headless Chromium: load event {loaded:.2f} s, first scenario's plots drawn {drawn:.2f} s")


if __name__ == "__main__":
    sys.exit(main())
