"""What the engine adapters share beyond the contract (`mechval.adapter`,
re-exported here for adapters and plug-ins): the step rule and silencing
what engines print from C.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys

import dataclasses

import numpy as np
import pandas as pd

from mechval.records import engine_inputs
from mechval.adapter import (MAX_STEPS_PER_SAMPLE, EngineAdapter, PeakRates, RawRun,  # noqa: F401 (re-exported)
                             RunInfo, Unrepresentable)
from mechval.reference.dynamics import RTOL, raw_dynamics
from mechval.model.kinematics import dense_grid, peak_rate
from mechval.model.mechanism import Mechanism
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.mechanism import spatial_solution

#: The forward-dynamics reference's tolerance where only a run's peak rates
#: and forces are needed (`planned_motion`: the step rule, force scales, the
#: audit's speed clamp): on every case of tests/dynamic_mechanisms.py it
#: gives the step rule's Ω of 1e-10 to 4 digits in about half the time (a
#: looser 1e-4 misjudged the jerk of the falling four-bar by 40 %).
RATE_RTOL = 1e-6


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


def reference_motion(mechanism: Mechanism, t: np.ndarray, rtol: float = RTOL) -> pd.DataFrame:
    """The reference's raw columns at instants t: the prescribed motion, or
    for a torque-driven or free mechanism (`Mechanism.forward_dynamics`) the
    forward dynamics from its consistent initial state at t[0], the state
    every adapter starts such a run from; an initial state the reference
    refuses is Unrepresentable with its key and reason."""
    if not mechanism.forward_dynamics:
        return mechanism.motion(t)

    def integrate() -> pd.DataFrame:
        try:
            if mechanism.spatial is not None:      # integrated at the spatial reference's own tolerance
                return spatial_solution(mechanism.spatial, t).frame
            return raw_dynamics(mechanism, t, rtol=rtol).frame
        except MechanismError as exc:
            raise Unrepresentable(exc.key, exc.reason) from None
    # Through the run's recorded inputs, where the harness feeds them
    # (`mechval.records.engine_inputs`).
    return engine_inputs.read(mechanism, "dynamics", t, rtol, integrate)


def planned_motion(mechanism: Mechanism) -> Mechanism:
    """The mechanism whose `motion` is what only needs its peak rates and
    forces (the step rule, force scales, the audit's speed clamp): a
    prescribed motion as it is; a torque-driven or free one integrated by
    the forward-dynamics reference at RATE_RTOL. Each call of its `motion`
    solves anew: the harness asks for the step rule's grid once per scene
    (`peak_rates`)."""
    if not mechanism.forward_dynamics:
        return mechanism
    if mechanism.spatial is not None:
        return dataclasses.replace(mechanism, motion=lambda t: spatial_solution(
            mechanism.spatial, np.asarray(t, dtype=float), reactions=False, rtol=RATE_RTOL).frame)
    return dataclasses.replace(
        mechanism, motion=lambda t: reference_motion(mechanism, np.asarray(t, dtype=float), RATE_RTOL))


def peak_rates(mechanism: Mechanism, times: np.ndarray) -> PeakRates:
    """The planned motion on the step rule's dense grid over the run, and
    its Ω (`mechval.model.kinematics.step_rate`): one solve, which the harness
    does once per scene and hands to every adapter (`uses_peak_rates`)."""
    t = dense_grid(times)
    motion = planned_motion(mechanism).motion(t)
    return PeakRates(t, motion, peak_rate(mechanism, motion, t))


def default_step(mechanism: Mechanism, times: np.ndarray, rad_per_step: float = 0.01,
                 max_step: float = 1e-3, rate: float | None = None) -> float:
    """dt = rad_per_step / Ω, at most max_step, rounded down so that every
    sample interval holds a whole number of steps. Ω is `rate` when given
    (the prepared scene's `PeakRates.rate`), else solved here
    (`peak_rates`)."""
    interval = float(times[1] - times[0])
    rate = peak_rates(mechanism, times).rate if rate is None else rate
    dt = min(rad_per_step / max(rate, 1e-12), max_step, interval)
    return interval / int(np.ceil(interval / dt - 1e-9))


def closing_start(mech: Mechanism, t: np.ndarray) -> pd.DataFrame:
    """The reference motion's first row at instants t if the loop closes
    at every one of them, else no row (the reference refuses them, or
    gives NaN where the loop cannot close)."""
    try:
        with np.errstate(invalid="ignore"):
            motion = engine_inputs.source_motion(mech)(t)
    except ValueError:                    # the reference refuses those instants
        return pd.DataFrame()
    return motion.iloc[:1].reset_index(drop=True) if np.all(np.isfinite(motion.to_numpy())) else pd.DataFrame()
