"""The analytic reference: closed-form kinematics + Newton–Euler reactions."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd

from . import __version__
from .linkages import build_mechanism
from .mechanism import Mechanism
from .newton_euler import reaction_values
from .scenario import Scenario
from .signals import Signals, canonical_signals


#: Instants per chunk: bounds memory on long runs and feeds one thread each.
CHUNK = 1 << 17


def raw_reference(mechanism: Mechanism, t: np.ndarray) -> pd.DataFrame:
    """Raw motion and reaction columns of the reference at instants t.

    Long runs are split into chunks evaluated on a thread per core (the
    work is numpy element-wise arithmetic, which releases the GIL), each
    writing its slice of one preallocated table.
    """
    t = np.asarray(t, dtype=float)
    starts = range(0, len(t), CHUNK)
    first = mechanism.motion(t[:1])
    columns = list(first.columns) + mechanism.reaction_columns()
    table = np.empty((len(columns), len(t)))

    def fill(start: int) -> None:
        motion = mechanism.motion(t[start:start + CHUNK])
        arrays = {name: motion[name].to_numpy() for name in motion.columns}
        table[:len(arrays), start:start + CHUNK] = np.array(list(arrays.values()))
        table[len(arrays):, start:start + CHUNK] = reaction_values(mechanism, arrays)

    if len(starts) == 1:
        fill(0)
    else:
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            list(pool.map(fill, starts))
    return pd.DataFrame(table.T, columns=columns, copy=False)


def simulate_reference(scenario: Scenario) -> Signals:
    """The reference's canonical signals at the scenario's samples."""
    mechanism = build_mechanism(scenario)
    raw = raw_reference(mechanism, scenario.time.t)
    return canonical_signals(mechanism, raw, "reference", __version__,
                             {"method": "closed-form kinematics + Newton–Euler (Norton ch. 4, 6, 7, 11)"})
