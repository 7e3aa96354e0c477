"""Stopping a run: SIGINT and SIGTERM end it promptly and cleanly, and its
worker processes never outlive it.

The command line turns both signals into `Interrupted`, raised in the main
thread wherever it is, so that every `finally` runs: the executor stops its
pool and kills the workers, the atomic folder writer removes its temporary
folder. Workers ask Linux to kill them when their parent dies, which covers
the cases no handler can (SIGKILL of the parent, a crash of the parent).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time
from typing import Iterator

#: The signals that stop a run (Ctrl-C; `timeout`, CI cancellation, `kill`).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: Seconds after a stop signal during which another is ignored, so that an
#: impatient second Ctrl-C does not cut short the clean-up the first started
#: (workers killed, temporary folder removed: well under a second). A signal
#: after that raises again, in case the first was swallowed somewhere.
GRACE = 2.0


class Interrupted(KeyboardInterrupt):
    """The run was stopped by a signal; the exit status is 128 + signum.

    A KeyboardInterrupt, so that like Ctrl-C it passes every `except
    Exception` and libraries treat it as a request to stop."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    @property
    def exit_status(self) -> int:
        return 128 + self.signum


@contextlib.contextmanager
def stop_on_signals() -> Iterator[None]:
    """Within: SIGINT or SIGTERM raises `Interrupted` in the main thread
    (not again within GRACE seconds). The previous handlers are restored on
    leaving. Off the main thread, where Python cannot install handlers,
    this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    owner = os.getpid()
    raised_at: float | None = None

    def handler(signum, frame):
        nonlocal raised_at
        if os.getpid() != owner:
            # A child just forked, before its pool installed its own
            # handlers: end it quietly (the parent is stopping it anyway).
            os._exit(128 + signum)
        if raised_at is not None and time.monotonic() - raised_at < GRACE:
            return
        raised_at = time.monotonic()
        raise Interrupted(signum)

    previous = {signum: signal.signal(signum, handler) for signum in STOP_SIGNALS}
    try:
        yield
    finally:
        for signum, old in previous.items():
            # None: a handler not installed from Python; the default is closest.
            signal.signal(signum, signal.SIG_DFL if old is None else old)


_PR_SET_PDEATHSIG = 1       # <linux/prctl.h>


def die_with_parent(parent_pid: int) -> None:
    """Worker initializer: have the kernel SIGKILL this process when its
    parent ends, however it ends (a SIGKILLed parent runs no clean-up; its
    workers would spin on, re-parented to PID 1). Linux only; elsewhere the
    parent's own clean-up is all there is.

    (pebble's workers already ignore SIGINT, so a Ctrl-C sent to the whole
    process group by a terminal reaches only the parent, which stops them.)
    """
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        # prctl is variadic: pass its arguments at their full width.
        libc.prctl(ctypes.c_int(_PR_SET_PDEATHSIG), ctypes.c_ulong(signal.SIGKILL), ctypes.c_ulong(0),
                   ctypes.c_ulong(0), ctypes.c_ulong(0))
    # The parent may have died between the fork and the prctl call; then
    # there is nobody to signal us, so go now.
    if os.getppid() != parent_pid:
        os._exit(1)
