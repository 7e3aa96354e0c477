"""The comparison rule on signals that are zero in theory."""

from __future__ import annotations

import numpy as np
import pandas as pd

from mechval.judging.compare import ZERO_IN_THEORY, compare
from mechval.model.scenario import Tolerance
from mechval.records.signals import Signals


def signals(**columns) -> Signals:
    t = np.linspace(0.0, 1.0, 11)
    return Signals(pd.DataFrame({"t": t, **{k: np.asarray(v, dtype=float) for k, v in columns.items()}}), "x")


def test_a_signal_zero_up_to_rounding_takes_its_class_peak():
    """A slider's vy on a level guide: the general reference gives rounding
    (1e-17), not an exact 0. Its bound must be the velocity class's (as for
    an exact zero), or no engine could meet it: with its own peak the bound
    would be 1e-19 m/s."""
    t = np.linspace(0.0, 1.0, 11)
    noise = 1e-17 * np.sin(7 * t)
    reference = signals(**{"slider.vy": noise, "slider.vx": 2.0 * np.cos(t)})
    engine = signals(**{"slider.vy": noise + 1e-9, "slider.vx": 2.0 * np.cos(t)})
    row = compare(reference, engine, Tolerance()).set_index("signal").loc["slider.vy"]
    assert row["peak"] == 2.0 and row["verdict"] == "pass"
    assert abs(noise).max() <= ZERO_IN_THEORY * 2.0


def test_a_small_but_real_signal_keeps_its_own_peak():
    """A signal 1e-6 of its class's largest is real: judged on its own peak."""
    t = np.linspace(0.0, 1.0, 11)
    small = 1e-6 * np.cos(t)
    reference = signals(**{"a.vy": small, "a.vx": np.cos(t)})
    engine = signals(**{"a.vy": small * 1.5, "a.vx": np.cos(t)})
    row = compare(reference, engine, Tolerance()).set_index("signal").loc["a.vy"]
    assert row["peak"] == 1e-6 and row["verdict"] == "fail"
