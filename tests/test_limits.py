"""Limits (README "Limits"): resource bombs and scenes that cannot be
simulated meaningfully are refused with the file, the key and how much they
would take, before any work; output is checked before the engines run."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import ENGINES, engine_or_skip
from fake_engines import registered
from mechval.harness import cli
from mechval.engines import registry
from mechval.harness.run_limits import Limits, check_run, run_size
from mechval.model.scenario import ScenarioError
from mechval.scenarios import builtin_path, kinds, load, parse
from mechval.harness.simulate import simulate
from mechval.testing.scenes import fourbar, slider_crank
from mechval.testing.twins import twin_document


def refused(data, key: str, words: str) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        parse(data, "bad.toml")
    assert (info.value.source, info.value.key) == ("bad.toml", key), str(info.value)
    assert words in info.value.reason, str(info.value)
    assert "\n" not in str(info.value)
    return info.value


@pytest.fixture
def nothing_evaluated(monkeypatch):
    """Fail if the kinds' front end evaluates anything at the samples: a refusal of
    a resource bomb must come first."""
    def evaluated(*args):
        raise AssertionError("the loader evaluated the scene before refusing it")
    monkeypatch.setattr(kinds, "_dense_times", evaluated)
    monkeypatch.setattr(kinds, "check_trustworthy", evaluated)


@pytest.mark.parametrize("samples", [9223372036854775807, 10**18, 10**7, 10**4000])
def test_too_many_samples_refused_before_any_array(nothing_evaluated, samples):
    error = refused(fourbar(time={"samples": samples}), "time.samples", "exceed the limit of 1,000,000")
    assert "GiB" in error.reason


def test_long_integers_and_deep_nesting_in_a_file(tmp_path):
    """tomllib cannot read a 5000-digit integer (ValueError) nor arrays or
    tables nested 1000 deep (RecursionError): one-line refusals instead."""
    seed = builtin_path("fourbar-seed").read_text(encoding="utf-8")
    checks = [
        (seed.replace("samples = 601", "samples = " + "9" * 5000), "time.samples", "an integer of 5000 digits"),
        (seed + "\ndeep = " + "[" * 1000 + "]" * 1000 + "\n", "file", "nested too deeply"),
        (seed + "\ndeep = " + "{a = " * 1000 + "1" + "}" * 1000 + "\n", "file", "nested too deeply"),
    ]
    for text, key, words in checks:
        path = tmp_path / "deep.toml"
        path.write_text(text, encoding="utf-8")
        with pytest.raises(ScenarioError) as info:
            load(path)
        assert (info.value.key, words in info.value.reason) == (key, True), str(info.value)


@pytest.mark.parametrize("data,key,words", [
    (fourbar(time={"end": 5e-324}), "time.end", "sample interval"),
    (fourbar(time={"end": 1e-5, "samples": 101}), "time.end", "below 1e-06 s"),
    (fourbar(drive={"phi0": 1e15}), "drive.phi0", "resolves it only to 0.12 rad"),
    (fourbar(drive={"omega0": 1e20}), "drive", "crank angle reaches 6e+20 rad"),
    # The turning point of a reversing drive is found, not only the ends.
    (fourbar(drive={"omega0": 2e3, "alpha": -1.0}, time={"end": 3000.0}), "drive", "at t = 2000 s"),
    (fourbar(mass={"crank": 1e-300}), "mass.crank", "below 1e-09 kg"),
    (fourbar(mass={"coupler": 2.5e-9}), "mass.coupler", "times lighter than the heaviest"),
    (fourbar(mass={"coupler": {"mass": 2.0, "izz": 1e-20}}), "mass.coupler", "below 1e-14 kg·m²"),
    (fourbar(mass={"crank": 1e-9, "coupler": 1e-9, "rocker": {"mass": 1e-9, "com": 0.25, "izz": 5e-15}}),
     "mass.rocker", "izz = 5e-15"),
    # A distant centre of mass was refused as "redundant constraints" (1e9 m,
    # by Exudyn) or crashed the reference's assembly (1e12 m, exit 1).
    (fourbar(mass={"rocker": {"mass": 25.0, "com": 1e9}}), "mass.rocker", "lies 1e+09 m from its link's nearest"),
    (fourbar(mass={"rocker": {"mass": 25.0, "com": -1e12}}), "mass.rocker", "1e+04 times the mechanism's size"),
    (fourbar(effects={"gravity": [0.0, 10**400]}), "effects.gravity[1]", "magnitude ~1e400 exceeds"),
    (fourbar(effects={"gravity": [0.0, float("nan")]}), "effects.gravity[1]", "must be finite"),
])
def test_scenes_that_cannot_be_simulated_meaningfully(data, key, words):
    refused(data, key, words)


def test_bounds_leave_the_builtins_and_their_neighbourhood_alone():
    """The bounds hold with margin for what engines handle (the light and
    heavy ends measured in README "Limits")."""
    parse(fourbar(mass={"crank": 1e-9, "coupler": 1e-9, "rocker": 1e-9}), "light.toml")
    parse(fourbar(mass={"crank": 1e-6, "coupler": 1e3}), "ratio.toml")
    parse(fourbar(drive={"phi0": -1e6 + 20.0}), "far.toml")
    parse(fourbar(mass={"rocker": {"mass": 25.0, "com": 5e3}}), "distant-com.toml")


def test_the_distant_centre_of_mass_bound_is_where_the_reference_breaks(monkeypatch):
    """MAX_COM_DISTANCE's measurement (the engines' figures are in its
    comment): the general reference follows fourbar-seed's planar twin
    with the rocker's centre of mass 5e3 m out (8.3e3 sizes) as with it on
    the rocker (kinematics do not depend on it: angles within 1e-9 rad,
    measured 3e-12); 1e5 m out (1.7e5 sizes) it can no longer assemble the
    four-bar, its closure tolerance scaled by a size the centre of mass
    sets (from an approximate pose, as a file gives it: the closed form's
    angles at t = 0 rounded to 0.01 rad)."""
    from mechval.reference import limits
    doc = twin_document("fourbar-seed")
    doc["time"].update(end=1.0, samples=101)
    doc["assembly"] = {body: round(theta, 2) for body, theta in doc["assembly"].items()}
    near = simulate(parse(doc, "near.toml"), "reference").frame["rocker.theta"]
    doc["body"][2]["com"] = [5e3, 0.0]
    far = simulate(parse(doc, "far.toml"), "reference").frame["rocker.theta"]
    assert np.abs(far - near).max() < 1e-9
    monkeypatch.setattr(limits, "MAX_COM_DISTANCE", 1e9)
    doc["body"][2]["com"] = [1e5, 0.0]
    with pytest.raises(ScenarioError, match="cannot be assembled"):
        parse(doc, "beyond.toml")


@pytest.mark.engine
def test_mass_that_crashed_mujoco_is_refused_and_the_bound_runs_in_mujoco():
    """A 1e-300 kg crank crashed MuJoCo's compiler (mass below mjMINVAL);
    the lightest accepted links run."""
    refused(fourbar(mass={"crank": 1e-300}), "mass.crank", "MuJoCo refuses")
    mujoco = engine_or_skip("mujoco")
    light = parse(fourbar(mass={"crank": 1e-9, "coupler": 1e-9, "rocker": 1e-9}, time={"end": 0.05, "samples": 6}),
                  "light.toml")
    assert np.isfinite(simulate(light, mujoco).frame.to_numpy()).all()


def test_huge_keys_and_values_are_not_echoed_in_full():
    key = "k" * 1_000_000
    error = refused(fourbar(geometry={key: 1.0}), "geometry." + key[:50] + "…", "unknown key")
    assert len(error.key) == 60 and error.key.endswith("…") and len(str(error)) < 400
    error = refused(fourbar(mass={"crank": "v" * 1_000_000}), "mass.crank", "expected a number, got str")
    assert len(str(error)) < 400
    refused(fourbar(**{"bad\nkey": 1}), "bad\\nkey", "unknown key")


def test_one_line():
    from mechval.model.scenario import one_line
    assert one_line("a|b\nc\x00é") == "a|b\\nc\\x00é"
    assert one_line("x" * 100, 10) == "x" * 9 + "…"


def test_unreadable_scenario_is_cannot_read_not_cannot_write(tmp_path, monkeypatch, capsys):
    path = tmp_path / "locked" / "scene.toml"
    path.parent.mkdir()
    path.write_text(builtin_path("fourbar-seed").read_text(encoding="utf-8"), encoding="utf-8")

    def denied(self, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(self))
    monkeypatch.setattr(Path, "read_text", denied)
    assert cli.main(["simulate", str(path), "--csv", str(tmp_path / "out.csv")]) == 2
    assert capsys.readouterr().err == f"mechval: error: {path}: file: cannot read: Permission denied\n"
    monkeypatch.setattr(Path, "is_file", denied)
    assert cli.main(["simulate", str(path), "--csv", str(tmp_path / "out.csv")]) == 2
    assert "file: cannot read: Permission denied" in capsys.readouterr().err


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads every file: permissions cannot be tested")
def test_unreadable_scenario_folder(tmp_path, capsys):
    folder = tmp_path / "locked"
    folder.mkdir()
    (folder / "scene.toml").write_text(builtin_path("fourbar-seed").read_text(encoding="utf-8"))
    folder.chmod(0)
    try:
        assert cli.main(["simulate", str(folder / "scene.toml"), "--csv", str(tmp_path / "o.csv")]) == 2
    finally:
        folder.chmod(stat.S_IRWXU)
    assert "cannot read" in capsys.readouterr().err


# --- run size: steps and memory of an engine run ------------------------------------------

def short_150(**time) -> dict:
    """slider-crank-150 (150 rad/s), as a dict, with another time grid."""
    import tomllib
    data = tomllib.loads(builtin_path("slider-crank-150").read_text(encoding="utf-8"))
    data["time"].update(time)
    return data


@pytest.mark.engine
@pytest.mark.parametrize("engine", ENGINES)
def test_long_runs_refused_with_the_step_count(engine):
    """end = 5000 s at 150 rad/s: within the angle bound, but every engine
    would take over 10⁸ steps (end = 1e7 asked 9.8 TiB or hung)."""
    engine_or_skip(engine)
    scene = parse(short_150(end=5000.0, samples=5001), "long.toml")
    with pytest.raises(ScenarioError) as info:
        check_run(scene, engine)
    # A step setting the file sets is named instead (Drake's `refine` on
    # slider-crank-150): the file chose the step, so the file says so.
    from mechval.engines.registry import adapter_class
    in_file = [key for key in adapter_class(engine).step_settings if key in scene.settings_for(engine)]
    expected = f"engines.{engine}.{in_file[0]}" if in_file else "time.end"
    assert info.value.key == expected and "steps" in info.value.reason and "--max-steps" in info.value.reason
    assert run_size(scene, "reference", {}).steps == 0
    check_run(scene, engine, limits=Limits(max_steps=1e9, max_memory=1e12))


@pytest.mark.engine
@pytest.mark.parametrize("engine,setting,value", [
    ("mujoco", "refine", 1000), ("pybullet", "preroll_steps", 100_000), ("exudyn", "pre_roll_steps", 100_000),
    ("exudyn", "timestep", 1e-12)])
def test_settings_that_multiply_steps_are_named(engine, setting, value):
    """Each value is within its setting's own range (the adapters refuse
    more), yet makes the run longer than the step limit given."""
    engine_or_skip(engine)
    data = short_150(end=0.5, samples=1501)
    if setting == "timestep":       # a step that divides the interval, 10⁶ steps per sample
        value = (0.5 / 1500) / 10**6
    data["engines"] = {engine: {setting: value}}
    with pytest.raises(ScenarioError) as info:
        check_run(parse(data, "s.toml"), engine, limits=Limits(max_steps=50_000))
    assert info.value.key == f"engines.{engine}.{setting}" and "steps" in info.value.reason


@pytest.mark.engine
def test_step_estimate_matches_the_engines_own_count():
    """The estimate from the settings is the count each engine reports
    (PyBullet's includes one step past the last sample, for its readings)."""
    scene = parse(slider_crank(time={"end": 0.2, "samples": 21}), "count.toml")
    for engine in ENGINES:
        signals = simulate(scene, engine_or_skip(engine))
        size = run_size(scene, engine, signals.settings)
        if engine == "opensim":
            # Simbody's error-controlled steps are its own and OpenSim's
            # Python API reports no count: the estimate is one step per
            # `max_step` (its cap): the fewest steps the run can take.
            assert signals.info.steps is None and size.steps >= 1, engine
            continue
        assert size.steps + (engine == "pybullet") == signals.info.steps, engine


def test_memory_refused_with_the_estimate():
    scene = parse(slider_crank(time={"end": 2.0, "samples": 400_001}), "big.toml")
    with pytest.raises(ScenarioError) as info:
        check_run(scene, "reference", limits=Limits(max_memory=2**20))
    assert info.value.key == "time.samples" and "GiB" in info.value.reason and "--max-memory" in info.value.reason


@pytest.fixture
def fakes(monkeypatch):
    monkeypatch.setattr(registry, "targets", registered())


def test_cli_refuses_over_max_steps_before_engine_work(fakes, no_engine_work, tmp_path, capsys):
    scene = tmp_path / "scene.toml"
    scene.write_text(builtin_path("slider-crank").read_text(encoding="utf-8"), encoding="utf-8")
    commands = [["simulate", str(scene), "--engine", "faithful", "--csv", str(tmp_path / "x.csv")],
                ["run", str(scene), "--engine", "faithful", "--out", str(tmp_path / "r"), "--quiet"],
                ["cost", str(scene), "--engine", "faithful", "--out", str(tmp_path / "c"), "--quiet"],
                ["baseline", "save", str(scene), "--engine", "faithful", "--dir", str(tmp_path / "b")],
                ["baseline", "check", str(scene), "--engine", "faithful", "--dir", str(tmp_path / "b")]]
    for command in commands:
        assert cli.main(command + ["--max-steps", "1000"]) == 2, command
        err = capsys.readouterr().err
        assert err.startswith(f"mechval: error: {scene}: time.end: one faithful run would take ") and \
            "more than the limit of 1e+03 (--max-steps)" in err and err.count("\n") == 1, err
        assert cli.main(command + ["--max-memory", "0.0001"]) == 2, command
        assert "GiB (--max-memory)" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [scene]


def test_output_checked_before_engine_work(fakes, no_engine_work, tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    commands = [["simulate", "slider-crank", "--engine", "faithful", "--csv", str(blocker / "x.csv")],
                ["simulate", "slider-crank", "--engine", "faithful", "--csv", str(tmp_path)],
                ["run", "slider-crank", "--engine", "faithful", "--out", str(blocker / "r"), "--quiet"],
                ["run", "slider-crank", "--engine", "faithful", "--out", str(tmp_path), "--quiet"],
                ["cost", "slider-crank", "--engine", "faithful", "--out", str(blocker / "deeper" / "c")],
                ["baseline", "save", "slider-crank", "--engine", "faithful", "--dir", str(blocker / "b")]]
    for command in commands:
        assert cli.main(command) == 2, command
        err = capsys.readouterr().err
        assert ("cannot write" in err or "exists" in err) and err.count("\n") == 1, err


# --- output files: permissions and escaping -------------------------------------------------

def test_output_files_follow_the_umask(tmp_path):
    from mechval.harness.baseline_store import save
    from mechval.records.signals import write_folder_atomically
    signals = simulate(parse(slider_crank(time={"end": 0.1, "samples": 11}), "x.toml"), "reference")
    previous = os.umask(0o022)
    try:
        signals.to_csv(tmp_path / "signals.csv")
        write_folder_atomically(tmp_path / "report", lambda folder: None)
        save(tmp_path / "baseline" / "default.csv", signals, {"engine": "reference"})
        os.umask(0o027)
        signals.to_csv(tmp_path / "private.csv")
    finally:
        os.umask(previous)
    mode = lambda p: stat.S_IMODE(p.stat().st_mode)
    assert mode(tmp_path / "signals.csv") == 0o644 and mode(tmp_path / "report") == 0o755
    assert mode(tmp_path / "baseline" / "default.csv") == 0o644
    assert mode(tmp_path / "baseline" / "default.json") == 0o644
    assert mode(tmp_path / "private.csv") == 0o640


def test_summary_table_escapes_names_and_reasons():
    from mechval.reports.build import summary_markdown
    scene = parse(slider_crank(name="a | b\nc", time={"end": 0.1, "samples": 11}), "x.toml")
    records = pd.DataFrame([dict(scenario=scene.name, engine="fake|engine", setting="default", signal="T12",
                                 max_error=1.0, ratio=2.0, verdict="fail", reason="off\nby | far", t_max=0.0,
                                 **{"class": "torque"})])
    text = summary_markdown(records, [scene], {"date": "today", "commit": "abc"})
    rows = [line for line in text.splitlines() if line.startswith("|")]
    cells = lambda line: len(line.replace("\\|", "").split("|"))
    header, failures = rows[:3], rows[3:]
    assert {cells(r) for r in header} == {cells(header[0])} and cells(header[0]) == 4
    assert {cells(r) for r in failures} == {12}        # ten columns: seven, then the error growth's three
    assert "a \\| b\\nc" in text and "off\\nby \\| far" in text


@pytest.mark.parametrize("edit, key", [
    (lambda doc: doc["time"].update(samples=10**7), "time.samples"),
    (lambda doc: doc["drive"][0].update(phi0=1e15), "drive[0].phi0"),
    (lambda doc: doc["body"][0].update(mass=1e-300), "body[0]"),
    (lambda doc: doc["body"][2].update(com=[1e9, 0.0]), "body[2].com"),
])
def test_planar_files_get_the_same_scene_bounds(edit, key):
    """A planar file is bounded like the four kinds, before the mechanism is
    followed over the run (10⁷ samples would otherwise be solved first)."""
    doc = twin_document("fourbar-seed")
    edit(doc)
    with pytest.raises(ScenarioError) as info:
        parse(doc, "twin.toml")
    assert info.value.key == key


@pytest.mark.engine
def test_a_run_refuses_a_later_scene_over_the_limits_before_any_scene_runs(no_engine_work, tmp_path, capsys):
    """`mechval run` prepares its scenes on the workers and checks the
    limits once all are prepared: a second scene over --max-steps stops
    the run before the first scene's reference or engine runs start."""
    engine_or_skip("mujoco")
    text = builtin_path("slider-crank").read_text(encoding="utf-8")
    short, long = tmp_path / "short.toml", tmp_path / "long.toml"
    short.write_text(text, encoding="utf-8")
    long.write_text(text.replace("end = 2.0", "end = 2000.0").replace('name = "slider-crank"', 'name = "long"'),
                    encoding="utf-8")
    assert cli.main(["run", str(short), "--engine", "mujoco", "--out", str(tmp_path / "r"), "--quiet",
                     "--max-steps", "1"]) == 2
    steps = float(capsys.readouterr().err.split("would take ")[1].split()[0])      # the short scene's run size
    assert cli.main(["run", str(short), str(long), "--engine", "mujoco", "--out", str(tmp_path / "r"), "--quiet",
                     "--max-steps", f"{10 * steps:g}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"mechval: error: {long}: time.end: one mujoco run would take ") and err.count("\n") == 1
    assert not (tmp_path / "r").exists()
