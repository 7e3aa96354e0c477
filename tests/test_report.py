"""`mechval run` and its report: isolation of failing engines, longest
runs first, report files, escaping, tolerance reasons, failures first,
display data (thinning that keeps spikes, 16-bit codes), atomic output, and
the report as a person uses it in a real headless browser."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import page_codes
from fake_engines import FAKES, registered
from mechval.engines import registry
from mechval.harness.simulate import simulate
from mechval.records.outcome import Outcome, Task
from mechval.reports import build, plots
from mechval.harness.runner import discrepancies, run_tasks, tasks_for
from mechval.scenarios import parse
from mechval.records.signals import Signals
from mechval.testing.scenes import slider_crank

HOSTILE = ('Slider <b>bold</b> & <script>document.title="pwned"</script> "quoted" '
           '<img src=x onerror="document.title=\'pwned\'">')
#: An engine name that would end a <script> element if it were not escaped
#: (the report passes run labels to the page's script as JSON).
HOSTILE_ENGINE = '</script><script>document.title="pwned"</script>'
FORCE_REASON = "the fake's forces are 0.1 % high <on purpose> & known"


@pytest.fixture
def fakes(monkeypatch):
    monkeypatch.setattr(registry, "targets", registered())


@pytest.fixture(scope="module")
def scene():
    engines = {"mujoco": {"tolerance": {"force": {"bound": 2e-2, "reason": FORCE_REASON}, "torque": 3e-2}}}
    return parse(slider_crank(description=HOSTILE, time={"end": 0.5, "samples": 51}, engines=engines),
                 "hostile.toml")


def run_fakes(scene, engines, timeout=30.0):
    outcomes = run_tasks(tasks_for([scene], engines), workers=2, timeout=timeout)
    references = {scene.name: simulate(scene, "reference")}
    return outcomes, references, discrepancies(outcomes, references)


def test_failing_engines_fail_only_their_own_rows(fakes, scene):
    outcomes, _, records = run_fakes(scene, ["faithful", "crashing", "hanging", "nonfinite", "raising"], timeout=5.0)
    verdicts = records.groupby("engine")["verdict"].apply(set).to_dict()
    assert verdicts["faithful"] == {"pass"}
    for engine in ("crashing", "hanging", "raising", "nonfinite"):
        assert "fail" in verdicts[engine], engine
    faithful = next(o for o in outcomes if o.task.engine == "faithful")
    assert faithful.error == "" and faithful.wall_time > 0            # no "FAILED" on the progress bar
    reasons = {o.task.engine: o.error for o in outcomes}
    assert "crashed" in reasons["crashing"] and "timed out" in reasons["hanging"]
    assert "solver diverged" in reasons["raising"]
    nonfinite = records[records["engine"] == "nonfinite"].set_index("signal")
    assert nonfinite.loc["F32x", "verdict"] == "fail" and "non-finite" in nonfinite.loc["F32x", "reason"]
    # The run's health counts the NaNs too; every other signal still passes.
    assert nonfinite.loc["health.nonfinite", "verdict"] == "fail"
    others = nonfinite.drop(["F32x", "health.nonfinite"])
    assert set(others["verdict"]) == {"pass"}, others[others["verdict"] != "pass"]


def test_longest_runs_start_first_and_outcomes_keep_the_task_order(fakes, scene):
    tasks = [replace(task, steps=steps) for task, steps in zip(tasks_for([scene] * 3, ["faithful"]), (10, 30, 20))]
    assert [task.steps > 0 for task in tasks_for([scene], ["faithful"])] == [True]   # end / timestep
    started = []
    outcomes = run_tasks(tasks, workers=1, timeout=30.0, on_done=lambda outcome: started.append(outcome.task.steps))
    assert started == [30, 20, 10]                  # one worker: finished in the order started
    assert [o.task.steps for o in outcomes] == [10, 30, 20]


@pytest.fixture(scope="module")
def report(tmp_path_factory, scene):
    from _pytest.monkeypatch import MonkeyPatch
    patch = MonkeyPatch()
    # "mujoco" stands in for an engine whose [engines.NAME] table overrides bounds.
    patch.setattr(registry, "targets", registered({**FAKES, "mujoco": FAKES["spiking"],
                                         HOSTILE_ENGINE: FAKES["faithful"]}))
    try:
        outcomes, references, records = run_fakes(scene, ["faithful", "nonfinite", "raising", "spiking", "mujoco",
                                                          HOSTILE_ENGINE])
    finally:
        patch.undo()
    out = tmp_path_factory.mktemp("report") / "run"
    build.write_report(out, [scene], references, outcomes, records)
    return out, records


def test_report_files(report):
    out, records = report
    assert sorted(p.name for p in out.iterdir()) == ["discrepancies.csv", "index.html", "runs.csv", "summary.md"]
    csv = pd.read_csv(out / "discrepancies.csv", keep_default_na=False)
    assert len(csv) == len(records)
    assert "nan" not in (out / "discrepancies.csv").read_text().lower()
    faithful = records[records["engine"] == "faithful"]
    np.testing.assert_array_equal(csv[csv["engine"] == "faithful"]["max_error"].astype(float),
                                  faithful["max_error"].to_numpy())
    summary = (out / "summary.md").read_text()
    assert "run failed ✗" in summary and "solver diverged" in summary


def test_report_escapes_scenario_text(report):
    html = (report[0] / "index.html").read_text()
    assert "<script>document.title" not in html
    assert "&lt;b&gt;bold&lt;/b&gt; &amp; &lt;script&gt;" in html
    # Run labels reach the page's script as JSON: "</" cannot end the element,
    # so every data element holds all of its JSON.
    blocks = re.findall(r'<script type="application/json" id="([^"]+)">(.*?)</script>', html, re.S)
    assert [name for name, _ in blocks] == ["s-test-slider-drawing", "s-test-slider-signals", "s-test-slider-energy"]
    for _, block in blocks[1:]:
        assert HOSTILE_ENGINE in [run["label"] for run in json.loads(block)["runs"]]


def test_tolerance_override_shows_its_reason_beside_the_bound(report):
    out, records = report
    html = (out / "index.html").read_text()
    overridden = records[(records["engine"] == "mujoco") & (records["class"] == "force")]
    assert (overridden["tolerance"] == 2e-2).all() and len(overridden)
    escaped = "the fake&#39;s forces are 0.1 % high &lt;on purpose&gt; &amp; known"
    note = f"mujoco override: force 0.02 (scenario 0.01): {escaped}"
    # Once above the scenario's plots, once in mujoco's records, and beside
    # the bound of every force row of mujoco.
    assert html.count(note) == 2 + len(overridden)
    # The plain number form: no reason, said so; beside T12's bound, the
    # power residual's and the energy balance's, held to the torque tolerance.
    assert html.count("mujoco override: torque 0.03 (scenario 0.01): no reason given in the scene file") == 2 + 3


def test_failing_scenarios_come_first_and_open(tmp_path):
    """Sections and the sidebar list failing scenarios first, opened; the
    summary-matrix cells link to that scenario's records of that run."""
    good = parse(slider_crank(name="a-passes", time={"end": 0.2, "samples": 21}), "a.toml")
    bad = parse(slider_crank(name="b-fails", time={"end": 0.2, "samples": 21}), "b.toml")
    references = {s.name: simulate(s, "reference") for s in (good, bad)}
    spiked = references["b-fails"].frame.copy()
    spiked.loc[10, "F32x"] += 1.0
    outcomes = [Outcome(Task(good, "faithful"), references["a-passes"], wall_time=0.1),
                Outcome(Task(bad, "faithful"), Signals(spiked, "faithful"), wall_time=0.1)]
    records = discrepancies(outcomes, references)
    html = (build.write_report(tmp_path / "run", [good, bad], references, outcomes, records) / "index.html").read_text()
    sections = re.findall(r'<section class="scenario" id="([^"]+)">\s*<details( open)?>', html)
    assert sections == [("s-b-fails", " open"), ("s-a-passes", "")]
    sidebar = html[html.index('id="scenario-list"'):html.index('id="filter"')]
    assert sidebar.index("b-fails") < sidebar.index("a-passes")
    assert '<a href="#s-b-fails--faithful">' in html and 'id="s-b-fails--faithful"' in html


def test_display_thinning_keeps_a_single_sample_spike():
    n = 100_000
    rng = np.random.default_rng(1)
    values = np.sin(np.linspace(0, 40, n)) + 1e-3 * rng.standard_normal(n)
    values[31_337] = 5.0
    values[77_777] = -5.0
    gap = values.copy()
    gap[50_001] = np.nan
    keep = plots.display_indices(n, 500, values, gap)
    assert keep[0] == 0 and keep[-1] == n - 1 and np.all(np.diff(keep) > 0)
    assert {31_337, 77_777, 50_001} <= set(keep.tolist())
    assert len(keep) <= 2 + 500 * 5            # per window: min, max of each, a NaN
    for lo, hi in zip(np.arange(0, n, 200), np.arange(200, n + 200, 200)):    # every window's extremes kept
        window = values[lo:hi]
        assert values[keep[(keep >= lo) & (keep < hi)]].max() == window.max()
        assert values[keep[(keep >= lo) & (keep < hi)]].min() == window.min()
    assert plots.display_indices(1000, 500, values[:1000]) is None


def test_display_codes_round_trip_to_their_resolution():
    values = np.array([0.0, 1e-3, -2.5, np.nan, 7.0, 3.25, -1e-9])
    codes, lo, hi = plots.linear_codes(values)
    back = page_codes.linear_values(page_codes.decode_stream(plots.encode_stream(codes)), lo, hi)
    assert np.isnan(back[3]) and np.all(np.abs(np.delete(back - values, 3)) <= (hi - lo) / 65534 / 2 + 1e-15)
    codes, lo, hi = plots.log_codes(values)
    back = page_codes.log_values(page_codes.decode_stream(plots.encode_stream(codes)), lo, hi)
    assert np.isnan(back[3]) and back[0] == 0.0
    finite = np.isfinite(values) & (values != 0)
    np.testing.assert_allclose(back[finite], values[finite], rtol=10 ** (plots.LOG_DECADES / 32766 / 2) - 1)
    assert page_codes.log_values(plots.log_codes(np.array([1.0, 1e-25]))[0], 0.0, 0.0)[1] == 0.0  # below the range


def test_page_data_keeps_a_spike_of_a_long_run(scene):
    """A run long enough to be thinned for display: the spike of one sample
    in one engine's error survives into the page's data."""
    long = parse(slider_crank(time={"end": 2.0, "samples": 20_001}), "long.toml")
    reference = simulate(long, "reference")
    frame = reference.frame.copy()
    frame["F32x"] += 1e-6 * np.abs(frame["F32x"]).max()
    frame.loc[12_345, "F32x"] += 0.5
    engine = Signals(frame, "spiky")
    data = plots.signal_data(reference, {"spiky": engine}, {}, plots.colours(["spiky"]))
    codes = page_codes.decode_stream(data["stream"])
    trace = data["runs"][0]["traces"]["F32x"]
    start, count = trace["error"]["codes"]
    error = page_codes.log_values(codes[start:start + count], *trace["error"]["log"])
    start, count = trace["samples"]["codes"]
    at = np.cumsum(codes[start:start + count])
    assert count < 4 * plots.DISPLAY_WINDOWS + 2 and at[np.argmax(error)] == 12_345
    assert error.max() == pytest.approx(0.5, rel=1e-3)


def test_interrupted_report_leaves_nothing(tmp_path, scene, monkeypatch):
    def broken(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(build.plots, "signal_data", broken)
    reference = simulate(scene, "reference")
    with pytest.raises(KeyboardInterrupt):
        build.write_report(tmp_path / "run", [scene], {scene.name: reference}, [], discrepancies([], {}))
    assert list(tmp_path.iterdir()) == []


def test_existing_report_folder_is_not_overwritten(tmp_path, scene):
    (tmp_path / "run").mkdir()
    with pytest.raises(FileExistsError):
        build.write_report(tmp_path / "run", [scene], {}, [], discrepancies([], {}))


@pytest.mark.engine
def test_cli_run_end_to_end(tmp_path):
    """The main job on one scene and two engines, as a user runs it; the
    report carries PyBullet's engine findings, measured."""
    out = tmp_path / "report"
    proc = subprocess.run([str(Path(sys.executable).parent / "mechval"), "run", "slider-crank",
                           "--engine", "exudyn", "--engine", "pybullet", "--out", str(out), "--quiet"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "| slider-crank |" in proc.stdout and (out / "index.html").exists()
    html = (out / "index.html").read_text()
    assert '<h2 id="findings">Engine findings</h2>' in html and '<td class="text">pybullet</td>' in html
    assert "Model audit: what each engine will simulate" in html


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (make test tries apt-get)")
def test_report_in_a_real_browser(report):
    """Offline, the page asks for nothing but itself and logs no error;
    hostile text shows as text and no script of it runs; the failing
    scenario's plots draw the signals; clicking an engine in a legend hides
    its traces in both figures; a matrix cell leads to its run's records;
    an override's reason is shown in its run's records, beside the bound;
    the filter hides an engine's records and traces, and records by verdict."""
    from playwright.sync_api import sync_playwright

    out, records = report
    section = "#s-test-slider"
    overlays, errors_plot = f"{section} .plot[data-kind=overlays]", f"{section} .plot[data-kind=errors]"
    shown = ("([selector, group]) => document.querySelector(selector).data"
             ".filter(t => t.legendgroup === group && t.visible !== 'legendonly').length")
    errors, requests = [], []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[
            "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
            "--disable-sync", "--no-first-run"])
        try:
            page = browser.new_context(viewport={"width": 1300, "height": 1000}, offline=True).new_page()
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("request", lambda r: requests.append(r.url))
            page.goto((out / "index.html").as_uri())
            title = page.title()
            description = page.inner_text("p.description")
            headers = page.locator(".matrix th").all_inner_texts()
            for plot in (f"{section} .plot[data-kind=plotly]", overlays, errors_plot):
                page.locator(plot).scroll_into_view_if_needed()
                page.wait_for_function("s => document.querySelector(s).dataset.drawn === 'true'", arg=plot)
            drawn_reference = page.evaluate(
                "s => Array.from(document.querySelector(s).data.find(t => t.name === 'reference'"
                " && t.yaxis === 'y8').y)", overlays)
            before = [page.evaluate(shown, [plot, "spiking"]) for plot in (overlays, errors_plot)]
            paths = page.locator(f"{overlays} .scatterlayer .trace").count()
            page.locator(f"{overlays} .legend .traces").filter(has_text=re.compile("^spiking$")).click()
            page.wait_for_function(f"() => ({shown})(['{errors_plot}', 'spiking']) === 0")
            after = [page.evaluate(shown, [plot, "spiking"]) for plot in (overlays, errors_plot)]
            paths_after = page.locator(f"{overlays} .scatterlayer .trace").count()
            page.locator(".matrix a[href='#s-test-slider--nonfinite']").click()
            jumped = page.locator("#s-test-slider--nonfinite").bounding_box()
            overridden = page.locator("#s-test-slider--mujoco")
            override_head = overridden.locator("tr.run-head").inner_text()
            force_bound = overridden.evaluate(
                "run => [...run.rows].find(r => r.cells[0].innerText === 'F32x').cells[5].innerText")
            page.locator("#filter input[data-engine=faithful]").uncheck()
            faithful_hidden = page.locator("tbody[data-engine=faithful]").evaluate_all("runs => runs.map(r => r.hidden)")
            faithful_traces = page.evaluate(shown, [overlays, "faithful"])
            page.locator("#filter input[data-verdict=pass]").uncheck()
            rows = page.locator("tr[data-verdict]").evaluate_all(
                "rows => rows.filter(r => !r.hidden).map(r => r.dataset.verdict)")
        finally:
            browser.close()
    assert errors == [] and requests == [(out / "index.html").as_uri()]
    assert "pwned" not in title
    assert description == HOSTILE and HOSTILE_ENGINE in headers
    reference = simulate(parse(slider_crank(time={"end": 0.5, "samples": 51}), "x"), "reference")["F12y"]
    assert len(drawn_reference) == len(reference)        # F12y is the 8th signal; short runs are not thinned
    np.testing.assert_allclose(drawn_reference, reference, rtol=0, atol=np.ptp(reference) / 65534)
    assert before[0] == 17 and before[1] >= 17 and after == [0, 0]      # 17 signals; errors add bound lines
    assert paths_after == paths - 17
    assert jumped is not None and -2 < jumped["y"] < 1000      # scrolled into view
    assert f"mujoco override: force 0.02 (scenario 0.01): {FORCE_REASON}" in override_head
    f32x = records[(records["engine"] == "mujoco") & (records["signal"] == "F32x")].iloc[0]
    assert f32x["tolerance"] == 0.02 and force_bound == f"{f32x['bound']:.3g} † override"   # the bound column
    assert faithful_hidden == [True] and faithful_traces == 0
    assert rows and set(rows) == {"fail"}
