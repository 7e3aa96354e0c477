"""The analytic reference: closed-form kinematics + Newton–Euler reactions."""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import __version__
from .linkages import build_mechanism
from .mechanism import Mechanism
from .newton_euler import reactions
from .scenario import Scenario
from .signals import Signals, canonical_signals


def raw_reference(mechanism: Mechanism, t: np.ndarray) -> pd.DataFrame:
    """Raw motion and reaction columns of the reference at instants t."""
    motion = mechanism.motion(np.asarray(t, dtype=float))
    return pd.concat([motion, reactions(mechanism, motion)], axis=1)


def simulate_reference(scenario: Scenario) -> Signals:
    """The reference's canonical signals at the scenario's samples."""
    mechanism = build_mechanism(scenario)
    raw = raw_reference(mechanism, scenario.time.t)
    return canonical_signals(mechanism, raw, "reference", __version__,
                             {"method": "closed-form kinematics + Newton–Euler (Norton ch. 4, 6, 7, 11)"})
