"""The report's energy figure and the reference's integration facts:
the page data decodes to each run's energy and drift (to its 16-bit
resolution), the figure draws in a real browser, and summary.md and the
page say how a forward-dynamics reference was integrated."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

import dynamic_mechanisms as dm
import page_codes
from fake_engines import registered
from mechval.judging.compare import COLUMNS
from mechval.reference.dynamics import RTOL
from mechval.engines import registry
from mechval.harness.runner import discrepancies, references_for, run_tasks, tasks_for
from mechval.judging.health import health
from mechval.reference.adapter import ReferenceAdapter
from mechval.reports import build, plots
from mechval.scenarios import parse
from mechval.records.signals import Signals
from mechval.testing.scenes import slider_crank

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def free_fourbar_reference(samples: int = 101) -> Signals:
    case = dm.free_fourbar()
    t = np.linspace(0.0, 1.0, samples)
    raw = ReferenceAdapter().run(case.mech, t, {})
    return Signals(pd.DataFrame({"t": t}), "reference", health=health(case.mech, raw.frame, raw.missing),
                   info=raw.info)


def decoded(data: dict, entry: dict, kind: str) -> np.ndarray:
    codes = page_codes.decode_stream(data["stream"])
    start, count = entry["codes"]
    values = codes[start:start + count]
    return page_codes.linear_values(values, *entry["lin"]) if kind == "lin" else page_codes.log_values(values, *entry["log"])


def test_energy_data_decodes_to_each_runs_energy_and_drift():
    reference = free_fourbar_reference()
    data = plots.energy_data(reference, {"engine": reference}, {"engine": "#123456"})
    assert data["measure"] == "energy_drift" and [r["label"] for r in data["runs"]] == ["reference", "engine"]
    run = data["runs"][1]
    energy, drift = reference.health["energy"].to_numpy(), reference.health["energy_drift"].to_numpy()
    assert run["colour"] == "#123456" and run["t"] == [0.0, 1.0, 101] and "samples" not in run
    np.testing.assert_allclose(decoded(data, run["energy"], "lin"), energy, rtol=0, atol=np.ptp(energy) / 65534)
    drawn = decoded(data, run["residual"], "log")
    shown = drift >= drift.max() * 1e-20        # log codes keep 20 decades below the largest
    np.testing.assert_allclose(drawn[shown], drift[shown], rtol=2e-3)


def test_no_energy_figure_without_the_energy_series():
    bare = Signals(pd.DataFrame({"t": [0.0, 1.0]}), "reference")
    assert plots.energy_data(bare, {"engine": bare}, {}) is None


def test_summary_and_page_state_the_reference_integrator_and_tolerance():
    reference = free_fourbar_reference()
    method = build.reference_method(reference)
    assert "scipy.integrate.DOP853" in method and f"rtol {RTOL:g}" in method
    scene = parse(slider_crank(), "scene.toml")
    records = pd.DataFrame(columns=COLUMNS)
    text = build.summary_markdown(records, [scene], {"date": "today", "commit": "abc"}, {scene.name: reference})
    assert "## Reference integration (forward dynamics)" in text and f"- {scene.name}: {method}" in text
    prescribed = build.summary_markdown(records, [scene], {"date": "today", "commit": "abc"},
                                        references_for([scene]))
    assert "Reference integration" not in prescribed


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    from _pytest.monkeypatch import MonkeyPatch
    patch = MonkeyPatch()
    patch.setattr(registry, "targets", registered())
    scene = parse(slider_crank(time={"end": 0.5, "samples": 51}), "energy.toml")
    try:
        outcomes = run_tasks(tasks_for([scene], ["faithful"]), workers=1, timeout=30.0)
    finally:
        patch.undo()
    references = references_for([scene])
    out = tmp_path_factory.mktemp("report") / "run"
    build.write_report(out, [scene], references, outcomes, discrepancies(outcomes, references))
    return out


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (make test tries apt-get)")
def test_energy_figure_draws_in_a_real_browser(report):
    """The energy figure draws with no console error: each run's energy
    over its balance residual, one legend entry per run."""
    from playwright.sync_api import sync_playwright

    plot = ".plot[data-kind=energy]"
    errors = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox", "--disable-gpu"])
        try:
            page = browser.new_page(viewport={"width": 1300, "height": 1000})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto((report / "index.html").as_uri())
            page.locator("section.scenario summary").click()       # a passing scene opens collapsed
            page.locator(plot).scroll_into_view_if_needed()
            page.wait_for_function("s => document.querySelector(s).dataset.drawn === 'true'", arg=plot)
            traces = page.evaluate(f"() => document.querySelector('{plot}').data.map(t => [t.name, t.yaxis])")
            titles = page.evaluate(f"() => document.querySelector('{plot}').layout.annotations.map(a => a.text)")
        finally:
            browser.close()
    assert errors == []
    assert traces == [["reference", "y"], ["reference", "y2"], ["faithful", "y"], ["faithful", "y2"]]
    assert titles == ["energy E = kinetic + potential [J]", "energy balance |E − E(t0) − W| / S"]
