"""Worker processes forked from a small process forked once, not from this
one: a multiprocessing context for pebble (`ProcessPool(context=…)`).

The local pool forks a fresh worker per task. Forked from the main
process, every fork copies its page tables, the size of everything the
run has gathered by then (references, drawings, audits: some 400 MB),
and marks all its pages copy-on-write, so the main process then faults on
each page it writes until the next fork does it again (measured: 800k
faults and 5 s of system time in one `mechval run`; tests/bench/
worker_overhead_bench.py prints the CPU times). Forked from a zygote, a
copy of the main process made as the pool starts (engines imported,
nothing gathered yet) that does nothing but fork, the main process never
forks again.

The zygote holds the pool's channels and the worker function pebble
asked for first, and forks a process running it on each request (every
request of a pool is for that same function, on the same channels: it
refuses another); it tells the main process each worker's PID and, as
each ends, its exit code. It dies with the main process, and its workers
with it (`interrupts.die_with_parent`).
"""

from __future__ import annotations

import contextlib
import functools
import multiprocessing
import multiprocessing.connection
import os
import queue
import select
import signal
import socket
import struct
import threading
from typing import Any, Callable

from .interrupts import die_with_parent

#: A message from the zygote: a kind (b"P": a worker's PID; b"X": a
#: worker ended, with its exit code as multiprocessing gives it), a PID, a code.
MESSAGE = struct.Struct("=cii")
#: Seconds to wait for the zygote to report a fork, and for a killed worker to end.
START_TIMEOUT = 30.0
KILL_WAIT = 5.0


class Zygote:
    """The multiprocessing context pebble uses: pipes and locks as the fork
    context's (inherited by the zygote, so by the workers), processes
    forked by the zygote. `close` ends it (pebble has stopped the workers by
    then); `kill` ends it and its workers at once."""

    def __init__(self):
        self._fork = multiprocessing.get_context("fork")
        self._lock = threading.Lock()        # one fork request at a time
        self._started: queue.Queue[int] = queue.Queue()
        self._ended: dict[int, int] = {}
        #: The live workers' pidfds: a signal through one cannot reach another
        #: process that took the PID meanwhile (they are not our children).
        self._handles: dict[int, int] = {}
        self._changed = threading.Condition()
        self._socket: socket.socket | None = None
        self._pid = 0
        self._work: tuple | None = None

    def Pipe(self, duplex: bool = True):  # noqa: N802 (multiprocessing's names)
        return self._fork.Pipe(duplex)

    def RLock(self):  # noqa: N802
        return self._fork.RLock()

    def Lock(self):  # noqa: N802
        return self._fork.Lock()

    def Process(self, target: Callable, name: str | None = None, args: tuple = (),  # noqa: N802
                kwargs: dict | None = None) -> "Worker":
        return Worker(self, (target, args, kwargs or {}), name)

    # -- the zygote ------------------------------------------------------------------------------

    def fork(self, work: tuple) -> int:
        """A new worker running `work` (target, args, kwargs); its PID."""
        with self._lock:
            if self._work is None:
                self._begin(work)
            elif work != self._work:
                raise RuntimeError("a zygote forks one pool's workers only")
            try:
                self._socket.sendall(b"F")
                pid = self._started.get(timeout=START_TIMEOUT)
            except (OSError, queue.Empty) as exc:
                raise OSError(f"the worker zygote did not fork: {exc}") from exc
            if pid <= 0:
                raise OSError("the worker zygote has ended")
            return pid

    def _begin(self, work: tuple) -> None:
        parent, child = socket.socketpair()
        main = os.getpid()
        pid = os.fork()
        if pid == 0:                                   # the zygote
            code = 1
            try:
                parent.close()
                signal.signal(signal.SIGINT, signal.SIG_IGN)
                signal.signal(signal.SIGTERM, signal.SIG_DFL)
                die_with_parent(main)
                _serve(child, work, self._fork)
                code = 0
            finally:
                os._exit(code)
        child.close()
        self._socket, self._pid, self._work = parent, pid, work
        threading.Thread(target=self._listen, name="worker zygote", daemon=True).start()

    def _listen(self) -> None:
        """The zygote's reports, until it ends."""
        stream = self._socket.makefile("rb")
        while True:
            try:
                data = stream.read(MESSAGE.size)
            except (OSError, ValueError):       # closed here
                break
            if len(data) < MESSAGE.size:
                break
            kind, pid, code = MESSAGE.unpack(data)
            if kind == b"P":
                with self._changed:
                    self._ended.pop(pid, None)      # a PID used before
                    with contextlib.suppress(OSError):      # ended already
                        self._handles[pid] = os.pidfd_open(pid)
                self._started.put(pid)
            else:
                with self._changed:
                    self._ended[pid] = code
                    if pid in self._handles:
                        os.close(self._handles.pop(pid))
                    self._changed.notify_all()
        with self._changed:                     # the zygote is gone, and its workers with it
            self._ended[-1] = -signal.SIGKILL
            self._changed.notify_all()
        self._started.put(0)

    def exitcode(self, pid: int) -> int | None:
        with self._changed:
            if pid in self._ended:
                return self._ended[pid]
            return self._ended.get(-1)

    def send(self, pid: int, signum: int) -> None:
        """Signal a live worker."""
        with self._changed:
            if pid in self._handles:
                with contextlib.suppress(OSError):        # ended, not yet reported
                    signal.pidfd_send_signal(self._handles[pid], signum)

    def join(self, pid: int, timeout: float | None) -> None:
        with self._changed:
            self._changed.wait_for(lambda: pid in self._ended or -1 in self._ended, timeout)

    def close(self) -> None:
        """End the zygote (its workers, if any, with it) and reap it."""
        if self._socket is not None:
            with contextlib.suppress(OSError):
                self._socket.shutdown(socket.SHUT_RDWR)
            self._socket.close()
            with contextlib.suppress(ChildProcessError):
                os.waitpid(self._pid, 0)
            self._socket = None
            with self._changed:
                for handle in self._handles.values():
                    os.close(handle)
                self._handles.clear()

    def kill(self) -> None:
        """SIGKILL the workers, wait until they are gone (as a parent's
        join would: they are not this process's children, so by a pidfd,
        which cannot name a PID used again meanwhile), then the zygote."""
        if self._socket is None:
            return
        with self._changed:
            handles = list(self._handles.values())
            for handle in handles:
                with contextlib.suppress(OSError):        # ended already
                    signal.pidfd_send_signal(handle, signal.SIGKILL)
            for handle in handles:
                select.select([handle], [], [], KILL_WAIT)   # readable once the process has ended
        with contextlib.suppress(ProcessLookupError):
            os.kill(self._pid, signal.SIGKILL)
        self.close()


def _serve(requests: socket.socket, work: tuple, context) -> None:
    """The zygote's loop: a worker per request byte, each one's PID back,
    and each one's exit code as it ends; until the main process hangs up."""
    target, args, kwargs = work
    running: dict[Any, Any] = {}
    while True:
        for ready in multiprocessing.connection.wait([requests, *running]):
            if ready is requests:
                if not requests.recv(1):
                    return
                worker = context.Process(target=functools.partial(_worker, os.getpid(), target), args=args,
                                         kwargs=kwargs)
                worker.start()
                running[worker.sentinel] = worker
                requests.sendall(MESSAGE.pack(b"P", worker.pid, 0))
            else:
                worker = running.pop(ready)
                worker.join()
                requests.sendall(MESSAGE.pack(b"X", worker.pid, worker.exitcode))


def _worker(zygote: int, target: Callable, *args, **kwargs) -> Any:
    die_with_parent(zygote)
    return target(*args, **kwargs)


class Worker:
    """A worker process as pebble sees one (multiprocessing.Process's
    start, pid, is_alive, exitcode, join, terminate, kill)."""

    def __init__(self, zygote: Zygote, work: tuple, name: str | None):
        self._zygote, self._work, self.name = zygote, work, name
        self.daemon = False
        self.pid: int | None = None

    def start(self) -> None:
        self.pid = self._zygote.fork(self._work)

    @property
    def exitcode(self) -> int | None:
        return None if self.pid is None else self._zygote.exitcode(self.pid)

    def is_alive(self) -> bool:
        return self.pid is not None and self.exitcode is None

    def join(self, timeout: float | None = None) -> None:
        if self.pid is not None:
            self._zygote.join(self.pid, timeout)

    def terminate(self) -> None:
        if self.pid is not None:
            self._zygote.send(self.pid, signal.SIGTERM)

    def kill(self) -> None:
        if self.pid is not None:
            self._zygote.send(self.pid, signal.SIGKILL)
