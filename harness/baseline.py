"""The rule that judges an engine run against its stored baseline (what a
baseline is and where it lives: `mechval.harness.baseline_store`).

The regression rule is much tighter than the accuracy tolerances: an engine
is deterministic on one machine (bit-identical across runs, processes and
thread counts, as measured for the committed baselines), so any change beyond
rounding means the engine, its settings or the scenario changed.
`compare_to_baseline` returns the verdict per signal as data; the CLI and
pytest both print and judge from it.

The verdict must depend on the engine alone, not on the machine: the JSON
record keeps everything the engine was fed — every resolved setting and
every value the run read from the reference (`inputs`,
`mechval.records.engine_inputs`) — and a check feeds exactly those, since
the reference's last bits vary with the machine's BLAS kernels and an
engine can amplify them a hundred-million-fold. It also keeps each signal's
`sensitivity`, how far the signal moved when those inputs moved by one unit
in the last place, measured when the baseline was saved: the threshold
stays SENSITIVITY_MARGIN times above it, so that what an engine makes of
another machine's last bits is not a regression.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import MISSING, fields, is_dataclass
from typing import Any, Mapping

import numpy as np
import pandas as pd

from mechval.judging.compare import compare
from mechval.model.scenario import Scenario, Tolerance
from mechval.records.signals import SIGNAL_CLASS, Signals

#: Default regression threshold: max |new − stored| ≤ RTOL · peak, with peak
#: the stored signal's max |value| over the run. Measured on the committed
#: baselines: reruns fed the same inputs are bit-identical (other process,
#: 1 or 2 workers, one BLAS/OpenMP thread, other OpenBLAS kernels); what
#: another machine's engine arithmetic may add is the sensitivity term
#: (SENSITIVITY_MARGIN), while an engine upgrade moves
#: the signals by orders of magnitude more (tests/test_baselines.py checks
#: it on the committed MuJoCo 3.3.7 and 4.0.0 baselines).
DEFAULT_RTOL = 1e-9
#: Absolute floor of the threshold (SI units). A signal that is identically
#: zero in theory (α2 of a crank at constant speed) comes out as 0 (Exudyn)
#: or as integration residue (PyBullet, MuJoCo; its size on the committed
#: baselines: tests/test_baselines.py); its own peak is no scale for it, as
#: 1e-9 of it would flag a change in the residue's last bits. 1e-12 is
#: above the last bits of the quantities it derives from (1 ulp of an
#: acceleration of 50 rad/s² is 7e-15) and far below a physical change.
ABSOLUTE_FLOOR = 1e-12
#: The threshold is at least this many times a signal's recorded
#: sensitivity (its largest move when the run's inputs moved by ±1 ulp). A
#: machine whose libm or CPU dispatch changes an engine's own arithmetic in
#: the last bits moves its signals by about that much; tests/test_baselines.py
#: checks that the margin keeps every committed threshold below the smallest
#: change an engine upgrade made.
SENSITIVITY_MARGIN = 100.0
#: Accuracy against the reference counts as unchanged while the old and new
#: max relative errors differ by less than this fraction of the old one; a
#: smaller shift of an error says nothing about accuracy (halving the step
#: moves it by a factor of 2 to 16).
ACCURACY_CHANGE = 1e-3

COLUMNS = ["signal", "class", "max_abs_diff", "t_max", "peak", "relative", "rtol", "sensitivity", "threshold",
           "verdict", "reason"]


def scenario_hash(scenario: Scenario, engine: str) -> str:
    """sha256 of what determines an engine's signals: the scene's physics
    (bodies, joints, drives, force elements, torque laws, initial values,
    gravity, assembly pose), the closed form's kind (it names the signals),
    the samples and this engine's settings table (`physics`). Name,
    description, tags, tolerances, comments and the file's path are left
    out, so that a reworded scene or a new tolerance is not reported as a
    changed scenario; so is how mechval holds a scene, so that a
    restructured model or a new field left at its default keeps every
    recorded baseline's hash."""
    content = {"scene": physics(scenario.scene), "kind": scenario.mechanism,
               "time": physics(scenario.time), "engine_settings": physics(dict(scenario.settings_for(engine)))}
    text = json.dumps(content, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def physics(value: Any) -> Any:
    """`value` as plain JSON data: a dataclass as its compared fields that
    differ from their defaults (by name), sequences as lists, mappings with
    text keys, floats by repr (exact)."""
    if is_dataclass(value) and not isinstance(value, type):
        content = {}
        for f in fields(value):
            item = getattr(value, f.name)
            default = f.default if f.default is not MISSING else (
                f.default_factory() if f.default_factory is not MISSING else MISSING)
            if f.compare and not (default is not MISSING and _same(item, default)):
                content[f.name] = physics(item)
        return content
    if isinstance(value, Mapping):
        return {str(k): physics(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [physics(v) for v in value]
    if isinstance(value, float):
        return repr(value)
    if value is None or isinstance(value, (bool, int, str)):
        return value
    return repr(value)


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(a == b)
    except ValueError:      # arrays
        return False


def metadata(scenario: Scenario, setting: str, overrides: Mapping[str, Any], signals: Signals,
             provenance: Mapping[str, str], sensitivity: Mapping[str, float] | None = None) -> dict[str, Any]:
    """The JSON record of a run: engine, version, settings (the resolved
    inputs) apart from the run's own facts (steps taken, measured gap, wall
    time), what the run read from the reference and each signal's
    sensitivity to it, scenario and its hash, machine and commit."""
    plain = lambda values: json.loads(json.dumps(dict(values), default=repr))
    fed = {} if signals.inputs is None else {"inputs": signals.inputs.as_json()}
    if sensitivity is not None:
        fed["sensitivity"] = {name: float(value) for name, value in sensitivity.items()}
    return {**fed,
        "engine": signals.source, "version": signals.version, "setting": setting,
        "overrides": plain(overrides),
        "settings": plain(signals.settings),
        "run_info": plain(signals.info.as_dict()),
        "missing": dict(signals.missing),
        "scenario": scenario.name, "scenario_hash": scenario_hash(scenario, signals.source),
        "samples": len(signals.frame), "provenance": dict(provenance),
    }


def compare_to_baseline(stored: Signals, new: Signals, rtol: float = DEFAULT_RTOL,
                        signal_rtol: Mapping[str, float] | None = None,
                        sensitivity: Mapping[str, float] | None = None) -> pd.DataFrame:
    """One row per signal (t included): max |new − stored|, where (t), its
    ratio to the stored peak, the threshold max(rtol·peak,
    SENSITIVITY_MARGIN·sensitivity, ABSOLUTE_FLOOR) and the verdict
    "identical", "within" or "regression". A signal added or removed, a
    changed number of samples or a changed set of missing values is a
    regression."""
    signal_rtol, sensitivity = dict(signal_rtol or {}), dict(sensitivity or {})
    if len(stored.frame) != len(new.frame):
        reason = f"{len(stored.frame)} samples stored, {len(new.frame)} now"
        return pd.DataFrame([dict(signal="(samples)", verdict="regression", reason=reason)], columns=COLUMNS)
    t = stored.t
    rows = []
    for name in dict.fromkeys([*stored.frame.columns, *new.frame.columns]):
        r = signal_rtol.get(name, rtol)
        row = dict(signal=name, **{"class": SIGNAL_CLASS.get(name, "time")}, rtol=r,
                   sensitivity=float(sensitivity.get(name, 0.0)), reason="")
        if name not in new.frame or name not in stored.frame:
            rows.append(dict(row, verdict="regression",
                             reason="signal removed" if name not in new.frame else "signal added"))
            continue
        old, now = stored[name].astype(float), new[name].astype(float)
        peak = float(np.nanmax(np.abs(old))) if np.isfinite(old).any() else 0.0
        threshold = max(r * peak, SENSITIVITY_MARGIN * row["sensitivity"], ABSOLUTE_FLOOR)
        row.update(peak=peak, threshold=threshold)
        gaps = np.isnan(old) != np.isnan(now)
        if gaps.any():
            rows.append(dict(row, verdict="regression", t_max=float(t[gaps][0]),
                             reason=f"missing values changed at {int(gaps.sum())} sample(s)"))
            continue
        diff = np.abs(np.where(np.isnan(old), 0.0, now - old))
        worst = int(np.argmax(diff))
        largest = float(diff[worst])
        row.update(max_abs_diff=largest, t_max=float(t[worst]), relative=largest / peak if peak else np.nan)
        verdict = "identical" if largest == 0 else "within" if largest <= threshold else "regression"
        if not np.isfinite(largest):    # inf or NaN where the baseline had a value
            verdict, row["reason"] = "regression", "non-finite value"
        rows.append(dict(row, verdict=verdict))
    return pd.DataFrame(rows, columns=COLUMNS)


def sensitivity(signals: Signals, moved: list[Signals]) -> dict[str, float]:
    """Per signal, its largest move (max |moved − signals| over the run)
    among runs whose inputs moved by an ulp (`RecordedInputs.nudged`), at
    the samples where both have a value."""
    result = {}
    for name in signals.frame.columns:
        base = signals[name].astype(float)
        largest = 0.0
        for other in moved:
            if name in other.frame and len(other.frame) == len(base):
                diff = np.abs(other[name].astype(float) - base)
                finite = np.isfinite(diff)      # a gap is judged by the check itself
                largest = max(largest, float(diff[finite].max()) if finite.any() else 0.0)
        result[name] = largest
    return result


def regressed(rows: pd.DataFrame) -> bool:
    return bool((rows["verdict"] == "regression").any())


def context_changes(meta: Mapping[str, Any], new: Mapping[str, Any]) -> list[str]:
    """What differs between the stored and the new run besides the signals:
    engine version, each setting (old → new), the scenario's content."""
    changes = []
    if meta["version"] != new["version"]:
        changes.append(f"engine version differs: baseline {meta['engine']} {meta['version']}, "
                       f"now {new['version']}")
    old, now = meta["settings"], new["settings"]
    for key in sorted(set(old) | set(now)):
        if old.get(key, "(absent)") != now.get(key, "(absent)"):
            changes.append(f"setting {key}: {old.get(key, '(absent)')} → {now.get(key, '(absent)')}")
    if meta["scenario_hash"] != new["scenario_hash"]:
        changes.append(f"scenario content changed (hash {meta['scenario_hash']} → {new['scenario_hash']})")
    return changes


def accuracy_change(reference: Signals, stored: Signals, new: Signals, tolerance: Tolerance) -> pd.DataFrame:
    """Per signal class, the max relative error (max |error| / peak, as in
    `mechval.judging.compare`) against the reference of the stored and the new
    signals, and whether accuracy improved, worsened or is unchanged ("n/a"
    where one of them cannot be compared, e.g. the samples changed)."""
    table = pd.DataFrame({"old": _class_errors(reference, stored, tolerance),
                          "new": _class_errors(reference, new, tolerance)}).rename_axis("class").reset_index()
    old, now = table["old"], table["new"]
    table["verdict"] = np.select([old.isna() | now.isna(), (now - old).abs() <= ACCURACY_CHANGE * old, now < old],
                                 ["n/a", "unchanged", "improved"], default="worsened")
    return table


def _class_errors(reference: Signals, signals: Signals, tolerance: Tolerance) -> pd.Series:
    try:
        records = compare(reference, signals, tolerance)
    except ValueError:          # other sample instants than the reference's
        return pd.Series(dtype=float)
    records = records[records["class"] != "health"]
    return records.groupby("class", sort=False)["relative_error"].max()
