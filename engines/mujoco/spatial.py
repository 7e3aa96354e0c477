"""One MuJoCo run of a spatial scene (`run_spatial`): the model of
`spatial_model`, integrated by `mujoco.rollout` from the reference's state
at its start, read out in mechval's spatial conventions.

Start: a prescribed scene pre-rolls along its drives as the planar model
does (the soft constraints' transient dies out before t = 0), from the
reference solved on the pre-roll's grid; a torque-driven or free scene
starts at the first instant from the reference's consistent state there.
The MJCF puts every body at that start pose, so positions are MuJoCo's
reference configuration; velocities are the least-squares solution of
J·q̇ = (v, ω) over every body (MuJoCo's own Jacobians at the frame
origins), whose residual the run's info states.

Read-out at each sample (`mj_forward` + `mj_rnePostConstraint` on the
stored state):
- motion: xpos, xquat (sign w ≥ 0); cvel and cacc shifted from the root's
  subtree centre of mass to the frame origin, the acceleration made
  classical (+ ω × v) and gravity added back (cacc carries −g).
- a tree joint's reaction: `cfrc_int` of its child (by parent on the
  child's subtree), moved to Pj, negated when the child is body_i; its
  joint-space part taken out (drive, torque law, damper, or rounding:
  none is reaction): the moment along each hinge axis, the force along
  each slide axis, a ball's whole moment.
- a cut joint's reaction: its equalities' `efc_force` (a connect's rows are
  the world force on site1's body, body_j; the second connect of a revolute
  cut and the tendon of a universal cut add their force and its moment
  about Pj).
- drive effort: −`qfrc_constraint` on its clock's coordinate (the clock's
  only constraint is its drive equality); torque law: its actuator force.
"""

from __future__ import annotations

import collections
import time
from typing import Any, Mapping

import mujoco
import numpy as np
import pandas as pd

from mechval.adapter import RawRun, RunInfo, Unrepresentable
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.mechanism import spatial_solution
from mechval.reference.spatial.rotation import quaternion_to_matrix
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.mujoco.rollout import rollout_in_pieces
from mechval.engines.mujoco.run import compile_model, cross, origin_motion, warning_info, warnings_silenced
from mechval.engines.mujoco.spatial_model import Names, Pose, Tree, mjcf, spanning_tree

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
MOTION_TOLERANCE = 1e-9     # how closely the pre-roll's solve must meet the run's start (m)


def start_frame(system: SpatialSystem, first: pd.DataFrame, preroll: int, dt: float) -> tuple[int, pd.DataFrame]:
    """The longest pre-roll (≤ the one asked) over which the reference
    solves on the same branch as at the run's first instant (`first`, its
    row there), and the reference's row at the pre-roll's start."""
    times = first["t"].to_numpy()
    positions = [f"{b.name}.{q}" for b in system.bodies for q in ("x", "y", "z", "qw", "qx", "qy", "qz")]
    while preroll > 0:
        t = float(times[0]) - preroll * dt + dt * np.arange(preroll + 1)
        try:
            frame = spatial_solution(system, t).frame
        except MechanismError:
            frame = None
        motion = None if frame is None else frame[system.motion_columns()].to_numpy()
        if motion is not None and np.all(np.isfinite(motion)) and \
                np.abs(frame[positions].to_numpy()[-1] - first[positions].to_numpy()[0]).max() <= MOTION_TOLERANCE:
            return preroll, frame.iloc[:1].reset_index(drop=True)
        preroll //= 2
    return 0, first


def poses_of(system: SpatialSystem, row: pd.DataFrame) -> dict[str, Pose]:
    return {b.name: Pose(row[[f"{b.name}.{c}" for c in "xyz"]].to_numpy()[0],
                         quaternion_to_matrix(row[[f"{b.name}.q{c}" for c in "wxyz"]].to_numpy()[0]))
            for b in system.bodies}


class SpatialModel:
    """The compiled model of a spatial scene and its index maps."""

    def __init__(self, system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]):
        self.system, self.times = system, np.asarray(times, dtype=float)
        dt = self.dt = float(settings["timestep"]) / float(settings["refine"])
        interval = float(self.times[1] - self.times[0]) if len(self.times) > 1 else dt
        self.substeps = int(round(interval / dt))
        if abs(self.substeps * dt - interval) > 1e-9 * interval:
            raise ValueError(f"mujoco: the step {dt} does not divide the sample interval {interval}")
        asked = 0 if system.forward_dynamics else int(np.ceil(settings["preroll_timeconsts"] * settings["solref_steps"]))
        # Two instants: the dynamics reference cannot integrate over one
        # (scipy's solve_ivp refuses an empty span).
        reference = spatial_solution(system, self.times[:2])
        self.preroll, self.start = start_frame(system, reference.frame.iloc[:1].reset_index(drop=True), asked, dt)
        self.t_start = float(self.start["t"].iloc[0])
        self.tree: Tree = spanning_tree(system)
        self.xml = mjcf(system, self.tree, poses_of(system, self.start), settings, dt)
        self.m = m = compile_model(self.xml)
        self.d = mujoco.MjData(m)
        names = self.names = Names(system)
        self.bid = {b.name: m.body(names.body(b.name)).id for b in system.bodies}
        self.site = lambda name: m.site(name).id        # noqa: E731
        self.clock_dofs = [m.jnt_dofadr[m.joint(f"clock{k}").id] for k in range(len(system.drives))]
        self.torque_acts = [m.actuator(f"torque{k}").id for k in range(len(system.torques))]

    # -- start state --------------------------------------------------------------------

    def initial_state(self) -> tuple[np.ndarray, float]:
        """The full physics state at the start, and the residual (m/s, rad/s)
        of the least-squares joint velocities against the reference's."""
        m, d, row = self.m, self.d, self.start
        mujoco.mj_resetData(m, d)
        d.time = self.t_start
        mujoco.mj_forward(m, d)
        rows, target = [], []
        jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        for b in self.system.bodies:
            mujoco.mj_jacBody(m, d, jacp, jacr, self.bid[b.name])
            rows += [jacp.copy(), jacr.copy()]
            target += [row[[f"{b.name}.v{c}" for c in "xyz"]].to_numpy()[0],
                       row[[f"{b.name}.w{c}" for c in "xyz"]].to_numpy()[0]]
        J, v = np.vstack(rows), np.concatenate(target)
        mechanism_dofs = np.setdiff1d(np.arange(m.nv), self.clock_dofs)
        qvel = np.zeros(m.nv)
        if len(mechanism_dofs):
            qvel[mechanism_dofs] = np.linalg.lstsq(J[:, mechanism_dofs], v, rcond=None)[0]
        residual = float(np.abs(J @ qvel - v).max()) if len(v) else 0.0
        for dof, drive in zip(self.clock_dofs, self.system.drives):
            qvel[dof] = float(drive.law.rate(self.t_start))
        d.qvel[:] = qvel
        for act, law in zip(self.torque_acts, self.system.torques):
            d.act[m.actuator_actadr[act]] = float(law.law.value(self.t_start))
        state = np.empty(mujoco.mj_stateSize(m, FULL))
        mujoco.mj_getState(m, d, state, FULL)
        return state, residual

    def controls(self, nstep: int) -> tuple[np.ndarray | None, int | None]:
        """The rollout's controls and their spec: each torque law's
        activation rate over each step (the slope of its law, so the torque
        is the law at every step boundary) and, with body loads, every
        body's applied force and torque (`loads`), which a rollout takes
        only as a control."""
        if not self.torque_acts and not self.system.loads:
            return None, None
        control = np.zeros((nstep, self.m.nu))
        t = self.t_start + self.dt * np.arange(nstep + 1)
        for act, law in zip(self.torque_acts, self.system.torques):
            control[:, act] = np.diff(np.asarray(law.law.value(t), dtype=float) + 0 * t) / self.dt
        if not self.system.loads:
            return control, None
        spec = mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_XFRC_APPLIED
        return np.hstack([control, np.broadcast_to(self.loads().ravel(), (nstep, self.loads().size))]), spec

    def loads(self) -> np.ndarray:
        """(nbody, 6) MuJoCo's xfrc_applied: each body load's force at the
        centre of mass and torque, world axes (the scene's convention)."""
        xfrc = np.zeros((self.m.nbody, 6))
        for load in self.system.loads:
            xfrc[self.bid[load.body]] += np.concatenate([np.asarray(load.force, float), np.asarray(load.torque, float)])
        return xfrc

    # -- run ------------------------------------------------------------------------------

    def forward(self) -> tuple[pd.DataFrame, dict[str, Any]]:
        m, d = self.m, self.d
        state0, residual = self.initial_state()
        nstep = self.preroll + self.substeps * (len(self.times) - 1)
        start = time.perf_counter()
        control, spec = self.controls(nstep)
        states = rollout_in_pieces(m, d, state0, control, nstep, spec) if nstep else np.empty((0, len(state0)))
        d.xfrc_applied[:] = self.loads()       # for the read-out (a state does not hold them)
        wall = time.perf_counter() - start
        after = self.preroll + self.substeps * np.arange(len(self.times))
        samples = np.empty((len(after), len(state0)))
        samples[after == 0] = state0
        samples[after > 0] = states[after[after > 0] - 1]
        warnings = collections.Counter({mujoco.mjtWarning(i).name: w.number for i, w in enumerate(d.warning)
                                        if w.number})
        fields = ("time", "xpos", "xquat", "cvel", "cacc", "cfrc_int", "subtree_com", "site_xpos", "xaxis",
                  "qfrc_constraint", "qpos", "actuator_force")
        record = {name: [] for name in fields}
        cuts: list[dict[str, np.ndarray]] = []
        for state in samples:
            mujoco.mj_setState(m, d, state, FULL)
            mujoco.mj_forward(m, d)
            mujoco.mj_rnePostConstraint(m, d)
            for name in fields:
                value = getattr(d, name)
                record[name].append(np.array(value, dtype=float))
            cuts.append(self.cut_forces())
        S = {name: np.stack(values) for name, values in record.items()}
        frame = self.columns(S, {key: np.stack([c[key] for c in cuts]) for key in (cuts[0] if cuts else {})})
        info = warning_info(warnings)
        info.update(steps=nstep, preroll_steps_used=self.preroll, wall_time_s=wall, step=self.dt,
                    start_velocity_residual=residual, nan_free=bool(np.all(np.isfinite(states))),
                    time_stamp_error_max=float(np.abs(S["time"] - self.times).max()),
                    closure_gap_max=self.closure_gap(S["site_xpos"]), drive_error_max=self.drive_error(S["qpos"]))
        return frame, info

    def equality_rows(self, name: str) -> np.ndarray:
        d = self.d
        eq = self.m.equality(name).id
        mask = (d.efc_type[:d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & (d.efc_id[:d.nefc] == eq)
        return np.flatnonzero(mask)

    def cut_forces(self) -> dict[str, np.ndarray]:
        """Per cut joint its equalities' forces now: the connect's world
        force on body_j ("c"), the second connect's ("c1"), the tendon's λ ("t")."""
        out = {}
        for j in self.tree.cuts:
            jn = self.names.joint(j.name)
            parts = ("c", "c1") if j.kind == "revolute" else ("c", "t") if j.kind == "universal" else ("c",)
            for part in parts:
                out[f"{j.name}/{part}"] = np.array(self.d.efc_force[self.equality_rows(jn + part)])
        return out

    def columns(self, S: Mapping[str, np.ndarray], cut: Mapping[str, np.ndarray]) -> pd.DataFrame:
        m, system = self.m, self.system
        col: dict[str, np.ndarray] = {"t": self.times}
        bids = np.fromiter(self.bid.values(), dtype=int)
        w, v, dw, a = origin_motion(m, S, bids)
        q = S["xquat"][:, bids]
        q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
        for k, body in enumerate(self.bid):
            for name, values in (("x y z", S["xpos"][:, bids[k]]), ("qw qx qy qz", q[:, k]), ("vx vy vz", v[:, k]),
                                 ("wx wy wz", w[:, k]), ("ax ay az", a[:, k]), ("alphax alphay alphaz", dw[:, k])):
                for c, label in enumerate(name.split()):
                    col[f"{body}.{label}"] = values[:, c]
        for tj in self.tree.joints:
            self.tree_reaction(tj, S, col)
        for j in self.tree.cuts:
            jn = self.names.joint(j.name)
            F = cut[f"{j.name}/c"]
            M = np.zeros_like(F)
            p_j = S["site_xpos"][:, self.site(f"{jn}j")]
            if j.kind == "revolute":
                F1 = cut[f"{j.name}/c1"]
                F, M = F + F1, cross(S["site_xpos"][:, self.site(f"{jn}j1")] - p_j, F1)
            elif j.kind == "universal":
                A, B = S["site_xpos"][:, self.site(f"{jn}i1")], S["site_xpos"][:, self.site(f"{jn}j1")]
                u = (B - A) / np.linalg.norm(B - A, axis=1, keepdims=True)
                f = cut[f"{j.name}/t"][:, :1] * u
                F, M = F + f, cross(B - p_j, f)
            self.put_reaction(col, j.name, F, M)
        for k, drive in enumerate(system.drives):
            kind = system.joint(drive.joint).kind
            col[f"{drive.name}.{'T' if kind == 'revolute' else 'F'}"] = -S["qfrc_constraint"][:, self.clock_dofs[k]]
        for act, law in zip(self.torque_acts, system.torques):
            col[f"{law.name}.T"] = S["actuator_force"][:, act]
        names = ["t"] + system.motion_columns() + system.reaction_columns()
        # Body resultants of redundant scenes: the harness computes them
        # from these columns (`mechval.reference.spatial.resultants`).
        return pd.DataFrame(np.column_stack([col[n] for n in names]), columns=names)

    @staticmethod
    def put_reaction(col: dict, name: str, F: np.ndarray, M: np.ndarray) -> None:
        for c, axis in enumerate("xyz"):
            col[f"{name}.F{axis}"], col[f"{name}.M{axis}"] = F[:, c], M[:, c]

    def tree_reaction(self, tj, S: Mapping[str, np.ndarray], col: dict) -> None:
        """Fij of a tree joint from `cfrc_int` of its child (module docstring)."""
        m, bid = self.m, self.bid[tj.child]
        jn = self.names.joint(tj.joint.name)
        torque, force = S["cfrc_int"][:, bid, :3], S["cfrc_int"][:, bid, 3:]
        p_j = S["site_xpos"][:, self.site(f"{jn}j")]
        moment = torque + cross(S["subtree_com"][:, m.body_rootid[bid]] - p_j, force)
        F, M = tj.sign * force, tj.sign * moment
        # The parts along the joint's own coordinates are joint-space
        # forces (drive, torque law, damper, or rounding), not reaction:
        # a hinge's axial moment, a slide's axial force, a ball's moment.
        # A joint's hinge and slide axes are orthogonal to each other or
        # parallel (universal, planar, cylindrical), so one at a time.
        first = m.body_jntadr[bid]
        for jid in range(first, first + m.body_jntnum[bid]):
            axis = S["xaxis"][:, jid]
            if m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_HINGE:
                M = M - np.sum(M * axis, axis=1, keepdims=True) * axis
            elif m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_SLIDE:
                F = F - np.sum(F * axis, axis=1, keepdims=True) * axis
            elif m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_BALL:
                M = np.zeros_like(M)
        self.put_reaction(col, tj.joint.name, F, M)

    def closure_gap(self, site_xpos: np.ndarray) -> float:
        """The largest distance between a cut's two sites over the run (m)."""
        gaps = [np.linalg.norm(site_xpos[:, self.site(f"{jn}j")] - site_xpos[:, self.site(f"{jn}i")], axis=1).max()
                for jn in (self.names.joint(j.name) for j in self.tree.cuts)]
        return float(max(gaps, default=0.0))

    def drive_error(self, qpos: np.ndarray) -> float:
        """The largest |q − sign·(φ(t) − φ(t_start))| of a driven coordinate (rad or m)."""
        worst = 0.0
        for drive in self.system.drives:
            tj = self.tree.of_joint(drive.joint)
            q = qpos[:, self.m.jnt_qposadr[self.m.joint(self.names.joint(drive.joint)).id]]
            want = tj.sign * (drive.law.angle(self.times) - drive.law.angle(self.t_start))
            worst = max(worst, float(np.abs(q - want).max()))
        return worst


def run_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
    """MuJoCo's run of a spatial scene at `times` with the adapter's settings."""
    if settings.get("mode", "forward") != "forward":
        raise Unrepresentable("settings.mode", "a spatial scene runs in MuJoCo's forward mode only")
    start = time.perf_counter()
    try:
        model = SpatialModel(system, times, settings)
    except MechanismError as exc:
        raise Unrepresentable(exc.key, exc.reason) from None
    build = time.perf_counter() - start
    with warnings_silenced:
        frame, info = model.forward()
    info.update(build_time_s=build)
    return RawRun(frame, {}, RunInfo.of(info))
