"""`mechval run --dask ADDRESS`: the same report as a local run, number for
number, on a LocalCluster of processes and on a real `dask scheduler` with
two `dask worker` processes; a worker lost mid-run, an unreachable
scheduler, Ctrl-C, and workers with different engine versions."""

from __future__ import annotations

import os
import pickle
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from fake_engines import registered
from mechval.engines import registry
from mechval.harness.cli import main
from mechval.harness.executors import DaskExecutor
from mechval.harness.run import run_and_report
from mechval.harness.runner import simulate_task, tasks_for
from mechval.scenarios import builtin_path, load

ENGINES = [name for name, reason in registry.availability().items() if not reason]
PRELOAD = str(Path(__file__).with_name("dask_preload.py"))
#: runs.csv columns that depend on where and when a run happened.
WHERE_AND_WHEN = {"task_wall_time_s", "task_cpu_time_s", "worker", "build_time_s", "wall_time_s"}


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> list[str]:
    """fourbar-seed cut to 0.5 s, and slider-crank-motor (torque-driven:
    its reference is integrated) cut to 0.3 s, as files."""
    folder = tmp_path_factory.mktemp("scenes")
    text = builtin_path("fourbar-seed").read_text(encoding="utf-8")
    text = text.replace('name = "fourbar-seed"', 'name = "short-fourbar"').replace("end = 6.0", "end = 0.5")
    (folder / "short.toml").write_text(text.replace("samples = 601", "samples = 51"), encoding="utf-8")
    motor = builtin_path("slider-crank-motor").read_text(encoding="utf-8")
    end = next(line for line in motor.splitlines() if line.startswith("end ="))
    samples = next(line for line in motor.splitlines() if line.startswith("samples ="))
    motor = motor.replace('name = "slider-crank-motor"', 'name = "short-motor"')
    (folder / "motor.toml").write_text(motor.replace(end, "end = 0.3").replace(samples, "samples = 31"),
                                       encoding="utf-8")
    return [str(folder / "short.toml"), str(folder / "motor.toml")]


def _runs(folder: Path) -> pd.DataFrame:
    runs = pd.read_csv(folder / "runs.csv", dtype=str, keep_default_na=False)
    return runs[~runs["name"].isin(WHERE_AND_WHEN)].reset_index(drop=True)


def assert_same_report(local: Path, remote: Path) -> None:
    """discrepancies.csv identical (written at %.17g: to the last bit),
    runs.csv identical but for the times and the worker."""
    assert (local / "discrepancies.csv").read_text() == (remote / "discrepancies.csv").read_text()
    pd.testing.assert_frame_equal(_runs(local), _runs(remote))
    assert _summary_tail(local) == _summary_tail(remote)


def _summary_tail(folder: Path) -> str:
    """summary.md less its provenance lines (the date differs)."""
    return "\n".join(line for line in (folder / "summary.md").read_text().splitlines()
                     if not line.startswith("# mechval discrepancy summary ("))


@pytest.fixture(scope="module")
def local_run(scenes, tmp_path_factory):
    if not ENGINES:
        pytest.skip("no engine installed")
    out = tmp_path_factory.mktemp("local") / "report"
    return run_and_report(scenes, ENGINES, out, workers=2, quiet=True)


@pytest.mark.engine
def test_a_local_cluster_of_processes_gives_the_local_report(local_run, scenes, tmp_path):
    from distributed import LocalCluster
    out = tmp_path / "report"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        remote = run_and_report(scenes, ENGINES, out, quiet=True, dask=cluster.scheduler_address)
    assert_same_report(local_run.folder, out)
    workers = {o.worker for o in remote.outcomes}
    assert all(w.startswith("tcp://") for w in workers) and not any(o.error for o in remote.outcomes)
    assert "worker" in _runs_all(out)["name"].values
    assert 'id="worker-versions"' not in (out / "index.html").read_text()      # one version of each engine


def _runs_all(folder: Path) -> pd.DataFrame:
    return pd.read_csv(folder / "runs.csv", dtype=str, keep_default_na=False)


def test_a_task_carries_its_scene_not_a_path(scenes, tmp_path):
    """A worker may not have the scene's file: a task pickled, its file
    gone, still runs."""
    copy = tmp_path / "scene.toml"
    copy.write_text(Path(scenes[0]).read_text(encoding="utf-8"), encoding="utf-8")
    task = tasks_for([load(str(copy))], ["reference"])[0]
    travelled = pickle.dumps(task)
    copy.unlink()
    signals, wall, cpu = simulate_task(pickle.loads(travelled))
    assert len(signals.frame) == 51 and wall > 0


def _cluster(**kwargs):
    from distributed import LocalCluster
    return LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                        preload=[PRELOAD], **kwargs)


def test_a_worker_lost_mid_run_is_retried_elsewhere_or_a_failed_row(monkeypatch, scenes, tmp_path):
    """crashing-once kills its worker once: run again on another worker, it
    passes; crashing kills every worker it runs on: after Dask's allowed
    failures (here 1) it is a failed row with the reason. The other runs
    are all there, and nothing hangs."""
    import dask
    monkeypatch.setattr(registry, "targets", registered())
    monkeypatch.setenv("MECHVAL_TEST_CRASH_DIR", str(tmp_path))
    start = time.monotonic()
    # One task at a time per worker (worker-saturation 1.0): a worker that
    # dies takes with it only the task it was running, none queued behind.
    with dask.config.set({"distributed.scheduler.allowed-failures": 1,
                          "distributed.scheduler.worker-saturation": 1.0}), _cluster() as cluster:
        run = run_and_report(scenes[:1], ["faithful", "crashing-once", "crashing"], tmp_path / "report",
                             quiet=True, dask=cluster.scheduler_address)
    assert time.monotonic() - start < 120
    by_engine = {o.task.engine: o for o in run.outcomes}
    assert len(run.outcomes) == 3 and (tmp_path / "crashed").exists()
    assert by_engine["faithful"].error == "" and by_engine["crashing-once"].error == ""
    assert by_engine["crashing"].error.startswith("its Dask worker died while running it, on 2 workers")
    failed = run.records[run.records["engine"] == "crashing"]
    assert list(failed["verdict"]) == ["fail"] and "Dask worker died" in failed["reason"].iloc[0]


def test_ctrl_c_cancels_the_clusters_tasks():
    """Interrupted while waiting (here: by the first result's callback),
    the tasks still queued or running are cancelled on the cluster at
    once, the client still connected (20 tasks of 0.5 s on one thread
    would keep it busy for 10 s)."""
    from distributed import Client, LocalCluster

    def interrupt(index, done):
        raise KeyboardInterrupt

    def tasks(dask_scheduler) -> int:
        return {ts.key[0] if isinstance(ts.key, tuple) else ts.key: ts.state for ts in dask_scheduler.tasks.values()}

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster.scheduler_address) as observer, \
            DaskExecutor(cluster.scheduler_address, timeout=60) as executor:
        with pytest.raises(KeyboardInterrupt):
            executor.run(time.sleep, [0.0] + [0.5] * 20, interrupt)
        # Left: the finished task and the one running when interrupted (a
        # running task cannot be stopped), done; none queued or processing.
        deadline = time.monotonic() + 3
        while set(observer.run_on_scheduler(tasks).values()) != {"memory"} and time.monotonic() < deadline:
            time.sleep(0.1)
        left = observer.run_on_scheduler(tasks)
        assert set(left.values()) == {"memory"} and len(left) <= 2, left


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def test_unreachable_scheduler_is_one_line_exit_3_within_the_connect_timeout(tmp_path, capsys, scenes):
    address = f"tcp://127.0.0.1:{_free_port()}"
    out = tmp_path / "report"
    start = time.monotonic()
    status = main(["run", scenes[0], "--engine", "reference", "--dask", address, "--dask-connect-timeout", "1",
                   "--out", str(out), "--quiet"])
    assert status == 3 and time.monotonic() - start < 5
    err = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("note: skipping ")]
    assert len(err) == 1 and not out.exists()
    assert err[0].startswith(f"mechval: error: cannot connect to the Dask scheduler at {address} (waited up to 1 s)")


def test_a_bad_address_is_refused_before_any_work(tmp_path, capsys, scenes):
    out = tmp_path / "report"
    assert main(["run", scenes[0], "--dask", "http://127.0.0.1:8786", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mechval: error: --dask 'http://127.0.0.1:8786': not a Dask scheduler address: "
                          "unknown scheme 'http'") and err.count("\n") == 1 and not out.exists()


def _start(command: list[str], env: dict) -> subprocess.Popen:
    return subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)


@pytest.mark.engine
@pytest.mark.slow
def test_a_real_scheduler_and_two_workers(local_run, scenes, tmp_path, monkeypatch, capsys):
    """`dask scheduler` and two `dask worker` processes, started here: the
    report is the local one, number for number; the two workers report
    different versions of one engine ('versioned'), and the report and the
    summary name each worker with its version."""
    monkeypatch.setattr(registry, "targets", registered())
    dask = str(Path(sys.executable).with_name("dask"))
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ)
    processes = [_start([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                        dict(env, DASK_DISTRIBUTED__SCHEDULER__WORKER_SATURATION="1.0"))]
    try:
        for version in ("1.0", "2.0"):
            processes.append(_start([dask, "worker", address, "--nthreads", "1", "--no-dashboard", "--preload",
                                     PRELOAD, "--name", f"worker-{version}"],
                                    dict(env, MECHVAL_TEST_VERSION=version)))
        from distributed import Client
        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
        out = tmp_path / "report"
        status = main(["run", *scenes, *(f"--engine={e}" for e in ENGINES), "--dask", address, "--out", str(out),
                       "--quiet"])
        assert status == 0
        assert_same_report(local_run.folder, out)
        versioned = tmp_path / "versioned"
        # Two runs of a second each, two idle workers taking one task at a
        # time (worker-saturation 1.0): one run on each.
        main(["run", scenes[0], "slider-crank", "--engine", "versioned", "--dask", address, "--out", str(versioned),
              "--quiet"])
    finally:
        for process in processes:
            os.killpg(process.pid, signal.SIGTERM)
        for process in processes:
            process.wait(timeout=30)
    printed = capsys.readouterr().out
    runs = _runs_all(versioned)
    assert set(runs.loc[runs["engine"] == "versioned", "version"]) == {"1.0", "2.0"}, runs[runs["kind"] == "error"]
    warning = next(line for line in printed.splitlines() if line.startswith("warning: versioned"))
    assert warning.startswith("warning: versioned ran at different versions: 1.0 on tcp://127.0.0.1:")
    assert "; 2.0 on tcp://127.0.0.1:" in warning
    html = (versioned / "index.html").read_text()
    assert 'id="worker-versions"' in html and html.count('<td class="text bad">') >= 2


def test_a_cluster_without_workers_fails_the_tasks_instead_of_hanging():
    """No worker for the connect timeout (all died, none came back): the
    waiting tasks are failed with that reason."""
    from distributed import LocalCluster
    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        start = time.monotonic()
        done = DaskExecutor(cluster.scheduler_address, timeout=60, connect_timeout=1).run(time.sleep, [0.1, 0.1])
    assert time.monotonic() - start < 10
    assert [d.error for d in done] == ["no Dask worker left on the cluster for 1 s"] * 2


@pytest.mark.parametrize("where", ["local", "dask"])
def test_jobs_alongside_the_runs_come_back_in_order_with_their_cpu_time(where, scenes):
    """The main job's own work (`run_alongside`'s jobs) goes through the
    same executor as the engine runs: each job's value and CPU time come
    back in the jobs' order, on_job hears of each, and the runs' outcomes
    are those of run_tasks."""
    import functools
    from distributed import LocalCluster
    from mechval.harness.executors import LocalExecutor
    from mechval.harness.runner import run_alongside
    tasks = tasks_for([load(scenes[0])], ["reference"])
    jobs = [functools.partial(pow, 2, k) for k in range(4)]
    heard = []

    def run(executor):
        return run_alongside(tasks, jobs, executor, on_job=lambda index, done: heard.append(index))

    if where == "local":
        outcomes, side = run(LocalExecutor(workers=2, timeout=60))
    else:
        with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
                DaskExecutor(cluster.scheduler_address, timeout=60) as executor:
            outcomes, side = run(executor)
    assert [done.value[0] for done in side] == [1, 2, 4, 8] and all(done.value[1] >= 0 for done in side)
    assert sorted(heard) == [0, 1, 2, 3]
    assert len(outcomes) == 1 and outcomes[0].error == "" and len(outcomes[0].signals.frame) == 51
