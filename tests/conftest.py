"""Shared fixtures: scenarios, the cached reference, engine adapters. The
marks, `mechval_compare` and `--mechval-report DIR` come from mechval's
pytest plugin (`mechval.testing.plugin`), as in any repository."""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
import os
from pathlib import Path

import pytest

from mechval.engines.registry import ENTRY_POINT_GROUP
from mechval.scenarios import builtin_names, load
from mechval.testing.comparison import engine_or_skip, reference_of

BUILTIN = builtin_names()
#: mechval's own engines: the entry points its pyproject.toml registers
#: (a plug-in installed beside them is not tested by this suite).
ENGINES = tuple(entry.name for entry in importlib.metadata.distribution("mechval").entry_points
                if entry.group == ENTRY_POINT_GROUP)


@functools.lru_cache(maxsize=None)
def builtin_scenario(name: str):
    return load(name)


#: Built-ins of the four closed-form kinds (each has a planar twin); the
#: planar built-ins have no closed form (tests/test_new_scenes.py), nor
#: have torque-driven and free scenes (integrated: tests/test_dynamic_scenes.py).
CLOSED_FORM = [name for name in BUILTIN if builtin_scenario(name).mechanism != "planar"
               and not builtin_scenario(name).forward_dynamics]
#: Built-in × engine pairs the engine cannot run at all, with the refusal the
#: harness gives up front (the engine's failure is the finding, see the
#: scene's file; tests/test_exudyn_planar.py runs the engine on it anyway
#: and fails when the engine starts to run it, so that the note gets updated).
CANNOT_RUN = {("exudyn", "planar-extra/parallelogram-double-fourbar"):
              "parallelogram-double-fourbar.toml: joint: exudyn: cannot run redundant constraints",
              ("exudyn", "planar-extra/double-fourbar-falling"):
              "double-fourbar-falling.toml: joint: exudyn: cannot run redundant constraints",
              ("drake", "planar-extra/parallelogram-double-fourbar"):
              "parallelogram-double-fourbar.toml: joint: drake: its adapter does not build redundant constraints",
              ("drake", "planar-extra/double-fourbar-falling"):
              "double-fourbar-falling.toml: joint: drake: its adapter does not build redundant constraints"}


#: (engine, built-in) pairs out of the default tolerances at the engine's
#: default settings, each an engine finding with its measured figure
#: (docs/engines.md): strict xfails, so that a fix shows.
OUT_OF_TOLERANCE: dict[tuple[str, str], str] = {
    # None at present. Drake 1.51.1 missed six built-ins at the shared
    # step rule (its discrete step is first order); those scene files set
    # its `refine` ([engines.drake], with the figures), and
    # tests/test_drake.py shows the misses at refine 1.
}

def builtin_reference(name: str):
    """The reference on a built-in, solved once per session (shared with
    `mechval_compare`)."""
    return reference_of(builtin_scenario(name))


@pytest.fixture(params=ENGINES)
def engine(request):
    return engine_or_skip(request.param)




#: Where `engine_work_started` leaves its mark (the environment: a worker
#: process gets the stand-in pickled by name, not the test's closure).
WORK_MARK = "MECHVAL_TEST_WORK_MARK"


def engine_work_started(*args, **kwargs):
    """Stands in for engine work under `no_engine_work`: leaves its mark and fails."""
    Path(os.environ[WORK_MARK]).write_text("started", encoding="utf-8")
    raise AssertionError("engine work started before the refusal")


@pytest.fixture
def no_engine_work(monkeypatch, tmp_path_factory):
    """Fail if any engine (or the reference for a report) starts working,
    in this process or in a worker."""
    mark = tmp_path_factory.mktemp("work") / "started"
    monkeypatch.setenv(WORK_MARK, str(mark))
    for module, name in [("runner", "scene_job"), ("runner", "simulate_task"), ("cost", "sweep"),
                         ("simulate", "simulate")]:
        monkeypatch.setattr(importlib.import_module(f"mechval.harness.{module}"), name, engine_work_started)
    yield
    assert not mark.exists(), "engine work started before the refusal"
