"""The commands' defaults, in a module that imports nothing heavy: the
command line reads them to build its parser, before it knows which command
runs (`mechval list` imports neither numpy, pandas, scipy nor an engine)."""

from __future__ import annotations

import os
from dataclasses import dataclass

#: Default limits of one engine run (overridden by --max-steps, --max-memory).
#: Measured 11-34 µs per step (up to 100 on a loaded machine): 10⁷ steps
#: take 2-6 min, up to 17.
DEFAULT_MAX_STEPS = 10_000_000


def physical_memory() -> float:
    """This machine's memory (bytes); 8 GiB where the OS does not say."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 8.0 * 2**30


#: Default memory limit of one run: three quarters of this machine's memory
#: (a run beyond it would swap or be killed).
DEFAULT_MAX_MEMORY = 0.75 * physical_memory()


@dataclass(frozen=True)
class Limits:
    """The limits of one engine run (--max-steps, --max-memory in bytes)."""

    max_steps: float = DEFAULT_MAX_STEPS
    max_memory: float = DEFAULT_MAX_MEMORY


#: Seconds to wait for a Dask scheduler to answer before giving up
#: (`mechval cost --dask-connect-timeout`; Dask's own default is 30 s).
DASK_CONNECT_TIMEOUT = 10.0
