"""Engine regression baselines: stored signals per engine version, and the
one rule that compares a new run with them.

A baseline is what one engine version produced on one scenario at one
setting (the adapter's `variants` name), stored as

    DIR/<engine>/<version>/<scenario>/<setting>.csv    canonical signals, %.17g
    DIR/<engine>/<version>/<scenario>/<setting>.json   where they came from

The regression rule is much tighter than the accuracy tolerances: an engine
is deterministic on one machine (bit-identical across runs, processes and
thread counts, as measured for the committed baselines), so any change beyond
rounding means the engine, its settings or the scenario changed.
`compare_to_baseline` returns the verdict per signal as data; the CLI and
pytest both print and judge from it.

The verdict must depend on the engine alone, not on the machine: the JSON
record keeps everything the engine was fed — every resolved setting and
every value the run read from the reference (`inputs`,
`mechval.records.engine_inputs`) — and a check feeds exactly those (`feed`), since
the reference's last bits vary with the machine's BLAS kernels and an
engine can amplify them a hundred-million-fold. It also keeps each signal's
`sensitivity`, how far the signal moved when those inputs moved by one unit
in the last place, measured when the baseline was saved: the threshold
stays SENSITIVITY_MARGIN times above it, so that what an engine makes of
another machine's last bits is not a regression.

Engine, version, scenario name and setting each become one folder or file
name under the root, so each must be a plain name (`checked_name`): a
scenario called "../../x" or "/tmp/x" must not write outside the root. A
file that cannot be read as a baseline raises `CorruptBaseline` naming the
file and the reason, so that one bad file is one verdict, not a traceback.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import warnings
from dataclasses import MISSING, dataclass, fields, is_dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pandas as pd
from packaging.version import InvalidVersion, Version

from mechval.judging.compare import compare
from mechval.records.engine_inputs import Feed, RecordedInputs
from mechval.model.scenario import Scenario, Tolerance
from mechval.records.signals import SIGNAL_CLASS, Signals

#: Default regression threshold: max |new − stored| ≤ RTOL · peak, with peak
#: the stored signal's max |value| over the run. Measured on the committed
#: baselines: reruns are bit-identical (other process, 1 or 2 workers, one
#: BLAS/OpenMP thread, 4 Python threads in one process). A CI machine of the
#: same kind could differ in the last bits (another libm or CPU dispatch;
#: not measured, there is no second machine here): 1 ulp (2e-16) grown over
#: a few thousand steps stays far below 1e-9, while an engine upgrade moves
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

#: What a name must look like to be one folder or file name under the root:
#: ASCII letters, digits and . _ - +, not starting with "." (no "..", no
#: hidden files) or "-" (not an option in the printed commands), at most 100
#: characters. No separator, no glob pattern, valid on Windows too.
SAFE_NAME = re.compile(r"[A-Za-z0-9_+][A-Za-z0-9._+-]{0,99}")
SAFE_NAME_RULE = "1 to 100 of the characters A-Z a-z 0-9 . _ - +, not starting with . or -"
#: Keys of a baseline's JSON record that the check reads, with their types.
REQUIRED_META = {"engine": str, "version": str, "setting": str, "settings": dict, "missing": dict,
                 "scenario_hash": str, "provenance": dict, "samples": int}
JSON_TYPE = {str: "a string", dict: "an object", int: "a whole number"}

COLUMNS = ["signal", "class", "max_abs_diff", "t_max", "peak", "relative", "rtol", "sensitivity", "threshold",
           "verdict", "reason"]


@dataclass(frozen=True)
class Baseline:
    """One stored baseline: its signals and its metadata (the JSON file)."""

    path: Path                  # the .csv file
    signals: Signals
    meta: Mapping[str, Any]

    @property
    def sensitivity(self) -> dict[str, float]:
        """Per signal, its recorded move under ±1 ulp of the inputs (none
        for a baseline saved before mechval measured it)."""
        return dict(self.meta.get("sensitivity") or {})

    def feed(self) -> tuple[Feed | None, str]:
        """What to feed the engine to reproduce this run, or None and why
        it cannot be reproduced."""
        if "inputs" not in self.meta:
            return None, ("this baseline does not record what the engine was fed (saved before mechval "
                          "recorded it)")
        return Feed(dict(self.meta["settings"]), RecordedInputs.from_json(self.meta["inputs"])), ""


class UnsafeName(ValueError):
    """A name that cannot be one folder or file name under the baseline root."""


class CorruptBaseline(ValueError):
    """A stored baseline that cannot be read: names the file and the reason."""

    def __init__(self, path: Path, reason: str):
        self.path, self.reason = Path(path), reason
        super().__init__(f"{path}: {reason}")


def checked_name(name: str, what: str) -> str:
    """`name` if it is safe as one path component (SAFE_NAME), else UnsafeName."""
    if not isinstance(name, str) or not SAFE_NAME.fullmatch(name):
        raise UnsafeName(f"{what} {name!r} cannot name a baseline folder or file: it must be {SAFE_NAME_RULE}")
    return name


def baseline_path(root: Path, engine: str, version: str, scenario: str, setting: str) -> Path:
    """DIR/engine/version/scenario/setting.csv; every part checked to be a
    plain name, so the path always lies inside `root`."""
    parts = [checked_name(engine, "engine"), checked_name(version, f"{engine} version"),
             checked_name(scenario, "scenario name"), checked_name(setting, "setting")]
    return Path(root).joinpath(*parts[:3], f"{parts[3]}.csv")


def obtained_path(path: Path) -> Path:
    """Where a check that found a regression writes the new signals, for
    diffing: SETTING.obtained.csv (git-ignored)."""
    return Path(path).with_suffix(".obtained.csv")


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


class BaselineAppeared(FileExistsError):
    """`save` without overwriting found the file created meanwhile (a
    concurrent save of the same baseline): it is left as it is."""


def save(path: Path, signals: Signals, meta: Mapping[str, Any], overwrite: bool = False) -> None:
    """Write the CSV and JSON, each whole or not at all: into a temporary
    file named after this process (`remove_stale_temporaries` knows it),
    then renamed over the target (`overwrite`), or linked to it, which
    fails when it exists (BaselineAppeared), so that two saves of one
    baseline never both succeed. Nothing is followed through a symbolic
    link (`refuse_links`)."""
    refuse_links(path)
    text = json.dumps(meta, indent=2, sort_keys=True) + "\n"
    for target, write in ((path, signals.write_csv), (path.with_suffix(".json"), lambda f: f.write(text))):
        target.parent.mkdir(parents=True, exist_ok=True)
        temporary = target.with_name(f".{target.name}.{os.getpid()}.tmp")
        try:
            with open(temporary, "x", newline="") as f:
                write(f)
            if overwrite:
                os.replace(temporary, target)
            else:
                try:
                    os.link(temporary, target)
                except FileExistsError:
                    raise BaselineAppeared(f"{target} appeared while this save ran (another save of the same "
                                           "baseline?); it was left as it is") from None
        finally:
            temporary.unlink(missing_ok=True)


#: A temporary file of `save`: .NAME.PID.tmp.
TEMPORARY = re.compile(r"\.(?P<name>.+)\.(?P<pid>[0-9]+)\.tmp")


def remove_stale_temporaries(folder: Path) -> list[Path]:
    """Remove the temporary files that a save killed mid-write left in
    `folder` (their process is gone); the removed paths."""
    removed = []
    for path in Path(folder).glob(".*.tmp") if Path(folder).is_dir() else ():
        match = TEMPORARY.fullmatch(path.name)
        if match and not path.is_symlink() and not _alive(int(match["pid"])):
            path.unlink(missing_ok=True)
            removed.append(path)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


class LinkInside(ValueError):
    """A symbolic link inside the baseline folder, which mechval does not
    follow (it could lead outside the folder the user named)."""


def refuse_links(path: Path, root: Path | None = None) -> None:
    """LinkInside if `path`, its .json or a folder between it and the
    baseline root (DIR, three levels up) is a symbolic link."""
    path = Path(path)
    root = Path(root) if root is not None else path.parents[min(3, len(path.parents) - 1)]
    for part in (path, path.with_suffix(".json"), *path.parents):
        if part == root or len(part.parts) <= len(root.parts):
            break
        if part.is_symlink():
            raise LinkInside(f"{part} is a symbolic link: mechval neither follows nor replaces links inside "
                             f"the baseline folder {root}")


def load(path: Path) -> Baseline:
    """Read a baseline (the .csv and the .json beside it); CorruptBaseline
    when either cannot be read or is a symbolic link, lacks what the check
    needs, the two disagree on the number of samples or a cell is empty
    without a stated reason."""
    path = Path(path)
    try:
        refuse_links(path)
    except LinkInside as exc:
        raise CorruptBaseline(path, str(exc)) from None
    meta = _read_meta(path.with_suffix(".json"))
    frame = _read_frame(path)
    if len(frame) != meta["samples"]:
        raise CorruptBaseline(path, f"{len(frame)} samples, but its .json records {meta['samples']} "
                                    "(a truncated or edited file)")
    signals = Signals(frame, meta["engine"], meta["version"], meta["settings"], meta["missing"])
    if "inputs" in meta:
        try:
            RecordedInputs.from_json(meta["inputs"])
        except ValueError as exc:
            raise CorruptBaseline(path.with_suffix(".json"), f"key 'inputs': {exc}") from None
    sensitivity = meta.get("sensitivity", {})
    if not isinstance(sensitivity, dict) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) and v >= 0
            for v in sensitivity.values()):
        raise CorruptBaseline(path.with_suffix(".json"), "key 'sensitivity': expected an object of "
                                                         "non-negative numbers")
    gaps = signals.unexplained_gaps()
    if gaps:    # `save` stores none: a cell lost from a truncated or edited file
        raise CorruptBaseline(path, f"empty or non-finite cells that its .json gives no reason for "
                                    f"({'; '.join(gaps)})")
    return Baseline(path, signals, meta)


def _read_meta(path: Path) -> dict[str, Any]:
    try:
        meta = json.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise CorruptBaseline(path, "missing (a baseline is a .csv and a .json beside it)") from None
    except UnicodeDecodeError as exc:
        raise CorruptBaseline(path, f"not UTF-8 text (byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise CorruptBaseline(path, f"invalid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") from None
    except RecursionError:
        raise CorruptBaseline(path, "invalid JSON: nested too deeply") from None
    except OSError as exc:
        raise CorruptBaseline(path, f"cannot be read ({exc.strerror})") from None
    if not isinstance(meta, dict):
        raise CorruptBaseline(path, f"expected a JSON object, got {type(meta).__name__}")
    for key, kind in REQUIRED_META.items():
        if key not in meta:
            raise CorruptBaseline(path, f"key {key!r} missing")
        value = meta[key]
        if not isinstance(value, kind) or isinstance(value, bool):
            raise CorruptBaseline(path, f"key {key!r}: expected {JSON_TYPE[kind]}, got {json.dumps(value)[:40]}")
    return meta


def _read_frame(path: Path) -> pd.DataFrame:
    try:
        with warnings.catch_warnings():
            # A first row longer than the header: pandas would drop cells
            # (ParserWarning); later long rows raise ParserError.
            warnings.simplefilter("error", pd.errors.ParserWarning)
            # pandas ≥ 3 parses %.17g text exactly (tests/test_baselines.py checks it).
            frame = pd.read_csv(path, index_col=False)
    except FileNotFoundError:
        raise CorruptBaseline(path, "missing") from None
    except pd.errors.EmptyDataError:
        raise CorruptBaseline(path, "empty file") from None
    except pd.errors.ParserWarning:
        raise CorruptBaseline(path, "malformed CSV: the first row has more cells than the header") from None
    except pd.errors.ParserError as exc:
        raise CorruptBaseline(path, f"malformed CSV: {str(exc).strip()}") from None
    except UnicodeDecodeError as exc:
        raise CorruptBaseline(path, f"not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise CorruptBaseline(path, f"cannot be read ({exc.strerror})") from None
    unknown = [str(c) for c in frame.columns if c != "t" and c not in SIGNAL_CLASS]
    if "t" not in frame.columns or unknown:
        reason = f"unknown column(s) {', '.join(map(repr, unknown))}" if unknown else "no column 't'"
        raise CorruptBaseline(path, f"{reason} in the header (canonical signal names expected)")
    if frame.empty:
        raise CorruptBaseline(path, "no samples (a header only)")
    for name in frame.columns:
        if not pd.api.types.is_numeric_dtype(frame[name]) or pd.api.types.is_bool_dtype(frame[name]):
            cells = frame[name]
            bad = cells.notna() & pd.to_numeric(cells, errors="coerce").isna()
            row = int(np.flatnonzero(bad.to_numpy())[0]) if bad.any() else 0
            raise CorruptBaseline(path, f"column {name}, line {row + 2}: {str(cells.iloc[row])[:40]!r} "
                                        "is not a number")
    return frame


def _version_key(version: str) -> tuple:
    try:
        return (1, Version(version))
    except InvalidVersion:      # a hand-made key: after every real release
        return (2, version)


def stored_versions(root: Path, engine: str, scenario: str, setting: str) -> list[str]:
    """Versions of `engine` that have this baseline, oldest first."""
    for name, what in ((engine, "engine"), (scenario, "scenario name"), (setting, "setting")):
        checked_name(name, what)        # also: no glob pattern in the names
    found = [p.parent.parent.name for p in Path(root, engine).glob(f"*/{scenario}/{setting}.csv")
             if SAFE_NAME.fullmatch(p.parent.parent.name)]
    return sorted(found, key=_version_key)



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
