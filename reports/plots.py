"""Figures of a report as data that the page draws in the browser with
Plotly (zoom, hover values, an engine's traces toggled from the legend).

plotly.js is inlined once per page, deflated (`page_scripts`), with the small script
`templates/report.js` that draws each figure when it scrolls into view. A
figure is JSON inside `<script type="application/json">` (Jinja's `tojson`
escapes `<`, `>` and `&`, so no text can close the script element).

Signals here are display data, not results (every full-precision number
is in the CSV files). To keep the page of all built-ins within a few
megabytes, a scenario's signals are sent as the reference plus each
engine's error against it (the page draws engine = reference + error),
each as 16-bit codes (`linear_codes`, `log_codes`: ~5 significant digits),
one deflated stream per scenario (`encode_stream`); a run with many
samples is thinned to the minimum and maximum of every window of samples
(`display_indices`), so no peak or spike is ever thinned away.
"""

from __future__ import annotations

import base64
import zlib
from functools import lru_cache
from pathlib import Path
from typing import Mapping

import numpy as np
from markupsafe import Markup

from mechval.model.kinematics import point_position, rotate
from mechval.model.mechanism import GROUND, Mechanism, SpringDamper
from mechval.records.signals import SIGNAL_CLASS, Signals

from .spatial_plots import ATTITUDE_ANGLES, spatial_figure, with_attitude_angles

UNITS = {"angle": "rad", "position": "m", "velocity": "m/s", "acceleration": "m/s²", "force": "N", "torque": "N·m"}
#: Units of a body's rates (theta2, omega2, B.alpha: the quantity after the last dot).
ANGULAR_UNITS = {"velocity": "rad/s", "acceleration": "rad/s²"}
#: A spatial body's attitude quaternion's components (no unit).
QUATERNION = ("qw", "qx", "qy", "qz")
#: Windows a long run is thinned to (min and max of each): about as many
#: as a plot is pixels wide, so the thinned trace looks like the full one.
DISPLAY_WINDOWS = 500
#: Runs of up to this many samples are drawn whole: thinning them would
#: keep most samples and add their indices and values to the page.
DISPLAY_WHOLE = 4000
#: Decades below a trace's largest error that are still drawn: float64
#: carries ~16, so anything further down is rounding, not information.
LOG_DECADES = 20.0
#: Signals per overlay or error figure: a scene of many signals (a six-bar
#: has 60) gets several figures, each drawn when it scrolls into view
#: (Plotly took ~3 s to draw 84 subplots at once).
SIGNALS_PER_FIGURE = 18
#: Engine colours in the order runs first appear on the page (the
#: reference is black); Plotly's default colour sequence.
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
           "#bcbd22", "#17becf")
_U16_NAN = 65535        # linear_codes' code for NaN
_I16_NAN = -32768       # log_codes' code for NaN
_I16_TOP = 32766        # log_codes: 1 … 32767 for magnitudes, 0 for zero


def display_indices(n: int, windows: int, *series: np.ndarray) -> np.ndarray | None:
    """The samples to draw of `n`: None (all of them) when n ≤ 2·windows;
    else the first and last sample and, in each of `windows` runs of
    consecutive samples, the minimum and the maximum of every series (and
    its first NaN, so a gap stays a gap). Sorted and unique.

    Display only: a peak survives thinning by construction, even a single
    sample, since it is the maximum of its window.
    """
    if n <= 2 * windows:
        return None
    width = -(-n // windows)                        # ceil: windows of `width` samples
    starts = np.arange(windows) * width
    keep = [np.array([0, n - 1])]
    for values in series:
        block = np.full(windows * width, np.nan)
        block[:n] = values
        block = block.reshape(windows, width)
        nan = np.isnan(block)
        finite = ~nan.all(axis=1)
        keep.append((starts + np.where(nan, np.inf, block).argmin(axis=1))[finite])
        keep.append((starts + np.where(nan, -np.inf, block).argmax(axis=1))[finite])
        keep.append((starts + nan.argmax(axis=1))[nan.any(axis=1)])
    indices = np.unique(np.concatenate(keep))
    return indices[indices < n]


def _thinned(n: int, *series: np.ndarray) -> np.ndarray | None:
    return display_indices(n, DISPLAY_WINDOWS, *series) if n > DISPLAY_WHOLE else None


def linear_codes(values: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Values as 16-bit steps of their range [lo, hi] (resolution
    (hi − lo) / 65534), NaN as 65535: (uint16 codes, lo, hi)."""
    values = np.asarray(values, dtype=float)
    ok = np.isfinite(values)
    lo, hi = (float(values[ok].min()), float(values[ok].max())) if ok.any() else (0.0, 0.0)
    codes = np.full(values.shape, _U16_NAN, dtype=np.uint16)
    codes[ok] = np.rint((values[ok] - lo) / ((hi - lo) or 1.0) * (_U16_NAN - 1)).astype(np.uint16)
    return codes, lo, hi


def log_codes(values: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Signed values as 16-bit steps of log10 |value| over [lo, hi], the
    top LOG_DECADES below the largest magnitude (resolution ~0.14 % of the
    value): sign kept, 0 for zero (or below lo), −32768 for NaN:
    (int16 codes, lo, hi)."""
    values = np.asarray(values, dtype=float)
    magnitude = np.abs(values)
    ok = np.isfinite(values) & (magnitude > 0)
    hi = float(np.log10(magnitude[ok].max())) if ok.any() else 0.0
    lo = hi - LOG_DECADES
    codes = np.zeros(values.shape, dtype=np.int16)
    level = (np.log10(np.where(ok, magnitude, 1.0)) - lo) / LOG_DECADES
    drawn = ok & (level >= 0)
    codes[drawn] = (np.sign(values[drawn]) * (1 + np.rint(level[drawn] * _I16_TOP))).astype(np.int16)
    codes[~np.isfinite(values)] = _I16_NAN
    return codes, lo, hi


def encode_stream(codes: np.ndarray) -> str:
    """16-bit codes (any sign) for the page: differences of neighbours
    (modulo 2¹⁶; smooth signals give small ones), low bytes then high
    bytes, deflated (zlib; the browser's DecompressionStream inflates it),
    base64."""
    words = codes.view(np.uint16) if codes.dtype.itemsize == 2 else codes.astype(np.uint16)
    steps = np.diff(words, prepend=np.uint16(0))         # wraps modulo 2¹⁶, as intended
    return deflated(np.concatenate([steps & 0xFF, steps >> 8]).astype(np.uint8).tobytes())


class _Stream:
    """The codes of one scenario's arrays, one after another: each array
    is described by {"codes": [start, count], …} and the page decodes the
    whole stream once."""

    def __init__(self) -> None:
        self.parts: list[np.ndarray] = []
        self.size = 0

    def add(self, codes: np.ndarray, **about) -> dict:
        self.parts.append(codes.view(np.uint16))
        entry = {"codes": [self.size, len(codes)], **about}
        self.size += len(codes)
        return entry

    def linear(self, values: np.ndarray) -> dict:
        codes, lo, hi = linear_codes(values)
        return self.add(codes, lin=[lo, hi])

    def log(self, values: np.ndarray) -> dict:
        codes, lo, hi = log_codes(values)
        return self.add(codes, log=[lo, hi])

    def samples(self, indices: np.ndarray) -> dict:
        """Sample indices (sorted) as the gaps between them."""
        gaps = np.diff(indices, prepend=0)
        if gaps.max(initial=0) >= 2**16:
            raise ValueError("display windows wider than 65535 samples")
        return self.add(gaps.astype(np.uint16), gaps=True)

    def encoded(self) -> str:
        return encode_stream(np.concatenate(self.parts) if self.parts else np.zeros(0, np.uint16))


def unit(signal: str) -> str:
    quantity = signal.rpartition(".")[2]
    if quantity in ATTITUDE_ANGLES:
        return "rad"
    cls = SIGNAL_CLASS[signal]
    if quantity in QUATERNION:
        return "1"
    angular = quantity.startswith(("omega", "alpha")) or quantity in ("wx", "wy", "wz")
    return ANGULAR_UNITS[cls] if angular and cls in ANGULAR_UNITS else UNITS[cls]


def colours(labels) -> dict[str, str]:
    """A colour per run label, in order of first appearance."""
    return {label: PALETTE[k % len(PALETTE)] for k, label in enumerate(dict.fromkeys(labels))}


def signal_data(reference: Signals, results: Mapping[str, Signals], bounds: Mapping[str, Mapping[str, float]],
                palette: Mapping[str, str]) -> dict:
    """One scenario's signals for the page's overlay and error figures: the
    sample instants as [first, last, count], per signal the reference, per
    run and signal the error against it and the run's bound; arrays as
    entries of one code stream (see module doc), thinned where long. A
    spatial body's attitude angles are drawn too (`with_attitude_angles`:
    display only, with no bound)."""
    # each frame's columns as arrays once (a frame's column look-up costs more than a signal's encoding)
    reference = {name: column.to_numpy() for name, column in with_attitude_angles(reference.frame).items()}
    results = {label: {name: column.to_numpy() for name, column in with_attitude_angles(r.frame).items()}
               for label, r in results.items()}
    stream = _Stream()
    t = reference["t"]
    names = [c for c in reference if c != "t"]
    signals = []
    for name in names:
        keep = _thinned(len(t), reference[name])
        entry = {"values": stream.linear(reference[name] if keep is None else reference[name][keep])}
        if keep is not None:
            entry["samples"] = stream.samples(keep)
        signals.append({"name": name, "unit": unit(name), "reference": entry})
    runs = []
    for label, result in results.items():
        traces = {}
        for name in names:
            if name not in result:
                continue
            error = result[name] - reference[name]
            keep = _thinned(len(t), error, result[name])
            trace = {"error": stream.log(error if keep is None else error[keep])}
            if keep is not None:     # the reference is not kept at these samples: send the values too
                trace["samples"] = stream.samples(keep)
                trace["values"] = stream.linear(result[name][keep])
            bound = bounds.get(label, {}).get(name)
            if bound is not None and np.isfinite(bound):
                trace["bound"] = float(bound)
            traces[name] = trace
        runs.append({"label": label, "colour": palette.get(label, PALETTE[0]), "traces": traces})
    return {"t": [float(t[0]), float(t[-1]), len(t)], "signals": signals, "runs": runs,
            "stream": stream.encoded()}


#: The health measures the energy figure draws, whichever a run has
#: (mechval.judging.health: a conservative scene's drift, else the balance residual).
ENERGY_MEASURES = ("energy_drift", "energy_balance")


def energy_data(reference: Signals, results: Mapping[str, Signals], palette: Mapping[str, str]) -> dict | None:
    """One scenario's energy against time for the page (data-kind "energy"):
    per run, the reference's first, its energy E = kinetic + potential (J)
    and its energy drift or balance residual (relative) from its health,
    as entries of one code stream like `signal_data`; None when no run's
    health has the energy series."""
    runs = {"reference": (reference, "black"), **{label: (result, palette.get(label, PALETTE[0]))
                                                  for label, result in results.items()}}
    stream = _Stream()
    drawn, measure = [], ""
    for label, (result, colour) in runs.items():
        health = result.health
        if health is None or "energy" not in health:
            continue
        name = next(m for m in ENERGY_MEASURES if m in health)
        measure = measure or name
        energy, residual = health["energy"].to_numpy(dtype=float), health[name].to_numpy(dtype=float)
        keep = _thinned(len(energy), energy, residual)
        entry = {"label": label, "colour": colour, "t": [float(health["t"].iloc[0]), float(health["t"].iloc[-1]),
                                                         len(energy)]}
        if keep is not None:
            energy, residual = energy[keep], residual[keep]
            entry["samples"] = stream.samples(keep)
        entry.update(energy=stream.linear(energy), residual=stream.log(residual))
        drawn.append(entry)
    if not drawn:
        return None
    return {"measure": measure, "runs": drawn, "stream": stream.encoded()}


def mechanism_figure(mech: Mechanism, times: np.ndarray, instants: int = 4) -> dict:
    """The linkage to scale at a few instants (a Plotly figure): every body
    as the polygon of its joint points (closed for a ternary or larger
    link), ground pivots as triangles, guides as dashed lines, springs as
    dotted lines."""
    if mech.spatial is not None:
        return spatial_figure(mech, times, instants)
    # Instants of the run's own samples: a torque-driven or free scene's
    # motion on them is the reference's run, already integrated.
    rows = np.unique(np.linspace(0, len(times) - 1, instants).round().astype(int))
    motion = mech.motion(np.asarray(times, dtype=float)).iloc[rows].reset_index(drop=True)
    traces = []
    for joint in mech.joints:
        if joint.body_i == GROUND and joint.kind == "revolute":
            traces.append(dict(x=[joint.point_i[0]], y=[joint.point_i[1]], mode="markers", showlegend=False,
                               marker=dict(symbol="triangle-up", size=14, color="#555"), hoverinfo="skip"))
        if joint.kind == "prismatic" and joint.body_i == GROUND:
            ux, uy = (float(v) for v in rotate(np.array(0.0), joint.axis))
            span = max(abs(v) for j in mech.joints for v in j.point_j + j.point_i) * 3 + 0.1
            px, py = joint.point_i
            traces.append(dict(x=[px - span * ux, px + span * ux], y=[py - span * uy, py + span * uy],
                               mode="lines", line=dict(dash="dash", color="#999", width=1), showlegend=False,
                               hoverinfo="skip"))
    shades = ["#440154", "#31688e", "#35b779", "#b5de2b", "#fde725"]
    t = motion["t"].to_numpy()
    for k in range(len(rows)):
        name = f"t = {t[k]:.3g} s"
        for body in mech.bodies:
            points = [point_position(motion, body.name, j.point_j if j.body_j == body.name else j.point_i)
                      for j in mech.joints if body.name in (j.body_i, j.body_j)]
            if len({(float(p["x"][k]), float(p["y"][k])) for p in points}) >= 3:
                points.append(points[0])
            traces.append(dict(x=[float(p["x"][k]) for p in points], y=[float(p["y"][k]) for p in points],
                               mode="lines+markers", name=name, legendgroup=name,
                               showlegend=body is mech.bodies[0], text=[body.name] * len(points),
                               line=dict(color=shades[k % len(shades)], width=4 if k == 0 else 2),
                               marker=dict(size=6), hovertemplate="%{text}: (%{x:.4g}, %{y:.4g}) m"))
        for spring in (f for f in mech.forces if isinstance(f, SpringDamper)):
            ends = [point_position(motion, spring.body_a, spring.point_a),
                    point_position(motion, spring.body_b, spring.point_b)]
            traces.append(dict(x=[float(p["x"][k]) for p in ends], y=[float(p["y"][k]) for p in ends],
                               mode="lines", legendgroup=name, showlegend=False, text=[spring.name] * 2,
                               line=dict(color=shades[k % len(shades)], width=1, dash="dot"),
                               hovertemplate="%{text}: (%{x:.4g}, %{y:.4g}) m"))
    layout = dict(height=360, margin=dict(l=60, r=20, t=20, b=50), xaxis=dict(title=dict(text="x [m]")),
                  yaxis=dict(title=dict(text="y [m]"), scaleanchor="x", scaleratio=1),
                  legend=dict(font=dict(size=10)))
    return {"data": traces, "layout": layout}


def deflated(data: bytes) -> str:
    """Bytes for the page as text: deflated (zlib), base64. report.js
    inflates them with the browser's DecompressionStream. zlib's default
    level: its highest takes many times as long on the signal streams for
    under a percent less (tests/bench/run_bench.py prints the page's size)."""
    return base64.b64encode(zlib.compress(data)).decode("ascii")


@lru_cache(maxsize=1)
def _plotly_js() -> str:
    from plotly.offline import get_plotlyjs
    return deflated(get_plotlyjs().encode("utf-8"))


def page_scripts() -> Markup:
    """plotly.js and the page's own script, inlined once per page. plotly.js
    comes deflated (4.8 MB of script, 2.0 MB on the page), as inert text
    that report.js inflates and runs when the first figure is drawn:
    compiling it would otherwise hold up the opening of the page."""
    own = (Path(__file__).resolve().parent / "templates" / "report.js").read_text(encoding="utf-8")
    return Markup(f'<script type="text/plain" id="plotly-js">{_plotly_js()}</script>\n<script>{own}</script>')
