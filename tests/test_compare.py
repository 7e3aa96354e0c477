"""The comparison rule on signals that are zero in theory."""

from __future__ import annotations

import numpy as np
import pandas as pd

from mechval.judging.compare import ZERO_IN_THEORY, compare
from mechval.model.scenario import Tolerance
from mechval.records.signals import SIGNAL_CLASS, Signals


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


def test_each_signal_is_judged_as_if_compared_alone():
    """`compare` works on all signals as rows of one array; each record
    equals, bit for bit, the record of that signal compared on its own
    beside its class's other signals (the class's peak is the only figure
    signals share). Clean, growing, partly missing with a reason,
    non-finite without one, and unreported signals."""
    t = np.linspace(0.0, 2.0, 2001)
    rng = np.random.default_rng(3)
    reference = {"a.x": np.cos(t), "a.vx": -np.sin(t), "b.theta": t ** 2, "b.omega": 2 * t,
                 "c.Fx": 1e3 * np.sin(3 * t), "c.Fy": np.zeros_like(t)}
    engine = {name: values + 1e-6 * rng.standard_normal(len(t)) * (1 + t) for name, values in reference.items()}
    engine["b.omega"][100:120] = np.nan          # with a stated reason: left out
    engine["c.Fx"][5] = np.inf                   # without one: fails
    del engine["c.Fy"]                           # not reported
    result = Signals(pd.DataFrame({"t": t, **engine}), "x", missing={"b.omega": "not sampled there"})
    together = compare(Signals(pd.DataFrame({"t": t, **reference}), "reference"), result, Tolerance())
    for name in reference:
        same_class = {k: v for k, v in reference.items() if SIGNAL_CLASS[k] == SIGNAL_CLASS[name]}
        alone_reference = Signals(pd.DataFrame({"t": t, **same_class}), "reference")
        alone = compare(alone_reference, result, Tolerance()).set_index("signal").loc[[name]].reset_index()
        row = together.set_index("signal").loc[[name]].reset_index()
        pd.testing.assert_frame_equal(row, alone, check_exact=True, check_dtype=False)
    verdicts = together.set_index("signal")["verdict"]
    assert verdicts["c.Fx"] == "fail" and verdicts["c.Fy"] == "missing" and verdicts["a.x"] == "pass"
