"""The engine registry: every engine, mechval's own included, from the
`mechval.engines` entry-point group; a name taken twice warns and keeps
mechval's; availability keyed on the engine library's own import name."""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from conftest import ENGINES
from mechval.engines import registry

MUJOCO = "mechval.engines.mujoco.adapter:MujocoAdapter"

TINY_ADAPTER = '''
"""A third-party engine adapter, installed as its own distribution."""
from mechval.engines.base import EngineAdapter, RawRun
from mechval.reference.adapter import raw_reference


class TinyAdapter(EngineAdapter):
    name = "tiny"
    library = "json"                     # the "engine library": always importable
    distribution = "tiny-mechval-engine"

    def default_settings(self, mechanism, times):
        return {"timestep": 1e-3}

    def run(self, mechanism, times, settings):
        return RawRun(raw_reference(mechanism, times))


class MissingLibraryAdapter(TinyAdapter):
    name = "missing"
    library = "no_such_engine_library_xyz"
'''

TINY_PYPROJECT = '''
[build-system]
requires = ["setuptools"]
build-backend = "setuptools.build_meta"

[project]
name = "tiny-mechval-engine"
version = "0.0.1"

[project.entry-points."mechval.engines"]
tiny = "tiny_mechval_engine:TinyAdapter"
missing = "tiny_mechval_engine:MissingLibraryAdapter"
mujoco = "tiny_mechval_engine:TinyAdapter"
reference = "tiny_mechval_engine:TinyAdapter"
'''


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The tiny adapter package, pip-installed into a folder of its own."""
    root = tmp_path_factory.mktemp("tiny")
    source, target = root / "src", root / "site"
    (source / "tiny_mechval_engine").mkdir(parents=True)
    (source / "tiny_mechval_engine" / "__init__.py").write_text(TINY_ADAPTER)
    (source / "pyproject.toml").write_text(TINY_PYPROJECT)
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    "--target", str(target), str(source)], check=True, capture_output=True)
    return target


def mechval(site: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(site)}
    return subprocess.run([sys.executable, "-m", "mechval.harness.cli", *args], capture_output=True,
                          text=True, env=env, timeout=120)


def test_an_installed_plugin_is_listed_and_runs(installed, tmp_path):
    listing = mechval(installed, "list")
    assert listing.returncode == 0, listing.stderr
    assert "tiny         installed (tiny-mechval-engine 0.0.1)" in listing.stdout
    # The plug-in's library is missing: not installed, with the library's name.
    assert "missing      not installed: missing: no_such_engine_library_xyz is not installed" in listing.stdout
    csv = tmp_path / "tiny.csv"
    run = mechval(installed, "simulate", "fourbar-seed", "--engine", "tiny", "--csv", str(csv))
    assert run.returncode == 0, run.stderr
    reference = tmp_path / "reference.csv"
    assert mechval(installed, "simulate", "fourbar-seed", "--csv", str(reference)).returncode == 0
    assert csv.read_text().splitlines()[1:] == reference.read_text().splitlines()[1:]


def test_a_plugin_cannot_take_a_builtin_name_or_the_reference(installed):
    """The plug-in's "mujoco" and "reference" are ignored, and a warning
    says so, naming the plug-in's distribution and which one is used."""
    code = textwrap.dedent("""
        from mechval.engines import registry
        print(registry.targets()["mujoco"])
        print(type(registry.adapter("reference")).__name__, "reference" in registry.engine_names())
    """)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(installed)}, check=True)
    assert run.stdout.split("\n")[:2] == [MUJOCO, "ReferenceAdapter False"]
    assert ("mechval.engines: 'mujoco' = 'tiny_mechval_engine:TinyAdapter' of tiny-mechval-engine 0.0.1 is "
            f"ignored: mechval's built-in engine, {MUJOCO!r}, has that name and is used") in run.stderr
    assert ("'reference' = 'tiny_mechval_engine:TinyAdapter' of tiny-mechval-engine 0.0.1 is ignored: "
            "'reference' is mechval's analytic reference") in run.stderr
    listing = mechval(installed, "list")
    said = [line for line in listing.stderr.splitlines() if line.startswith("mechval: warning: ")]
    assert listing.returncode == 0 and len(said) == 2 and "'mujoco'" in said[0] and "is used" in said[0], said


def test_the_builtins_are_mechvals_own_entry_points(monkeypatch):
    """mechval registers its engines as a plug-in does: its distribution's
    `mechval.engines` entry points are the built-ins, first, and with no
    entry point found there is no engine but the reference."""
    own = [e for e in importlib.metadata.distribution("mechval").entry_points if e.group == registry.ENTRY_POINT_GROUP]
    assert {e.name: e.value for e in own} == {"mujoco": MUJOCO, "pybullet": "mechval.engines.pybullet.adapter:PybulletAdapter",
                                             "exudyn": "mechval.engines.exudyn.adapter:ExudynAdapter",
                                             "pinocchio": "mechval.engines.pinocchio.adapter:PinocchioAdapter",
                                             "opensim": "mechval.engines.opensim.adapter:OpensimAdapter",
                                             "drake": "mechval.engines.drake.adapter:DrakeAdapter"}
    assert registry.engine_names()[:len(ENGINES)] == ENGINES == tuple(e.name for e in own)
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda **_: [])
    registry.targets.cache_clear()
    try:
        assert registry.engine_names() == ()
        assert type(registry.adapter("reference")).__name__ == "ReferenceAdapter"
        with pytest.raises(registry.UnknownEngine, match="'mujoco'"):
            registry.adapter("mujoco")
    finally:
        monkeypatch.undo()
        registry.targets.cache_clear()


def test_a_bug_in_an_adapter_module_is_not_unavailability(monkeypatch, tmp_path):
    """Only the engine library missing makes an engine unavailable; an
    adapter importing a module of its own package that does not exist fails."""
    package = tmp_path / "buggy_adapter_pkg"
    package.mkdir()
    (package / "__init__.py").write_text("from buggy_adapter_pkg import no_such_module\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    targets = {**registry.targets(), "buggy": "buggy_adapter_pkg:Adapter"}
    monkeypatch.setattr(registry, "targets", lambda: targets)
    with pytest.raises(ImportError):
        registry.adapter_class("buggy")


def test_installed_is_found_and_available_is_imported(monkeypatch, tmp_path):
    """`installed` (what `mechval list` shows) finds the library and its
    distribution's version without importing either; a library that is
    found but fails to import (a broken installation) is reported where
    the engine is used (`availability`, `adapter`)."""
    (tmp_path / "broken_engine_lib").mkdir()
    (tmp_path / "broken_engine_lib" / "__init__.py").write_text("raise ImportError('a broken build')\n")
    (tmp_path / "broken_engine_adapter.py").write_text(textwrap.dedent("""
        from mechval.engines.base import EngineAdapter

        class BrokenAdapter(EngineAdapter):
            name = "broken"
            library = "broken_engine_lib"
            distribution = "pytest"
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "targets", lambda: {"broken": "broken_engine_adapter:BrokenAdapter"})
    assert registry.installed() == {"broken": f"pytest {importlib.metadata.version('pytest')}"}
    assert "broken_engine_adapter" not in sys.modules and "broken_engine_lib" not in sys.modules
    assert registry.availability()["broken"].startswith("broken: broken_engine_lib cannot be imported")
