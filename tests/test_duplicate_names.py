"""Two scenarios of one name in one command are refused before anything
runs: references, report rows, discrepancies.csv and baseline folders are
keyed by the name, so the second scenario would be judged against the
first one's reference (issue 18, item 1)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fake_engines import registered
from mechval.harness.cli import main
from mechval.harness.cost import sweep
from mechval.engines import registry
from mechval.harness.executors import LocalExecutor
from mechval.harness.runner import references_for, tasks_for
from mechval.model.scenario import ScenarioError
from mechval.scenarios import builtin_path, load


def scene(tmp_path: Path, file: str, name: str, crank: str = "0.10") -> Path:
    """A short copy of the built-in slider-crank named `name`."""
    text = builtin_path("slider-crank").read_text(encoding="utf-8")
    path = tmp_path / file
    path.write_text(text.replace('name = "slider-crank"', f'name = "{name}"').replace("crank = 0.10", f"crank = {crank}")
                    .replace("end = 2.0", "end = 0.1").replace("samples = 401", "samples = 11"), encoding="utf-8")
    return path


@pytest.fixture
def fakes(monkeypatch):
    monkeypatch.setattr(registry, "targets", registered())


@pytest.mark.parametrize("command", [
    ["run", "SCENES", "--out", "OUT", "--quiet"],
    ["cost", "SCENES", "--out", "OUT", "--quiet", "--quick", "--repeats", "1"],
    ["baseline", "save", "SCENES", "--dir", "OUT"],
    ["baseline", "check", "SCENES", "--dir", "OUT"],
])
def test_same_name_in_two_files_is_refused(tmp_path, fakes, capsys, command):
    first, second = scene(tmp_path, "a.toml", "dup"), scene(tmp_path, "b.toml", "dup", crank="0.12")
    fill = {"SCENES": [str(first), str(second)], "OUT": [str(tmp_path / "report")]}
    args = [word for arg in command for word in fill.get(arg, [arg])]
    assert main([*args, "--engine", "faithful", "--workers", "1"]) == 2
    error = capsys.readouterr().err
    assert error.strip() == (f"mechval: error: {second}: name: 'dup' is also the name of {first}; "
                             "scenario names must be unique in one command (rename one)")
    assert not (tmp_path / "report").exists()


def test_same_file_twice_is_refused(tmp_path, fakes, capsys):
    path = scene(tmp_path, "a.toml", "dup")
    assert main(["run", str(path), str(path), "--engine", "faithful", "--out", str(tmp_path / "r"), "--quiet"]) == 2
    assert f"{path}: name: 'dup': the same scenario is given twice" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_library_entry_points_refuse_duplicate_names(tmp_path, fakes):
    scenarios = [load(scene(tmp_path, "a.toml", "dup")), load(scene(tmp_path, "b.toml", "dup", crank="0.12"))]
    for call in (lambda: references_for(scenarios), lambda: tasks_for(scenarios, ["faithful"]),
                 lambda: sweep(scenarios, ["faithful"], LocalExecutor(1, 60.0), quick=True, repeats=1)):
        with pytest.raises(ScenarioError, match="'dup' is also the name of"):
            call()


def test_distinct_names_are_each_judged_against_their_own_reference(tmp_path, fakes, capsys):
    """The faithful engine reproduces each scene's own reference: both pass
    (with one shared name the 0.12 crank scene's rows failed at ratio 200)."""
    first, second = scene(tmp_path, "a.toml", "one"), scene(tmp_path, "b.toml", "two", crank="0.12")
    assert main(["run", str(first), str(second), "--engine", "faithful", "--out", str(tmp_path / "r"),
                 "--quiet", "--workers", "1"]) == 0
    summary = capsys.readouterr().out
    assert "| one |" in summary and "| two |" in summary
