"""`mechval run` phase by phase: what start-up, planning, the engine runs
(with the references, the model audit and the findings alongside them) and
the report cost, in wall time and CPU time, per engine run and per scene;
the main job's overhead as the two ratios of issue 27; the page's size and
how fast it opens.

    .venv/bin/python tests/bench/run_bench.py [SCENARIO...] [--engine NAME...] [--skip-hard]
                                              [--workers N] [--browser]

Without SCENARIO: every built-in, as `make run` runs them. The phases are
those of `mechval run` itself (`mechval.harness.run.run_and_report`), so the
figures are the ones users get. The machine may be shared: CPU time is the
steadier figure, and wall time well above CPU time / workers shows
contention (the load average is printed before and after). With --browser,
headless Chromium opens the page offline and the time to its load event
and to the first scenario's plots being drawn is printed, with any network
request the page made (there should be none).
"""

from __future__ import annotations

import time

STARTED = time.perf_counter(), time.process_time()      # before the imports below: start-up is a phase

import argparse  # noqa: E402
import os  # noqa: E402
import re  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from collections import defaultdict  # noqa: E402
from pathlib import Path  # noqa: E402

from mechval.harness.run import run_and_report  # noqa: E402


class Phases:
    """Wall time, this process's CPU time (all threads) and its finished
    children's CPU time (the engine workers) per named phase."""

    def __init__(self):
        self.rows = [("start-up: imports", time.perf_counter() - STARTED[0], time.process_time() - STARTED[1], 0.0)]

    def __call__(self, name: str):
        return _Phase(name, self.rows)


class _Phase:
    def __init__(self, name: str, rows: list):
        self.name, self.rows = name, rows

    def __enter__(self):
        self.wall, self.cpu, self.children = time.perf_counter(), time.process_time(), _children_cpu()

    def __exit__(self, *exc):
        self.rows.append((self.name, time.perf_counter() - self.wall, time.process_time() - self.cpu,
                          _children_cpu() - self.children))


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def page_parts(page: Path) -> dict[str, int]:
    """Bytes of the page by what they hold."""
    html = page.read_text(encoding="utf-8")
    sizes = {"plotly.js": sum(len(m) for m in re.findall(r'<script[^>]*id="plotly-js">.*?</script>', html, re.S)),
             "figure data": sum(len(m) for m in re.findall(r'<script type="application/json".*?</script>', html, re.S)),
             "discrepancy tables": sum(len(m) for m in re.findall(r'<tbody class="run".*?</tbody>', html, re.S)),
             "model audit": len(html[html.find('<h2 id="audit"'):html.find('<h2', html.find('<h2 id="audit"') + 1)])
             if '<h2 id="audit"' in html else 0}
    sizes["the rest"] = len(html) - sum(sizes.values())
    return sizes


def open_in_chromium(page: Path) -> tuple[float, float, list[str]]:
    """Seconds until the page's load event and until the plots of the first
    scenario (opened through its sidebar link) are drawn, with the browser
    offline; and the network requests the page made."""
    from playwright.sync_api import sync_playwright
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    requests: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox", "--disable-gpu"])
        try:
            context = browser.new_context(viewport={"width": 1400, "height": 1000}, offline=True)
            tab = context.new_page()
            tab.on("request", lambda r: requests.append(r.url) if not r.url.startswith("file:") else None)
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
    return loaded, drawn, requests


def print_ratios(rows: list[tuple[str, float, float, float]], engine_cpu: float, alongside_cpu: float,
                 workers: int) -> None:
    """The main job's two goals (issue 27), as measured and as this
    machine's CPU times predict them on a quiet machine (each phase as
    long as all the CPU spent in it, the workers' and the parent's, shared
    by the workers, and at least as long as the parent's part; the
    overhead of forks and transfers is in those CPU times):

    - the whole run ≤ 1.15 × its engine phase (the references, the model
      audit and the findings run alongside the engine runs);
    - the engine phase ≤ 1.1 × (its tasks' CPU time ÷ workers), the
      tasks being the engine runs and the work alongside them."""
    phase = next(row for row in rows if row[0] == "engine runs")
    total = sum(row[1] for row in rows)
    task_cpu = engine_cpu + alongside_cpu
    quiet = {row[0]: max(row[2], (row[2] + row[3]) / workers) for row in rows}
    quiet_phase, quiet_total = quiet["engine runs"], sum(quiet.values())
    print(f"\nthe engine phase's tasks: engine runs {engine_cpu:.1f} s CPU, alongside them (references, audit, "
          f"findings) {alongside_cpu:.1f} s; the workers' CPU in all {phase[3]:.1f} s, the parent's {phase[2]:.1f} s")
    print(f"whole run / engine phase: measured {total / phase[1]:.2f}, quiet-machine estimate "
          f"{quiet_total / quiet_phase:.2f} (goal ≤ 1.15)")
    print(f"engine phase / (tasks' CPU / workers): measured {phase[1] / (task_cpu / workers):.3f}, quiet-machine "
          f"estimate {quiet_phase / (task_cpu / workers):.3f} (goal ≤ 1.1); against the engine runs' CPU alone: "
          f"measured {phase[1] / (engine_cpu / workers):.2f}, estimate {quiet_phase / (engine_cpu / workers):.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*")
    parser.add_argument("--engine", action="append", default=[])
    parser.add_argument("--skip-hard", action="store_true")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--browser", action="store_true", help="also time opening the page in Chromium")
    args = parser.parse_args()

    load_before = os.getloadavg()
    out = Path(tempfile.mkdtemp(prefix="mechval-bench-")) / "report"
    phases = Phases()
    run = run_and_report(args.scenarios, args.engine or None, out, workers=args.workers, skip_hard=args.skip_hard,
                         quiet=True, phase=phases)
    outcomes = run.outcomes

    print(f"{'scenario':<28} {'engine':<24} {'wall [s]':>9} {'CPU [s]':>9}")
    for o in sorted(outcomes, key=lambda o: -o.cpu_time):
        setting = "" if o.task.setting == "default" else f" [{o.task.setting}]"
        print(f"{o.task.scenario.name:<28} {o.task.engine + setting:<24} {o.wall_time:>9.2f} {o.cpu_time:>9.2f}"
              + (f"  FAILED: {o.error}" if o.error else ""))

    engine_cpu = sum(o.cpu_time for o in outcomes)
    per_scene: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0, 0])
    for o in outcomes:
        scene = per_scene[o.task.scenario.name]
        scene[0], scene[1], scene[2] = scene[0] + o.wall_time, scene[1] + o.cpu_time, scene[2] + 1
    print(f"\n{'scenario':<28} {'runs':>4} {'wall [s]':>9} {'CPU [s]':>9} {'of engine CPU':>14}")
    for name, (wall, cpu, count) in sorted(per_scene.items(), key=lambda item: -item[1][1]):
        print(f"{name:<28} {count:>4} {wall:>9.2f} {cpu:>9.2f} {cpu / max(engine_cpu, 1e-9):>14.0%}")

    print(f"\n{'phase':<32} {'wall [s]':>9} {'CPU here [s]':>13} {'CPU workers [s]':>16}")
    for name, wall, cpu, children in phases.rows:
        print(f"{name:<32} {wall:>9.2f} {cpu:>13.2f} {children:>16.2f}")
    total = sum(row[1] for row in phases.rows)
    report = sum(row[1] for row in phases.rows if row[0].startswith("report"))
    report_cpu = sum(row[2] for row in phases.rows if row[0].startswith("report"))
    print(f"{'total':<32} {total:>9.2f} {sum(r[2] for r in phases.rows):>13.2f} {sum(r[3] for r in phases.rows):>16.2f}")
    print(f"report building: {report:.2f} s wall, {report_cpu:.2f} s CPU")
    engine_wall = next(row[1] for row in phases.rows if row[0] == "engine runs")
    busy = sum(o.wall_time for o in outcomes)
    print(f"\n{len(outcomes)} engine runs on {args.workers} workers: runs' wall time {busy:.1f} s in all, "
          f"CPU time {engine_cpu:.1f} s; efficiency {busy / (args.workers * engine_wall):.0%}; "
          f"CPU time / workers {engine_cpu / args.workers:.1f} s against {engine_wall:.1f} s wall "
          f"(longest run {max(o.wall_time for o in outcomes):.1f} s wall, {max(o.cpu_time for o in outcomes):.1f} s CPU)")
    print(f"load average (1 min) {load_before[0]:.2f} before, {os.getloadavg()[0]:.2f} after, on {os.cpu_count()} cores")
    print_ratios(phases.rows, engine_cpu, run.alongside_cpu_time, args.workers)
    page = run.folder / "index.html"
    print(f"\npage: {page.stat().st_size / 1e6:.2f} MB ({page}); "
          + ", ".join(f"{name} {size / 1e6:.2f} MB" for name, size in page_parts(page).items()))
    if args.browser:
        loaded, drawn, requests = open_in_chromium(page)
        print(f"headless Chromium, offline: load event {loaded:.2f} s, first scenario's plots drawn {drawn:.2f} s; "
              f"network requests: {len(requests)}" + (f" ({', '.join(requests[:5])})" if requests else ""))


if __name__ == "__main__":
    sys.exit(main())
