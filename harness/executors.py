"""One interface for running independent tasks: a local process pool or a
Dask distributed cluster.

`Executor.run(fn, items, on_done)` calls fn(item) for every item, somewhere
else, and returns one `Done` per item in the items' order: the value, or the
reason there is none (the exception, a crashed worker, a timeout) as text,
so a failing task is data and never stops the others. The local pool is
pebble's, in a host process of its own (`pool_host`): a task that hangs
past the timeout is killed, a worker that crashes is replaced, the
workers die with the host and the host with the parent
(`interrupts.die_with_parent`), and an interrupted run kills them rather
than waiting for them. On Dask, fn and its arguments travel pickled to the
cluster's workers, which must have mechval installed; a running Dask task
cannot be killed, so the timeout there only stops waiting for it. A Dask
task whose worker dies is run again on another worker (Dask's
`distributed.scheduler.allowed-failures`, default 3 more times), then it
is a failed task with that reason; a cluster left without any worker for
the connect timeout fails the tasks still waiting, so a run never hangs.
"""

from __future__ import annotations

import collections
import contextlib
import multiprocessing
import os
import pickle
import time
from dataclasses import dataclass
from typing import Any, Callable, Protocol, Sequence

from . import pool_host
from .task_files import TaskFiles
from .defaults import DASK_CONNECT_TIMEOUT
from .pool_host import describe


@dataclass(frozen=True)
class Done:
    """The outcome of one task: its value, or why there is none."""

    value: Any = None
    error: str = ""
    #: The Dask worker that ran it (its address); "" for a local process.
    worker: str = ""


class Executor(Protocol):
    def run(self, fn: Callable[[Any], Any], items: Sequence[Any],
            on_done: Callable[[int, Done], Sequence[Any] | None] = lambda index, done: None) -> list[Done]:
        """fn(item) for every item; on_done(index, done) as each finishes
        (the local pool: in the items' order). Items that on_done returns
        join the batch, after those given so far (their indices follow):
        work that a finished item makes possible starts on the same
        workers without waiting for the batch to end."""


class LocalExecutor:
    """Worker processes on this machine (pebble), a fresh one per task: no
    engine state leaks from one task into the next, and a crash is charged
    to the one task whose process died.

    At most `workers` tasks run at once, and one more process is forked
    ahead, waiting: a task that ends hands its slot to that one at once,
    while pebble forks the next in the background (else a slot idles
    while the pool notices the exit and forks: tests/bench/
    worker_overhead_bench.py prints it). The workers are forked by a host
    process (`pool_host`), itself forked from this one as the batch
    starts, so that this process's pages are not made copy-on-write again
    at every fork. Where a host ends before its time (killed from outside,
    or pebble's pool broken), the tasks it held run again on a new one,
    each alone, and a task held by HOST_LIVES hosts that ended fails with
    the reason. A task whose function or item cannot be pickled fails
    alone."""

    def __init__(self, workers: int, timeout: float):
        self.workers, self.timeout = workers, timeout

    def __enter__(self) -> "LocalExecutor":
        return self

    def __exit__(self, *exc) -> None:
        pass

    def run(self, fn, items, on_done=lambda index, done: None) -> list[Done]:
        with TaskFiles() as files:
            return self._run(fn, items, on_done, files)

    def _run(self, fn, items, on_done, files: TaskFiles) -> list[Done]:
        results: list[Done] = []
        waiting = collections.deque(enumerate(items))      # not yet given to the host
        held: dict[int, tuple[Any, str]] = {}             # given to the host, not yet back: item, value's path
        ended: dict[int, Done] = {}
        lost: collections.Counter = collections.Counter()  # per task: hosts that ended holding it
        count = len(items)
        host = conn = None

        def room() -> bool:
            """Room in the host for the next task: as many as run, and one
            ready; but a task that a host which ended held runs alone (it
            may be what ended it: then it alone fails)."""
            suspect = any(lost[k] for k in held) or lost[waiting[0][0]]
            return not held if suspect else len(held) <= self.workers

        def give() -> None:
            while waiting and room():
                index, item = waiting.popleft()
                task, value = files.paths(index)
                try:
                    with open(task, "wb") as file:
                        pickle.dump((fn, item), file, protocol=pickle.HIGHEST_PROTOCOL)
                except Exception as exc:        # fn or item cannot be pickled: that task fails, alone
                    files.release(index)
                    ended[index] = Done(error=describe(exc))
                    continue
                try:
                    conn.send((index, task, value))
                except OSError:                 # the host ended: the task waits for the next host
                    waiting.appendleft((index, item))
                    return
                held[index] = item, value

        def host_ended() -> None:
            """The tasks the host held run again on a new one, each alone,
            but a task held by HOST_LIVES hosts that ended fails with the
            reason."""
            nonlocal host, conn
            reason = _host_end(host.exitcode)
            again = []
            for k, (item, _) in sorted(held.items()):
                lost[k] += 1
                if lost[k] < HOST_LIVES:
                    again.append((k, item))
                else:
                    ended[k] = Done(error=reason)
                    files.release(k)
            waiting.extendleft(reversed(again))
            held.clear()
            conn.close()
            host, conn = self._host()

        try:
            host, conn = self._host()
            give()
            while len(results) < count:
                index = len(results)
                if index not in ended:          # the next in order still runs: wait for the first to end
                    message = None
                    if conn.poll(HOST_LOOK):
                        try:
                            message = conn.recv()
                        except (EOFError, OSError):     # the pipe's end: the host ended
                            host.join(HOST_STOP)
                    if message is not None:
                        k, error = message
                        _, value = held.pop(k)
                        ended[k] = Done(error=error) if error else _value(value)
                        files.release(k)
                    elif not host.is_alive():
                        host_ended()
                    give()
                    continue
                done = ended.pop(index)
                results.append(done)
                with pool_host.FORK_GUARD:
                    more = on_done(index, done) or ()
                waiting.extend(enumerate(more, start=count))
                count += len(more)
                give()
            with contextlib.suppress(OSError):
                conn.send(None)
            host.join(HOST_STOP)
        finally:
            # interrupted (Ctrl-C, SIGTERM) or a failure here: stop now;
            # else the host has ended already
            _stop_host(host, conn)
        return results

    def _host(self):
        """A new pool host and this side of its pipe."""
        context = multiprocessing.get_context("fork")
        here, there = context.Pipe()
        host = context.Process(target=pool_host.serve, name="mechval pool host",
                               args=(there, self.workers, self.timeout, os.getpid()))
        host.start()
        there.close()
        return host, here


#: How often the main process looks whether the pool host still lives
#: while no result comes (s).
HOST_LOOK = 0.5
#: How long a stopped host may take to kill its workers and wait for them
#: before it is killed itself (s): they are SIGKILLed, so milliseconds.
HOST_STOP = 10.0
#: A task held by this many pool hosts that ended (killed from outside,
#: or pebble's pool broken) fails: once is chance, twice may be the task.
HOST_LIVES = 2


def _host_end(exitcode: int | None) -> str:
    """Why a task fails whose hosts ended while they held it."""
    why = ("pebble's worker pool broke (a worker ended before the pool had recorded its task)"
           if exitcode == pool_host.POOL_BROKE else f"the worker pool's host process died (exit code {exitcode})")
    return f"{why}, on each of the {HOST_LIVES} hosts given this task"


def _value(path: str) -> Done:
    """A task's value as its worker wrote it (`pool_host.call`)."""
    try:
        with open(path, "rb") as file:
            return Done(pickle.load(file))
    except Exception as exc:    # e.g. a class this process cannot import
        return Done(error=describe(exc))


def _stop_host(host, conn) -> None:
    """SIGTERM the host, which SIGKILLs its workers and waits until they
    are gone, reading what it may still be sending meanwhile (else it
    could block on a full pipe); SIGKILL it if it does not end in
    HOST_STOP (its workers then die with it)."""
    if host is None:
        return
    if host.is_alive():
        host.terminate()
    deadline = time.monotonic() + HOST_STOP
    while host.is_alive() and time.monotonic() < deadline:
        with contextlib.suppress(EOFError, OSError):
            while conn.poll(0):
                conn.recv_bytes()
        host.join(0.02)
    if host.is_alive():
        host.kill()
    host.join()
    conn.close()


class SchedulerUnreachable(RuntimeError):
    """No Dask scheduler answered at the address given."""


def dask_address_problem(address: str) -> str:
    """Why `address` is not a Dask scheduler address, or "" if it is one:
    SCHEME://HOST:PORT (or HOST:PORT, meaning tcp), the scheme one Dask
    knows; inproc://HOST/PID/N (a scheduler inside this very process, as
    an in-process test starts) only with this process's PID."""
    from distributed.comm import parse_address
    from distributed.comm.registry import backends
    if not address.strip():
        return "empty"
    scheme, location = parse_address(address, strict=False)
    if scheme not in backends:
        return f"unknown scheme {scheme!r} (known: {', '.join(sorted(backends))})"
    if scheme == "inproc":
        parts = location.split("/")
        if len(parts) != 3 or not parts[1].isdigit() or not parts[2].isdigit():
            return "expected inproc://HOST/PID/N, the address of a scheduler inside this process"
        if int(parts[1]) != os.getpid():
            return (f"an inproc:// address names a scheduler inside process {parts[1]}, and this is process "
                    f"{os.getpid()}: give the scheduler's tcp://HOST:PORT")
        return ""
    host, colon, port = location.rpartition(":")
    if not colon or not host.strip("[]"):
        return f"expected {scheme}://HOST:PORT"
    if not port.isdigit() or not 0 < int(port) < 65536:
        return f"the port {port!r} is not a number from 1 to 65535"
    return ""


class DaskExecutor:
    """The workers of a running Dask distributed scheduler at `address`.

    For meaningful timings each worker should run one task at a time
    (`dask worker ADDRESS --nthreads 1`): tasks sharing a process's cores
    slow each other down. The timeout bounds the whole batch (timeout ×
    number of tasks); tasks unfinished by then are cancelled and reported.
    A scheduler that does not answer within `connect_timeout` seconds
    raises SchedulerUnreachable.
    """

    def __init__(self, address: str, timeout: float, connect_timeout: float = DASK_CONNECT_TIMEOUT):
        self.address, self.timeout, self.connect_timeout = address, timeout, connect_timeout
        self._client = None

    def __enter__(self) -> "DaskExecutor":
        """Connected until the block ends: a command connects before its
        first piece of work, so an unreachable scheduler costs nothing
        more than the connect timeout."""
        self._client = self._connect()
        return self

    def __exit__(self, *exc) -> None:
        client, self._client = self._client, None
        if client is not None:
            client.close()

    def _connect(self):
        from distributed import Client
        try:
            return Client(self.address, timeout=self.connect_timeout)
        except Exception as exc:    # refused, timed out, or not a Dask scheduler at all
            raise SchedulerUnreachable(f"cannot connect to the Dask scheduler at {self.address} "
                                       f"(waited up to {self.connect_timeout:g} s): {exc}") from None

    def run(self, fn, items, on_done=lambda index, done: None) -> list[Done]:
        if self._client is None:
            with self:
                return self.run(fn, items, on_done)
        return self._run(self._client, fn, items, on_done)

    def _run(self, client, fn, items, on_done) -> list[Done]:
        from distributed import wait
        results: list[Done | None] = [None] * len(items)
        # pure=False: equal items (repeated timings) must each run.
        futures = [client.submit(_on_worker, fn, item, pure=False) for item in items]
        index_of = {future.key: index for index, future in enumerate(futures)}
        deadline = time.monotonic() + self.timeout * max(1, len(items))

        def add(more: Sequence[Any]) -> None:
            nonlocal deadline
            for item in more:
                futures.append(client.submit(_on_worker, fn, item, pure=False))
                index_of[futures[-1].key] = len(results)
                results.append(None)
                pending.add(futures[-1])
            deadline += self.timeout * len(more)

        no_workers_since: float | None = None
        pending, missing = set(futures), "timed out on the Dask cluster"
        try:
            while pending and time.monotonic() < deadline:
                try:
                    finished, pending = wait(pending, timeout=min(1.0, self.connect_timeout),
                                             return_when="FIRST_COMPLETED")
                except TimeoutError:
                    finished = set()
                for future in finished:
                    index = index_of[future.key]
                    results[index] = _done(future)
                    add(on_done(index, results[index]) or ())
                if finished or client.nthreads():
                    no_workers_since = None
                elif no_workers_since is None:
                    no_workers_since = time.monotonic()
                elif time.monotonic() - no_workers_since > self.connect_timeout:
                    missing = f"no Dask worker left on the cluster for {self.connect_timeout:g} s"
                    break
        finally:
            # Also on Ctrl-C: the cluster stops the tasks not yet run.
            client.cancel([f for f in futures if not f.done()])
        return [done or Done(error=missing) for done in results]


def _on_worker(fn: Callable[[Any], Any], item: Any) -> tuple[Any, str]:
    """A Dask task: fn(item), and the address of the worker that ran it."""
    from distributed import get_worker
    return fn(item), get_worker().address


def _done(future) -> Done:
    """A finished Dask future as a Done: a worker that died running it
    (on every worker tried) is a reason, like any other error."""
    from distributed import KilledWorker
    exc = future.exception()
    if isinstance(exc, KilledWorker):
        return Done(error=f"its Dask worker died while running it, on {exc.allowed_failures + 1} workers "
                          f"(the last {exc.last_worker.address})")
    if exc is not None:
        return Done(error=describe(exc))
    value, worker = future.result()
    return Done(value, worker=worker)


def executor_for(dask_address: str | None, workers: int, timeout: float,
                 connect_timeout: float = DASK_CONNECT_TIMEOUT) -> Executor:
    """The Dask cluster at `dask_address` if given (checked by
    dask_address_problem first), else a local pool."""
    if dask_address is None:
        return LocalExecutor(workers, timeout)
    return DaskExecutor(dask_address, timeout, connect_timeout)
