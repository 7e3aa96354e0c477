"""The analytic reference: closed-form kinematics + Newton–Euler reactions,
behind the same adapter contract as every engine (`mechval.adapter`)."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Mapping

import numpy as np
import pandas as pd

from mechval import __version__
from mechval.adapter import FEATURES, SPATIAL, EngineAdapter, RawRun, RunInfo, Unrepresentable
from mechval.model.mechanism import Mechanism
from mechval.reference.dynamics import raw_dynamics
from mechval.reference.newton_euler import reaction_values
from mechval.reference.planar.solver import MechanismError, raw_planar
from mechval.reference.spatial.mechanism import spatial_solution
from mechval.reference.spatial.system import JOINT_KINDS

#: Instants per chunk: bounds memory on long runs and feeds one thread each.
CHUNK = 1 << 17
METHOD = "closed-form kinematics + Newton–Euler (Norton ch. 4, 6, 7, 11)"


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


class ReferenceAdapter(EngineAdapter):
    """The exact solution, as an adapter: no settings, no time steps."""

    name = "reference"
    library = "numpy"
    distribution = "mechval"
    settings_spec: Mapping = {}
    step_setting = ""
    step_settings = ()
    output_copies = 8
    bytes_per_step = 0
    features = frozenset(FEATURES) | {SPATIAL}
    spatial_joints = frozenset(JOINT_KINDS)

    @classmethod
    def version(cls) -> str:
        return __version__

    def default_settings(self, mechanism: Mechanism, times: np.ndarray) -> dict[str, Any]:
        return {}

    def run(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
        if mechanism.spatial is not None:
            try:
                solution = spatial_solution(mechanism.spatial, times)
            except MechanismError as exc:
                raise Unrepresentable(exc.key, exc.reason) from None
            return RawRun(solution.frame, solution.missing, RunInfo(facts=dict(solution.facts)))
        if mechanism.forward_dynamics:
            try:
                solution = raw_dynamics(mechanism, times)
            except MechanismError as exc:
                raise Unrepresentable(exc.key, exc.reason) from None
            return RawRun(solution.frame, solution.missing, RunInfo(facts=dict(solution.facts)))
        if mechanism.kind == "planar":     # no closed form: the general reference
            try:
                solution = raw_planar(mechanism, times)
            except MechanismError as exc:
                raise Unrepresentable(exc.key, exc.reason) from None
            return RawRun(solution.frame, solution.missing, RunInfo(facts=dict(solution.facts)))
        return RawRun(raw_reference(mechanism, times), info=RunInfo(facts={"method": METHOD}))

