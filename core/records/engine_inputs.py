"""What an engine run reads from the reference, recorded so that it can be
fed to the engine again (docs/comparison.md#what-a-baseline-feeds-the-engine).

An engine starts from the reference's state: a prescribed run from the
reference motion at its pre-roll's start (MuJoCo also checks that the loop
closes along the pre-roll), a torque-driven or free run from the
forward-dynamics reference's consistent initial state. Those values are
computed with the machine's BLAS, whose kernels (picked per CPU) change
their last bits, and an engine can amplify a change of 1e-15 in its start
to 1e-7 of its forces. A baseline therefore stores every value a run read
(`RecordedInputs`, beside the run's resolved settings), and a regression
check feeds exactly those values back, so that its verdict depends on the
engine library alone.

Every read of an adapter's `run` goes through the run's `EngineInputs`
(the harness wraps the mechanism's `motion` in one, `fed_mechanism`):
recording, it computes the value and keeps it; replaying, it returns the
kept value and refuses a read it does not hold (`InputsNotRecorded`).
Reads are keyed by what was asked — a kind and the instants, bit for bit
(the instants derive from the samples and the settings, which a replay
feeds too) — and kept as the rows the adapter asked for, so a recording
is a few rows, not a motion.
"""

from __future__ import annotations

import dataclasses
import hashlib
from typing import Any, Callable, Mapping

import numpy as np
import pandas as pd

from mechval.model.mechanism import Mechanism

#: The read kinds: the reference motion at some instants (prescribed, or the
#: integrated motion of a torque-driven or free scene), the forward-dynamics
#: reference's raw columns at a tolerance (`mechval.engines.base.
#: reference_motion`), and the first row of a motion that must close at every
#: instant (MuJoCo's pre-roll; empty where it does not close).
KINDS = ("motion", "dynamics", "closing start")


class InputsNotRecorded(ValueError):
    """A replayed run asked the reference for something the baseline did
    not record (the adapter reads other instants than it did then)."""


def read_key(kind: str, t: np.ndarray) -> str:
    """The key of one read: what the adapter asked for, a kind and a digest
    of the instants' bytes (two reads of the same instants give the same
    key). The tolerance the reference computes it to is the reference's
    business, recorded beside the value but not part of what was asked:
    a recording stays valid when the reference's own accuracy changes."""
    t = np.ascontiguousarray(t, dtype=float)
    digest = hashlib.sha256(t.tobytes()).hexdigest()[:16]
    return f"{kind}|{len(t)}|{digest}"


@dataclasses.dataclass(frozen=True)
class RecordedInputs:
    """The reads of one run, as JSON-ready data: key → {"t0", "t1", "n",
    "columns": {name: [values]}} (floats written with repr and read back
    exactly; NaN kept)."""

    reads: Mapping[str, Mapping[str, Any]]

    def as_json(self) -> dict[str, Any]:
        return {key: dict(value) for key, value in self.reads.items()}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> "RecordedInputs":
        """The record stored in a baseline; ValueError naming the entry that
        is not of that form."""
        if not isinstance(data, Mapping):
            raise ValueError(f"expected an object of reads, got {type(data).__name__}")
        for key, value in data.items():
            columns = value.get("columns") if isinstance(value, Mapping) else None
            if not isinstance(columns, Mapping) or not all(
                    isinstance(v, list) and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
                    for v in columns.values()):
                raise ValueError(f"read {key!r}: expected {{'columns': {{name: [numbers]}}}}")
            if len({len(v) for v in columns.values()}) > 1:
                raise ValueError(f"read {key!r}: columns of different lengths")
        return cls({key: dict(value) for key, value in data.items()})

    def frame(self, key: str) -> pd.DataFrame:
        columns = self.reads[key]["columns"]
        return pd.DataFrame({name: np.asarray(values, dtype=float) for name, values in columns.items()})

    def nudged(self, ulps: int) -> "RecordedInputs":
        """Every value moved by `ulps` units in the last place (towards +inf
        for positive ulps), the time column included: the inputs a machine
        with other floating point might have computed."""
        def nudge(values: list) -> list:
            x = np.asarray(values, dtype=float)
            for _ in range(abs(ulps)):
                x = np.nextafter(x, np.inf if ulps > 0 else -np.inf)
            return [float(v) for v in x]
        return RecordedInputs({key: dict(value, columns={name: nudge(v) for name, v in value["columns"].items()})
                               for key, value in self.reads.items()})

    def __len__(self) -> int:
        return len(self.reads)


@dataclasses.dataclass(frozen=True)
class Feed:
    """What a regression check feeds an engine run: the resolved settings
    and the reads the recorded run made."""

    settings: Mapping[str, Any]
    reads: RecordedInputs


class EngineInputs:
    """The reads of one engine run: recorded (`replay` None) or fed from a
    recording."""

    def __init__(self, replay: RecordedInputs | None = None):
        self.replay = replay
        self.recorded: dict[str, dict[str, Any]] = {}

    def read(self, kind: str, t: np.ndarray, rtol: float | None, compute: Callable[[], pd.DataFrame]) -> pd.DataFrame:
        """The value of one read: `compute()` while recording (and kept),
        the recorded value while replaying."""
        t = np.asarray(t, dtype=float)
        key = read_key(kind, t)
        if key in self.recorded:                # asked again in the same run
            return self.replay.frame(key) if self.replay is not None else self.frame(key)
        if self.replay is not None:
            if key not in self.replay.reads:
                raise InputsNotRecorded(
                    f"the run read the reference ({kind}, {len(t)} instant(s) from t = {t[0] if t.size else 0:.6g} s) "
                    "where the baseline recorded no value: the adapter reads other inputs than when it was "
                    "recorded")
            self.recorded[key] = self.replay.reads[key]
            return self.replay.frame(key)
        frame = compute()
        self.recorded[key] = {"t0": float(t[0]) if t.size else None, "t1": float(t[-1]) if t.size else None,
                              "n": int(t.size), "rtol": rtol,
                              "columns": {str(c): [float(v) for v in frame[c].to_numpy(dtype=float)] for c in frame}}
        return frame.copy()

    def frame(self, key: str) -> pd.DataFrame:
        return RecordedInputs({key: self.recorded[key]}).frame(key)

    def record(self) -> RecordedInputs:
        """What was read (while recording) or fed (while replaying)."""
        return self.replay if self.replay is not None else RecordedInputs(dict(self.recorded))


class FedMotion:
    """A mechanism's `motion` whose every call is one read of `inputs`."""

    def __init__(self, motion: Callable[[np.ndarray], pd.DataFrame], inputs: EngineInputs):
        self.source, self.inputs = motion, inputs

    def __call__(self, t: np.ndarray) -> pd.DataFrame:
        return self.inputs.read("motion", t, None, lambda: self.source(np.asarray(t, dtype=float)))


def fed_mechanism(mechanism: Mechanism, inputs: EngineInputs) -> Mechanism:
    """The mechanism an adapter's run gets: the same, with every read of
    its reference motion going through `inputs`."""
    return dataclasses.replace(mechanism, motion=FedMotion(mechanism.motion, inputs))


def source_motion(mechanism: Mechanism) -> Callable[[np.ndarray], pd.DataFrame]:
    """The reference motion itself, not a read of the run's inputs (for a
    read's own computation)."""
    motion = mechanism.motion
    return motion.source if isinstance(motion, FedMotion) else motion


def read(mechanism: Mechanism, kind: str, t: np.ndarray, rtol: float | None,
         compute: Callable[[], pd.DataFrame]) -> pd.DataFrame:
    """A read of kind `kind` through the mechanism's inputs when its motion
    is fed (`fed_mechanism`), else `compute()` as it is."""
    motion = mechanism.motion
    if isinstance(motion, FedMotion):
        return motion.inputs.read(kind, t, rtol, compute)
    return compute()
