"""The drawing of a spatial scene on the report page: a Plotly 3-D figure
(rotate, zoom, pan) of the mechanism at a few instants of the reference's
run. Each body is the polyline of its joint points (closed for three or
more) and its centre of mass, with a short triad of its axes at the centre
of mass; ground joints are grey diamonds, springs dotted lines."""

from __future__ import annotations

import numpy as np
import pandas as pd

from mechval.model.mechanism import GROUND, Mechanism
from mechval.reference.spatial.rotation import quaternion_to_matrix

SHADES = ["#440154", "#31688e", "#35b779", "#b5de2b", "#fde725"]
AXIS_COLOURS = ("#d62728", "#2ca02c", "#1f77b4")


def rotations(motion: pd.DataFrame, body: str) -> np.ndarray:
    """The body's rotation matrices (N, 3, 3) from its quaternion columns."""
    return quaternion_to_matrix(motion[[f"{body}.q{c}" for c in "wxyz"]].to_numpy(dtype=float))


def world_points(motion: pd.DataFrame, body: str, points) -> np.ndarray:
    """Body points (body axes) in world axes at every row: (N, P, 3)."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if body == GROUND:
        return np.broadcast_to(points, (len(motion), *points.shape))
    origin = motion[[f"{body}.{c}" for c in "xyz"]].to_numpy(dtype=float)
    return origin[:, None, :] + np.einsum("nij,pj->npi", rotations(motion, body), points)


def body_points(system, body) -> list:
    points = [j.point_i if j.body_i == body.name else j.point_j
              for j in system.joints if body.name in (j.body_i, j.body_j)]
    return points + [body.com] if len(points) < 3 else points + [points[0]]


def line(xyz: np.ndarray, **style) -> dict:
    return dict(type="scatter3d", x=xyz[:, 0].tolist(), y=xyz[:, 1].tolist(), z=xyz[:, 2].tolist(), **style)


def spatial_figure(mech: Mechanism, times: np.ndarray, instants: int = 4) -> dict:
    system = mech.spatial
    rows = np.unique(np.linspace(0, len(times) - 1, instants).round().astype(int))
    motion = mech.motion(np.asarray(times, dtype=float)).iloc[rows].reset_index(drop=True)
    ground = [j.point_i if j.body_i == GROUND else j.point_j for j in system.joints if GROUND in (j.body_i, j.body_j)]
    traces = []
    if ground:
        traces.append(line(np.asarray(ground, dtype=float), mode="markers", showlegend=False, hoverinfo="skip",
                           marker=dict(symbol="diamond", size=5, color="#555")))
    size = max((np.linalg.norm(np.subtract(p, b.com)) for b in system.bodies for p in body_points(system, b)),
               default=0.0) or 0.1
    t = motion["t"].to_numpy()
    for k in range(len(rows)):
        name = f"t = {t[k]:.3g} s"
        for n, body in enumerate(system.bodies):
            xyz = world_points(motion.iloc[[k]], body.name, body_points(system, body))[0]
            traces.append(line(xyz, mode="lines+markers", name=name, legendgroup=name, showlegend=n == 0,
                               text=[body.name] * len(xyz), marker=dict(size=3),
                               line=dict(color=SHADES[k % len(SHADES)], width=5 if k == 0 else 3),
                               hovertemplate="%{text}: (%{x:.4g}, %{y:.4g}, %{z:.4g}) m"))
            if k == 0:
                centre = world_points(motion.iloc[[k]], body.name, [body.com])[0, 0]
                axes = rotations(motion.iloc[[k]], body.name)[0].T * 0.25 * size
                for axis, colour in zip(axes, AXIS_COLOURS):
                    traces.append(line(np.array([centre, centre + axis]), mode="lines", legendgroup=name,
                                       showlegend=False, hoverinfo="skip", line=dict(color=colour, width=2)))
        for spring in system.springs:
            ends = np.concatenate([world_points(motion.iloc[[k]], spring.body_a, [spring.point_a])[0],
                                   world_points(motion.iloc[[k]], spring.body_b, [spring.point_b])[0]])
            traces.append(line(ends, mode="lines", legendgroup=name, showlegend=False, text=[spring.name] * 2,
                               line=dict(color=SHADES[k % len(SHADES)], width=1, dash="dot"),
                               hovertemplate="%{text}: (%{x:.4g}, %{y:.4g}, %{z:.4g}) m"))
    scene = dict(aspectmode="data", **{f"{c}axis": dict(title=dict(text=f"{c} [m]")) for c in "xyz"})
    layout = dict(height=420, margin=dict(l=0, r=0, t=20, b=0), scene=scene, legend=dict(font=dict(size=10)))
    return {"data": traces, "layout": layout}


#: A spatial body's attitude as the angles a user reads, drawn beside its
#: quaternion on the page: intrinsic z-y-x (yaw, pitch, roll) Tait–Bryan
#: angles from the world axes (rad), each unwrapped along the run. Display
#: only: they wrap and lock at pitch ±π/2, so the comparison judges the
#: quaternion (up to its sign), never these.
ATTITUDE_ANGLES = ("yaw", "pitch", "roll")


def with_attitude_angles(frame: pd.DataFrame) -> pd.DataFrame:
    """`frame` with B.yaw, B.pitch, B.roll after each body's B.qz."""
    bodies = [name[:-3] for name in frame.columns if name.endswith(".qw")]
    if not bodies:
        return frame
    added = {}
    for body in bodies:
        R = quaternion_to_matrix(frame[[f"{body}.q{c}" for c in "wxyz"]].to_numpy(dtype=float))
        yaw = np.unwrap(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
        pitch = np.arcsin(np.clip(-R[:, 2, 0], -1.0, 1.0))
        roll = np.unwrap(np.arctan2(R[:, 2, 1], R[:, 2, 2]))
        added.update({f"{body}.yaw": yaw, f"{body}.pitch": pitch, f"{body}.roll": roll})
    order = []
    for name in frame.columns:
        order.append(name)
        if name.endswith(".qz") and name[:-3] in bodies:
            order += [f"{name[:-3]}.{a}" for a in ATTITUDE_ANGLES]
    return frame.assign(**added)[order]
