"""Where engine baselines live, and reading and writing them safely.

    DIR/<engine>/<version>/<scenario>/<setting>.csv    canonical signals, %.17g
    DIR/<engine>/<version>/<scenario>/<setting>.json   where they came from

Engine, version, scenario name and setting each become one folder or file
name under the root, so each must be a plain name (`checked_name`): a
scenario called "../../x" or "/tmp/x" must not write outside the root, and
nothing inside it is followed through a symbolic link (`refuse_links`). A
save writes each file whole or not at all, and without --force never
replaces a file (two concurrent saves of one baseline never both succeed).
A file that cannot be read as a baseline raises `CorruptBaseline` naming
the file and the reason, so that one bad file is one verdict, not a
traceback. The rule that judges a new run against a stored one is
`mechval.harness.baseline`.
"""

from __future__ import annotations

import json
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pandas as pd
from packaging.version import InvalidVersion, Version

from mechval.records.engine_inputs import Feed, RecordedInputs
from mechval.records.signals import SIGNAL_CLASS, Signals


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
