"""mechval's pytest plugin in a repository of a user's own (docs/testing.md):
a folder outside mechval's tree with a scene file and a test file that
uses `mechval_compare`, run by pytest in a process of its own, as the user
would run it. A comparison that passes; one out of tolerance (an engine
that reports the reference with a bias on one force) whose failure message
is the discrepancy table; `--mechval-report DIR` writing the report of
both; a report folder that exists refused before any test; the engines a
test names, run by name."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"

SCENE = """
name = "my-crank-rocker"
mechanism = "fourbar"

[geometry]
ground = 0.6
crank = 0.25
coupler = 0.5
rocker = 0.5
branch = "open"

[mass]
crank = 1.0
coupler = 2.0
rocker = 2.0

[drive]
phi0 = 0.0
omega0 = 6.0
alpha = 0.0

[effects]
gravity = [0.0, -9.81]

[time]
end = 0.5
samples = 51
"""

#: Two adapters of the user's own, not registered: one reports the
#: reference, one the reference with the crank pin's Fx 5 % of its peak
#: too large (the force tolerance is 1 % of the peak).
FAKE_TESTS = '''
import pytest
from mechval.adapter import EngineAdapter, RawRun
from mechval.reference.adapter import raw_reference


class Faithful(EngineAdapter):
    name = "faithful"
    library = "numpy"
    distribution = "numpy"
    settings_spec = {}
    step_setting = ""

    def default_settings(self, mechanism, times):
        return {}

    def run(self, mechanism, times, settings):
        return RawRun(raw_reference(mechanism, times))


class Biased(Faithful):
    name = "biased"

    def run(self, mechanism, times, settings):
        frame = raw_reference(mechanism, times)
        frame["O2.Fx"] += 0.05 * frame["O2.Fx"].abs().max()
        return RawRun(frame)


def test_faithful(mechval_compare):
    records = mechval_compare("../scenes/crank-rocker.toml", Faithful())
    assert (records["verdict"] == "pass").all()


def test_biased(mechval_compare):
    mechval_compare("../scenes/crank-rocker.toml", Biased())


@pytest.mark.engine
@pytest.mark.slow
@pytest.mark.hard
@pytest.mark.baseline
def test_the_marks_are_known():
    pass
'''

#: docs/testing.md's example test file.
(ENGINE_TESTS,) = re.findall(r"^```python compare-example\n(.*?)^```", (DOCS / "testing.md").read_text(encoding="utf-8"),
                             re.S | re.M)


def user_repository(root: Path, tests: str) -> Path:
    (root / "scenes").mkdir(parents=True)
    (root / "scenes" / "crank-rocker.toml").write_text(SCENE)
    (root / "tests").mkdir()
    (root / "tests" / "test_linkages.py").write_text(tests)
    return root


def pytest_in(repository: Path, *args: str) -> subprocess.CompletedProcess:
    """pytest as the user runs it there: mechval installed (this
    interpreter's environment), nothing of mechval's tree on the path."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-rA", "tests", *args],
                          cwd=repository, env=env, capture_output=True, text=True, timeout=300)


def test_a_comparison_fails_with_the_table_and_the_report_holds_both(tmp_path):
    repository = user_repository(tmp_path / "my-linkages", FAKE_TESTS)
    run = pytest_in(repository, "--mechval-report", "report")
    out = run.stdout
    assert run.returncode == 1 and "1 failed, 2 passed" in out, out + run.stderr
    assert "warning" not in out.lower(), out                  # the marks are registered
    # The failure message: the count, then the table, worst first.
    message = out[out.index("1 of "):]
    header, worst = message.splitlines()[1:3]
    assert message.startswith("1 of ") and " signals out of tolerance:" in message.splitlines()[0]
    assert header.split() == ["scenario", "engine", "setting", "signal", "max_error", "t_max", "relative_error",
                              "bound", "ratio", "verdict", "reason"]
    assert worst.split()[:4] == ["my-crank-rocker", "biased", "default", "F12x"] and worst.split()[9] == "fail"
    # The report of the session: both comparisons, the same records.
    report = repository / "report"
    assert "mechval report: report/index.html" in out
    assert {p.name for p in report.iterdir()} == {"index.html", "discrepancies.csv", "runs.csv", "summary.md"}
    records = pd.read_csv(report / "discrepancies.csv")
    assert set(records["engine"]) == {"faithful", "biased"}
    failed = records[records["verdict"] == "fail"]
    assert list(zip(failed["engine"], failed["signal"])) == [("biased", "F12x")]
    assert "my-crank-rocker" in (report / "index.html").read_text(encoding="utf-8")
    # A report folder that exists is refused before any test runs.
    again = pytest_in(repository, "--mechval-report", "report")
    assert again.returncode == pytest.ExitCode.USAGE_ERROR, again.stdout + again.stderr
    assert "--mechval-report report: it exists; choose another folder or remove it" in again.stderr
    assert "passed" not in again.stdout


@pytest.mark.engine
def test_the_engines_a_test_names_run_on_the_users_scene(tmp_path):
    """The docs' example (docs/testing.md): each built-in engine by name on
    the user's scene, within its default tolerances (an engine not
    installed would skip with the reason)."""
    repository = user_repository(tmp_path / "my-linkages", ENGINE_TESTS)
    run = pytest_in(repository)
    assert run.returncode == 0 and "3 passed" in run.stdout, run.stdout + run.stderr


def test_a_second_scene_of_a_name_is_left_out_of_the_report_saying_so(tmp_path):
    """The report keys scenes by name: of two scene files named alike, the
    second's comparisons are left out, with a line naming both files; the
    same file compared again (another engine) is kept."""
    from mechval.testing.comparison import compare_with_reference
    from mechval.testing.report import write_session_report
    first, second = tmp_path / "a.toml", tmp_path / "b.toml"
    first.write_text(SCENE)
    second.write_text(SCENE.replace("end = 0.5", "end = 0.4").replace("samples = 51", "samples = 41"))
    comparisons = [compare_with_reference(first, "reference"), compare_with_reference(second, "reference"),
                   compare_with_reference(first, "reference", setting="again")]
    assert comparisons[0].scenario is comparisons[2].scenario and comparisons[0].reference is comparisons[2].reference
    folder, left_out = write_session_report(tmp_path / "report", comparisons)
    assert left_out == [f"left out reference on {second}: its name 'my-crank-rocker' is also the name of {first}"]
    records = pd.read_csv(folder / "discrepancies.csv")
    assert set(records["setting"]) == {"default", "again"} and (records["verdict"] == "pass").all()
