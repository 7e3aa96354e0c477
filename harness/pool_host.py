"""The local pool's host: a process of its own, forked from the main
process as a batch starts, that owns pebble's pool and forks every worker.

Why a process between them: a fresh worker per task is a fork per task,
and a fork makes every page of the forking process copy-on-write again.
The main process works between forks (plans built, runs compared, the
progress bar), so each page it wrote after a fork was copied: in one
`mechval run`, 800k page faults and 5 s of system time on the cores the
workers need. The host does nothing between forks but hand tasks on and
results back, so its pages stay shared and a fork costs it little.

Tasks and values go by files (`task_files`): the main process writes
(fn, item) pickled to a task's file and sends (index, task's file,
value's file) on a pipe (None once it has every result); the worker
reads the one and writes the value, pickled, to the other; the host
sends back (index, error text) as the task ends, and the main process
reads the value. The host runs at most `workers` tasks at once, with
one more process forked ahead, waiting (`executors.LocalExecutor`); the
main process keeps at most `workers + 1` tasks in the host, so neither
side blocks on a full pipe while the other waits for it. SIGTERM stops
the host at once: it SIGKILLs its workers and waits until they are gone.
The host dies with the main process, its workers with the host
(`interrupts.die_with_parent`).
"""

from __future__ import annotations

import contextlib
import functools
import multiprocessing
import os
import pickle
import signal
import threading
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from multiprocessing.connection import Connection

from pebble import ProcessExpired, ProcessPool
from pebble.common.types import CONSTS as PEBBLE
from pebble.pool.process import WORKERS_NAME

from .interrupts import die_with_parent

#: How often the host's main thread looks for a stop, or a broken pool (s).
LOOK = 0.05
#: The host's exit status where pebble's pool broke.
POOL_BROKE = 70

#: Held around every fork (os.register_at_fork), while the main process
#: handles a finished task (`executors.LocalExecutor`: plans built, runs
#: compared, the progress bar drawn) and while the host hands a task to
#: pebble: pebble forks each worker from a thread of
#: its own, and a process forked while another thread held a lock (a
#: buffered stream's, a functools.cached_property's, numba's compiler
#: lock) would inherit it held by a thread it does not have and wait for
#: it forever.
FORK_GUARD = threading.RLock()
os.register_at_fork(before=FORK_GUARD.acquire, after_in_parent=FORK_GUARD.release,
                    after_in_child=FORK_GUARD.release)

#: How often pebble's pool looks at its workers (s): a worker that ended
#: its one task is replaced only then, so at pebble's own 0.1 s a slot
#: idled about half of it per task, a sizeable part of a short engine
#: run (tests/bench/worker_overhead_bench.py measures it).
POLL = 0.01


def serve(conn: Connection, workers: int, timeout: float, parent: int) -> None:
    """The host's life: pebble's pool for the tasks `conn` brings, until
    None arrives (the batch is done) or SIGTERM (stopped). As each task
    ends, (its index, why it has no value or "") goes back."""
    stop = threading.Event()
    stopped = []
    # a terminal's Ctrl-C reaches the whole process group: it is the main
    # process's to handle, which then stops the host by SIGTERM
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda signum, frame: (stopped.append(signum), stop.set()))
    die_with_parent(parent)
    pool = ProcessPool(max_workers=workers + 1, max_tasks=1, initializer=_worker_start,
                       initargs=(os.getpid(), conn.fileno()))
    slots = threading.Semaphore(workers)
    sending = threading.Lock()

    def send(index: int, future: Future) -> None:
        slots.release()             # its worker has sent its result and ends
        _, error = outcome(future, timeout)
        with sending, contextlib.suppress(OSError):     # OSError: the main process is gone
            conn.send((index, error))

    def take() -> None:
        try:
            while (message := conn.recv()) is not None:
                index, task, value = message
                slots.acquire()
                with FORK_GUARD:
                    future = pool.schedule(call, args=(task, value), timeout=timeout)
                future.add_done_callback(functools.partial(send, index))
        except (EOFError, OSError):         # the main process is gone
            stopped.append(0)
        except RuntimeError:                # pebble's pool stopped, or broke: the main thread looks which
            pass
        stop.set()

    with polling(POLL):
        threading.Thread(target=take, name="mechval pool host: tasks", daemon=True).start()
        while not stop.wait(LOOK) and pool.active:
            pass
        if stopped:
            stop_now(pool)
        elif not pool.active:
            # pebble's pool broke (its manager ends where a worker dies
            # before the pool has recorded its task: "All workers
            # expired"), and its futures will never resolve: end, and let
            # the main process give the tasks to a new host
            kill_workers()
            os._exit(POOL_BROKE)
        else:
            pool.close()
            pool.join()
    conn.close()


def _worker_start(host: int, fd: int) -> None:
    """pebble's worker initializer: die with the host, and close the host's
    end of the main process's pipe (a worker has no use for it, and a
    copy held open would hide the host's death from the main process)."""
    die_with_parent(host)
    os.close(fd)


def call(task: str, value: str) -> None:
    """A worker's task: fn(item) for the (fn, item) pickled in the file
    `task`, its value pickled into the file `value` (`task_files`).
    Neither passes through the host, which only names the task to run and
    the task that ended (its writes after each fork, every page of which
    the kernel copies, were mostly tasks' and values' buffers of MB)."""
    with open(task, "rb") as file:
        fn, item = pickle.load(file)
    result = fn(item)
    with open(value, "wb") as file:
        pickle.dump(result, file, protocol=pickle.HIGHEST_PROTOCOL)


def outcome(future: Future, timeout: float) -> tuple[object, str]:
    """A finished task's (value, "") or (None, why there is none)."""
    try:
        return future.result(), ""
    except FutureTimeout:
        return None, f"timed out after {timeout:g} s (worker killed)"
    except ProcessExpired as exc:
        return None, f"worker crashed (exit code {exc.exitcode})"
    except Exception as exc:  # the task's own error, reported as data
        return None, describe(exc)


def describe(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}"


@contextlib.contextmanager
def polling(interval: float):
    """pebble's period for its pool-managing loop, for one batch."""
    before, PEBBLE.sleep_unit = PEBBLE.sleep_unit, interval
    try:
        yield
    finally:
        PEBBLE.sleep_unit = before


def stop_now(pool: ProcessPool) -> None:
    """Stop the pool and SIGKILL its workers: an engine busy in C code does
    not act on SIGTERM, and pebble waits 3 s per worker before killing it.
    Engine state is disposable, so nothing is lost."""
    pool.stop()
    kill_workers()
    pool.join()


def kill_workers() -> None:
    """SIGKILL this process's pebble workers."""
    for process in multiprocessing.active_children():
        if process.name == WORKERS_NAME and process.pid is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(process.pid, signal.SIGKILL)
