"""`mechval cost`: the ladder, failures as data, the convergence and
cheapest-setting rules, the report, and identical errors from the local
pool and a Dask cluster. The full sweep of fourbar-seed is marked slow."""

from __future__ import annotations

import base64
import json
import re
import zlib

import numpy as np
import pandas as pd
import pytest
from plotly.offline import get_plotlyjs

from fake_engines import registered
from mechval.harness.cli import main
from mechval.harness.cost import HEADLINE, REFERENCE, nice_count, points_for, sweep
from mechval.judging.cost_tables import asymptotic_range, cheapest, convergence
from mechval.engines import registry
from mechval.harness.executors import LocalExecutor
from mechval.reports import build
from mechval.reports.cost_report import cost_section
from mechval.scenarios import builtin_path, load
from mechval.harness.simulate import simulate
from mechval.model.kinematics import step_rate
from mechval.reference.linkages import build_mechanism

ENGINES = [name for name, reason in registry.availability().items() if not reason]
#: Columns that must not depend on where a point ran (times naturally do).
RESULT_COLUMNS = ["scenario", "engine", "variant", "step_s", "default", "class", "error", "worst_signal", "failure"]


@pytest.fixture(scope="module")
def short_toml(tmp_path_factory):
    """fourbar-seed cut to 0.5 s (51 samples, interval 10 ms) as a file."""
    text = builtin_path("fourbar-seed").read_text(encoding="utf-8")
    text = text.replace('name = "fourbar-seed"', 'name = "short-fourbar"').replace("end = 6.0", "end = 0.5")
    path = tmp_path_factory.mktemp("scene") / "short.toml"
    path.write_text(text.replace("samples = 601", "samples = 51"), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def local_table(short_toml):
    if not ENGINES:
        pytest.skip("no engine installed")
    return sweep([load(str(short_toml))], ENGINES, LocalExecutor(workers=2, timeout=300.0), quick=True)


def test_nice_count_is_the_next_1_2_5_count():
    assert [nice_count(r) for r in (0.3, 1, 1.2, 2, 4.5, 9, 18, 45, 90)] == [1, 1, 2, 2, 5, 10, 20, 50, 100]


@pytest.mark.engine
@pytest.mark.parametrize("engine", ENGINES)
def test_ladder_spans_two_decades_of_steps_dividing_the_interval(engine):
    scenario = load("fourbar-seed")
    points = points_for(scenario, engine)
    interval = scenario.time.t[1] - scenario.time.t[0]
    steps = sorted({p.step for p in points})
    assert steps[-1] / steps[0] >= 100 - 1e-9
    for step in steps:       # each a whole number of steps per sample interval
        assert abs(interval / step - round(interval / step)) < 1e-9
    assert sum(p.default for p in points) == 1
    cls = registry.adapter_class(engine)
    assert {p.setting for p in points} == set(cls.cost_variants)
    assert all(p.overrides[cls.step_setting] == p.step for p in points)


@pytest.mark.engine
def test_quick_sweep_gives_two_points_per_engine(local_table):
    table = local_table
    headline = table[table["class"] == HEADLINE]
    assert set(headline["engine"]) == set(ENGINES)
    assert headline.groupby("engine").size().eq(2).all()
    assert headline.groupby("engine")["default"].sum().eq(1).all()
    assert (headline["failure"] == "").all(), headline[headline["failure"] != ""]
    # Every default setting meets the default force tolerance (1e-2), the
    # time is positive and compared with the reference's own.
    assert (headline.loc[headline["default"], "error"] < 1e-2).all()
    assert (headline["s_per_sim_s"] > 0).all() and (headline["vs_reference"] > 0).all()
    reference = table[table["engine"] == REFERENCE]
    assert len(reference) == 1 and reference["s_per_sim_s"].iloc[0] > 0
    classes = set(table.loc[table["engine"] != REFERENCE, "class"])
    assert classes == {"angle", "velocity", "acceleration", "force", "torque", HEADLINE}


@pytest.mark.engine
def test_dask_cluster_gives_identical_errors(local_table, short_toml, tmp_path, capsys):
    from distributed import LocalCluster
    out = tmp_path / "cost"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        status = main(["cost", str(short_toml), "--quick", "--dask", cluster.scheduler_address, "--out", str(out),
                       "--quiet"])
    assert status == 0
    printed = capsys.readouterr().out
    assert "Cheapest setting reaching a force+torque error" in printed and "index.html" in printed
    assert sorted(p.name for p in out.iterdir()) == ["cheapest.csv", "convergence.csv", "cost.csv", "index.html"]
    csv_text = (out / "cost.csv").read_text()
    assert "nan" not in csv_text.lower() and "inf" not in csv_text.lower()
    remote = pd.read_csv(out / "cost.csv", keep_default_na=False, na_values={"step_s": [""], "error": [""]})
    engine_rows = lambda t: t.loc[t["engine"] != REFERENCE, RESULT_COLUMNS].reset_index(drop=True)
    # %.17g round-trips float64, so "identical" means equal to the last bit.
    pd.testing.assert_frame_equal(engine_rows(remote), engine_rows(local_table), check_dtype=False,
                                  check_exact=True)
    html = (out / "index.html").read_text()
    # The interactive diagram's library, inlined once (deflated; the page inflates it).
    inlined = re.findall(r'<script type="text/plain" id="plotly-js">(.*?)</script>', html, re.S)
    assert len(inlined) == 1 and zlib.decompress(base64.b64decode(inlined[0])).decode() == get_plotlyjs()
    figure = json.loads(re.search(r'<script type="application/json" id="cost-s-short-fourbar">(.*?)</script>',
                                  html, re.S).group(1))
    names = {trace["name"] for trace in figure["data"]}
    assert {name.split(" [")[0] for name in names} == set(ENGINES)


def test_failures_are_data(monkeypatch, short_toml):
    monkeypatch.setattr(registry, "targets", registered())
    engines = ["faithful", "raising", "nonfinite", "crashing"]
    table = sweep([load(str(short_toml))], engines, LocalExecutor(workers=2, timeout=60.0), quick=True, repeats=1)
    headline = table[table["class"] == HEADLINE].groupby("engine")["failure"].first()
    assert headline["faithful"] == ""
    assert "solver diverged" in headline["raising"]
    assert "non-finite" in headline["nonfinite"]
    assert "crashed" in headline["crashing"]
    # A failed point has no error and no time; it never counts as reaching a target.
    failed = table[table["engine"].isin(["raising", "crashing"])]
    assert failed["error"].isna().all() and failed["s_per_sim_s"].isna().all()
    assert set(cheapest(table)["engine"]) == {"faithful"}


def test_an_adapter_without_a_time_step_costs_one_point(monkeypatch, short_toml):
    """No step to sweep: its defaults are one point, timed and compared."""
    monkeypatch.setattr(registry, "targets", registered())
    table = sweep([load(str(short_toml))], ["stepless"], LocalExecutor(workers=1, timeout=60.0), repeats=1)
    mine = table[table["engine"] == "stepless"]
    assert set(mine["variant"]) == {"default"} and mine["default"].all() and (mine["failure"] == "").all()
    assert mine["s_per_sim_s"].notna().all()


def test_a_free_scene_sweeps_its_ladder_at_its_reference_runs_peak_rate(monkeypatch, tmp_path):
    """fourbar-falling (no drive) cut to 0.5 s: the ladder's rotations per
    step are taken at Ω of the reference's integrated run (at least its
    peak |ω2|); each point's error is over the whole run (the largest
    |engine − reference| over every sample), finite, and shrinks with the
    setting (the fake 'loose' engine: the reference at rtol = step)."""
    monkeypatch.setattr(registry, "targets", registered())
    text = builtin_path("fourbar-falling").read_text(encoding="utf-8")
    path = tmp_path / "short-falling.toml"
    path.write_text(text.replace("end = 3.0", "end = 0.5").replace("samples = 301", "samples = 51"), encoding="utf-8")
    scenario = load(str(path))
    interval, times = 0.01, scenario.time.t
    reference = simulate(scenario, "reference").frame
    rate = step_rate(build_mechanism(scenario), times)
    assert rate >= np.abs(reference["omega2"]).max() > 0
    points = points_for(scenario, "loose")
    ladder = {nice_count(interval * rate / rad) for rad in registry.adapter_class("loose").cost_ladder}
    assert {round(interval / p.step) for p in points} == ladder | {10}       # the fake's default: 1 ms
    table = sweep([scenario], ["loose"], LocalExecutor(workers=2, timeout=300.0), repeats=1)
    angle = table[(table["engine"] == "loose") & (table["class"] == "angle")].sort_values("step_s")
    assert (angle["failure"] == "").all() and np.isfinite(angle["error"]).all()
    assert angle["error"].iloc[0] < angle["error"].iloc[-1]
    coarsest = angle.iloc[-1]
    engine = simulate(scenario, "loose", {"timestep": coarsest["step_s"]}).frame
    whole_run = max(np.abs(engine[s] - reference[s]).max() for s in ("theta2", "theta3", "theta4"))
    assert coarsest["error"] == whole_run


def test_order_is_fitted_over_the_asymptotic_range_only():
    steps = np.array([1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2])
    # O(h²) with a floor at 1e-4 (fine end) and saturation at the coarsest step.
    errors = np.maximum(1e3 * steps**2, 1e-4)
    errors[-1] = errors[-2] * 1.5
    used = asymptotic_range(steps, errors)
    assert list(steps[used]) == [5e-4, 1e-3, 2e-3, 5e-3]
    table = pd.DataFrame(dict(scenario="s", engine="e", variant="v", **{"class": "force"}, step_s=steps,
                              error=errors, failure=""))
    orders = convergence(table)
    assert orders["order"].iloc[0] == pytest.approx(2.0, abs=1e-9) and orders["points"].iloc[0] == 4
    flat = convergence(table.assign(error=1e-6))
    assert np.isnan(flat["order"].iloc[0]) and flat["points"].iloc[0] == 0


def test_cheapest_setting_or_the_best_when_not_reached():
    table = pd.DataFrame(dict(scenario="s", engine="e", variant=["a", "a", "b"], **{"class": "force"},
                              step_s=[1e-3, 1e-4, 1e-3], error=[2e-3, 2e-5, 5e-4], s_per_sim_s=[0.1, 1.0, 0.3],
                              vs_reference=[10.0, 100.0, 30.0], failure=""))
    cheap = cheapest(table, targets=(1e-2, 1e-3, 1e-6)).set_index("target")
    assert cheap.loc[1e-2, "variant"] == "a" and cheap.loc[1e-2, "step_s"] == 1e-3
    assert cheap.loc[1e-3, "variant"] == "b" and cheap.loc[1e-3, "reached"]
    assert not cheap.loc[1e-6, "reached"] and cheap.loc[1e-6, "error"] == 2e-5


@pytest.mark.engine
def test_cost_section_in_the_run_report(local_table, tmp_path, short_toml):
    scene = load(str(short_toml))
    section = cost_section(local_table, convergence(local_table), cheapest(local_table))
    reference = simulate(scene, "reference")
    records = pd.DataFrame(columns=["scenario", "engine", "setting", "signal", "verdict", "ratio"])
    out = build.write_report(tmp_path / "run", [scene], {scene.name: reference}, [], records, [section])
    html = (out / "index.html").read_text()
    assert 'id="cost"' in html and "work-precision diagram of short-fourbar" in html
    # the section is HTML, not text shown as HTML source
    assert '<div class="plot" data-figure="cost-s-short-fourbar"' in html and "&lt;h3&gt;" not in html


@pytest.mark.engine
@pytest.mark.slow
def test_full_sweep_of_fourbar_seed(tmp_path, capsys):
    """`mechval cost fourbar-seed`: the orders the engines are known for."""
    assert main(["cost", "fourbar-seed", "--out", str(tmp_path / "cost"), "--quiet"]) == 0
    orders = pd.read_csv(tmp_path / "cost" / "convergence.csv").set_index(["engine", "variant", "class"])["order"]
    if "exudyn" in ENGINES:
        assert orders["exudyn", "index2", "force"] == pytest.approx(2.0, abs=0.2)
    if "mujoco" in ENGINES:
        assert orders["mujoco", "Euler", "angle"] == pytest.approx(1.0, abs=0.2)
    if "pybullet" in ENGINES:     # F14 converges only as O(dt) (docs/engines.md)
        assert orders["pybullet", "Dantzig", "force"] == pytest.approx(1.0, abs=0.2)
    assert "not reached" in capsys.readouterr().out


@pytest.mark.engine
@pytest.mark.slow
def test_run_with_cost_adds_the_section(tmp_path, short_toml):
    """`mechval run --cost`: the full ladder of one engine in the run report."""
    engine = ENGINES[0] if ENGINES else pytest.skip("no engine installed")
    out = tmp_path / "run"
    main(["run", str(short_toml), "--engine", engine, "--cost", "--out", str(out), "--quiet"])
    assert 'id="cost"' in (out / "index.html").read_text()
    assert (out / "cost.csv").exists()


@pytest.mark.parametrize("address,reason", [
    ("garbage", "expected tcp://HOST:PORT"),
    ("tcp://127.0.0.1:notaport", "the port 'notaport' is not a number from 1 to 65535"),
    ("tcp://127.0.0.1:70000", "the port '70000' is not a number from 1 to 65535"),
    ("tcp://:8786", "expected tcp://HOST:PORT"),
    ("http://127.0.0.1:8786", "unknown scheme 'http'"),
    ("", "empty"),
])
def test_bad_dask_address_refused_before_any_run(tmp_path, capsys, short_toml, address, reason):
    out = tmp_path / "cost"
    assert main(["cost", str(short_toml), "--quick", "--dask", address, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"mechval: error: --dask {address!r}: not a Dask scheduler address: {reason}")
    assert err.count("\n") == 1 and not out.exists()


def test_unreachable_dask_scheduler_is_one_line_and_quick(tmp_path, capsys, short_toml):
    """Nobody listens on the port: exit 3 after the stated connect timeout,
    not Dask's 30 s default, and no "cannot write" with an empty path."""
    import socket
    import time
    with socket.socket() as sock:           # a port that was free a moment ago
        sock.bind(("127.0.0.1", 0))
        address = f"tcp://127.0.0.1:{sock.getsockname()[1]}"
    out = tmp_path / "cost"
    start = time.monotonic()
    status = main(["cost", str(short_toml), "--quick", "--dask", address, "--dask-connect-timeout", "1",
                   "--out", str(out), "--quiet"])
    assert status == 3 and time.monotonic() - start < 5
    # Engines that are not installed are noted before, one line each.
    err = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("note: skipping ")]
    assert len(err) == 1 and not out.exists()
    assert err[0].startswith(f"mechval: error: cannot connect to the Dask scheduler at {address} (waited up to 1 s): ")
