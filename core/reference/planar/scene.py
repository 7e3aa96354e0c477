"""The general reference's side of a scene without a closed form: its
`motion` solved by `mechval.reference.planar.solver`, and whether its joints are
redundant (each body's resultant is then a signal, docs/conventions.md).
The scene model itself is `mechval.model.scene`; the one path from a scene to
its `Mechanism` is `mechval.reference.linkages.build_mechanism`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from mechval.model.mechanism import Mechanism
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.planar.solver import raw_planar, redundant_constraints


def has_redundant_constraints(mechanism: Mechanism) -> bool:
    """Whether the joints' Jacobian is rank-deficient at the assembly pose;
    a pose that does not assemble is refused later, where it always was."""
    try:
        return bool(redundant_constraints(mechanism))
    except MechanismError:
        return False


class SolvedMotion:
    """A planar mechanism's `motion`: the raw motion columns of its frames,
    from the general reference (the four kinds have closed forms instead)."""

    def __init__(self, mechanism: Mechanism | None = None):
        self.mechanism = mechanism

    def __call__(self, t: np.ndarray) -> pd.DataFrame:
        frame = raw_planar(self.mechanism, np.asarray(t, dtype=float)).frame
        return frame[["t"] + self.mechanism.motion_columns()]
