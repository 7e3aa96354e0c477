"""The command line as scripts outside the repository use it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import builtin_reference
from mechval.scenarios import builtin_path
from mechval.records.signals import signal_names

MECHVAL = str(Path(sys.executable).parent / "mechval")


def mechval(*args, cwd=None):
    return subprocess.run([MECHVAL, *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=300)


def test_list_names_scenarios_and_engines():
    out = mechval("list")
    assert out.returncode == 0, out.stderr
    for word in ("fourbar-seed", "slider-crank", "reference", "mujoco", "pybullet", "exudyn", "drake"):
        assert word in out.stdout
    assert "engines (installed: the library found and its version, not imported; a run imports it):" in out.stdout


def test_list_imports_nothing_heavy():
    """`mechval list` reads the scenario files' headers and the registry's
    entry points (issue 24: under 0.5 s; tests/bench/plan_bench.py prints
    the time): it imports neither numpy, pandas, scipy nor an engine
    library, nor the scenario loader."""
    from mechval.engines.registry import EngineUnavailable, adapter_class, engine_names
    libraries = set()
    for name in engine_names():
        try:
            libraries.add(adapter_class(name).library.split(".")[0])
        except EngineUnavailable:       # not installed: it cannot be imported either
            pass
    heavy = sorted({"numpy", "pandas", "scipy", "mechval.model.scenario", "mechval.scenarios.loader"} | libraries)
    code = (f"import sys; from mechval.harness.cli import main; status = main(['list']); "
            f"print(status, [m for m in {heavy!r} if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and out.stdout.splitlines()[-1] == "0 []", (out.stdout[-500:], out.stderr)


def test_the_listing_reads_what_the_loader_reads():
    """The listing finds the built-ins and escapes text without importing
    the loader or `mechval.model.scenario`: the same names and the same lines."""
    from mechval.harness.listing import builtin_files, one_line
    from mechval.model.scenario import one_line as scenario_one_line
    from mechval.scenarios import builtin_names
    assert list(builtin_files()) == builtin_names()
    assert all(path == builtin_path(name) for name, path in builtin_files().items())
    for text, limit in [("a\nb\x00c\u2028d é", None), ("x" * 30, 10), ("tab\there", 5), ("", 1)]:
        assert one_line(text, limit) == scenario_one_line(text, limit)


@pytest.mark.parametrize("name", ["fourbar-seed", "slider-crank"])
def test_simulate_reference_csv_round_trips(tmp_path, name):
    csv = tmp_path / "out.csv"
    out = mechval("simulate", name, "--engine", "reference", "--csv", csv)
    assert out.returncode == 0, out.stderr
    frame = pd.read_csv(csv)
    reference = builtin_reference(name)
    assert tuple(frame.columns) == signal_names("fourbar" if name.startswith("fourbar") else "slider_crank")
    # %.17g round-trips float64 exactly.
    np.testing.assert_array_equal(frame.to_numpy(), reference.frame.to_numpy())


def test_simulate_a_scenario_file_by_path(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(builtin_path("slider-crank-offset").read_text(encoding="utf-8"), encoding="utf-8")
    out = mechval("simulate", path, "--csv", tmp_path / "mine.csv")
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "mine.csv").exists()


def test_bad_file_is_refused_cleanly(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(builtin_path("fourbar-seed").read_text(encoding="utf-8").replace("coupler = 0.50", "coupler = -0.50"))
    csv = tmp_path / "out.csv"
    out = mechval("simulate", path, "--csv", csv)
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
    assert f"{path}: geometry.coupler: must be positive" in out.stderr
    assert not csv.exists() and list(tmp_path.iterdir()) == [path]


def test_unknown_engine_lists_available(tmp_path):
    out = mechval("simulate", "fourbar-seed", "--engine", "bullet3", "--csv", tmp_path / "x.csv")
    from mechval.engines.registry import engine_names
    listed = ", ".join(["reference", *sorted(engine_names())])
    assert out.returncode == 2 and f"available: {listed}" in out.stderr
    assert "Traceback" not in out.stderr


def test_analyse_reports_grashof_and_toggles():
    out = mechval("analyse", "fourbar-seed")
    assert out.returncode == 0, out.stderr
    assert "crank-rocker" in out.stdout and "toggle" in out.stdout


def test_simulate_refuses_to_write_an_engine_blow_up(tmp_path, monkeypatch):
    """NaN without a reason (an engine blow-up) writes no CSV, exit 1."""
    from fake_engines import registered
    from mechval.harness import cli
    from mechval.engines import registry
    monkeypatch.setattr(registry, "targets", registered())
    csv = tmp_path / "out.csv"
    assert cli.main(["simulate", "slider-crank", "--engine", "nonfinite", "--csv", str(csv)]) == 1
    assert not csv.exists()


def test_simulate_reports_an_engine_error_on_one_line(tmp_path, monkeypatch, capsys):
    """An engine that raises (a solver giving up, as Exudyn's SolverError on
    a 10¹⁸ m conrod) is an engine failure: exit 1, one line, no CSV, no
    traceback."""
    from fake_engines import registered
    from mechval.harness import cli
    from mechval.engines import registry
    monkeypatch.setattr(registry, "targets", registered())
    csv = tmp_path / "out.csv"
    assert cli.main(["simulate", "slider-crank", "--engine", "raising", "--csv", str(csv)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "engine failed: raising on" in err and "RuntimeError: solver diverged" in err
    assert not csv.exists()


def test_simulate_an_adapter_without_a_time_step(tmp_path, monkeypatch):
    """No step setting (like the reference): its run size is no steps, and
    it simulates (the run-size check once raised KeyError here)."""
    from fake_engines import registered
    from mechval.harness import cli
    from mechval.engines import registry
    monkeypatch.setattr(registry, "targets", registered())
    csv = tmp_path / "out.csv"
    assert cli.main(["simulate", "slider-crank", "--engine", "stepless", "--csv", str(csv)]) == 0
    assert csv.exists()


def short_scene(tmp_path, extra: str = "") -> Path:
    path = tmp_path / "short.toml"
    text = builtin_path("slider-crank").read_text(encoding="utf-8")
    path.write_text(text.replace("end = 2.0", "end = 0.1").replace("samples = 401", "samples = 11") + extra,
                    encoding="utf-8")
    return path


@pytest.mark.engine
@pytest.mark.parametrize("table,key,reason", [
    ("[engines.exudyn]\ntimestep = 0.0\n", "engines.exudyn.timestep", "must be positive"),
    ("[engines.exudyn]\ntimestep = 3e-3\n", "engines.exudyn.timestep", "0.003 s does not divide the sample interval"),
    ("[engines.mujoco]\nintegrator = \"bogus\"\n", "engines.mujoco.integrator", "must be one of"),
    ("[engines.pybullet]\nlayout = \"bogus\"\n", "engines.pybullet.layout", "must be one of"),
    ("[engines.mujoco]\nfoo = 1\n", "engines.mujoco.foo", "unknown setting"),
])
def test_bad_engine_settings_refused_before_any_run(tmp_path, table, key, reason):
    scene = short_scene(tmp_path, "\n" + table)
    engine = key.split(".")[1]
    for command in (["simulate", scene, "--engine", engine, "--csv", tmp_path / "x.csv"],
                    ["run", scene, "--engine", engine, "--out", tmp_path / "rep", "--quiet"]):
        out = mechval(*command)
        assert out.returncode == 2, out.stdout + out.stderr
        assert f"{scene}: {key}: {reason}" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "x.csv").exists() and not (tmp_path / "rep").exists()


def test_bad_numbers_and_paths_refused(tmp_path):
    checks = [
        (["run", "slider-crank", "--workers", "-1"], "must be 0 or more"),
        (["run", "slider-crank", "--timeout", "0"], "must be a positive number"),
        (["run", "slider-crank", "--engine", "reference"], "not an engine to run here"),
        (["simulate", "slider-crank", "--csv", tmp_path], "cannot write"),
    ]
    for command, message in checks:
        out = mechval(*command)
        assert out.returncode == 2 and message in out.stderr and "Traceback" not in out.stderr, command


def test_an_error_without_a_path_names_no_path(monkeypatch, capsys):
    """An OSError that is not about a file (a network timeout) is not
    reported as "cannot write" with an empty path."""
    from mechval.harness import cli

    def time_out(args):
        raise TimeoutError("Timed out trying to connect")
    monkeypatch.setattr(cli, "cmd_list", time_out)
    assert cli.main(["list"]) == 2
    assert capsys.readouterr().err == "mechval: error: Timed out trying to connect\n"


def test_output_into_a_closed_pipe_is_quiet(tmp_path):
    """`mechval list | head -1`: the reader goes away; no error, status 0."""
    import os
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        out = subprocess.run([MECHVAL, "list"], stdout=write_end, stderr=subprocess.PIPE, text=True, timeout=300)
    finally:
        os.close(write_end)
    assert out.returncode == 0 and out.stderr == ""
