"""Fuzz `mechval simulate` with mutations of every built-in scenario file.

Every input must end in success with a CSV of finite values (empty cells
only in columns the notes explain), or in a one-line refusal, exit status 2,
naming the file, the key and the reason; never a traceback, a warning, a
hang or a half-written file. The default suite runs a dozen mutations per
built-in file (reference only) and, through each engine's command line in
a subprocess, five mutated files; `-m slow` runs 250 per file, a sample
through each engine on a shortened time grid, and three mutations of
every built-in through each engine's command line. Last, one test per
case the fuzz and fault probe found.
"""

from __future__ import annotations

import contextlib
import math
import os
import random
import signal
import subprocess
import sys
import tomllib
import traceback
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import BUILTIN, CLOSED_FORM, ENGINES, engine_or_skip
from mechval.harness.cli import main
from mechval.scenarios import builtin_path
from mechval.records.signals import SIGNAL_CLASS
from toml_fuzz import Case, mutate, mutate_text
from mechval.testing.twins import twin_document

#: Seconds one case may take before it counts as a hang (a refusal takes
#: milliseconds; the slowest accepted case loads and simulates 10⁶ samples).
HANG = 120
#: Engine runs in the fuzz are capped far below the default step limit.
ENGINE_MAX_STEPS = 20_000


def document(name: str) -> dict:
    """A built-in file's document, or for "twin/NAME" the built-in NAME
    written as a planar file (testing/twins.py)."""
    if name.startswith("twin/"):
        return twin_document(name.removeprefix("twin/"))
    return tomllib.loads(builtin_path(name).read_text(encoding="utf-8"))


def cases(name: str, count: int, seed: int = 0):
    """`count` mutated versions of a built-in file, reproducible by seed."""
    doc = document(name)
    for k in range(count):
        rng = random.Random(f"{name}/{seed}/{k}")
        case = mutate(doc, rng, rng.randint(1, 3))
        if rng.random() < 0.15:
            case = mutate_text(case, rng)
        yield f"{name.replace('/', '-')}-{seed}-{k}", case


@contextlib.contextmanager
def deadline(seconds: int):
    def hang(signum, frame):
        raise TimeoutError(f"no answer within {seconds} s")
    previous = signal.signal(signal.SIGALRM, hang)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def check_case(capfd, tmp_path, label: str, case: Case, engine: str = "reference", extra=()) -> int:
    """Run `mechval simulate` in-process on the case; assert the contract;
    return the exit status. `capfd` (pytest's) also catches what native
    code prints."""
    path, csv = tmp_path / f"{label}.toml", tmp_path / f"{label}.csv"
    path.write_text(case.toml(), encoding="utf-8")
    capfd.readouterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with deadline(HANG):
                status = main(["simulate", str(path), "--engine", engine, "--csv", str(csv), *extra])
        except BaseException:
            pytest.fail(f"{label} ({engine}): {case.steps}\n{traceback.format_exc()}")
    out, err = capfd.readouterr()
    context = f"{label} ({engine}): {case.steps}\nstdout: {out[:2000]}\nstderr: {err[:2000]}"
    assert not caught, context + "\nwarnings: " + "; ".join(str(w.message) for w in caught)
    if status == 0:
        assert out.startswith(f"wrote {csv}: ") and len(out.splitlines()) == 1, context
    else:
        assert not out, context
    lines = err.splitlines()
    if status == 0:
        notes = [line for line in lines if line.startswith("note: ")]
        assert notes == lines, context
        explained = {line.split(": ")[1] for line in notes}
        frame = pd.read_csv(csv)
        assert frame.columns[0] == "t" and all(name in SIGNAL_CLASS for name in frame.columns[1:]), context
        assert len(frame) >= 2, context
        for name in frame.columns:
            values = frame[name].to_numpy(dtype=float)
            finite = [math.isfinite(v) for v in values]
            assert all(finite) or (name in explained and not any(math.isinf(v) for v in values)), \
                f"{context}\n{name} has non-finite values without a reason"
        return status
    assert len(lines) == 1 and len(lines[0]) < 2500, context
    if status == 1 and engine != "reference":
        assert lines[0].startswith("mechval: engine failed: "), context
    else:
        assert status == 2, context
        prefix = f"mechval: error: {path}: "
        assert lines[0].startswith(prefix), context
        key, _, reason = lines[0][len(prefix):].partition(": ")
        assert key and reason, context
    assert not csv.exists(), context
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(label)) == [path.name], context
    return status


def run_all(capfd, tmp_path, labelled_cases, engine: str = "reference", extra=()) -> list[int]:
    """check_case on every case; fails at the end, listing every failure."""
    statuses, failures = [], []
    for label, case in labelled_cases:
        try:
            statuses.append(check_case(capfd, tmp_path, label, case, engine, extra))
        except (AssertionError, pytest.fail.Exception) as exc:
            failures.append(str(exc)[:3000])
    assert not failures, f"{len(failures)} failing cases:\n\n" + "\n\n".join(failures[:10])
    # The mutations must reach both outcomes, or the fuzz tests little.
    assert 0 in statuses and 2 in statuses
    return statuses


#: Planar files (`mechanism = "planar"`): the closed-form built-ins written
#: as planar files ("twin/NAME", testing/twins.py). The default run takes one
#: of each kind; the 509-revolution twin (slow to follow) only in the slow run.
PLANAR = [f"twin/{name}" for name in CLOSED_FORM]
PLANAR_DEFAULT = [f"twin/{name}" for name in
                  ("fourbar-seed", "slider-crank-offset", "shaper-quick-return", "hand-pump")]


@pytest.mark.parametrize("name", BUILTIN + PLANAR_DEFAULT)
def test_mutated_builtins_are_simulated_or_refused(capfd, tmp_path, name):
    run_all(capfd, tmp_path, cases(name, 12))


@pytest.mark.slow
@pytest.mark.parametrize("name", BUILTIN + PLANAR)
def test_many_mutated_builtins(capfd, tmp_path, name):
    # the general reference follows the 509-revolution twin for about a
    # minute per case: 12 cases (as the default run takes of each), not 250
    run_all(capfd, tmp_path, cases(name, 12 if name == "twin/fourbar-long-run" else 250, seed=1))


#: Spatial files (`mechanism = "spatial"`, scenarios/spatial/): simulated by
#: the reference as every built-in (the loader's checks: keys, values,
#: limits, the assembly, the mobility against the drives, a prescribed run
#: followed to its end, a consistent initial state; then the run), and
#: analysed (`mechval analyse`: the reference at ≥ 2001 instants, or the
#: integrated run's kept rows).
SPATIAL = [f"spatial/{p.stem}" for p in sorted(builtin_path("spatial/x").parent.glob("*.toml"))]


def check_analyse_case(capfd, tmp_path, label: str, case: Case) -> int:
    """`mechval analyse` in-process on the case: its report, or one line
    naming the file, the key and the reason (exit 2); nothing else."""
    path = tmp_path / f"{label}.toml"
    path.write_text(case.toml(), encoding="utf-8")
    capfd.readouterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with deadline(HANG):
                status = main(["analyse", str(path)])
        except BaseException:
            pytest.fail(f"{label}: {case.steps}\n{traceback.format_exc()}")
    out, err = capfd.readouterr()
    context = f"{label}: {case.steps}\nstdout: {out[:2000]}\nstderr: {err[:2000]}"
    assert not caught, context + "\nwarnings: " + "; ".join(str(w.message) for w in caught)
    if status == 0:
        assert out.startswith("scenario ") and "mobility" in out and not err, context
    else:
        assert status == 2 and not out and err.startswith(f"mechval: error: {path}: ") and err.count("\n") == 1, \
            context
    return status


@pytest.mark.parametrize("name", SPATIAL)
def test_mutated_spatial_files_are_simulated_or_refused(capfd, tmp_path, name):
    run_all(capfd, tmp_path, cases(name, 8))


@pytest.mark.parametrize("name", SPATIAL)
def test_mutated_spatial_files_are_analysed_or_refused(capfd, tmp_path, name):
    statuses = [check_analyse_case(capfd, tmp_path, label, case) for label, case in cases(name, 4, seed=2)]
    assert set(statuses) <= {0, 2}


@pytest.mark.slow
@pytest.mark.parametrize("name", SPATIAL)
def test_many_mutated_spatial_files(capfd, tmp_path, name):
    run_all(capfd, tmp_path, cases(name, 250, seed=1))
    for label, case in cases(name, 40, seed=3):
        check_analyse_case(capfd, tmp_path, label, case)


def engine_document(name: str, engine: str) -> dict:
    """The built-in file with a short time grid (where it has a [time]
    table: engine runs take a second or less) and an [engines.ENGINE] table
    holding every setting the adapter derives for it, so that mutations
    reach the settings too."""
    from mechval.reference.linkages import build_mechanism
    from mechval.scenarios import parse
    doc = document(name)
    if isinstance(doc.get("time"), dict):
        doc["time"] = {**doc["time"], "end": 0.05, "samples": 6}
    scenario = parse(doc, name)
    settings = engine_or_skip(engine).default_settings(build_mechanism(scenario), scenario.time.t)
    # A setting named "tolerance" cannot be given in a file: [engines.NAME.tolerance]
    # is the table of tolerance overrides.
    doc["engines"] = {engine: {k: v for k, v in settings.items() if k != "tolerance"}}
    return doc


@pytest.mark.slow
@pytest.mark.engine
@pytest.mark.parametrize("engine", ENGINES)
def test_mutated_builtins_through_engines(capfd, tmp_path, engine):
    """As above, through an engine; an engine that fails on a valid scene
    may also say so on one line (exit status 1)."""
    def engine_cases():
        for name in BUILTIN:
            doc = engine_document(name, engine)
            for k in range(20):
                rng = random.Random(f"{engine}/{name}/{k}")
                yield f"{name}-{k}", mutate(doc, rng, rng.randint(1, 2))
    run_all(capfd, tmp_path, engine_cases(), engine, ["--max-steps", str(ENGINE_MAX_STEPS)])


# --- Through each engine's command line, in a subprocess (the way users meet
# it): every engine command once let a refusal escape as a traceback on
# torque-driven and free scenes (the step rule integrates their motion).

MECHVAL = str(Path(sys.executable).parent / "mechval")
#: Built-ins the default sweep mutates per engine, and how many times
#: each: the free and the torque-driven scene (their settings integrate
#: the motion), and a prescribed one.
ENGINE_SWEEP = {"fourbar-falling": 2, "slider-crank-motor": 2, "slider-crank": 1}
#: Spatial files each engine's command line meets in the default sweep: a
#: free body (its initial state) and a driven closed loop.
SPATIAL_ENGINE_SWEEP = {"spatial/t-handle": 1, "spatial/rssr": 1}


def check_command_line(tmp_path: Path, label: str, case: Case, engine: str) -> int:
    """`mechval simulate FILE --engine ENGINE` in a subprocess: exit 0, 1
    or 2, no traceback, no warning; on failure one line and no CSV."""
    path, csv = tmp_path / f"{label}.toml", tmp_path / f"{label}.csv"
    path.write_text(case.toml(), encoding="utf-8")
    try:
        out = subprocess.run([MECHVAL, "simulate", str(path), "--engine", engine, "--csv", str(csv),
                              "--max-steps", str(ENGINE_MAX_STEPS)], capture_output=True, text=True, timeout=HANG)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"{label} ({engine}): {case.steps}: no answer within {HANG} s") from None
    context = f"{label} ({engine}): {case.steps}\nexit {out.returncode}\nstderr: {out.stderr[-3000:]}"
    assert out.returncode in (0, 1, 2) and "Traceback" not in out.stderr and "Warning" not in out.stderr, context
    lines = out.stderr.splitlines()
    if out.returncode == 0:
        assert all(line.startswith("note: ") for line in lines) and csv.exists(), context
    else:
        assert len(lines) == 1 and not csv.exists(), context
    return out.returncode


def engine_cases(engine: str, counts: dict[str, int], seed: int = 0):
    """Mutations of each named built-in (engine_document), count[name] of each."""
    for name, count in counts.items():
        doc = engine_document(name, engine)
        for k in range(count):
            rng = random.Random(f"{engine}/{name}/{seed}/{k}")
            yield f"{name.replace('/', '-')}-{seed}-{k}", mutate(doc, rng, rng.randint(1, 2))


def sweep_command_line(tmp_path: Path, engine: str, labelled_cases) -> list[int]:
    failures, statuses = [], []
    for label, case in labelled_cases:
        try:
            statuses.append(check_command_line(tmp_path, label, case, engine))
        except AssertionError as exc:
            failures.append(str(exc)[:3000])
    assert not failures, f"{len(failures)} failing cases:\n\n" + "\n\n".join(failures[:10])
    return statuses


@pytest.mark.engine
@pytest.mark.parametrize("engine", ENGINES)
def test_mutated_scenes_through_each_engine_command_line(tmp_path, engine):
    """A short sweep (five files, a few seconds each: one start-up of
    mechval and the engine); `-m slow` runs the longer one below."""
    engine_or_skip(engine)
    sweep_command_line(tmp_path, engine, engine_cases(engine, {**ENGINE_SWEEP, **SPATIAL_ENGINE_SWEEP}))


@pytest.mark.slow
@pytest.mark.engine
@pytest.mark.parametrize("engine", ENGINES)
def test_many_mutated_scenes_through_each_engine_command_line(tmp_path, engine):
    engine_or_skip(engine)
    counts = {name: 3 for name in BUILTIN + SPATIAL if name != "fourbar-long-run"}
    statuses = sweep_command_line(tmp_path, engine, engine_cases(engine, counts, seed=1))
    assert 0 in statuses and 2 in statuses


# --- Cases the fuzz and fault probe found (one each; the sweeps above may
# not draw them again).

def falling_with(tmp_path: Path, old: str, new: str, name: str = "fourbar-falling") -> Path:
    text = builtin_path(name).read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / f"{name}-probe.toml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


@pytest.mark.engine
@pytest.mark.parametrize("engine", ENGINES)
def test_a_motion_beyond_float64_is_refused_by_every_engine_command(tmp_path, capsys, engine):
    """fourbar-falling under gravity 9.2e18: the reference refuses it in one
    line; every engine command did so only as a traceback (Unrepresentable
    from the step rule, which integrates the motion)."""
    engine_or_skip(engine)
    scene = falling_with(tmp_path, "gravity = [0.0, -9.81]", "gravity = [0.0, -9.2e18]")
    out = tmp_path / "out"
    commands = [["simulate", str(scene), "--engine", engine, "--csv", str(out / "x.csv")],
                ["run", str(scene), "--engine", engine, "--out", str(out / "run"), "--quiet"],
                ["audit", str(scene), "--engine", engine],
                ["cost", str(scene), "--engine", engine, "--quick", "--out", str(out / "cost"), "--quiet"],
                ["baseline", "save", str(scene), "--engine", engine, "--dir", str(out / "baselines")],
                ["baseline", "check", str(scene), "--engine", engine, "--dir", str(out / "baselines")]]
    for command in commands:
        assert main(command) == 2, command
        captured = capsys.readouterr()
        assert captured.err.startswith(f"mechval: error: {scene}: time: {engine}: the motion leaves float64's "
                                       "range") and captured.err.count("\n") == 1, (command, captured.err)
        assert not captured.out and not out.exists(), command


@pytest.mark.engine
@pytest.mark.parametrize("engine", ENGINES)
def test_an_engine_blow_up_is_one_line_without_numpy_warnings(tmp_path, engine):
    """fourbar-seed under gravity 1e49 (MuJoCo returns NaN from the start):
    no `RuntimeWarning: All-NaN slice` from the health figures before the
    one-line failure."""
    engine_or_skip(engine)
    scene = falling_with(tmp_path, "gravity = [0.0, -9.81]", "gravity = [0.0, -1e49]", "fourbar-seed")
    scene.write_text(scene.read_text().replace("end = 6.0", "end = 0.5").replace("samples = 601", "samples = 51"))
    status = check_command_line(tmp_path, "blow-up", Case(tomllib.loads(scene.read_text()), ["gravity 1e49"]),
                                engine)
    if engine == "mujoco":      # the probe's case: the others follow it, or refuse it in one line
        assert status == 1


def test_health_of_an_all_nan_run_warns_nothing():
    from mechval.judging.health import health
    from mechval.reference.linkages import build_mechanism
    from mechval.reference.adapter import raw_reference
    from mechval.scenarios import load
    for name in ("fourbar-seed", "slider-crank"):
        mechanism = build_mechanism(load(name))
        raw = raw_reference(mechanism, np.linspace(0.0, 0.1, 5))
        raw.loc[:, raw.columns != "t"] = np.nan
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            result = health(mechanism, raw)
        assert result["nonfinite"].gt(0).all() and result["power_residual"].isna().all(), name


def test_a_scenario_name_is_at_most_100_characters(tmp_path):
    from mechval.model.scenario import ScenarioError
    from mechval.scenarios import parse
    for name in ("fourbar-seed", "twin/fourbar-seed"):
        doc = document(name)
        assert parse({**doc, "name": "n" * 100}, "ok.toml").name == "n" * 100
        with pytest.raises(ScenarioError) as refused:
            parse({**doc, "name": "n" * 10**6}, "long.toml")
        assert refused.value.key == "name" and "at most 100 characters, got 1,000,000" in refused.value.reason


def test_a_built_in_name_names_a_built_in(tmp_path, capsys):
    """`../../x` once loaded x.toml from wherever it led: a path outside
    scenarios/ needs its .toml."""
    from mechval.model.scenario import ScenarioError
    from mechval.scenarios import load
    (tmp_path / "x.toml").write_text(builtin_path("slider-crank").read_text(encoding="utf-8"), encoding="utf-8")
    escape = os.path.relpath(tmp_path / "x", builtin_path("x").parent)
    assert escape.startswith("..")
    with pytest.raises(ScenarioError) as refused:
        load(escape)
    assert refused.value.key == "file" and "no such scenario file or built-in scenario" in refused.value.reason
    assert main(["simulate", escape, "--csv", str(tmp_path / "x.csv")]) == 2
    assert capsys.readouterr().err.startswith(f"mechval: error: {escape}: file: no such scenario")
    assert load("planar-extra/double-fourbar-falling").mechanism == "planar"   # names under scenarios/ stay names
    assert load(str(tmp_path / "x.toml")).name == "slider-crank"


@pytest.mark.parametrize("address,reason", [
    ("inproc://x", "expected inproc://HOST/PID/N"),
    ("inproc://127.0.0.1/1/1", "an inproc:// address names a scheduler inside process 1"),
])
def test_an_inproc_dask_address_of_another_process_is_refused(tmp_path, capsys, address, reason):
    out = tmp_path / "cost"
    assert main(["cost", "slider-crank", "--quick", "--dask", address, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"mechval: error: --dask {address!r}: not a Dask scheduler address: {reason}")
    assert err.count("\n") == 1 and not out.exists()
