"""mechval's pytest plugin, loaded by pytest in any environment where
mechval is installed (entry point group `pytest11`; `-p no:mechval` leaves
it out). It gives a repository's own test suite:

- the marks mechval's tests and the contract suite use (`engine`, `slow`,
  `hard`, `baseline`), registered;
- the fixture `mechval_compare(scene, engine, overrides=None,
  setting="default")`: runs the engine on a scene (a file, relative to the
  test file's folder, a built-in's name or a `Scenario`), compares it with
  the reference within the scene's tolerances, fails the test with the
  discrepancy table when a signal is out of tolerance, and returns the
  records (`mechval.testing.comparison`);
- `pytest --mechval-report DIR`: the report `mechval run` writes (the page,
  discrepancies.csv, runs.csv, summary.md) of the session's comparisons.

It imports nothing of mechval until a test uses it: every pytest session
of the environment loads it.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

#: The marks, as mechval's own test suite documents them.
MARKS = {
    "engine": "needs an engine library (runs, builds or checks an engine); -m \"not engine\" needs none "
              "(mechval's tests/test_markers.py checks its own suite)",
    "slow": "long sweeps, excluded by mechval's default selection (run with -m slow)",
    "hard": "numerically hard cases",
    "baseline": "regression checks against the committed baselines of the installed engine versions",
}
COMPARISONS = pytest.StashKey[list]()
REPORT_LINES = pytest.StashKey[list]()


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.getgroup("mechval").addoption(
        "--mechval-report", metavar="DIR", default=None,
        help="write the report of the session's mechval comparisons (mechval_compare) to DIR, which must not exist")


def pytest_configure(config: pytest.Config) -> None:
    for name, text in MARKS.items():
        config.addinivalue_line("markers", f"{name}: {text}")
    config.stash[COMPARISONS] = []
    out = config.getoption("--mechval-report", default=None)
    if out and os.path.lexists(out):
        raise pytest.UsageError(f"--mechval-report {out}: it exists; choose another folder or remove it")


@pytest.fixture
def mechval_compare(request: pytest.FixtureRequest):
    """compare(scene, engine, overrides=None, setting="default") → the
    discrepancy records; fails the test when any is out of tolerance, skips
    it when the engine is not installed."""
    from .comparison import assert_within_tolerance, compare_with_reference

    def compare(scene, engine, overrides=None, setting: str = "default"):
        if isinstance(scene, (str, Path)) and not Path(scene).is_absolute():
            beside = Path(os.path.normpath(request.path.parent / scene))
            scene = beside if beside.exists() else scene       # else a built-in's name
        comparison = compare_with_reference(scene, engine, overrides, setting)
        request.config.stash[COMPARISONS].append(comparison)
        assert_within_tolerance(comparison.records)
        return comparison.records
    return compare


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Write the report (the terminal summary, which follows, says where)."""
    out = session.config.getoption("--mechval-report", default=None)
    if not out or hasattr(session.config, "workerinput"):      # a pytest-xdist worker: its share only
        return
    comparisons, said = session.config.stash.get(COMPARISONS, []), []
    session.config.stash[REPORT_LINES] = said
    if not comparisons:
        said.append(f"not written, no comparison ran ({out})")
        return
    from .report import write_session_report
    try:
        path, left_out = write_session_report(Path(out), comparisons)
    except OSError as exc:
        said.append(f"cannot write {out}: {exc.strerror or exc}")
        session.exitstatus = session.exitstatus or pytest.ExitCode.TESTS_FAILED
        return
    said += left_out + [str(path / "index.html")]


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:
    for line in config.stash.get(REPORT_LINES, []):
        terminalreporter.write_line(f"mechval report: {line}")
