"""Stand-in engines for testing the harness's isolation of failures: one
crashes the worker process, one hangs, one returns NaN, one raises, one is
a faithful copy of the reference. They are registered only inside tests."""

from __future__ import annotations

import os
import time

import numpy as np

from mechval.engines.base import EngineAdapter, RawRun
from mechval.reference import raw_reference


class _Fake(EngineAdapter):
    library = "numpy"
    distribution = "numpy"

    def default_settings(self, mechanism, times):
        return {"timestep": 1e-3}


class Faithful(_Fake):
    name = "faithful"

    def run(self, mechanism, times, settings):
        return RawRun(raw_reference(mechanism, times))


class Crashing(_Fake):
    name = "crashing"

    def run(self, mechanism, times, settings):
        os._exit(7)


class Hanging(_Fake):
    name = "hanging"

    def run(self, mechanism, times, settings):
        time.sleep(600)


class NonFinite(_Fake):
    name = "nonfinite"

    def run(self, mechanism, times, settings):
        raw = raw_reference(mechanism, times)
        raw.loc[raw.index[len(raw) // 2]:, "A.Fx"] = np.nan
        return RawRun(raw)


class Raising(_Fake):
    name = "raising"

    def run(self, mechanism, times, settings):
        raise RuntimeError("solver diverged")


class Spiking(_Fake):
    """The reference with forces 0.1 % high and one sample of A.Fx 50 % high
    (a spike that fails the force bound)."""
    name = "spiking"

    def run(self, mechanism, times, settings):
        raw = raw_reference(mechanism, times)
        forces = [c for c in raw.columns if c.endswith((".Fx", ".Fy"))]
        raw[forces] *= 1.001
        raw.loc[raw.index[len(raw) // 3], "A.Fx"] *= 1.5
        return RawRun(raw)


FAKES = {cls.name: f"fake_engines:{cls.__name__}"
         for cls in (Faithful, Crashing, Hanging, NonFinite, Raising, Spiking)}
