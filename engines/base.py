"""What the engine adapters share beyond the contract (`mechval.adapter`,
re-exported here for adapters and plug-ins): the step rule and silencing
what engines print from C.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys

import numpy as np

from mechval.adapter import (MAX_STEPS_PER_SAMPLE, EngineAdapter, RawRun, RunInfo,  # noqa: F401 (re-exported)
                             Unrepresentable)
from mechval.kinematics import step_rate
from mechval.mechanism import Mechanism


@contextlib.contextmanager
def native_output_silenced():
    """Send what C code prints to stdout and stderr (file descriptors 1, 2)
    to /dev/null for the duration: some engines print banners and solver
    notices from C, which would clutter `mechval` output and reports.
    Python exceptions are unaffected."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    try:
        with open(os.devnull, "w") as devnull:
            for fd in saved:
                os.dup2(devnull.fileno(), fd)
        yield
    finally:
        # C's stdio buffers a pipe: flush it while it still points nowhere.
        ctypes.CDLL(None).fflush(None)
        sys.stdout.flush()
        sys.stderr.flush()
        for fd, copy in saved.items():
            os.dup2(copy, fd)
            os.close(copy)


def default_step(mechanism: Mechanism, times: np.ndarray, rad_per_step: float = 0.01,
                 max_step: float = 1e-3) -> float:
    """dt = rad_per_step / Ω, at most max_step, rounded down so that every
    sample interval holds a whole number of steps."""
    interval = float(times[1] - times[0])
    dt = min(rad_per_step / max(step_rate(mechanism, times), 1e-12), max_step, interval)
    return interval / int(np.ceil(interval / dt - 1e-9))
