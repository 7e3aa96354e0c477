"""Engine regression checks against the committed baselines (baselines/),
and the baseline lifecycle: a tiny change of an engine's output, a changed
setting or engine version is caught and explained, an unchanged engine
passes, and no baseline is ever written or rewritten except by an explicit
`mechval baseline save` (with --force for an existing one)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import BUILTIN, builtin_reference, builtin_scenario, engine_or_skip
from mechval.harness import baseline as bl
from mechval.harness.baseline_run import check_run
from mechval.harness.cli import main
from mechval.engines.registry import ENGINE_NAMES, availability
from mechval.reports.build import provenance
from mechval.harness.runner import tasks_for
from mechval.signals import Signals

ROOT = Path(__file__).resolve().parent.parent / "baselines"
NOT_HARD = [n for n in BUILTIN if "hard" not in builtin_scenario(n).tags]
COMMITTED = sorted(ROOT.rglob("*.csv"))
#: A small, fast scene for the command-line tests (201 samples).
CLI_SCENARIO = "slider-crank-damped"


@pytest.mark.baseline
@pytest.mark.engine
@pytest.mark.parametrize("task", tasks_for([builtin_scenario(n) for n in NOT_HARD], ENGINE_NAMES),
                         ids=lambda task: f"{task.scenario.name}-{task.engine}-{task.setting}")
def test_engine_matches_its_baseline(task):
    engine = engine_or_skip(task.engine)
    path = bl.baseline_path(ROOT, task.engine, engine.version(), task.scenario.name, task.setting)
    if not path.exists():
        pytest.skip(f"no committed baseline for {task.engine} {engine.version()} (the installed version); "
                    f"create one with: mechval baseline save {task.scenario.name} --engine {task.engine} "
                    f"--dir baselines")
    signals = engine.simulate(task.scenario, task.overrides)
    verdict, text = check_run(ROOT, task, signals, builtin_reference(task.scenario.name), provenance())
    assert verdict == "ok", "\n" + text


# --- the comparison rule, on committed data (no engine run) ---------------

@pytest.fixture
def stored() -> bl.Baseline:
    if not COMMITTED:
        pytest.skip("no committed baselines")
    return bl.load(COMMITTED[0])


def perturbed(signals: Signals, name: str, factor: float) -> Signals:
    frame = signals.frame.copy()
    frame[name] = frame[name] * factor
    return Signals(frame, signals.source, signals.version, signals.settings, signals.missing)


def test_csv_round_trips_float64_exactly(stored, tmp_path):
    path = tmp_path / "copy.csv"
    stored.signals.to_csv(path)
    again = pd.read_csv(path)
    assert path.read_bytes() == stored.path.read_bytes()
    assert np.array_equal(again.to_numpy(), stored.signals.frame.to_numpy(), equal_nan=True)


def test_unchanged_signals_pass(stored):
    rows = bl.compare_to_baseline(stored.signals, stored.signals)
    assert set(rows["verdict"]) == {"identical"} and not bl.regressed(rows)


def test_change_of_1e7_relative_is_a_regression(stored, tmp_path):
    name = stored.signals.frame.columns[-1]
    path = tmp_path / "new.csv"
    perturbed(stored.signals, name, 1 + 1e-7).to_csv(path)       # through the file, as stored
    new = Signals(pd.read_csv(path), stored.signals.source)
    rows = bl.compare_to_baseline(stored.signals, new).set_index("signal")
    assert bl.regressed(rows.reset_index())
    assert rows.loc[name, "verdict"] == "regression"
    assert rows.loc[name, "relative"] == pytest.approx(1e-7, rel=1e-3)
    assert (rows.drop(index=name)["verdict"] == "identical").all()
    looser = bl.compare_to_baseline(stored.signals, new, signal_rtol={name: 1e-6})
    assert not bl.regressed(looser)


def test_last_bit_noise_is_within_the_threshold(stored):
    name = stored.signals.frame.columns[-1]
    rows = bl.compare_to_baseline(stored.signals, perturbed(stored.signals, name, 1 + 1e-13))
    assert set(rows["verdict"]) <= {"identical", "within"} and not bl.regressed(rows)


def test_zero_signal_is_judged_by_the_absolute_floor():
    t = np.linspace(0.0, 1.0, 5)
    zero = Signals(pd.DataFrame({"t": t, "alpha2": np.zeros(5)}), "x")
    noise = lambda v: Signals(pd.DataFrame({"t": t, "alpha2": np.full(5, v)}), "x")
    assert not bl.regressed(bl.compare_to_baseline(zero, noise(0.5 * bl.ABSOLUTE_FLOOR)))
    assert bl.regressed(bl.compare_to_baseline(zero, noise(10 * bl.ABSOLUTE_FLOOR)))


def test_changed_missing_values_samples_or_columns_are_regressions(stored):
    frame = stored.signals.frame
    name = frame.columns[-1]
    gap = frame.copy()
    gap.loc[3, name] = np.nan
    assert bl.regressed(bl.compare_to_baseline(stored.signals, Signals(gap, "x")))
    assert bl.regressed(bl.compare_to_baseline(stored.signals, Signals(frame.iloc[:-1], "x")))
    assert bl.regressed(bl.compare_to_baseline(stored.signals, Signals(frame.drop(columns=[name]), "x")))


def test_context_changes_name_version_settings_and_scenario(stored):
    meta = dict(stored.meta)
    key = sorted(meta["settings"])[0]
    new = dict(meta, version="99.0", scenario_hash="0" * 16,
               settings={**meta["settings"], key: "changed"})
    changes = bl.context_changes(meta, new)
    assert f"engine version differs: baseline {meta['engine']} {meta['version']}, now 99.0" in changes
    assert f"setting {key}: {meta['settings'][key]} → changed" in changes
    assert any(c.startswith("scenario content changed") for c in changes)
    assert bl.context_changes(meta, meta) == []


def test_find_prefers_the_same_version_else_the_newest(stored, tmp_path):
    meta = stored.meta
    for version in ("3.3.7", "3.10.0", "4.0.0"):
        bl.save(bl.baseline_path(tmp_path, "e", version, meta["scenario"], meta["setting"]), stored.signals, meta)
    find = lambda version: bl.find(tmp_path, "e", version, meta["scenario"], meta["setting"]).path.parent.parent.name
    assert find("3.3.7") == "3.3.7"
    assert find("5.0") == "4.0.0"
    assert bl.find(tmp_path, "other", "1.0", meta["scenario"], meta["setting"]) is None


def test_accuracy_change_says_improved_worsened_unchanged():
    reference = builtin_reference(CLI_SCENARIO)
    tolerance = builtin_scenario(CLI_SCENARIO).tolerance
    worse = perturbed(reference, "T12", 1 + 1e-3)
    verdicts = lambda old, new: dict(zip(*bl.accuracy_change(reference, old, new, tolerance)[["class", "verdict"]]
                                         .to_numpy().T))
    assert verdicts(reference, worse)["torque"] == "worsened"
    assert verdicts(worse, reference)["torque"] == "improved"
    assert set(verdicts(worse, worse).values()) == {"unchanged"}


# --- the command line: lifecycle of a baseline ---------------------------

@pytest.fixture(scope="module")
def any_engine() -> str:
    for name, reason in availability().items():
        if not reason:
            return name
    pytest.skip("no engine installed")


def baseline_cli(*args: str) -> int:
    return main(["baseline", *args, CLI_SCENARIO, "--workers", "1"])


def test_save_never_overwrites_without_force(any_engine, tmp_path, capsys):
    assert baseline_cli("save", "--engine", any_engine, "--dir", str(tmp_path)) == 0
    files = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    assert files and len(files) == 2 * len(tasks_for([builtin_scenario(CLI_SCENARIO)], [any_engine]))
    capsys.readouterr()
    assert baseline_cli("save", "--engine", any_engine, "--dir", str(tmp_path)) == 2
    error = capsys.readouterr().err
    assert "exist and were left as they are" in error and "--force" in error
    assert str(next(p for p in files if p.suffix == ".csv")) in error
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == files
    assert baseline_cli("save", "--engine", any_engine, "--dir", str(tmp_path), "--force") == 0
    assert "saved" in capsys.readouterr().out


def test_check_without_baseline_fails_and_writes_nothing(any_engine, tmp_path, capsys):
    assert baseline_cli("check", "--engine", any_engine, "--dir", str(tmp_path)) == 1
    out = capsys.readouterr().out
    assert f"mechval baseline save {CLI_SCENARIO} --engine {any_engine} --dir {tmp_path}" in out
    assert not any(tmp_path.iterdir())


def test_check_catches_and_explains_changes(any_engine, tmp_path, capsys):
    assert baseline_cli("save", "--engine", any_engine, "--dir", str(tmp_path)) == 0
    assert baseline_cli("check", "--engine", any_engine, "--dir", str(tmp_path)) == 0
    assert "bit-identical" in capsys.readouterr().out
    path = next(tmp_path.rglob("default.csv"))
    original = bl.load(path)

    perturbed(original.signals, "T12", 1 + 1e-7).to_csv(path)
    assert baseline_cli("check", "--engine", any_engine, "--dir", str(tmp_path)) == 1
    out = capsys.readouterr().out
    assert "T12" in out and "regression" in out and "verdict: REGRESSION" in out
    original.signals.to_csv(path)

    meta = dict(original.meta)
    key = sorted(meta["settings"])[0]
    changed = dict(meta, settings={**meta["settings"], key: "old-value"})
    path.with_suffix(".json").write_text(json.dumps(changed))
    assert baseline_cli("check", "--engine", any_engine, "--dir", str(tmp_path)) == 0
    assert f"setting {key}: old-value → {meta['settings'][key]}" in capsys.readouterr().out

    for json_path in path.parent.glob("*.json"):      # as if saved by version 0.0.1 of the engine
        json_path.write_text(json.dumps(dict(json.loads(json_path.read_text()), version="0.0.1")))
    shutil.move(path.parent.parent, path.parent.parent.with_name("0.0.1"))
    assert baseline_cli("check", "--engine", any_engine, "--dir", str(tmp_path)) == 0
    assert f"engine version differs: baseline {any_engine} 0.0.1, now {meta['version']}" in capsys.readouterr().out
