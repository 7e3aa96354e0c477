"""`mechval run` and its report: isolation of failing engines, report
files, escaping, atomic output, and the report as a person sees it in a
real headless browser."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from fake_engines import FAKES
from mechval.engines import registry
from mechval.reference import simulate_reference
from mechval.reports import build
from mechval.harness.runner import discrepancies, run_tasks, tasks_for
from mechval.scenarios import parse
from scenario_data import slider_crank

HOSTILE = 'Slider <b>bold</b> & <script>document.title="pwned"</script> "quoted"'


@pytest.fixture
def fakes(monkeypatch):
    monkeypatch.setattr(registry, "ADAPTERS", {**registry.ADAPTERS, **FAKES})


@pytest.fixture(scope="module")
def scene():
    return parse(slider_crank(description=HOSTILE, time={"end": 0.5, "samples": 51}), "hostile.toml")


def run_fakes(scene, engines, timeout=30.0):
    outcomes = run_tasks(tasks_for([scene], engines), workers=2, timeout=timeout)
    references = {scene.name: simulate_reference(scene)}
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


@pytest.fixture(scope="module")
def report(tmp_path_factory, scene):
    from _pytest.monkeypatch import MonkeyPatch
    patch = MonkeyPatch()
    patch.setattr(registry, "ADAPTERS", {**registry.ADAPTERS, **FAKES})
    try:
        outcomes, references, records = run_fakes(scene, ["faithful", "nonfinite", "raising"])
    finally:
        patch.undo()
    out = tmp_path_factory.mktemp("report") / "run"
    build.write_report(out, [scene], references, outcomes, records)
    return out, records


def test_report_files(report):
    out, records = report
    assert sorted(p.name for p in out.iterdir()) == ["discrepancies.csv", "index.html", "summary.md"]
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


def test_interrupted_report_leaves_nothing(tmp_path, scene, monkeypatch):
    def broken(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(build.plots, "signal_overlays", broken)
    reference = simulate_reference(scene)
    with pytest.raises(KeyboardInterrupt):
        build.write_report(tmp_path / "run", [scene], {scene.name: reference}, [], discrepancies([], {}))
    assert list(tmp_path.iterdir()) == []


def test_existing_report_folder_is_not_overwritten(tmp_path, scene):
    (tmp_path / "run").mkdir()
    with pytest.raises(FileExistsError):
        build.write_report(tmp_path / "run", [scene], {}, [], discrepancies([], {}))


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
def test_report_in_a_real_browser(report, tmp_path):
    """No console errors, the plots render (non-blank), hostile text shows
    as text and its script does not run."""
    from PIL import Image
    from playwright.sync_api import sync_playwright

    out, _ = report
    errors = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[
            "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
            "--disable-sync", "--no-first-run"])
        try:
            page = browser.new_page(viewport={"width": 1300, "height": 1000})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("requestfailed", lambda r: errors.append(f"request failed: {r.url}"))
            page.goto((out / "index.html").as_uri())
            title = page.title()
            description = page.inner_text("p.description")
            images = page.eval_on_selector_all("img", "els => els.map(e => [e.complete, e.naturalWidth])")
            page.locator("img").nth(1).screenshot(path=str(tmp_path / "plot.png"))
        finally:
            browser.close()
    assert errors == []
    assert "pwned" not in title
    assert description == HOSTILE
    assert images and all(complete and width > 100 for complete, width in images)
    pixels = np.asarray(Image.open(tmp_path / "plot.png").convert("L"), dtype=float)
    assert pixels.std() > 10, "plot screenshot is blank"
