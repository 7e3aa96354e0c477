"""Stand-in engines for testing the harness's isolation of failures: one
crashes the worker process, one hangs, one spins on the CPU, one returns
NaN, one raises, one is a faithful copy of the reference. They are
registered only inside tests, or by running this file as `mechval`:

    python tests/fake_engines.py run SCENARIO --engine busy ...
"""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from mechval.engines import registry
from mechval.engines.base import EngineAdapter, RawRun
from mechval.reference.dynamics import raw_dynamics
from mechval.reference.adapter import raw_reference


class _Fake(EngineAdapter):
    library = "numpy"
    distribution = "numpy"

    def default_settings(self, mechanism, times):
        return {"timestep": 1e-3}


class Faithful(_Fake):
    name = "faithful"

    def run(self, mechanism, times, settings):
        return RawRun(raw_reference(mechanism, times))


class Stepless(_Fake):
    """An adapter with no time step and no settings (like the reference)."""
    name = "stepless"
    settings_spec = {}
    step_setting = ""

    def default_settings(self, mechanism, times):
        return {}

    def run(self, mechanism, times, settings):
        return RawRun(raw_reference(mechanism, times))


class Crashing(_Fake):
    name = "crashing"

    def run(self, mechanism, times, settings):
        os._exit(7)


class CrashingOnce(_Fake):
    """Kills its worker process the first time it runs (it leaves a file in
    $MECHVAL_TEST_CRASH_DIR to remember), then runs as the reference: a
    worker lost mid-run whose task is run again elsewhere."""
    name = "crashing-once"

    def run(self, mechanism, times, settings):
        marker = Path(os.environ["MECHVAL_TEST_CRASH_DIR"], "crashed")
        if not marker.exists():
            marker.touch()
            os._exit(9)
        return RawRun(raw_reference(mechanism, times))


class Versioned(Faithful):
    """The faithful copy, taking a second, and reporting as its version
    $MECHVAL_TEST_VERSION (as a worker with another release installed
    would)."""
    name = "versioned"

    def run(self, mechanism, times, settings):
        time.sleep(1.0)
        return super().run(mechanism, times, settings)

    @classmethod
    def version(cls) -> str:
        return os.environ.get("MECHVAL_TEST_VERSION", "1.0")


class Hanging(_Fake):
    name = "hanging"

    def run(self, mechanism, times, settings):
        time.sleep(600)


class Busy(_Fake):
    """Spins on the CPU like an engine stuck in a long step and, like one
    busy in C code, does not act on SIGTERM. It first creates a file named
    by its PID in $MECHVAL_TEST_BUSY_DIR, so a test knows it is running."""

    name = "busy"

    def run(self, mechanism, times, settings):
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        if os.environ.get("MECHVAL_TEST_BUSY_DIR"):
            Path(os.environ["MECHVAL_TEST_BUSY_DIR"], str(os.getpid())).touch()
        deadline = time.monotonic() + 60        # a bound, should a test leave it behind
        while time.monotonic() < deadline:
            pass
        raise RuntimeError("busy for 60 s")


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


class Loose(_Fake):
    """Torque-driven and free scenes: the forward-dynamics reference with
    its integrator's relative tolerance set to the time step (a coarser
    setting, a larger error: a stand-in for an engine's step ladder)."""
    name = "loose"
    features = frozenset({"torque laws", "free motion"})

    def run(self, mechanism, times, settings):
        solution = raw_dynamics(mechanism, times, rtol=float(settings["timestep"]))
        return RawRun(solution.frame, solution.missing)


FAKES = {cls.name: f"fake_engines:{cls.__name__}"
         for cls in (Faithful, Stepless, Crashing, CrashingOnce, Versioned, Hanging, Busy, NonFinite, Raising,
                     Spiking, Loose)}


def registered(extra: Mapping[str, str] = FAKES) -> Callable[[], dict[str, str]]:
    """A stand-in for `registry.targets` that adds `extra` (name →
    "module:Class", taking a name's place if it is one) to the installed
    engines: `monkeypatch.setattr(registry, "targets", registered())`."""
    engines = {**registry.targets(), **extra}
    return lambda: engines


if __name__ == "__main__":
    # `mechval` with the fakes registered; the workers, forked, inherit them.
    from mechval.harness import cli
    registry.targets = registered()
    sys.exit(cli.main())
