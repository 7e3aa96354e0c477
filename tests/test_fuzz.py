"""Fuzz `mechval simulate` with mutations of every built-in scenario file.

Every input must end in success with a CSV of finite values (empty cells
only in columns the notes explain), or in a one-line refusal, exit status 2,
naming the file, the key and the reason; never a traceback, a warning, a
hang or a half-written file. The default suite runs a dozen mutations per
built-in file (reference only); `-m slow` runs 250 per file and a sample
through each engine on a shortened time grid.
"""

from __future__ import annotations

import contextlib
import math
import random
import signal
import tomllib
import traceback
import warnings

import pandas as pd
import pytest

from conftest import BUILTIN, engine_or_skip
from mechval.harness.cli import main
from mechval.engines.registry import ENGINE_NAMES
from mechval.scenarios import builtin_path
from mechval.signals import SIGNAL_CLASS
from toml_fuzz import Case, mutate, mutate_text

#: Seconds one case may take before it counts as a hang (a refusal takes
#: milliseconds; the slowest accepted case loads and simulates 10⁶ samples).
HANG = 120
#: Engine runs in the fuzz are capped far below the default step limit.
ENGINE_MAX_STEPS = 20_000


def document(name: str) -> dict:
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


#: Planar files (`mechanism = "planar"`): the shipped twins of the built-ins,
#: by path under scenarios/. The default run takes one of each kind; the
#: 509-revolution twin (slow to follow) only in the slow run.
PLANAR = sorted(f"planar-twins/{p.stem}" for p in (builtin_path("x").parent / "planar-twins").glob("*.toml"))
PLANAR_DEFAULT = [f"planar-twins/{name}" for name in
                  ("fourbar-seed", "slider-crank-offset", "shaper-quick-return", "hand-pump")]


@pytest.mark.parametrize("name", BUILTIN + PLANAR_DEFAULT)
def test_mutated_builtins_are_simulated_or_refused(capfd, tmp_path, name):
    run_all(capfd, tmp_path, cases(name, 12))


@pytest.mark.slow
@pytest.mark.parametrize("name", BUILTIN + PLANAR)
def test_many_mutated_builtins(capfd, tmp_path, name):
    # the general reference follows the 509-revolution twin for about a
    # minute per case: 12 cases (as the default run takes of each), not 250
    run_all(capfd, tmp_path, cases(name, 12 if name == "planar-twins/fourbar-long-run" else 250, seed=1))


def engine_document(name: str, engine: str) -> dict:
    """The built-in file with a short time grid (where it has a [time]
    table: engine runs take a second or less) and an [engines.ENGINE] table
    holding every setting the adapter derives for it, so that mutations
    reach the settings too."""
    from mechval.linkages import build_mechanism
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
@pytest.mark.parametrize("engine", ENGINE_NAMES)
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
