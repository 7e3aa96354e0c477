"""One MuJoCo run of a generic planar mechanism: the compiled model, its
forward (rollout) and inverse modes, and the read-out converted to the Fij
convention (see `mechval.engines.mujoco.adapter` for the model layout and the
conversions). The adapter (`adapter`) and the model audit (`audit`)
both build on this module.
"""

from __future__ import annotations

import collections
import threading
import time
from typing import Any, Mapping

import mujoco
import numpy as np
import pandas as pd

from mechval.records import engine_inputs
from mechval.engines.base import Unrepresentable, closing_start, reference_motion
from mechval.model.kinematics import separation_gap, slide_axis
from mechval.model.mechanism import GROUND, BodyTorque, Mechanism, SpringDamper

from mechval.engines.mujoco.model import (Names, Topology, angle_coefficients, clock_name, coordinates, drive_name, force_name,
                           force_sites, inertia_shift, loop_name, mjcf, raw_columns, topology, torque_coefficients,
                           torque_law_controls, torque_law_name)
from mechval.engines.mujoco.rollout import rollout_in_pieces
from mechval.engines.mujoco.snapshot import Snapshot

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
#: Data fields the read-out needs at every sample (a forward run takes time,
#: qpos and qvel from the rollout's states).
RECORDED = ("qacc", "xpos", "xaxis", "cvel", "cacc", "cfrc_int", "cfrc_ext", "subtree_com", "site_xpos",
            "qfrc_passive", "qfrc_constraint")


class WarningsSilenced:
    """While any run is inside, MuJoCo's warning handler discards the text:
    by default MuJoCo prints each warning and appends it to MUJOCO_LOG.TXT
    in the user's working directory. The handler is process-wide, so
    overlapping runs (threads) share one installation, counted under a
    lock; the warnings themselves are counted per run from mjData.warning
    (`Model.warnings`)."""

    def __init__(self) -> None:
        self.lock, self.users, self.previous = threading.Lock(), 0, None

    def __enter__(self) -> None:
        with self.lock:
            if self.users == 0:
                self.previous = mujoco.get_mju_user_warning()
                mujoco.set_mju_user_warning(lambda message: None)
            self.users += 1

    def __exit__(self, *exc: object) -> None:
        with self.lock:
            self.users -= 1
            if self.users == 0:
                mujoco.set_mju_user_warning(self.previous)


warnings_silenced = WarningsSilenced()


def warning_info(counts: collections.Counter) -> dict[str, Any]:
    """Run-info entries: how many warnings MuJoCo raised and, if any, of
    which kinds (e.g. mjWARN_BADQACC: a NaN, Inf or huge acceleration)."""
    info: dict[str, Any] = {"warnings": sum(counts.values())}
    if counts:
        info["warning_kinds"] = ", ".join(f"{kind} ×{n}" for kind, n in counts.items())
    return info


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b over the last axis (3): numpy's formula, so bit for bit
    `np.cross`, without its axis handling, which costs more than the
    arithmetic on a few hundred samples."""
    a0, a1, a2, b0, b1, b2 = a[..., 0], a[..., 1], a[..., 2], b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def origin_motion(m: mujoco.MjModel, S: Mapping[str, np.ndarray], bids: np.ndarray) -> tuple[np.ndarray, ...]:
    """ω, the body origin's velocity, α and its acceleration (samples,
    bodies, 3), world axes, of the bodies `bids` from recorded cvel/cacc.
    Those are spatial vectors at the root's subtree_com: shifted to the
    body origin, the acceleration made classical (+ ω × v), gravity added
    back (cacc carries −g from the world, accelerometer style). All bodies
    at once: numpy's cost here is per call, not per number."""
    gravity = np.zeros(3) if m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY else np.array(m.opt.gravity)
    r = S["xpos"][:, bids] - S["subtree_com"][:, m.body_rootid[bids]]
    w, v_c = S["cvel"][:, bids, :3], S["cvel"][:, bids, 3:]
    dw, a_c = S["cacc"][:, bids, :3], S["cacc"][:, bids, 3:]
    v = v_c + cross(w, r)
    return w, v, dw, a_c + cross(dw, r) + cross(w, v) + gravity


def compile_model(xml: str) -> mujoco.MjModel:
    """The compiled model, with MuJoCo's warnings silenced (the compiler
    runs the model once and warns, e.g. of a near-singular inertia, into
    MUJOCO_LOG.TXT in the working directory otherwise). A model MuJoCo
    refuses is reported as Unrepresentable, not as its traceback."""
    with warnings_silenced:
        try:
            return mujoco.MjModel.from_xml_string(xml)
        except ValueError as exc:
            reason = " ".join(str(exc).split())
            raise Unrepresentable("engines.mujoco", f"MuJoCo cannot compile the model ({reason})") from None


class Model:
    """A compiled MuJoCo model of the mechanism and its index maps."""

    def __init__(self, mech: Mechanism, times: np.ndarray, settings: Mapping[str, Any]):
        self.mech, self.times = mech, np.asarray(times, dtype=float)
        dt = self.dt = settings["timestep"] / settings["refine"]
        interval = float(self.times[1] - self.times[0]) if len(self.times) > 1 else dt
        self.substeps = int(round(interval / dt))
        if abs(self.substeps * dt - interval) > 1e-9 * interval:
            raise ValueError(f"mujoco: the step {dt} does not divide the sample interval {interval}")
        # A torque-driven or free run starts at the first instant: there is
        # no prescribed path to pre-roll along.
        preroll = 0 if mech.forward_dynamics else int(np.ceil(settings["preroll_timeconsts"] * settings["solref_steps"]))
        self.preroll, self.start_motion = self.start(preroll, dt)
        self.topo: Topology = topology(mech, self.start_motion)
        self.names = names = Names.of(mech)
        self.xml = mjcf(mech, self.topo, settings, dt, names)
        self.m = compile_model(self.xml)
        self.d = mujoco.MjData(self.m)
        m = self.m
        self.jid = {tj.joint.name: m.joint(names.joint[tj.joint.name]).id for tj in self.topo.tree}
        self.clocks = [clock_name(k) for k in range(len(mech.drives))]
        self.jid.update({clock: m.joint(clock).id for clock in self.clocks})
        self.bid = {b.name: m.body(names.body[b.name]).id for b in mech.bodies}
        self.sid = {name: m.site(name).id for j in mech.joints for name in names.sites(j)}
        self.sid.update({name: m.site(name).id for k, f in enumerate(mech.forces) if isinstance(f, SpringDamper)
                         for name in force_sites(k)})
        self.loop_eqs = [m.equality(loop_name(k)).id for k in range(len(self.topo.cuts))]
        self.drive_eqs = [m.equality(drive_name(k)).id for k in range(len(mech.drives))]
        self.loop_eq, self.drive_eq = (self.loop_eqs or [None])[0], (self.drive_eqs or [None])[0]
        self.izz_shift = inertia_shift(mech)
        self.drive_joints = [self.topo.of_joint(d.joint) for d in mech.drives]
        self.drive = (self.drive_joints or [None])[0]
        #: Per torque law its actuator (on a fixed tendon whose length is the
        #: joint's θj − θi: `angle_coefficients`).
        self.law_actuators = [m.actuator(torque_law_name(k)).id for k in range(len(mech.torque_drives))]
        #: The data fields the read-out records (MuJoCo gives a model
        #: without actuators no actuator_force array in the data buffer).
        self.recorded = RECORDED + (("actuator_force",) if m.nu else ())
        #: Per force element its MuJoCo tendon.
        #: Per force element (by index) its MuJoCo tendon, and per body
        #: torque its actuator (none for a body that never turns:
        #: `torque_coefficients`).
        self.tendon = {k: m.tendon(force_name(k)).id for k in range(len(mech.forces))
                       if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, force_name(k)) >= 0}
        self.actuator = {k: m.actuator(force_name(k)).id for k in self.tendon if isinstance(mech.forces[k], BodyTorque)}

    def start(self, preroll: int, dt: float) -> tuple[int, dict[str, np.ndarray]]:
        """The longest pre-roll (≤ the requested one) along φ(t) over which
        the reference loop closes, and the reference motion at its start
        (raw columns of one instant). A torque-driven or free run starts
        at the first instant from the forward-dynamics reference's
        consistent state there (its pre-roll is 0)."""
        while preroll > 0:
            t = float(self.times[0]) - preroll * dt + dt * np.arange(preroll + 1)
            # One read of the run's inputs (`mechval.records.engine_inputs`): the
            # first row, or none where the loop does not close throughout.
            start = engine_inputs.read(self.mech, "closing start", t, None, lambda: closing_start(self.mech, t))
            if len(start):
                return preroll, raw_columns(start)
            preroll //= 2
        return 0, raw_columns(self.reference_motion(self.times[:1]))

    # -- state from the reference ------------------------------------------------

    def reference_motion(self, t: np.ndarray) -> pd.DataFrame:
        return reference_motion(self.mech, t)

    def set_reference(self, motion: Mapping[str, np.ndarray], row: int, coords) -> None:
        """Put the reference q, q̇, q̈ of instant `row` into the data."""
        d = self.d
        d.time = float(motion["t"][row])
        for name, (q, qd, qdd) in coords.items():
            jid = self.jid[name]
            d.qpos[self.m.jnt_qposadr[jid]] = q[row]
            d.qvel[self.m.jnt_dofadr[jid]] = qd[row]
            d.qacc[self.m.jnt_dofadr[jid]] = qdd[row]

    # -- modes --------------------------------------------------------------------

    @property
    def nstep(self) -> int:
        """Steps of a forward run: the pre-roll, then every sample interval."""
        return self.preroll + self.substeps * (len(self.times) - 1)

    def initial_state(self) -> np.ndarray:
        """The full physics state at the start of the pre-roll (reference q, q̇
        of every joint and the clock; each torque law's activation, its
        actuator force, at its value then)."""
        m, d = self.m, self.d
        mujoco.mj_resetData(m, d)
        self.set_reference(self.start_motion, 0, coordinates(self.mech, self.topo, self.start_motion))
        self.set_torque_laws(float(self.start_motion["t"][0]))
        state0 = np.empty(mujoco.mj_stateSize(m, FULL))
        mujoco.mj_getState(m, d, state0, FULL)
        return state0

    def set_torque_laws(self, t: float) -> None:
        """Each torque law's activation (its actuator's force) at T(t)."""
        for law, act in zip(self.mech.torque_drives, self.law_actuators):
            self.d.act[self.m.actuator_actadr[act]] = law.value(t)

    def controls(self, nstep: int) -> np.ndarray:
        """(nstep, nu) controls of the rollout: each torque law's slope over
        each step (`torque_law_controls`), 0 for the other actuators (which
        have no control gain)."""
        control = np.zeros((nstep, self.m.nu))
        start = float(self.start_motion["t"][0])
        control[:, self.law_actuators] = torque_law_controls(self.mech, start, self.dt, nstep)
        return control

    def forward(self) -> tuple[pd.DataFrame, dict[str, Any]]:
        m, d = self.m, self.d
        state0, nstep = self.initial_state(), self.nstep
        # Controls only for torque laws (8 B per actuator and step; the
        # other actuators have no control gain).
        control = self.controls(nstep) if self.law_actuators else None
        start = time.perf_counter()
        states = rollout_in_pieces(m, d, state0, control, nstep)
        wall = time.perf_counter() - start
        # Sample k is the state after step preroll + k·substeps; states[i]
        # is the state after step i + 1 (state0 is after none).
        after = self.preroll + self.substeps * np.arange(len(self.times))
        samples = np.empty((len(after), len(state0)))
        samples[after == 0] = state0
        samples[after > 0] = states[after[after > 0] - 1]
        snapshot = Snapshot(d, self.recorded, len(samples))
        loop_force, rows = np.empty((len(samples), 3 * len(self.loop_eqs))), None
        for k, state in enumerate(samples):
            mujoco.mj_setState(m, d, state, FULL)
            mujoco.mj_forward(m, d)
            mujoco.mj_rnePostConstraint(m, d)
            snapshot.take(k)
            rows = self.loop_rows() if rows is None else rows
            loop_force[k] = d.efc_force[rows]
        record = snapshot.fields() | self.state_fields(samples)
        frame, info = self.columns(record, loop_force.reshape(len(samples), -1, 3)[:, :, :2],
                                   self.drive_efforts(record))
        info.update(warning_info(self.warning_counts()))    # rollout and read-out: the rollout resets them
        info.update(steps=nstep, preroll_steps_used=self.preroll, wall_time_s=wall,
                    nan_free=bool(np.all(np.isfinite(states))))
        return frame, info

    def warning_counts(self) -> collections.Counter:
        """MuJoCo's warnings in the data since it was last reset, by kind."""
        return collections.Counter({mujoco.mjtWarning(i).name: w.number
                                    for i, w in enumerate(self.d.warning) if w.number})

    def state_fields(self, states: np.ndarray) -> dict[str, np.ndarray]:
        """time, qpos and qvel from full physics states (concatenated in
        the order of the mjtState bits)."""
        m = self.m
        size = lambda spec: mujoco.mj_stateSize(m, spec)
        qpos = size(mujoco.mjtState.mjSTATE_TIME)
        qvel = qpos + size(mujoco.mjtState.mjSTATE_QPOS)
        return {"time": states[:, 0], "qpos": states[:, qpos:qvel], "qvel": states[:, qvel:qvel + m.nv]}

    def inverse(self) -> tuple[pd.DataFrame, dict[str, Any]]:
        m, d = self.m, self.d
        m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
        motion = raw_columns(self.reference_motion(self.times))
        coords = coordinates(self.mech, self.topo, motion)
        dofs = [m.jnt_dofadr[self.jid[tj.joint.name]] for tj in self.topo.tree]
        cut_sites = [tuple(self.sid[s] for s in self.names.sites(cut)) for cut in self.topo.cuts]
        jac_i, jac_j = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        e_drives = np.eye(m.nv)[:, [m.jnt_dofadr[self.jid[tj.joint.name]] for tj in self.drive_joints]]
        # The body torques' generalized force: its actuator force on each
        # hinge of the body's path (`torque_coefficients`).
        known = np.zeros(m.nv)
        for k, act in self.actuator.items():
            for joint, coef in torque_coefficients(self.topo, self.mech.forces[k].body).items():
                known[m.jnt_dofadr[self.jid[joint]]] += coef * m.actuator_biasprm[act, 0] * m.actuator_gear[act, 0]
        # The torque laws' generalized force at each instant, likewise.
        law_rows = np.zeros((len(self.law_actuators), m.nv))
        for row, law in zip(law_rows, self.mech.torque_drives):
            for joint, coef in angle_coefficients(self.topo, self.mech.joint(law.joint)).items():
                row[m.jnt_dofadr[self.jid[joint]]] += coef
        snapshot = Snapshot(d, self.recorded + ("qpos", "qvel"), len(self.times))
        n, ncut = len(self.times), len(self.topo.cuts)
        cut_force, efforts = np.empty((n, ncut, 2)), np.empty((n, len(self.drive_joints)))
        signs = np.array([tj.sign for tj in self.drive_joints])
        warnings: collections.Counter = collections.Counter()
        start = time.perf_counter()
        for k in range(n):
            warnings += self.warning_counts()           # before mj_resetData clears them
            mujoco.mj_resetData(m, d)
            self.set_reference(motion, k, coords)
            self.set_torque_laws(float(self.times[k]))
            mujoco.mj_inverse(m, d)
            mujoco.mj_fwdActuation(m, d)              # the laws' actuator_force, for the read-out
            # qfrc_inverse = Σ e_drive·τ + Σ (J_j − J_i)ᵀ·λ over the mechanism's
            # coordinates (λ = in-plane force on body_j through each cut pin),
            # plus the body torques' actuator forces (known, taken out).
            columns = [e_drives]
            for site_i, site_j in cut_sites:
                mujoco.mj_jacSite(m, d, jac_i, None, site_i)
                mujoco.mj_jacSite(m, d, jac_j, None, site_j)
                columns.append((jac_j - jac_i)[:2].T)
            applied = known + d.act[m.actuator_actadr[self.law_actuators]] @ law_rows
            solution = np.linalg.lstsq(np.column_stack(columns)[dofs], (d.qfrc_inverse - applied)[dofs], rcond=None)[0]
            efforts[k] = signs * solution[:len(signs)]
            cut_force[k] = solution[len(signs):].reshape(ncut, 2)
            self.apply_loop_forces(cut_force[k])
            mujoco.mj_rnePostConstraint(m, d)
            snapshot.take(k)
        frame, info = self.columns(snapshot.fields() | {"time": self.times}, cut_force, efforts)
        info.update(warning_info(warnings + self.warning_counts()), wall_time_s=time.perf_counter() - start)
        return frame, info

    def apply_loop_forces(self, forces: np.ndarray) -> None:
        """λ on body_j and −λ on body_i at each cut pin (`forces` (cuts, 2)),
        as xfrc_applied (force at the body's centre of mass plus the moment
        of the shift)."""
        d = self.d
        d.xfrc_applied[:] = 0
        for cut, force in zip(self.topo.cuts, forces):
            site_i, site_j = self.names.sites(cut)
            for body, site, sign in ((cut.body_j, site_j, 1.0), (cut.body_i, site_i, -1.0)):
                if body == GROUND:
                    continue
                bid = self.bid[body]
                f = np.array([sign * force[0], sign * force[1], 0.0])
                arm = d.site_xpos[self.sid[site]] - d.xipos[bid]
                d.xfrc_applied[bid, :3] += f
                d.xfrc_applied[bid, 3:] += np.cross(arm, f)

    # -- read-out -----------------------------------------------------------------

    def loop_rows(self) -> np.ndarray:
        """The efc rows of the cut pins' `connect` equalities, 3 per cut in
        the order of `topo.cuts` (x, y, z world force on site1's body,
        body_j), in the data's current state. With contacts off and no
        limits the rows are the same at every state."""
        d = self.d
        equality = d.efc_type[:d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        rows = [np.flatnonzero(equality & (d.efc_id[:d.nefc] == eq)) for eq in self.loop_eqs]
        if any(len(r) != 3 for r in rows):
            raise RuntimeError("mujoco: a connect equality does not have 3 constraint rows")
        return np.concatenate(rows).astype(int) if rows else np.zeros(0, dtype=int)

    def drive_efforts(self, S: Mapping[str, np.ndarray]) -> np.ndarray:
        """(n, drives): each drive equality's force λ on its joint's
        coordinate, effort = sign·λ (T of a hinge, F of a slide). The
        equality q_drive − sign·q_clock = 0 is the only constraint on its
        own clock, so its generalized constraint force there is −sign·λ
        exactly."""
        dofs = [self.m.jnt_dofadr[self.jid[clock]] for clock in self.clocks]
        return -S["qfrc_constraint"][:, dofs]

    def columns(self, S: Mapping[str, np.ndarray], cut_force: np.ndarray,
                efforts: np.ndarray) -> tuple[pd.DataFrame, dict[str, Any]]:
        """Raw columns at every sample (vectorised over samples) from the
        recorded data fields, and summary facts. `cut_force` (n, cuts, 2)
        is Fij of each cut pin, `efforts` (n, drives) each drive's T or F."""
        m, mech = self.m, self.mech
        col: dict[str, np.ndarray] = {"t": self.times}
        bids = np.fromiter(self.bid.values(), dtype=int)
        w, v, dw, a = origin_motion(m, S, bids)
        zero = np.zeros(len(self.times))
        for k, (body, bid) in enumerate(self.bid.items()):
            theta = omega = alpha = zero
            for tj in self.topo.path(body):
                jid = self.jid[tj.joint.name]
                if tj.joint.kind == "revolute":
                    theta = theta + S["qpos"][:, m.jnt_qposadr[jid]]
                    omega = omega + S["qvel"][:, m.jnt_dofadr[jid]]
                    alpha = alpha + S["qacc"][:, m.jnt_dofadr[jid]]
                else:
                    theta = theta + tj.rel0
            col.update({f"{body}.x": S["xpos"][:, bid, 0], f"{body}.y": S["xpos"][:, bid, 1],
                        f"{body}.theta": theta, f"{body}.vx": v[:, k, 0], f"{body}.vy": v[:, k, 1],
                        f"{body}.omega": omega, f"{body}.ax": a[:, k, 0], f"{body}.ay": a[:, k, 1],
                        f"{body}.alpha": alpha})
        # Only x, y forces and the z couple: the out-of-plane reactions of a
        # planar loop closed in 3D are statically indeterminate, so MuJoCo's
        # values there are legitimate but arbitrary and are not reported.
        torques = self.torque_loads()
        driven = {d.joint for d in mech.drives}
        for tj in self.topo.tree:
            bid, jid, name = self.bid[tj.child], self.jid[tj.joint.name], tj.joint.name
            torque, force = S["cfrc_int"][:, bid, :3], S["cfrc_int"][:, bid, 3:]
            if tj.joint.kind == "prismatic":
                # The damper's force acts along the axis through body_j's joint
                # point: it has no moment about that point, so the couple is
                # the whole moment there, and the reaction force is the rest.
                p_j = S["site_xpos"][:, self.sid[self.names.sites(tj.joint)[1]]]
                moment = torque + cross(S["subtree_com"][:, m.body_rootid[bid]] - p_j, force)
                below = self.topo.subtree(tj.child)
                body_torques = sum(torque for body, torque in torques if body in below)
                col[f"{name}.M"] = tj.sign * (moment[:, 2] - self.cut_couple(tj.child, col, S.get("actuator_force"))
                                              - self.inertia_shift_couple(tj.child, col) - body_torques)
                axis = S["xaxis"][:, jid]
                if name in driven or mech.forces:
                    # The drive's force (and any spring's share of qfrc_passive)
                    # is along the axis too: none of the axial part is reaction.
                    force = force - np.sum(force * axis, axis=1)[:, None] * axis
                else:
                    force = force - S["qfrc_passive"][:, m.jnt_dofadr[jid], None] * axis
            col[f"{name}.Fx"], col[f"{name}.Fy"] = tj.sign * force[:, 0], tj.sign * force[:, 1]
        for k, cut in enumerate(self.topo.cuts):
            col[f"{cut.name}.Fx"], col[f"{cut.name}.Fy"] = cut_force[:, k, 0], cut_force[:, k, 1]
        for k, drive in enumerate(mech.drives):
            col[drive.effort_column(mech.joint(drive.joint).kind)] = efforts[:, k]
        for law, act in zip(mech.torque_drives, self.law_actuators):
            col[f"{law.name}.T"] = S["actuator_force"][:, act]        # the torque on the tendon θj − θi
        names = ["t"] + mech.motion_columns() + mech.reaction_columns()
        # One 2-D block: a DataFrame from a dict of columns costs milliseconds.
        block = np.empty((len(self.times), len(names)))
        for k, name in enumerate(names):
            block[:, k] = col[name]
        frame = pd.DataFrame(block, columns=names)
        drive_error = max((float(np.abs(tj.sign * S["qpos"][:, m.jnt_qposadr[self.jid[tj.joint.name]]]
                                        - drive.law.angle(self.times)).max())
                           for tj, drive in zip(self.drive_joints, mech.drives)), default=0.0)
        info = {"closure_gap_max": float(self.gaps(S["site_xpos"], col).max()),
                "drive_error_max": drive_error,
                "time_stamp_error_max": float(np.abs(S["time"] - self.times).max())}
        return frame, info

    def cut_couple(self, child: str, col: Mapping[str, np.ndarray],
                   actuator_force: np.ndarray) -> np.ndarray | float:
        """The couple a cut pin's damper and torque laws physically put on
        the subtree of `child`, when the pin joins that subtree to the rest.

        Their tendons apply the same generalized force through the hinges on
        the tree paths, so the motion is exact, but the couple lands on the
        path's bodies instead of the pin's: the moment MuJoCo transmits
        through a joint above the pin includes it, and it is taken out here.
        """
        below, total = self.topo.subtree(child), 0.0
        omega = lambda b: 0.0 if b == GROUND else col[f"{b}.omega"]
        laws = list(zip(self.mech.torque_drives, self.law_actuators))
        for cut in self.topo.cuts:
            if (cut.body_i in below) == (cut.body_j in below):
                continue
            couple_on_j = -cut.damping * (omega(cut.body_j) - omega(cut.body_i)) if cut.damping else 0.0
            for law, act in laws:
                if law.joint == cut.name:
                    couple_on_j = couple_on_j + actuator_force[:, act]
            total = total + (couple_on_j if cut.body_j in below else -couple_on_j)
        return total

    def torque_loads(self) -> list[tuple[str, float]]:
        """(body, torque) of every body torque: its actuator's constant
        force (or the scene's torque on a body that never turns, which has
        no actuator: `torque_coefficients`)."""
        m, loads = self.m, []
        for k, force in enumerate(self.mech.forces):
            if isinstance(force, BodyTorque):
                act = self.actuator.get(k)
                loads.append((force.body, force.torque if act is None
                              else float(m.actuator_biasprm[act, 0] * m.actuator_gear[act, 0])))
        return loads

    def inertia_shift_couple(self, child: str, col: Mapping[str, np.ndarray]) -> np.ndarray | float:
        """The couple the izz lent inside a turning group (`planar_inertias`)
        needs on the subtree of `child`: Σ Δizz·α over its bodies. A slide
        joint is the only place where such a group is split, so this is
        what the slide's couple carries besides the scene's physics."""
        couple: np.ndarray | float = 0.0
        for body in self.topo.subtree(child) & set(self.izz_shift):
            couple = couple + self.izz_shift[body] * col[f"{body}.alpha"]
        return couple

    def gaps(self, site_xpos: np.ndarray, col: Mapping[str, np.ndarray]) -> np.ndarray:
        """Per sample, the largest distance between the two sides of any
        joint (m), from MuJoCo's own joint sites (`separation_gap`)."""
        worst = np.zeros(len(site_xpos))
        for j in self.mech.joints:
            p_i, p_j = (site_xpos[:, self.sid[s], :2] for s in self.names.sites(j))
            u = slide_axis(col, j) if j.kind == "prismatic" else None
            worst = np.maximum(worst, separation_gap(j, p_j[:, 0] - p_i[:, 0], p_j[:, 1] - p_i[:, 1], u))
        return worst
