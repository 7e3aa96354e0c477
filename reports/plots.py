"""Figures of a report as base64 PNG strings (embedded, so the HTML opens
from disk with no network)."""

from __future__ import annotations

import base64
import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from mechval.mechanism import GROUND, Mechanism, point_motion, rotate  # noqa: E402
from mechval.signals import SIGNAL_CLASS, Signals  # noqa: E402

UNITS = {"angle": "rad", "position": "m", "velocity": "rad/s | m/s", "acceleration": "rad/s² | m/s²",
         "force": "N", "torque": "N·m"}


def to_png(fig) -> str:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=80, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def mechanism_drawing(mech: Mechanism, t_end: float, instants: int = 4) -> str:
    """The linkage to scale at a few instants: every body as the polygon of
    its joint points, ground pivots as triangles, guides as dashed lines."""
    t = np.linspace(0.0, t_end, instants)
    motion = mech.motion(t)
    fig, ax = plt.subplots(figsize=(6, 4))
    colours = plt.cm.viridis(np.linspace(0.0, 0.85, instants))
    for joint in mech.joints:
        if joint.body_i == GROUND and joint.kind == "revolute":
            ax.plot(*joint.point_i, marker="^", markersize=12, color="0.3")
        if joint.kind == "prismatic" and joint.body_i == GROUND:
            ux, uy = rotate(np.array(0.0), joint.axis)
            span = max(abs(v) for j in mech.joints for v in j.point_j + j.point_i) * 3 + 0.1
            px, py = joint.point_i
            ax.plot([px - span * ux, px + span * ux], [py - span * uy, py + span * uy], "--", color="0.6", lw=1)
    for k, colour in enumerate(colours):
        for body in mech.bodies:
            points = [point_motion(motion, body.name, j.point_j if j.body_j == body.name else j.point_i)
                      for j in mech.joints if body.name in (j.body_i, j.body_j)]
            xs = [p["x"][k] for p in points]
            ys = [p["y"][k] for p in points]
            ax.plot(xs, ys, "-o", color=colour, lw=3 if k == 0 else 1.5, markersize=4,
                    label=f"t = {t[k]:.3g} s" if body is mech.bodies[0] else None)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    return to_png(fig)


def _grid(n: int):
    cols = 3
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(12, 2.4 * rows), squeeze=False, sharex=True)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, axes.flat


def signal_overlays(reference: Signals, results: dict[str, Signals]) -> str:
    """Every compared signal: the reference and each engine over time."""
    names = [c for c in reference.frame.columns if c != "t"]
    fig, axes = _grid(len(names))
    for ax, name in zip(axes, names):
        ax.plot(reference.t, reference[name], color="black", lw=2.5, label="reference")
        for label, signals in results.items():
            if name in signals.frame:
                ax.plot(signals.t, signals[name], lw=1, label=label)
        ax.set_title(f"{name} [{UNITS[SIGNAL_CLASS[name]]}]", fontsize=9)
        ax.tick_params(labelsize=7)
    axes[0].legend(fontsize=7)
    return to_png(fig)


def error_plots(reference: Signals, results: dict[str, Signals], bounds: dict[str, dict[str, float]]) -> str:
    """|engine − reference| over time per signal (log scale), with each
    engine's bound as a dashed line of the same colour."""
    names = [c for c in reference.frame.columns if c != "t"]
    fig, axes = _grid(len(names))
    for ax, name in zip(axes, names):
        for k, (label, signals) in enumerate(results.items()):
            if name not in signals.frame:
                continue
            colour = f"C{k}"
            error = np.abs(signals[name] - reference[name])
            if not np.any(error > 0):      # exact agreement has no place on a log axis
                continue
            ax.semilogy(signals.t, np.where(error > 0, error, np.nan), lw=1, color=colour, label=label)
            bound = bounds.get(label, {}).get(name)
            if bound:
                ax.axhline(bound, ls="--", lw=0.8, color=colour)
        ax.set_title(f"|error| {name}", fontsize=9)
        ax.tick_params(labelsize=7)
    legend = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            legend.setdefault(label, handle)
    if legend:      # one legend for the figure: any subplot may lack a line
        fig.legend(legend.values(), legend.keys(), fontsize=8, loc="upper right")
    return to_png(fig)
