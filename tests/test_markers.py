"""The `engine` marker is complete: `-m "not engine"` needs no engine.

Checked in a Python where no engine library can be imported (a
`sitecustomize` on PYTHONPATH blocks them, in every process the tests
start), as on a machine without them: collecting the suite gives no error,
and the selection passes with nothing skipped for want of an engine.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ENGINE_LIBRARIES = ("mujoco", "pybullet", "pybullet_data", "exudyn", "pinocchio", "opensim", "pydrake")
BLOCKED = "engine libraries blocked"
SITECUSTOMIZE = f'''
import sys
from importlib.abc import MetaPathFinder


class NoEngines(MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in {ENGINE_LIBRARIES!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}} ({BLOCKED})", name=name)
        return None


sys.meta_path.insert(0, NoEngines())
'''
#: What a test that wanted an engine says when it skips for want of one.
WANTED_AN_ENGINE = re.compile(rf"{BLOCKED}|cannot be imported|could not import|no engine|empty parameter set",
                              re.IGNORECASE)


def pytest_without_engines(tmp_path: Path, *args: str) -> tuple[subprocess.CompletedProcess, Path]:
    """Run pytest on the suite (this module left out) with the engine
    libraries blocked; the process and its JUnit XML report."""
    (tmp_path / "sitecustomize.py").write_text(SITECUSTOMIZE, encoding="utf-8")
    path = os.pathsep.join(p for p in (str(tmp_path), os.environ.get("PYTHONPATH", "")) if p)
    report = tmp_path / "report.xml"
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-rs",
                           f"--ignore={Path(__file__).relative_to(ROOT)}", f"--junitxml={report}", *args],
                          cwd=ROOT, env={**os.environ, "PYTHONPATH": path}, capture_output=True, text=True,
                          timeout=1800)
    return proc, report


def test_the_blocker_blocks(tmp_path):
    """The check's premise: with the sitecustomize, importing an engine
    library fails as if it were not installed."""
    (tmp_path / "sitecustomize.py").write_text(SITECUSTOMIZE, encoding="utf-8")
    proc = subprocess.run([sys.executable, "-c", "import mujoco"], env={**os.environ, "PYTHONPATH": str(tmp_path)},
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode != 0 and "ModuleNotFoundError" in proc.stderr and BLOCKED in proc.stderr


def test_collecting_needs_no_engine(tmp_path):
    """Collecting every test (all markers) imports no engine library it
    needs: a missing engine must not break the run at collection."""
    proc, _ = pytest_without_engines(tmp_path, "--collect-only", "-m", "engine or not engine")
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]


@pytest.mark.slow
def test_not_engine_selection_runs_without_engines(tmp_path):
    """`pytest -m "not engine"` (slow tests included, as -m replaces the
    default selection) passes, and no test in it skips for want of an
    engine."""
    proc, report = pytest_without_engines(tmp_path, "-m", "not engine")
    assert proc.returncode == 0, proc.stdout[-6000:] + proc.stderr[-2000:]
    wanted = []
    for case in ET.parse(report).getroot().iter("testcase"):
        for skipped in case.findall("skipped"):
            reason = skipped.get("message") or ""
            if WANTED_AN_ENGINE.search(reason):
                wanted.append(f"{case.get('classname')}::{case.get('name')}: {reason}")
    assert not wanted, "tests that need an engine but are not marked `engine`:\n" + "\n".join(wanted)
