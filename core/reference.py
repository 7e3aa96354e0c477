"""The analytic reference: closed-form kinematics + Newton–Euler reactions."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd

from . import __version__
from .linkages import build_mechanism
from .mechanism import Mechanism
from .newton_euler import reactions
from .scenario import Scenario
from .signals import Signals, canonical_signals


CHUNK = 1 << 17


def raw_reference(mechanism: Mechanism, t: np.ndarray) -> pd.DataFrame:
    """Raw motion and reaction columns of the reference at instants t.

    Long runs are split into chunks evaluated on a thread per core: the
    work is numpy element-wise arithmetic, which releases the GIL.
    """
    t = np.asarray(t, dtype=float)
    if len(t) <= CHUNK:
        return _raw_chunk(mechanism, t)
    chunks = [t[k:k + CHUNK] for k in range(0, len(t), CHUNK)]
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        return pd.concat(pool.map(lambda c: _raw_chunk(mechanism, c), chunks), ignore_index=True)


def _raw_chunk(mechanism: Mechanism, t: np.ndarray) -> pd.DataFrame:
    motion = mechanism.motion(t)
    return pd.concat([motion, reactions(mechanism, motion)], axis=1)


def simulate_reference(scenario: Scenario) -> Signals:
    """The reference's canonical signals at the scenario's samples."""
    mechanism = build_mechanism(scenario)
    raw = raw_reference(mechanism, scenario.time.t)
    return canonical_signals(mechanism, raw, "reference", __version__,
                             {"method": "closed-form kinematics + Newton–Euler (Norton ch. 4, 6, 7, 11)"})
