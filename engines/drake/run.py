"""One Drake run of a generic planar mechanism: the start state, the
simulation, and the read-out at the samples converted to the Fij
convention (the adapter's docstring states every conversion).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import pandas as pd

from pydrake.systems.analysis import Simulator

from mechval.judging.health import drive_errors, mechanism_size
from mechval.model.kinematics import joint_gaps, point_motion, rotate
from mechval.model.mechanism import GROUND, Mechanism, SpringDamper
from mechval.records import engine_inputs

from mechval.engines.base import closing_start, reference_motion
from mechval.engines.drake.model import DrakeModel, build, set_position, set_rate
from mechval.engines.drake.topology import Topology, coordinates, topology


#: Where a sample's read-out is taken, in steps before the sample: Drake
#: takes the step that starts at an instant when it advances past it, so
#: advancing to just before t_n leaves the state x_n (n steps taken) whatever
#: the rounding of n·dt; the sources read there (the drive's desired state)
#: are off by this fraction of one step's change, far below any tolerance.
STEP_MARGIN = 1e-9


#: A drive this far off its path (rad; a slide's error over the mechanism's
#: size) has lost it: its PD lag T/Kp is 1e-8 rad on the built-ins.
BLOWN_DRIVE_ERROR = 0.1


@dataclass(frozen=True)
class Start:
    """Where a run starts: t0 (the first sample minus the pre-roll) and
    the reference motion there (raw columns, one row)."""

    t0: float
    steps: int
    motion: Mapping[str, np.ndarray]


def start_of(mech: Mechanism, times: np.ndarray, steps: int, dt: float) -> Start:
    """The longest pre-roll (≤ `steps`, halved until the reference closes
    the loop over it) along φ(t) before the first sample, and the
    reference state at its start; a torque-driven or free run starts at
    the first sample (its pre-roll is 0)."""
    while steps > 0:
        t = float(times[0]) - steps * dt + dt * np.arange(steps + 1)
        # One read of the run's inputs (`mechval.records.engine_inputs`): the
        # first row, or none where the loop does not close throughout.
        first = engine_inputs.read(mech, "closing start", t, None, lambda: closing_start(mech, t))
        if len(first):
            return Start(float(t[0]), steps, _columns(first))
        steps //= 2
    return Start(float(times[0]), 0, _columns(reference_motion(mech, np.asarray(times[:1], dtype=float))))


def _columns(frame: pd.DataFrame) -> dict[str, np.ndarray]:
    return dict(zip(frame.columns, frame.to_numpy(dtype=float).T))


class Run:
    """A built model, started from the reference state, stepped to every
    sample and read there."""

    def __init__(self, mech: Mechanism, times: np.ndarray, settings: Mapping[str, Any]):
        self.mech, self.times = mech, np.asarray(times, dtype=float)
        self.dt = dt = float(settings["timestep"]) / int(settings["refine"])
        steps = 0 if mech.forward_dynamics else int(settings["preroll_steps"])
        self.start = start_of(mech, self.times, steps, dt)
        self.topo: Topology = topology(mech)
        self.model: DrakeModel = build(mech, self.topo, settings, self.start.t0, float(self.times[-1]),
                                       self.start.motion)
        self.plant = self.model.plant

    def simulate(self) -> tuple[pd.DataFrame, dict[str, Any]]:
        """Step to every sample and read it; the run's facts."""
        m, plant = self.model, self.plant
        simulator = Simulator(m.diagram)
        context = simulator.get_mutable_context()
        # Drake's clock starts at 0 at the run's start t0: a periodic
        # discrete update fires first at time 0, so a pre-roll at negative
        # times would take no step.
        context.SetTime(0.0)
        plant_context = plant.GetMyMutableContextFromRoot(context)
        for name, (q, v, a) in coordinates(self.topo, self.start.motion).items():
            # Drake's v_n is the mean rate over the step that ends at t_n,
            # the rate half a step earlier: the start gets v(t0) − dt/2·v̇(t0)
            # (a start at v(t0) puts a phase error of O(dt) into the whole run).
            set_position(m.joints[name], plant_context, float(q[0]))
            set_rate(m.joints[name], plant_context, float(v[0] - 0.5 * self.dt * a[0]))
        simulator.Initialize()
        rows = []
        clock = time.perf_counter()
        for n in self.sample_steps():
            if n > 0:
                simulator.AdvanceTo((n - STEP_MARGIN) * self.dt)
            rows.append(self.read(plant_context))
        wall = time.perf_counter() - clock
        frame = self.frame(rows)
        blown = self.blown_up(frame)
        if blown is not None:
            frame.iloc[blown:, 1:] = np.nan
        motion = frame[["t"] + self.mech.motion_columns()]
        facts = {"wall_time_s": wall, "steps": int(round((self.times[-1] - self.start.t0) / self.dt)),
                 "preroll_steps_used": self.start.steps,
                 "closure_gap_max": float(joint_gaps(self.mech, motion).max()),
                 "drive_gains": " ".join(f"{kp:.6g} {kd:.6g}" for kp, kd in m.gains) or "none"}
        if blown is not None:
            facts["blown_up_at"] = float(self.times[blown])
        if self.mech.drives:
            facts["drive_error_max"] = float(drive_errors(self.mech, motion).max())
        return frame, facts

    def blown_up(self, frame: pd.DataFrame) -> int | None:
        """The first sample where Drake's model has come apart (a joint
        gap beyond the mechanism's size, a drive off its path by more than
        BLOWN_DRIVE_ERROR, or a value that is not finite), or None. Drake's SAP step does not stop on a blow-up (gravity
        1e49 runs on to forces of 1e305): from that sample on the run's
        values are NaN with no reason, so the comparison fails, as for a
        blow-up in any engine."""
        with np.errstate(all="ignore"):
            values = frame.to_numpy(dtype=float)
            gaps = joint_gaps(self.mech, frame)
            lost = drive_errors(self.mech, frame) if self.mech.drives else np.zeros(len(frame))
        bad = ~np.isfinite(values).all(axis=1) | ~(gaps <= mechanism_size(self.mech)) | ~(lost <= BLOWN_DRIVE_ERROR)
        return int(np.argmax(bad)) if bad.any() else None

    def sample_steps(self) -> np.ndarray:
        """The step count from t0 at every sample (the step divides the
        sample interval)."""
        return np.round((self.times - self.start.t0) / self.dt).astype(int)

    def read(self, context) -> dict[str, Any]:
        """Everything at the current state: body poses and velocities (the
        state x_n), and the accelerations, joint reactions, drive efforts
        and force elements of the step that starts here (the plant's output
        ports are not sampled, `model`)."""
        plant = self.plant
        out: dict[str, Any] = {}
        for b in self.mech.bodies:
            body = self.model.bodies[b.name]
            pose = plant.EvalBodyPoseInWorld(context, body)
            vel = plant.EvalBodySpatialVelocityInWorld(context, body)
            R = pose.rotation().matrix()
            out[b.name] = (pose.translation()[:2].copy(), float(np.arctan2(R[1, 0], R[0, 0])),
                           vel.translational()[:2].copy(), float(vel.rotational()[2]))
        out["A"] = [(a.translational()[:2].copy(), float(a.rotational()[2]))
                    for a in plant.get_body_spatial_accelerations_output_port().Eval(context)]
        out["R"] = plant.get_reaction_forces_output_port().Eval(context)
        out["u"] = plant.get_net_actuation_output_port().Eval(context).copy()
        out["X"] = {name: (j.frame_on_child().CalcPoseInWorld(context).rotation().matrix()[:2, :2].copy())
                    for name, j in self.model.joints.items()}
        return out

    # -- conversion ------------------------------------------------------------

    def frame(self, rows: list[dict[str, Any]]) -> pd.DataFrame:
        mech = self.mech
        cols: dict[str, np.ndarray] = {"t": self.times.copy()}
        for b in mech.bodies:
            idx = self.model.bodies[b.name].index()
            p = np.array([r[b.name][0] for r in rows])
            theta = np.unwrap(np.array([r[b.name][1] for r in rows]))
            # Anchored to the reference's angle at the start.
            theta += 2 * np.pi * np.round((float(self.start.motion[f"{b.name}.theta"][0]) - theta[0]) / (2 * np.pi))
            a = np.array([r["A"][int(idx)][0] for r in rows])
            alpha = np.array([r["A"][int(idx)][1] for r in rows])
            # Drake's v_n is the mean rate over the step that ends at t_n
            # (q_n = q_{n−1} + dt·v_n): half a step late. Its rate at t_n is
            # the mean of the steps that end and start there, v_n + dt/2·a_n
            # with a_n = (v_{n+1} − v_n)/dt of the step from t_n.
            v = np.array([r[b.name][2] for r in rows]) + 0.5 * self.dt * a
            omega = np.array([r[b.name][3] for r in rows]) + 0.5 * self.dt * alpha
            cols.update({f"{b.name}.x": p[:, 0], f"{b.name}.y": p[:, 1], f"{b.name}.theta": theta,
                         f"{b.name}.vx": v[:, 0], f"{b.name}.vy": v[:, 1], f"{b.name}.omega": omega,
                         f"{b.name}.ax": a[:, 0], f"{b.name}.ay": a[:, 1],
                         f"{b.name}.alpha": alpha})
        transmitted: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for tj in self.topo.tree:
            j, joint = tj.joint, self.model.joints[tj.joint.name]
            f = np.array([[*(r["X"][j.name] @ r["R"][int(joint.index())].translational()[:2]),
                           r["R"][int(joint.index())].rotational()[2]] for r in rows])
            fx, fy, tz = f[:, 0] * tj.sign, f[:, 1] * tj.sign, f[:, 2]
            # The whole force the joint transmits (a slide's damper and drive
            # included) balances the bodies (`cut_forces`).
            transmitted[j.name] = (fx, fy)
            if j.kind == "prismatic":
                ux, uy = rotate(self._theta(cols, j.body_i), j.axis)
                along = fx * ux + fy * uy              # the axial part is the damper or the drive, not reaction
                fx, fy = fx - along * ux, fy - along * uy
                cols[f"{j.name}.M"] = tz if tj.sign > 0 else self._shifted_couple(cols, j, -tz, fx, fy)
            cols[f"{j.name}.Fx"], cols[f"{j.name}.Fy"] = fx, fy
        cols.update(cut_forces(mech, self.topo, cols, transmitted))
        for k, drive in enumerate(mech.drives):
            tj = self.topo.of_joint(drive.joint)
            col = drive.effort_column(tj.joint.kind)
            cols[col] = tj.sign * np.array([r["u"][k] for r in rows])
        for law in mech.torque_drives:
            cols[f"{law.name}.T"] = law.value(self.times)
        return pd.DataFrame(cols)

    def _theta(self, cols, body: str) -> np.ndarray:
        return np.zeros(len(self.times)) if body == GROUND else cols[f"{body}.theta"]

    def _shifted_couple(self, cols, j, couple_i, fx, fy):
        """The couple on body_j about P_j when Drake gives the reaction on
        body_i at P_i: −τ_i, plus the moment of the force −Fij·(−1)… taken
        from P_i to P_j."""
        xi, yi = self._point(cols, j.body_i, j.point_i)
        xj, yj = self._point(cols, j.body_j, j.point_j)
        # Fij acts on body_j at P_i (the contact point of the child frame):
        # its moment about P_j is (P_i − P_j) × Fij.
        return couple_i + (xi - xj) * fy - (yi - yj) * fx

    def _point(self, cols, body, p):
        if body == GROUND:
            return np.full(len(self.times), p[0]), np.full(len(self.times), p[1])
        x, y = rotate(cols[f"{body}.theta"], p)
        return cols[f"{body}.x"] + x, cols[f"{body}.y"] + y


def cut_forces(mech: Mechanism, topo: Topology, cols: Mapping[str, np.ndarray],
               transmitted: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> dict[str, np.ndarray]:
    """Fx, Fy of every cut pin, which Drake 1.51 reports no force for (its
    ball constraints have no output): from each moving body's linear
    momentum balance with Drake's own motion and reactions, m·a_G = m·g +
    the force each tree joint transmits to it (`transmitted`: Drake's
    reaction, a slide's axial damper and drive included) + its
    spring-dampers' forces (their law at Drake's state), solved for the
    cut forces by least squares (one body's balance suffices per cut; the
    rest agree to Drake's own consistency)."""
    if not topo.cuts:
        return {}
    n = len(cols["t"])
    index = {b.name: k for k, b in enumerate(mech.bodies)}
    rhs = np.zeros((2 * len(mech.bodies), n))
    coef = np.zeros((2 * len(mech.bodies), 2 * len(topo.cuts)))
    for b in mech.bodies:
        g = point_motion(cols, b.name, b.com)
        k = 2 * index[b.name]
        rhs[k] += b.mass * (g["ax"] - mech.gravity[0])
        rhs[k + 1] += b.mass * (g["ay"] - mech.gravity[1])
    for tj in topo.tree:
        j = tj.joint
        for body, sign in ((j.body_j, 1.0), (j.body_i, -1.0)):
            if body != GROUND:
                rhs[2 * index[body]] -= sign * transmitted[j.name][0]
                rhs[2 * index[body] + 1] -= sign * transmitted[j.name][1]
    for force in mech.forces:
        if isinstance(force, SpringDamper):
            a, b = point_motion(cols, force.body_a, force.point_a), point_motion(cols, force.body_b, force.point_b)
            dx, dy = b["x"] - a["x"], b["y"] - a["y"]
            length = np.hypot(dx, dy)
            ux, uy = dx / length, dy / length
            rate = (b["vx"] - a["vx"]) * ux + (b["vy"] - a["vy"]) * uy
            tension = force.stiffness * (length - force.free_length) + force.damping * rate
            for body, sign in ((force.body_a, 1.0), (force.body_b, -1.0)):     # pulls the points together
                if body != GROUND:
                    rhs[2 * index[body]] -= sign * tension * ux
                    rhs[2 * index[body] + 1] -= sign * tension * uy
    for c, cut in enumerate(topo.cuts):
        for body, sign in ((cut.body_j, 1.0), (cut.body_i, -1.0)):
            if body != GROUND:
                coef[2 * index[body], 2 * c] = coef[2 * index[body] + 1, 2 * c + 1] = sign
    forces = np.linalg.lstsq(coef, rhs, rcond=None)[0]
    out = {}
    for c, cut in enumerate(topo.cuts):
        out[f"{cut.name}.Fx"], out[f"{cut.name}.Fy"] = forces[2 * c], forces[2 * c + 1]
    return out
