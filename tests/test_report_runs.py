"""The report's "Runs and settings": settings apart from run facts, named,
with units, to 4 significant digits, the time step and the step count
first; no raw JSON on the page; runs.csv keeps every figure in full."""

from __future__ import annotations

import csv
import re
from dataclasses import replace

import pytest

from mechval.adapter import RunInfo
from mechval.harness.runner import discrepancies
from mechval.records.outcome import Outcome, Task
from mechval.harness.simulate import simulate
from mechval.reports import build, runs
from mechval.scenarios import parse
from mechval.testing.scenes import slider_crank

#: Settings as an adapter hands them over (engines/exudyn/adapter.py's keys): an
#: unrounded step (1/46000 s) and a force-scaled tolerance.
STEP = 1 / 46000
SETTINGS = {"solver": "index2", "timestep": STEP, "pre_roll_steps": 10, "spectral_radius": 0.9,
            "full_newton": True, "newton_absolute_tolerance": 1.0204449945637917e-10}
INFO = RunInfo(build_time_s=0.0237427950000324, wall_time_s=0.45217077800003835, steps=27611,
               facts={"closure_gap_max": 2.0670549729125932e-07, "newton_iterations": 24182,
                      "start": "forward dynamics: poses at the first instant from the reference's state"})


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    """A report of three runs of one engine (two settings, the second with
    a time step of 2e-05 s) and one failed run."""
    scene = parse(slider_crank(time={"end": 0.2, "samples": 21}), "a.toml")
    reference = simulate(scene, "reference")
    ran = replace(reference, source="exudyn", version="1.13.6", settings=SETTINGS, info=INFO)
    fine = replace(ran, settings={**SETTINGS, "timestep": 2e-05, "solver": "index3"},
                   info=replace(INFO, steps=10011, build_time_s=0.011396794999996018, wall_time_s=0.1997929610000142,
                                         facts={**INFO.facts, "closure_gap_max": 3.3306690738754696e-16,
                                                "newton_iterations": 17324}))
    outcomes = [Outcome(Task(scene, "exudyn"), ran, wall_time=0.549, cpu_time=0.3127),
                Outcome(Task(scene, "exudyn", "index3"), fine, wall_time=0.273),
                Outcome(Task(scene, "mujoco"), None, error="worker crashed (exit code 7)", wall_time=0.1)]
    records = discrepancies(outcomes, {scene.name: reference})
    out = build.write_report(tmp_path_factory.mktemp("runs") / "run", [scene], {scene.name: reference},
                             outcomes, records)
    html = (out / "index.html").read_text()
    return out, html[html.index('<h2 id="metadata">'):html.index("<h2>Provenance</h2>")]


def cells(html: str) -> list[list[str]]:
    """The text of every row of the first table in `html`."""
    table = html[html.index("<table"):html.index("</table>")]
    return [[re.sub(r"<[^>]+>", "", cell).strip() for cell in re.findall(r"<t[hd][^>]*>(.*?)</t[hd]>", row, re.S)]
            for row in re.findall(r"<tr>(.*?)</tr>", table, re.S)]


def test_settings_table_leads_with_time_step_and_steps(page):
    _, section = page
    exudyn = section[section.index("<h3>exudyn 1.13.6"):]
    assert cells(exudyn) == [
        ["scenario", "setting", "time step", "steps", "solver"],
        ["test-slider", "default", "2.174e-05 s", "27611", "index2"],     # 1/46000 s to 4 significant digits
        ["test-slider", "index3", "2e-05 s", "10011", "index3"]]
    # Settings the same in every run are named once, with their units.
    shared = re.sub(r"<[^>]+>", "", exudyn[exudyn.index("In every run:"):exudyn.index("</p>")])
    assert shared == ("In every run: pre_roll_steps 10 · spectral_radius 0.9 · full_newton true · "
                      "newton_absolute_tolerance 1.02e-10 N")


def test_run_facts_apart_with_units_and_no_raw_json(page):
    _, section = page
    facts = section[section.index("Run facts of exudyn"):]
    header, first, second = cells(facts)
    assert header[:6] == ["scenario", "setting", "task time", "task CPU time", "build time", "engine time"]
    assert first[2:] == ["0.549 s", "0.3127 s", "0.02374 s", "0.4522 s", "2.067e-07 m", "24182"]
    assert second[2:] == ["0.273 s", "", "0.0114 s", "0.1998 s", "3.331e-16 m", "17324"]   # no CPU time measured
    assert "start (every run): forward dynamics: poses at the first instant" in facts
    # The failed run is named with its reason; no record is printed as JSON.
    mujoco = section[section.index("<h3>mujoco"):]
    assert cells(mujoco)[1] == ["test-slider", "default", "run failed: worker crashed (exit code 7)"]
    assert "{" not in section and '"build_time_s":' not in section
    assert repr(STEP) not in section and "0.0237427950000324" not in section


def test_runs_csv_keeps_every_figure_in_full(page):
    out, _ = page
    with (out / "runs.csv").open(encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    default = {(r["kind"], r["name"]): r["value"] for r in rows if r["setting"] == "default" and r["engine"] == "exudyn"}
    assert float(default["setting", "timestep"]) == STEP                   # repr round-trips
    assert float(default["fact", "build_time_s"]) == INFO.build_time_s
    assert default["setting", "full_newton"] == "true" and default["fact", "steps"] == "27611"
    failed = [r for r in rows if r["engine"] == "mujoco"]
    assert failed[0]["kind"] == "error" and failed[0]["value"] == "worker crashed (exit code 7)"
    assert {r["version"] for r in rows if r["engine"] == "exudyn"} == {"1.13.6"}


@pytest.mark.parametrize("value, unit, shown", [
    (0.0002173913043478261, "s", "0.0002174 s"), (2e-05, "s", "2e-05 s"), (1e12, "kg", "1e+12 kg"),
    (24400, "", "24400"), (True, "", "true"), ("0.00021739130434782608 1", "", "0.0002174 1"),
    ("RK4", "", "RK4"), (float("nan"), "m", "NaN m"), (None, "s", "")])
def test_a_value_to_4_significant_digits_with_its_unit(value, unit, shown):
    assert runs.show(value, unit) == shown
