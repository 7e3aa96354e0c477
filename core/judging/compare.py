"""One comparison rule: engine signals against the reference, as data.

`compare` returns one discrepancy record per signal (a pandas DataFrame):
where the largest error happened, how large it is in absolute and relative
terms, the bound it is judged by, their ratio and the verdict. pytest
messages (`mechval.testing`), reports and baselines are all built from
these records.

The rule (reference in the expected position):
- angle and position classes: max |engine − reference| ≤ tol (rad, m);
- every other class: max |engine − reference| ≤ tol · peak, where peak is
  max |reference| of that signal over the run. Signals cross zero, so the
  bound is an absolute one scaled by the signal's own size. A reference
  signal that is identically zero (e.g. α2 at constant crank speed) is
  scaled by the largest peak of its class instead, since a relative error
  of a zero signal means nothing.
A spatial body's attitude quaternion is compared up to sign (q and −q
are one attitude), and a spatial scene's moments and forces are scaled
by each other where one class is zero in theory (`class_scales`).
Values an engine marks as missing (with a reason) are left out of the
error and counted; a signal with no value at all is "missing"; NaN or inf
without a reason fails. A signal the reference itself reports missing
(a reaction left statically indeterminate by redundant constraints) is
"missing" with the reference's reason, whatever the engine reports.

Error growth: besides the largest error, each record gives the largest
error over the first and over the last quarter of the run and the growth
exponent p of the error's running maximum, fitted as ∝ (t − t0)^p
(`error_growth`): a bias gives p ≈ 0, an error that grows with time (a
phase or frequency error, a drift) p ≈ 1 or more. They describe; they do
not judge.

Run health (mechval.judging.health) is judged in the same records, class "health":
a loop-closure gap beyond the position tolerance or a drive error beyond
the angle tolerance makes the positions meaningless; a constraint drift
(gaps over the mechanism's size, prismatic angle errors) is an angle,
held to the angle tolerance; a power residual and the energy balance are
held to the torque tolerance (they mix the torques and the motion); the
energy drift of a conservative scene to the velocity tolerance (its error
comes from the rates: to first order a relative speed error ε changes the
kinetic energy by 2ε); any unexplained non-finite value or assembly-branch
flip fails outright. An energy balance whose work the samples are too
coarse to integrate (its quadrature error above QUADRATURE_SHARE of the
bound) is "missing", with the estimate.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pandas as pd

from mechval.judging.health import NOT_APPLICABLE
from mechval.model.scenario import Tolerance
from mechval.records.signals import SIGNAL_CLASS, Signals

#: Error growth columns (`error_growth`), after the original ones so that
#: those keep their places in every CSV written before.
GROWTH_COLUMNS = ["error_first_quarter", "error_last_quarter", "growth_exponent"]
COLUMNS = ["scenario", "engine", "setting", "signal", "class", "max_error", "t_max", "rms_error",
           "peak", "relative_error", "tolerance", "bound", "ratio", "verdict", "missing", "reason", *GROWTH_COLUMNS]


#: A reference signal whose peak is at most this fraction of its class's
#: largest peak is zero in theory, its values rounding (the general reference
#: solves to 1e-12: a slider's vy on a level guide comes out near 1e-17;
#: a spatial body's origin acceleration, the difference of larger terms,
#: near a fold of Bennett's linkage at 6e-12 of its class's peak): its
#: relative bound is taken from the class's peak, as for an exact zero, so
#: rounding never becomes a bound no engine can meet.
ZERO_IN_THEORY = 1e-10
#: Classes a spatial scene scales by each other (`class_scales`): a moment
#: is a force times a length, so a scene whose moments are all zero in
#: theory (a governor spinning in balance) has them judged against its
#: forces times its size, and the other way round.
CROSS_SCALED = {"torque": ("force", 1.0), "force": ("torque", -1.0)}


def compare(reference: Signals, result: Signals, tolerance: Tolerance, scenario: str = "",
            engine: str | None = None, setting: str = "default") -> pd.DataFrame:
    """Discrepancy records of `result` against `reference` (same samples).

    Every signal's arithmetic is done on all signals at once, as rows of
    one array (the main job compares each engine run as it arrives, in
    the process that also feeds the workers): each row's figures are
    those of the rule applied to it alone, bit for bit."""
    engine = engine or result.source
    t = reference.t
    if len(result.t) != len(t) or not np.allclose(result.t, t, rtol=0, atol=1e-12 * max(1.0, abs(t[-1]))):
        raise ValueError(f"{engine}: sample instants differ from the reference's")
    names = [c for c in reference.frame.columns.tolist() if c != "t"]     # a list: pandas' string index iterates slowly
    ref = np.ascontiguousarray(reference.frame[names].to_numpy(dtype=float).T)      # one row per signal
    class_peak = class_scales(reference, names, dict(zip(names, ref)))
    result = with_aligned_quaternions(reference, result)
    values = np.ascontiguousarray(result.frame.reindex(columns=names).to_numpy(dtype=float).T)
    classes = [SIGNAL_CLASS[name] for name in names]
    peak = np.abs(ref).max(axis=1) if len(t) else np.zeros(len(names))
    zero = np.array([class_peak.get(cls, 0.0) for cls in classes])
    peak = np.where(peak <= ZERO_IN_THEORY * zero, np.where(zero > 0, zero, peak), peak)
    tol = np.array([tolerance[cls] for cls in classes], dtype=float)
    bound = np.where([tolerance.is_relative(cls) for cls in classes], tol * peak, tol)
    bad = ~np.isfinite(values)
    reported = set(result.frame.columns.tolist())
    reasons = [result.missing.get(name, "" if name in reported else f"{engine} does not report {name}")
               for name in names]
    records = {column: np.full(len(names), np.nan) for column in
               ("max_error", "t_max", "rms_error", "relative_error", "ratio", *GROWTH_COLUMNS)}
    records.update(peak=peak, bound=bound, reason=np.array(reasons, dtype=object),
                   verdict=np.full(len(names), "pass", dtype=object))
    clean = ~bad.any(axis=1) & np.array([name not in reference.missing for name in names], dtype=bool)
    if clean.any() and len(t):
        _judge(records, np.flatnonzero(clean), t, np.abs(values[clean] - ref[clean]))
    for k in np.flatnonzero(~clean):
        name, row_bad = names[k], bad[k]
        if name in reference.missing:
            # The reference has no value to compare with (e.g. a reaction
            # that redundant constraints leave statically indeterminate):
            # whatever the engine reports is never judged.
            records["peak"][k] = records["bound"][k] = np.nan
            records["verdict"][k], records["reason"][k] = "missing", f"reference: {reference.missing[name]}"
        elif row_bad.all():
            records["verdict"][k] = "fail" if not reasons[k] else "missing"
            records["reason"][k] = reasons[k] or "no finite value"
        elif not reasons[k]:
            for column in ("max_error", "rms_error", "relative_error", "ratio"):
                records[column][k] = np.inf
            records["t_max"][k] = float(t[row_bad][0])
            records["verdict"][k], records["reason"][k] = "fail", "non-finite values without a stated reason"
        else:                   # the values the engine marks missing, with a reason, are left out
            kept = ~row_bad
            _judge(records, np.array([k]), t[kept], np.abs(values[k, kept] - ref[k, kept])[None])
    frame = pd.DataFrame(dict(scenario=scenario, engine=engine, setting=setting, signal=names, **{"class": classes},
                              tolerance=tol, missing=bad.sum(axis=1), **records), columns=COLUMNS)
    if result.health is not None:
        health = _health_rows(result.health, tolerance, dict(scenario=scenario, engine=engine, setting=setting))
        frame = pd.concat([frame, pd.DataFrame(health, columns=COLUMNS)], ignore_index=True) if health else frame
    return frame


def _judge(records: dict[str, np.ndarray], rows: np.ndarray, t: np.ndarray, error: np.ndarray) -> None:
    """The figures and verdicts of signals `rows` from their |errors| at
    instants t (one row each), into `records`."""
    worst = np.argmax(error, axis=1)
    max_error = error[np.arange(len(rows)), worst]
    peak, bound = records["peak"][rows], records["bound"][rows]
    with np.errstate(divide="ignore", invalid="ignore"):
        records["relative_error"][rows] = np.where(peak != 0, max_error / peak, np.nan)
        ratio = np.where(bound != 0, max_error / bound, np.where(max_error == 0, 0.0, np.inf))
    records["max_error"][rows], records["t_max"][rows], records["ratio"][rows] = max_error, t[worst], ratio
    records["rms_error"][rows] = np.sqrt(np.mean(error**2, axis=1))
    for column, values in error_growths(t, error).items():
        records[column][rows] = values
    records["verdict"][rows] = np.where(ratio <= 1.0, "pass", "fail")


def class_scales(reference: Signals, names: list[str],
                 columns: dict[str, np.ndarray] | None = None) -> dict[str, float]:
    """Per class, its largest peak; for a spatial reference (one that
    states its scene's size, the fact `length_scale` in m) the torque
    class at least the force class's peak times that size, and the force
    class at least the torque class's over it (CROSS_SCALED)."""
    peaks: dict[str, float] = {}
    for name in names:
        if name not in reference.missing:
            cls = SIGNAL_CLASS[name]
            values = reference[name] if columns is None else columns[name]
            peaks[cls] = max(peaks.get(cls, 0.0), float(np.abs(values).max()))
    size = reference.info.facts.get("length_scale")
    if not size:
        return peaks
    return {cls: max(peak, peaks.get(CROSS_SCALED[cls][0], 0.0) * size ** CROSS_SCALED[cls][1])
            if cls in CROSS_SCALED else peak for cls, peak in peaks.items()}


def with_aligned_quaternions(reference: Signals, result: Signals) -> Signals:
    """`result` with each spatial body's attitude quaternion (B.qw … B.qz)
    turned to the reference's sign at every sample: q and −q are one
    attitude, and the qw ≥ 0 convention jumps at half a turn, where an
    engine a rounding past it would otherwise read 2 off."""
    frame = result.frame
    bodies = [name[:-3] for name in reference.frame.columns.tolist() if name.endswith(".qw")]
    flips, reported = {}, set(frame.columns.tolist())
    for body in bodies:
        columns = [f"{body}.q{c}" for c in "wxyz"]
        if not set(columns) <= reported:
            continue
        dot = np.einsum("ni,ni->n", frame[columns].to_numpy(dtype=float), reference.frame[columns].to_numpy())
        sign = np.where(dot < 0, -1.0, 1.0)
        if (sign < 0).any():
            flips.update({c: frame[c].to_numpy(dtype=float) * sign for c in columns})
    return dataclasses.replace(result, frame=frame.assign(**flips)) if flips else result


def error_growth(t: np.ndarray, error: np.ndarray) -> dict[str, float]:
    """How |error| grows over the run: its largest value over the first and
    the last quarter of the time span, and the exponent p of a least-squares
    fit log m(t) = p·log(t − t0) + c (least squares) of its running maximum
    m(t) = max |error| up to t, over the samples after t0 where m > 0 (NaN
    when fewer than three; the running maximum, so an error oscillating with
    the motion is measured by its envelope)."""
    return {column: float(values[0]) for column, values in
            error_growths(t, np.asarray(error, dtype=float)[None]).items()}


def error_growths(t: np.ndarray, error: np.ndarray) -> dict[str, np.ndarray]:
    """`error_growth` of each row of `error` (signals × instants t) at once:
    the element-wise work (the running maxima and their logarithms) on the
    whole array, then each row's fit over its own samples (the same
    operations in the same order as for that row alone)."""
    t = np.asarray(t, dtype=float)
    error = np.abs(np.asarray(error, dtype=float))
    result = {column: np.full(len(error), np.nan) for column in GROWTH_COLUMNS}
    if not len(t):
        return result
    since = t - t[0]
    span = since[-1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # all-NaN quarters: NaN, as stated
        result["error_first_quarter"] = np.nanmax(error[:, since <= span / 4], axis=1)
        result["error_last_quarter"] = np.nanmax(error[:, since >= 3 * span / 4], axis=1)
    envelope = np.fmax.accumulate(error, axis=1)
    fitted = (since > 0) & (envelope > 0) & np.isfinite(envelope)
    with np.errstate(divide="ignore", invalid="ignore"):
        logs, log_envelope = np.log(since), np.log(envelope)
    for k in np.flatnonzero(fitted.sum(axis=1) >= 3):
        x = logs[fitted[k]]
        if np.ptp(x) > 0:
            y = log_envelope[k, fitted[k]]
            dx = x - x.mean()           # the least-squares line's slope, as numpy.polyfit's degree 1 without its lstsq
            result["growth_exponent"][k] = float(dx @ (y - y.mean()) / (dx @ dx))
    return result


#: Health column → (tolerance class whose bound applies, or None for "must be 0").
HEALTH_BOUNDS = {"nonfinite": None, "gap": "position", "drive_error": "angle", "assembly_flip": None,
                 "power_residual": "torque", "constraint_drift": "angle", "energy_drift": "velocity",
                 "energy_balance": "torque"}
#: The energy balance is judged only where the work's quadrature error
#: (mechval.judging.health's energy_quadrature) is at most this share of its bound,
#: so that a verdict speaks of the engine, not of the sample interval.
QUADRATURE_SHARE = 0.1


def _health_rows(health: pd.DataFrame, tolerance: Tolerance, ids: dict) -> list[dict]:
    rows = []
    t = health["t"].to_numpy()
    for name, cls in HEALTH_BOUNDS.items():
        row = dict(ids, signal=f"health.{name}", **{"class": "health"}, peak=np.nan, rms_error=np.nan,
                   relative_error=np.nan, missing=0, reason="")
        bound = tolerance[cls] if cls else 0.0
        row.update(tolerance=bound, bound=bound)
        if name not in health:
            if name not in NOT_APPLICABLE:      # else the measure does not apply: no row
                rows.append(dict(row, max_error=np.nan, t_max=np.nan, ratio=np.nan, verdict="missing",
                                 reason="not available for this mechanism"))
            continue
        values = health[name].to_numpy(dtype=float)
        if not np.isfinite(values).any():
            rows.append(dict(row, max_error=np.nan, t_max=np.nan, ratio=np.nan, verdict="missing",
                             reason="undefined for this run: the engine does not report the signals it needs, "
                                    "or nothing moves (no power or energy to scale it by)"))
            continue
        row.update(error_growth(t, values))
        quadrature = float(np.nanmax(health["energy_quadrature"])) if name == "energy_balance" else 0.0
        if quadrature > QUADRATURE_SHARE * bound:
            rows.append(dict(row, max_error=float(np.nanmax(values)), t_max=np.nan, ratio=np.nan, verdict="missing",
                             reason=f"the samples are too coarse to integrate the applied power: the work's "
                                    f"quadrature error is ~{quadrature:.2g}, over {QUADRATURE_SHARE:g} of the bound "
                                    "(add samples)"))
            continue
        worst = int(np.nanargmax(values))
        value = float(values[worst])
        ratio = value / bound if bound else (0.0 if value == 0 else np.inf)
        rows.append(dict(row, max_error=value, t_max=float(t[worst]), ratio=ratio,
                         rms_error=float(np.sqrt(np.nanmean(values**2))),
                         missing=int((~np.isfinite(values)).sum()),
                         verdict="pass" if ratio <= 1.0 else "fail",
                         reason="" if ratio <= 1.0 or cls else f"{int(np.nansum(values))} sample(s)"))
    return rows


def passed(records: pd.DataFrame) -> bool:
    """True when no record failed (missing values with a reason do not fail)."""
    return not (records["verdict"] == "fail").any()

