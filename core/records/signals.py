"""The canonical signals table shared by the reference and every engine.

`Signals` is time × named columns (docs/conventions.md names, SI units, Fij = force by
body i on body j in world axes, T12 = drive torque on the crank), plus where
it came from (source, version, every setting) and, for every column that has
missing values, the reason they are missing. Missing values are NaN in the
frame and empty cells in CSV; nothing is ever invented to fill them.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pandas as pd

from mechval.adapter import RunInfo
from mechval.records.engine_inputs import RecordedInputs
from mechval.model.kinematics import point_motion, slide_axis, slide_motion
from mechval.model.mechanism import Mechanism
# Re-exported: the harness and reports write signals, baselines and report
# folders through them (mechval.records.outputs).
from mechval.records.outputs import current_umask, write_atomically, write_folder_atomically  # noqa: F401
from mechval.reference.resultants import body_resultants, resultant_columns, resultant_inputs
from mechval.reference.spatial import resultants as spatial_resultants

COMMON_SIGNALS = (
    "t", "theta2", "omega2", "alpha2", "theta3", "omega3", "alpha3",
    "F12x", "F12y", "F32x", "F32y", "F43x", "F43y", "T12",
)
MECHANISM_SIGNALS = {
    "fourbar": ("theta4", "omega4", "alpha4", "F14x", "F14y"),
    "slider_crank": ("x4", "v4", "a4", "F14y"),
    # Inversions with a slide between moving links 3 and 4: s34 is link 3's
    # position along link 4's slide axis, N43 and M43 the slide's normal
    # force (along ẑ × axis) and couple on link 3.
    "slotted_lever": ("theta4", "omega4", "alpha4", "s34", "v34", "a34", "F14x", "F14y", "N43", "M43"),
    "inverted_slider": ("theta4", "omega4", "alpha4", "s34", "v34", "a34", "F14x", "F14y", "N43", "M43"),
}


class SignalClasses(dict):
    """Signal name → tolerance class: the four kinds' names as listed, and
    the names of planar files by their quantity (`PLANAR_CLASS`): BODY.theta,
    JOINT.Fx, DRIVE.T, … (docs/conventions.md)."""

    def _planar(self, name: str) -> str | None:
        head, dot, quantity = name.rpartition(".")
        return PLANAR_CLASS.get(quantity) if dot and head else None

    def __missing__(self, name: str) -> str:
        cls = self._planar(name) if isinstance(name, str) else None
        if cls is None:
            raise KeyError(name)
        return cls

    def __contains__(self, name) -> bool:
        return dict.__contains__(self, name) or (isinstance(name, str) and self._planar(name) is not None)

    def get(self, name, default=None):
        return self[name] if name in self else default


#: Tolerance class of each quantity of a planar file's signals: per body
#: its angle and its centre of mass's motion, per joint its reaction (a
#: prismatic joint adds its normal force N and couple M), per drive its
#: torque T or force F.
PLANAR_CLASS = {"theta": "angle", "omega": "velocity", "alpha": "acceleration",
                "x": "position", "y": "position", "vx": "velocity", "vy": "velocity",
                "ax": "acceleration", "ay": "acceleration",
                "Fx": "force", "Fy": "force", "N": "force", "M": "torque", "T": "torque", "F": "force",
                "Rx": "force", "Ry": "force", "Rm": "torque",
                # spatial scenes (docs/conventions.md, "Spatial signals"): a
                # quaternion component's error is about half the turn's (rad)
                "z": "position", "vz": "velocity", "az": "acceleration",
                **{f"q{c}": "angle" for c in "wxyz"}, **{f"w{c}": "velocity" for c in "xyz"},
                **{f"alpha{c}": "acceleration" for c in "xyz"},
                "Fz": "force", "Mx": "torque", "My": "torque", "Mz": "torque"}

#: Tolerance class of each signal (keys of a scenario's [tolerance] table).
SIGNAL_CLASS = SignalClasses({
    **{f"theta{k}": "angle" for k in (2, 3, 4)},
    **{f"omega{k}": "velocity" for k in (2, 3, 4)},
    **{f"alpha{k}": "acceleration" for k in (2, 3, 4)},
    "x4": "position", "v4": "velocity", "a4": "acceleration",
    **{f"F{ij}{c}": "force" for ij in ("12", "32", "43", "14") for c in "xy"},
    "T12": "torque",
    "s34": "position", "v34": "velocity", "a34": "acceleration", "N43": "force", "M43": "torque",
})


def signal_names(kind: str) -> tuple[str, ...]:
    """Canonical column order for a mechanism kind (docs/conventions.md)."""
    return COMMON_SIGNALS + MECHANISM_SIGNALS[kind]


def mechanism_signal_names(mechanism: Mechanism) -> tuple[str, ...]:
    """Canonical column order for a mechanism: its kind's (without T12 for
    a free crank, which has no drive), or for a planar file the order of
    its signal map (bodies, joints, drives, torque laws)."""
    if mechanism.kind in MECHANISM_SIGNALS:
        return tuple(n for n in signal_names(mechanism.kind) if n == "t" or n in mechanism.signal_map)
    return ("t", *mechanism.signal_map)


@dataclass(frozen=True)
class Signals:
    """Canonical signals at the scenario's samples and their provenance."""

    frame: pd.DataFrame
    source: str
    version: str = ""
    settings: Mapping[str, Any] = field(default_factory=dict)
    missing: Mapping[str, str] = field(default_factory=dict)
    #: Per-sample run health (mechval.judging.health.HEALTH_COLUMNS).
    health: pd.DataFrame | None = None
    #: What the run did (build and wall time, steps, warnings, facts).
    info: RunInfo = field(default_factory=RunInfo)
    #: What an engine run read from the reference (`mechval.records.engine_inputs`):
    #: a baseline stores it, and a regression check feeds it back.
    inputs: RecordedInputs | None = None

    @property
    def t(self) -> np.ndarray:
        return self.frame["t"].to_numpy()

    def __getitem__(self, name: str) -> np.ndarray:
        return self.frame[name].to_numpy()

    def unexplained_gaps(self) -> list[str]:
        """'signal from t = …' for every column with NaN/inf but no stated
        reason (an engine blow-up rather than a declared gap)."""
        gaps = []
        for name in self.frame.columns:
            bad = ~np.isfinite(self.frame[name].to_numpy(dtype=float))
            if bad.any() and name not in self.missing:
                gaps.append(f"{name} from t = {self.t[bad][0]:.6g} s")
        return gaps

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write full float64 precision (%.17g); missing values are empty.

        Written to a temporary file in the same folder and renamed, so an
        interrupted write never leaves a half-written file.
        """
        write_atomically(path, self.write_csv)

    def write_csv(self, file) -> None:
        """The CSV text (%.17g, missing values empty) into an open file."""
        self.frame.to_csv(file, index=False, float_format="%.17g", na_rep="")


def canonical_signals(
    mechanism: Mechanism,
    raw: pd.DataFrame,
    source: str,
    version: str = "",
    settings: Mapping[str, Any] | None = None,
    missing: Mapping[str, str] | None = None,
    health: pd.DataFrame | None = None,
    info: RunInfo | None = None,
) -> Signals:
    """Map raw columns ("crank.theta", "A.Fx", ...) to canonical signals.

    `missing` gives, per raw column, why some of its values are NaN; it is
    carried over to the canonical names. A NaN without a stated reason is
    kept and reported as such, so a blow-up is never mistaken for a gap.
    """
    raw, missing = with_slide_columns(mechanism, raw, dict(missing or {}))
    raw = with_com_columns(mechanism, raw)
    raw, missing = with_resultant_columns(mechanism, raw, missing)
    columns = {"t": raw["t"].to_numpy()}
    reasons = {}
    for name in mechanism_signal_names(mechanism)[1:]:
        raw_name = mechanism.signal_map[name]
        values = raw[raw_name].to_numpy(dtype=float) if raw_name in raw else np.full(len(raw), np.nan)
        columns[name] = values
        if raw_name in missing:
            reasons[name] = missing[raw_name]
        elif raw_name not in raw:
            reasons[name] = f"{source} does not report {raw_name}"
    return Signals(pd.DataFrame(columns), source, version, dict(settings or {}), reasons, health, info or RunInfo())


def with_slide_columns(mechanism: Mechanism, raw: pd.DataFrame,
                       missing: dict[str, str]) -> tuple[pd.DataFrame, dict[str, str]]:
    """Add the slide columns J.s, J.v, J.a of every prismatic joint J the
    signal map asks for (`mechval.model.kinematics.slide_motion`, from the raw
    body motion), and J.N = F·n, the reaction's component along the normal
    n = ẑ × u of the axis u (N; its reason for missing values is Fx's)."""
    wanted = set(mechanism.signal_map.values())
    extra = {}
    for j in mechanism.joints:
        if j.kind != "prismatic" or not {f"{j.name}.s", f"{j.name}.N"} & wanted:
            continue
        extra.update({f"{j.name}.{q}": values for q, values in slide_motion(raw, j).items()})
        if f"{j.name}.Fx" in raw and f"{j.name}.Fy" in raw:
            ux, uy = slide_axis(raw, j)
            nx, ny = -uy, ux
            extra[f"{j.name}.N"] = raw[f"{j.name}.Fx"].to_numpy() * nx + raw[f"{j.name}.Fy"].to_numpy() * ny
            if f"{j.name}.Fx" in missing:
                missing = {**missing, f"{j.name}.N": missing[f"{j.name}.Fx"]}
    return (raw.assign(**extra) if extra else raw), missing


def with_com_columns(mechanism: Mechanism, raw: pd.DataFrame) -> pd.DataFrame:
    """Add the centre-of-mass columns B.G.x, B.G.y, B.G.vx, … of every body
    B the signal map asks for (planar files' B.x, B.y, …), from the raw
    motion of its frame (rigid-body point motion)."""
    wanted = set(mechanism.signal_map.values())
    extra = {}
    for body in mechanism.bodies:
        if f"{body.name}.G.x" in wanted:
            G = point_motion(raw, body.name, body.com)
            extra.update({f"{body.name}.G.{q}": G[q] for q in ("x", "y", "vx", "vy", "ax", "ay")})
    return raw.assign(**extra) if extra else raw


def with_resultant_columns(mechanism: Mechanism, raw: pd.DataFrame,
                           missing: dict[str, str]) -> tuple[pd.DataFrame, dict[str, str]]:
    """Add each body's resultant constraint load B.R.Fx, B.R.Fy, B.R.M
    (`mechval.reference.resultants`) when the signal map asks for them (redundant
    constraints) and the raw frame has not got them already (the
    reference adds them before it blanks the reactions that are not
    unique). A reason for missing inputs carries over."""
    spatial = mechanism.spatial
    wanted = resultant_columns(mechanism) if spatial is None else spatial_resultants.resultant_columns(spatial)
    if not set(wanted) & set(mechanism.signal_map.values()) or set(wanted) <= set(raw.columns):
        return raw, missing
    inputs = resultant_inputs(mechanism) if spatial is None else spatial_resultants.resultant_inputs(spatial)
    if not set(inputs) <= set(raw.columns):
        return raw, missing
    reasons = [missing[c] for c in inputs if c in missing]
    if reasons:
        missing = {**missing, **{c: reasons[0] for c in wanted}}
    found = body_resultants(mechanism, raw) if spatial is None else spatial_resultants.spatial_resultants(spatial, raw)
    return raw.assign(**found), missing
