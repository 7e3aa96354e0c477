"""`mechval matrix`: the suite against several releases of one engine, each
in an environment of its own, and what each release changed.

End to end with a fake engine package built here at two releases that
differ in one signal (its adapter ships inside it, as a plug-in's may), plus
a release that does not exist; the environments are created once per test
session and shared by its tests. The real thing, MuJoCo 3.3.7 and 4.0.0
from the package index, is `slow`: its figures are checked against the
committed baselines of both releases (baselines/mujoco/).
"""

from __future__ import annotations

import base64
import hashlib
import os
import shutil
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mechval.harness import baseline as bl
from mechval.harness import baseline_store as store
from mechval.harness import cli, release_envs
from mechval.harness.matrix import parse_items
from mechval.harness.preflight import UsageError
from mechval.harness.runner import references_for
from mechval.reports.matrix_report import brief
from mechval.scenarios import load

ROOT = Path(__file__).resolve().parent.parent
ENGINE, DISTRIBUTION = "fakerelease", "mechval-fake-release"
#: The fake's scene: fourbar-seed under another name, from a file of its own.
SCENE = "my-fourbar"
#: What release 2.0 of the fake does differently: A.Fx, the ground pivot's
#: force, GAIN times the reference's (1.0 keeps it exact).
GAIN = 1.001
#: Release 1.5 installs but its engine library does not import.
BROKEN = "libfakeengine.so: cannot open shared object file"
ADAPTER = '''
"""The fake engine's mechval adapter, shipped with the library."""
from mechval.engines.base import EngineAdapter, RawRun
from mechval.reference.adapter import raw_reference


class FakeAdapter(EngineAdapter):
    name = "fakerelease"
    library = "mechval_fake_release_core"
    distribution = "mechval-fake-release"

    def default_settings(self, mechanism, times):
        return {"timestep": 1e-3}

    def run(self, mechanism, times, settings):
        from mechval_fake_release_core import GAIN
        raw = raw_reference(mechanism, times)
        raw["A.Fx"] *= GAIN
        return RawRun(raw)
'''
ENTRY_POINTS = "[mechval.engines]\nfakerelease = mechval_fake_release:FakeAdapter\n"


def _wheel(folder: Path, version: str, core: str) -> Path:
    """The fake's wheel at `version`, its engine library `core` (the text
    of mechval_fake_release_core), written as a zip (PEP 427: its modules,
    its dist-info and a RECORD of them) with no build backend to wait for."""
    info = f"mechval_fake_release-{version}.dist-info"
    files = {"mechval_fake_release/__init__.py": ADAPTER, "mechval_fake_release_core/__init__.py": core,
             f"{info}/METADATA": f"Metadata-Version: 2.1\nName: {DISTRIBUTION}\nVersion: {version}\n",
             f"{info}/WHEEL": ("Wheel-Version: 1.0\nGenerator: mechval-tests\nRoot-Is-Purelib: true\n"
                               "Tag: py3-none-any\n"),
             f"{info}/entry_points.txt": ENTRY_POINTS}
    record = "".join(f"{name},sha256={_digest(text)},{len(text.encode())}\n" for name, text in files.items())
    path = folder / f"mechval_fake_release-{version}-py3-none-any.whl"
    with zipfile.ZipFile(path, "w") as wheel:
        for name, text in {**files, f"{info}/RECORD": record + f"{info}/RECORD,,\n"}.items():
            wheel.writestr(name, text)
    return path


def _digest(text: str) -> str:
    return base64.urlsafe_b64encode(hashlib.sha256(text.encode()).digest()).rstrip(b"=").decode()


@pytest.fixture(scope="session")
def fake(tmp_path_factory):
    """The fake's wheels at 1.0, 1.5 and 2.0, release 1.0 unpacked into a folder
    of its own (so that the calling mechval knows the engine), and the
    session's environments folder."""
    root = tmp_path_factory.mktemp("fake-release")
    wheels, site = root / "wheels", root / "site"
    wheels.mkdir()
    cores = {"1.0": "GAIN = 1.0\n", "1.5": f"raise ImportError({BROKEN!r})\n", "2.0": f"GAIN = {GAIN!r}\n"}
    for version, core in cores.items():
        _wheel(wheels, version, core)
    with zipfile.ZipFile(wheels / "mechval_fake_release-1.0-py3-none-any.whl") as first:
        first.extractall(site)
    yield {"wheels": wheels, "site": site, "envs": root / "envs"}
    # The environments hold ~25,000 files: removed now, not by a later session.
    shutil.rmtree(root / "envs", ignore_errors=True)


def mechval(fake: dict[str, Path], *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(fake["site"])}
    return subprocess.run([sys.executable, "-m", "mechval.harness.cli", *args], capture_output=True, text=True,
                          env=env, timeout=900, cwd=ROOT)


@pytest.fixture(scope="session")
def fake_matrix(fake, tmp_path_factory) -> tuple[subprocess.CompletedProcess, Path]:
    """`mechval matrix fakerelease 1.0 1.5 3.0 2.0 SCENE.toml` (a file of
    the user's, which the releases' jobs carry): 1.5 does not import, 3.0
    exists nowhere."""
    folder = tmp_path_factory.mktemp("matrix")
    scene, out = folder / f"{SCENE}.toml", folder / "report"
    scene.write_text((ROOT / "scenarios" / "fourbar-seed.toml").read_text(encoding="utf-8").replace(
        'name = "fourbar-seed"', f'name = "{SCENE}"', 1), encoding="utf-8")
    run = mechval(fake, "matrix", ENGINE, "1.0", "1.5", "3.0", "2.0", str(scene), "--out", str(out),
                  "--envs", str(fake["envs"]), "--find-links", str(fake["wheels"]), "--workers", "2")
    return run, out


def test_a_release_that_cannot_be_installed_or_imported_is_a_row_with_the_reason(fake_matrix):
    run, out = fake_matrix
    assert run.returncode == 1, run.stderr[-3000:]      # a release did not run
    releases = pd.read_csv(out / "releases.csv", keep_default_na=False, dtype={"version": str}).set_index("version")
    assert list(releases.index) == ["1.0", "1.5", "3.0", "2.0"]
    assert releases.loc["1.5", "status"] == (f"not importable: {ENGINE}: mechval_fake_release_core cannot be "
                                             f"imported (ImportError: {BROKEN})")
    assert releases.loc["1.0", "status"] == releases.loc["2.0", "status"] == "ok"
    assert releases.loc["3.0", "status"].startswith(f"not installed: cannot install {DISTRIBUTION} 3.0: ")
    assert "mechval-fake-release==3.0" in releases.loc["3.0", "status"]
    assert releases.loc["2.0", "runs"] == 1 and releases.loc["2.0", "failed"] == 0
    assert "imported 2.0" in releases.loc["2.0", "facts"]
    assert "3.0" in (out / "index.html").read_text(encoding="utf-8")


def test_the_change_between_releases_and_its_size(fake_matrix):
    """1.0 → 2.0 (1.5 and 3.0 did not run): one signal family changed, by
    GAIN − 1 of its peak, and the force class got worse; the others are
    bit-identical."""
    run, out = fake_matrix
    changes = pd.read_csv(out / "changes.csv", keep_default_na=False, dtype={"old": str, "new": str})
    assert len(changes) == 1, changes
    change = changes.iloc[0]
    assert (change["old"], change["new"], change["scenario"], change["verdict"]) == ("1.0", "2.0", SCENE, "changed")
    assert change["size"] == pytest.approx(GAIN - 1, rel=1e-9)
    assert change["accuracy"] == "worse" and change["force"].endswith("(worsened)")
    assert change["angle"].endswith("(unchanged)")
    # Derived here from the stored signals of both releases: exactly the
    # ground pivot's x force (and the resultants made from it) moved.
    old = store.load(out / "signals" / ENGINE / "1.0" / SCENE / "default.csv").signals
    new = store.load(out / "signals" / ENGINE / "2.0" / SCENE / "default.csv").signals
    moved = [c for c in old.frame.columns if not np.array_equal(old[c], new[c])]
    assert moved and all("x" in c or c.startswith("F") for c in moved), moved
    assert change["changed_signals"] == len(moved)
    assert np.allclose(new[change["signal"]], GAIN * old[change["signal"]], rtol=1e-12, atol=0)


def test_accuracy_per_release_and_class(fake_matrix):
    """1.0 is the reference itself; 2.0's force error is GAIN − 1."""
    run, out = fake_matrix
    accuracy = pd.read_csv(out / "accuracy.csv", keep_default_na=False, dtype={"version": str})
    assert set(accuracy["version"]) == {"1.0", "2.0"}
    force = accuracy[accuracy["class"] == "force"].set_index("version")["error"]
    assert force["1.0"] < 1e-12 and force["2.0"] == pytest.approx(GAIN - 1, rel=1e-6)
    page = (out / "index.html").read_text(encoding="utf-8")
    assert "changed" in page and "accuracy worse" in page and "matrix-figure" in page


def test_environments_are_cached_and_isolated(fake):
    """Each release's environment holds that release and no other engine
    library (nor the caller's packages), and is reused as it is."""
    envs = sorted(p.name for p in fake["envs"].iterdir() if not p.name.startswith("."))
    python = f"py{sys.version_info.major}.{sys.version_info.minor}"
    assert envs == [f"{DISTRIBUTION}-{v}-{python}" for v in ("1.0", "1.5", "2.0")]
    env = fake["envs"] / envs[-1]
    code = ("import importlib.metadata as m, importlib.util as u, sys; "
            "print(m.version('mechval-fake-release'), [n for n in ('mujoco', 'pybullet', 'exudyn', 'pytest') "
            "if u.find_spec(n)], sys.flags.no_user_site)")
    seen = subprocess.run([str(release_envs.python_of(env)), "-c", code], capture_output=True, text=True,
                          env=release_envs.clean_environ(), check=True).stdout.split()
    assert seen == ["2.0", "[]", "1"]
    record = env / release_envs.RECORD
    before = record.stat().st_mtime_ns
    release = release_envs.Release(DISTRIBUTION, "2.0", tuple(release_envs.pinned_requirements()),
                                   (str(fake["wheels"]),))
    held = release_envs._read_record(env)
    assert release_envs.ensure_env(fake["envs"], release, Path("/nonexistent.whl"), held["mechval"]) == env
    assert record.stat().st_mtime_ns == before         # reused: nothing installed, nothing rewritten


def test_pins_leave_every_engine_out():
    pins = release_envs.pinned_requirements()
    names = {p.split("==")[0].split("[")[0] for p in pins}
    assert "numpy" in names and "pandas" in names
    assert not names & {"mujoco", "pybullet", "exudyn"}, pins
    assert not any("extra" in p for p in pins)


@pytest.mark.parametrize("args, says", [
    (["matrix", "nosuchengine", "1.0"], "unknown engine 'nosuchengine'"),
    (["matrix", "reference", "1.0"], "unknown engine 'reference'"),
    (["matrix", "pybullet", "3.x"], "version '3.x': not a release number"),
    (["matrix", "pybullet", "fourbar-seed"], "name at least one release"),
    (["matrix", "pybullet", "1.0", "1.0"], "release given twice: 1.0"),
    (["matrix", "pybullet", "1.0", "no-such-scene"], "no-such-scene"),
])
def test_bad_input_is_one_line_and_exit_2(args, says, capsys, tmp_path):
    assert cli.main(args + ["--out", str(tmp_path / "out"), "--envs", str(tmp_path / "envs")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and says in err, err
    assert not (tmp_path / "out").exists() and not (tmp_path / "envs").exists()


def test_an_unwritable_out_or_envs_folder_is_refused(capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    for option in ("--out", "--envs"):
        paths = {"--out": str(tmp_path / "out"), "--envs": str(tmp_path / "envs"), option: str(blocker / "x")}
        assert cli.main(["matrix", "pybullet", "1.0", "fourbar-seed", *[w for kv in paths.items() for w in kv]]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"cannot write {blocker / 'x'}" in err, err


def test_versions_then_scenarios():
    assert parse_items(["3.3.7", "4.0.0", "fourbar-seed", "x.toml"]) == (["3.3.7", "4.0.0"], ["fourbar-seed", "x.toml"])
    with pytest.raises(UsageError, match="not a release number"):
        parse_items(["4.0.0", "4.0.0rc1.x"])


def test_pip_reason_keeps_errors_on_one_line():
    stderr = textwrap.dedent("""\
        WARNING: Location 'file:///x' is ignored
        ERROR: Could not find a version that satisfies the requirement a==9 (from versions: 1.0)
        ERROR: No matching distribution found for a==9
    """)
    assert release_envs.pip_reason(stderr) == ("Could not find a version that satisfies the requirement a==9 "
                                               "(from versions: 1.0) No matching distribution found for a==9")


#: Built-ins with committed MuJoCo 3.3.7 and 4.0.0 baselines (baselines/mujoco/).
MUJOCO_SCENES = ("fourbar-seed", "fourbar-crossed")
#: A built-in whose MuJoCo model, as this mechval writes it, 3.3.7 cannot
#: compile (measured: every scene with a slide joint; its committed 3.3.7
#: baselines were recorded by an earlier adapter): 3.3.7's XML parser
#: refuses the slide joint's axis, 4.0.0 takes it.
REFUSED_BY_3_3_7 = "slider-crank"


@pytest.mark.slow
@pytest.mark.engine
def test_two_mujoco_releases(tmp_path):
    """`mechval matrix mujoco 3.3.7 4.0.0` from the package index: each
    release's runs agree with its committed baseline (baseline check's
    rule), and the change and the accuracy the matrix reports are those
    derived here from the two committed baselines. A scene 3.3.7 cannot
    load is a failed run with MuJoCo's reason, and the exit status is 1."""
    out, root = tmp_path / "report", ROOT / "baselines"
    try:
        run = subprocess.run([sys.executable, "-m", "mechval.harness.cli", "matrix", "mujoco", "3.3.7", "4.0.0",
                              *MUJOCO_SCENES, REFUSED_BY_3_3_7, "--out", str(out), "--envs", str(tmp_path / "envs")],
                             capture_output=True, text=True, timeout=1800, cwd=ROOT)
    finally:
        shutil.rmtree(tmp_path / "envs", ignore_errors=True)
    assert run.returncode == 1, run.stdout[-3000:] + run.stderr[-3000:]
    failed = pd.read_csv(out / "accuracy.csv", keep_default_na=False, dtype={"version": str})
    failed = failed[failed["class"] == "(run)"]
    assert set(zip(failed["version"], failed["scenario"])) == {("3.3.7", REFUSED_BY_3_3_7)}, failed
    assert all("MuJoCo cannot compile the model" in r and "attribute 'axis'" in r for r in failed["reason"])
    changes = pd.read_csv(out / "changes.csv", keep_default_na=False, dtype={"old": str, "new": str})
    assert (changes[changes["scenario"] == REFUSED_BY_3_3_7]["verdict"] == "n/a").all()
    changes = changes[changes["scenario"] != REFUSED_BY_3_3_7]
    accuracy = pd.read_csv(out / "accuracy.csv", keep_default_na=False, dtype={"version": str})
    assert len(changes) == 2 * len(MUJOCO_SCENES)       # default and high-accuracy
    for change in changes.itertuples():
        committed = {v: store.load(store.baseline_path(root, "mujoco", v, change.scenario, change.setting))
                     for v in ("3.3.7", "4.0.0")}
        for version, stored in committed.items():
            ran = store.load(store.baseline_path(out / "signals", "mujoco", version, change.scenario, change.setting))
            rows = bl.compare_to_baseline(stored.signals, ran.signals, sensitivity=stored.sensitivity)
            assert not bl.regressed(rows), rows[rows["verdict"] == "regression"]
        rows = bl.compare_to_baseline(committed["3.3.7"].signals, committed["4.0.0"].signals,
                                      sensitivity=committed["3.3.7"].sensitivity)
        moved = rows[rows["verdict"] != "identical"]
        assert change.verdict == "changed" and bl.regressed(rows)
        assert float(change.size) == pytest.approx(moved["relative"].max(), rel=1e-6)
        assert change.signal == moved.loc[moved["relative"].idxmax(), "signal"]
        scenario = load(change.scenario)
        reference = references_for([scenario])[scenario.name]
        expected = bl.accuracy_change(reference, committed["3.3.7"].signals, committed["4.0.0"].signals,
                                      scenario.tolerance_for("mujoco")).set_index("class")
        mine = accuracy[(accuracy["scenario"] == change.scenario) & (accuracy["setting"] == change.setting)]
        for cls, row in expected.iterrows():
            got = mine[mine["class"] == cls].set_index("version")["error"].astype(float)
            assert got["3.3.7"] == pytest.approx(row["old"], rel=1e-6)
            assert got["4.0.0"] == pytest.approx(row["new"], rel=1e-6)
            assert getattr(change, cls).endswith(f"({row['verdict']})")


@pytest.mark.slow
def test_on_dask_each_release_is_a_task_and_the_report_is_the_same(fake, fake_matrix, tmp_path):
    """--dask: each release's job runs on a worker of a LocalCluster
    (processes), finding the session's environments in --envs there; the
    tables are those of the local run, number for number."""
    from distributed import LocalCluster
    local_run, local = fake_matrix
    out = tmp_path / "report"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        run = mechval(fake, "matrix", ENGINE, "1.0", "1.5", "3.0", "2.0", str(local.parent / f"{SCENE}.toml"),
                      "--out", str(out), "--envs", str(fake["envs"]), "--find-links", str(fake["wheels"]),
                      "--workers", "2", "--dask", cluster.scheduler_address)
    assert run.returncode == local_run.returncode == 1, run.stderr[-3000:]
    for name in ("releases.csv", "accuracy.csv", "changes.csv"):
        mine, theirs = (pd.read_csv(folder / name, keep_default_na=False, dtype=str) for folder in (out, local))
        if name == "releases.csv":      # the same environments, found again
            mine, theirs = mine.drop(columns="status"), theirs.drop(columns="status")
        pd.testing.assert_frame_equal(mine, theirs)


def test_a_cell_gives_the_cause_of_a_failure_first():
    reason = ("ScenarioError: /home/u/.cache/mechval/envs/mujoco-3.3.7-py3.11/lib/python3.11/site-packages/mechval/"
              "scenarios/slider-crank.toml: engines.mujoco: mujoco: MuJoCo cannot compile the model (XML Error: "
              "number is too large in attribute 'axis' Element 'joint', line 14)")
    assert brief(reason, 1000) == reason[reason.index("engines.mujoco"):]
    assert brief(f"3.3.7: {reason}", 1000) == "3.3.7: " + reason[reason.index("engines.mujoco"):]
    assert len(brief(reason, 40)) == 40 and brief(reason, 40).endswith("…")


def test_without_a_source_tree_to_build_mechval_from_it_says_so(monkeypatch, capsys, tmp_path):
    """A mechval installed from a wheel has no source tree beside it: one
    line, exit 2, before any environment is made."""
    monkeypatch.setattr(release_envs.mechval, "__file__", str(tmp_path / "site-packages" / "mechval" / "__init__.py"))
    args = ["matrix", "pybullet", "1.0", "fourbar-seed", "--out", str(tmp_path / "out"), "--envs", str(tmp_path / "e")]
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no mechval source tree beside" in err, err
    assert not (tmp_path / "out").exists() and not (tmp_path / "e").exists()


def test_a_changed_mechval_only_reinstalls_mechval(fake, fake_matrix, tmp_path):
    """An environment whose record names another mechval build gets this
    one's wheel and a new record; the engine release stays as installed."""
    env = fake["envs"] / f"{DISTRIBUTION}-1.5-py{sys.version_info.major}.{sys.version_info.minor}"
    held = release_envs._read_record(env)
    engine_file = release_envs._site_packages(env) / "mechval_fake_release_core" / "__init__.py"
    before = engine_file.stat().st_ino
    wheel = release_envs.build_wheel(tmp_path)
    release = release_envs.Release(DISTRIBUTION, "1.5", tuple(held["requirements"]), (str(fake["wheels"]),))
    assert release_envs.ensure_env(fake["envs"], release, wheel, "another-build") == env
    assert release_envs._read_record(env) == {**held, "mechval": "another-build"}
    assert engine_file.stat().st_ino == before
    installed = subprocess.run([str(release_envs.python_of(env)), "-c", "import mechval.harness.release_run"],
                               env=release_envs.clean_environ(), capture_output=True, text=True)
    assert installed.returncode == 0, installed.stderr
