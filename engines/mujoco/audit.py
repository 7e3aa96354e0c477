"""Audit of the compiled MuJoCo model (see `mechval.records.audit`).

The model is built by the adapter's own `Model` (the MJCF of
`model`, compiled) and put in the state a forward run starts from
(`Model.initial_state`, the reference state at the start of the pre-roll);
`mj_fwdPosition` then gives every position-dependent quantity. Mechanism
bodies, tree joints and the loop and drive equalities are found through the
adapter's own maps (`Model.bid`, `Model.jid`, `Model.loop_eqs`,
`Model.drive_eqs`, `Model.tendon`, `Model.actuator`), never by element name.
Spring-dampers are spatial tendons between two sites (bodies, points,
stiffness, spring length, damping read back); body torques are constant
actuator forces on fixed tendons whose row is the body's angular-velocity
Jacobian; neither is counted again as a joint spring, damper or motor.

Conversion to the Mechanism's conventions: positions are MuJoCo's world
positions in that state (`xipos` for centres of mass, `xanchor` for tree
joints, the connect's sites for the cut pin) expressed in each body's frame
at the reference pose of that instant (`mechval.records.audit.to_body`); inertia is
`ximat·diag(body_inertia)·ximatᵀ` (world axes, about the centre of mass);
a joint's damping is the sum of every damper whose rate is that joint's
relative rate: each dof damper and fixed tendon damper is matched by
comparing its Jacobian row with the joint's relative-rate row from MuJoCo's
own body Jacobians (ω_j − ω_i, or the slide velocity along the axis), so
the cut pin's tendon over a path of hinges is checked, not assumed.
"""

from __future__ import annotations

from typing import Any, Mapping

import mujoco
import numpy as np
import pandas as pd

from mechval.records.audit import (AUDIT_RTOL, ModelReader, Reading, SCENE, axis_readings, bodies_text, body_item, drive_item,
                           force_item, inertia_readings, joint_item, listing, point_readings, to_body, torque_law_item)
from mechval.model.mechanism import GROUND, BodyTorque, Drive, Joint, Mechanism, SpringDamper, TorqueLaw

from mechval.engines.mujoco.run import Model

DSBL, ENBL = mujoco.mjtDisableBit, mujoco.mjtEnableBit
KINDS = {mujoco.mjtJoint.mjJNT_HINGE: "revolute", mujoco.mjtJoint.mjJNT_SLIDE: "prismatic"}
ENGINE = "mujoco"
#: A damper matches a joint when its Jacobian row is a multiple of the
#: joint's relative-rate row to this relative residual (rounding only).
PARALLEL = 1e-12
#: A torque law's parameters (its rows besides "joint").
LAW_PARAMETERS = ("torque", "amplitude", "frequency", "phase")


def audit_model(mech: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the MuJoCo model the adapter builds."""
    model = Model(mech, times, settings)
    model.initial_state()                    # leaves that state in model.d
    mujoco.mj_fwdPosition(model.m, model.d)
    return Reader(model).table()


def nonzero(values: np.ndarray) -> np.ndarray:
    """Indices of the rows (elements of a vector) that hold a non-zero."""
    values = np.asarray(values)
    if values.size == 0:
        return np.zeros(0, dtype=int)
    return np.flatnonzero(np.any(values.reshape(len(values), -1) != 0, axis=1))


class Reader(ModelReader):
    """Readings of one compiled model in its initial state."""

    def __init__(self, model: Model):
        self.model, self.m, self.d, self.mech = model, model.m, model.d, model.mech
        self.start = model.start_motion
        self.body_name = {bid: name for name, bid in model.bid.items()} | {0: GROUND}
        self.clock_jnts = [model.jid[clock] for clock in model.clocks]
        for k, jnt in enumerate(self.clock_jnts):
            self.body_name[int(self.m.jnt_bodyid[jnt])] = "clock" if k == 0 else f"clock {k}"
        #: The force elements' tendons and the body torques' actuators: each
        #: is audited as its force element, not as a spring, damper or motor.
        self.element_tendons = set(model.tendon.values())
        self.torque_actuators = set(model.actuator.values()) | set(model.law_actuators)
        self.off = int(self.m.opt.disableflags)

    def disabled(self, bit) -> bool:
        return bool(self.off & bit)

    def active(self, eq: int) -> bool:
        """Whether an equality acts in a forward run."""
        return bool(self.m.eq_active0[eq]) and not (
            self.disabled(DSBL.mjDSBL_EQUALITY) or self.disabled(DSBL.mjDSBL_CONSTRAINT))

    def readings(self) -> list[Reading]:
        out = [r for body in self.mech.bodies for r in self.body(body.name)]
        out += [r for joint in self.mech.joints for r in self.joint(joint)]
        damping = self.dampers()[0]
        out += [Reading(joint_item(j.name), "damping", damping[j.name][0], damping[j.name][1])
                for j in self.mech.joints]
        out += [r for k, drive in enumerate(self.mech.drives) for r in self.drive(k, drive)]
        out += [r for k, force in enumerate(self.mech.forces) for r in self.force(k, force)]
        out += [r for k, law in enumerate(self.mech.torque_drives) for r in self.torque_law(k, law)]
        out += [self.prescribed_motion(v.joint) for v in self.mech.initial_values]
        return out + self.scene() + self.notes()

    def prescribed_motion(self, joint: str) -> Reading:
        """The joint equalities that tie a joint integrated from its initial
        value to anything (none expected: a drive's equality on it would
        prescribe its motion)."""
        m, jid = self.m, self.model.jid.get(joint)
        found = [f"equality {eq}" for eq in range(m.neq) if m.eq_type[eq] == mujoco.mjtEq.mjEQ_JOINT
                 and jid is not None and jid in (int(m.eq_obj1id[eq]), int(m.eq_obj2id[eq]))]
        return Reading(joint_item(joint), "prescribed motion", listing(found),
                       "joint equalities on the joint's MuJoCo joint")

    # -- bodies -------------------------------------------------------------------

    def body(self, name: str) -> list[Reading]:
        m, d, bid = self.m, self.d, self.model.bid[name]
        com = to_body(self.start, name, d.xipos[bid])
        rotation = d.ximat[bid].reshape(3, 3)
        inertia = rotation @ np.diag(m.body_inertia[bid]) @ rotation.T
        izz, *products = inertia_readings(name, inertia)
        if self.mech.body(name).izz == 0.0 and not self.rotates(bid):
            izz = Reading(body_item(name), "izz", izz.value, "A point mass that only slides never rotates, so "
                          "any izz is exact; MuJoCo refuses 0 and the adapter puts mass·(1 m)².", "note")
        return [Reading(body_item(name), "mass", float(m.body_mass[bid])),
                Reading(body_item(name), "com x", float(com[0])),
                Reading(body_item(name), "com y", float(com[1])), izz, *products]

    def rotates(self, bid: int) -> bool:
        """Whether any joint between the world and the body turns it."""
        m = self.m
        while bid:
            adr, num = m.body_jntadr[bid], m.body_jntnum[bid]
            if any(m.jnt_type[j] != mujoco.mjtJoint.mjJNT_SLIDE for j in range(adr, adr + num)):
                return True
            bid = m.body_parentid[bid]
        return False

    # -- joints -------------------------------------------------------------------

    def joint(self, joint: Joint) -> list[Reading]:
        if joint.name in self.model.jid:
            return self.tree_joint(joint)
        if joint in self.model.topo.cuts:
            return self.cut_joint(joint, self.model.loop_eqs[self.model.topo.cuts.index(joint)])
        return []

    def tree_joint(self, joint: Joint) -> list[Reading]:
        m, d, jid, item = self.m, self.d, self.model.jid[joint.name], joint_item(joint.name)
        child_id = int(m.jnt_bodyid[jid])
        pair = (self.body_name[int(m.body_parentid[child_id])], self.body_name[child_id])
        kind = KINDS.get(int(m.jnt_type[jid]), mujoco.mjtJoint(m.jnt_type[jid]).name)
        note = f"MuJoCo {'hinge' if kind == 'revolute' else 'slide'} joint of the spanning tree"
        readings = [Reading(item, "kind", kind, note), Reading(item, "bodies", bodies_text(joint, pair))]
        anchor = d.xanchor[jid]
        if kind == "prismatic":
            readings += point_readings(self.mech, self.start, joint.name, {b: anchor for b in pair}, d.xaxis[jid],
                                       "The point of the slide's line nearest to the Mechanism's point.")
            readings += axis_readings(self.mech, self.start, joint.name, d.xaxis[jid])
            readings.append(Reading(item, "relative rotation", "locked", "A slide joint only translates."))
        else:
            readings += point_readings(self.mech, self.start, joint.name, {b: anchor for b in pair})
        return readings

    def cut_joint(self, joint: Joint, eq: int) -> list[Reading]:
        m, item = self.m, joint_item(joint.name)
        anchors = dict(self.equality_anchors(eq))
        kind = "revolute" if m.eq_type[eq] == mujoco.mjtEq.mjEQ_CONNECT else mujoco.mjtEq(m.eq_type[eq]).name
        if not self.active(eq):
            kind += " (inactive)"
        note = ("equality connect (a 3-D point constraint, soft: see the loop-closure note); the tree's hinges "
                "hold the rotations about x and y")
        return [Reading(item, "kind", kind, note), Reading(item, "bodies", bodies_text(joint, tuple(anchors))),
                *point_readings(self.mech, self.start, joint.name, anchors)]

    def equality_anchors(self, eq: int) -> list[tuple[str, np.ndarray]]:
        """(body, world anchor) of both sides of a connect equality."""
        m, d = self.m, self.d
        if m.eq_objtype[eq] == mujoco.mjtObj.mjOBJ_SITE:
            return [(self.body_name[int(m.site_bodyid[s])], d.site_xpos[s]) for s in (m.eq_obj1id[eq], m.eq_obj2id[eq])]
        sides = []
        for obj, local in ((m.eq_obj1id[eq], m.eq_data[eq, 0:3]), (m.eq_obj2id[eq], m.eq_data[eq, 3:6])):
            sides.append((self.body_name[int(obj)], d.xpos[obj] + d.xmat[obj].reshape(3, 3) @ local))
        return sides

    # -- dampers --------------------------------------------------------------------

    def rate_row(self, joint: Joint) -> np.ndarray:
        """d(relative rate)/dq̇ of the joint: ω_j − ω_i (revolute), or the
        velocity of body_j's point relative to body_i along the axis."""
        d = self.d
        jac = lambda body, point=None: self.jacobian(body, point)
        if joint.kind == "revolute":
            return jac(joint.body_j)[1][2] - jac(joint.body_i)[1][2]
        jid = self.model.jid[joint.name]
        point, axis = d.xanchor[jid], d.xaxis[jid]
        return axis @ (jac(joint.body_j, point)[0] - jac(joint.body_i, point)[0])

    def jacobian(self, body: str, point=None) -> tuple[np.ndarray, np.ndarray]:
        jacp, jacr = np.zeros((3, self.m.nv)), np.zeros((3, self.m.nv))
        if body != GROUND:
            bid = self.model.bid[body]
            mujoco.mj_jac(self.m, self.d, jacp, jacr, self.d.xipos[bid] if point is None else point, bid)
        return jacp, jacr

    def fixed_tendon_row(self, t: int) -> np.ndarray | None:
        """The Jacobian row of a fixed tendon (its coefficients on the dofs),
        or None if it wraps anything but joints."""
        m = self.m
        row, adr = np.zeros(m.nv), m.tendon_adr[t]
        for w in range(adr, adr + m.tendon_num[t]):
            if m.wrap_type[w] != mujoco.mjtWrap.mjWRAP_JOINT:
                return None
            row[m.jnt_dofadr[m.wrap_objid[w]]] += m.wrap_prm[w]
        return row

    def damper_rows(self) -> list[tuple[str, float, np.ndarray | None]]:
        """(label, coefficient, Jacobian row or None if not linear) of every
        damper in the model."""
        m, found = self.m, []
        for dof in np.flatnonzero(m.dof_damping):
            row = np.zeros(m.nv)
            row[dof] = 1.0
            found.append((f"dof_damping of joint {m.dof_jntid[dof]}", float(m.dof_damping[dof]), row))
        for t in np.flatnonzero(m.tendon_damping):
            if t in self.element_tendons:
                continue                         # a spring-damper's (`force`)
            found.append((f"tendon {t}", float(m.tendon_damping[t]), self.fixed_tendon_row(t)))
        for field in ("dof_dampingpoly", "tendon_dampingpoly", "actuator_damping", "actuator_dampingpoly"):
            found += [(f"{field}[{index}]", float("nan"), None) for index in nonzero(getattr(m, field))]
        return found

    def dampers(self) -> tuple[dict[str, tuple[float, str]], list[str]]:
        """Per joint (damping, note), and the dampers that match no joint."""
        rows = {j.name: self.rate_row(j) for j in self.mech.joints}
        damping = {j.name: 0.0 for j in self.mech.joints}
        sources: dict[str, list[str]] = {j.name: [] for j in self.mech.joints}
        unmatched = []
        for label, coefficient, row in self.damper_rows():
            match = None
            for name, rate in rows.items():
                scale = float(rate @ rate)
                if row is not None and scale > 0:
                    k = float(row @ rate) / scale
                    if np.linalg.norm(row - k * rate) <= PARALLEL * np.linalg.norm(row) and k != 0:
                        match = name, coefficient * k * k
                        break
            if match is None:
                unmatched.append(f"{label} ({coefficient:g})")
                continue
            damping[match[0]] += match[1]
            sources[match[0]].append(label)
        off = self.disabled(DSBL.mjDSBL_DAMPER)
        result = {}
        for name, value in damping.items():
            note = f"from {', '.join(sources[name])}" if sources[name] else "no damper on this joint's rate"
            result[name] = (0.0, "dampers disabled (mjDSBL_DAMPER): " + note) if off else (value, note)
        return result, unmatched

    # -- drive, scene, notes -----------------------------------------------------------

    def drive(self, k: int, spec: Drive) -> list[Reading]:
        """φ(t) of drive k as MuJoCo will impose it: the joint equality
        q_drive = c0 + c1·q_clock, its clock starting at q0, v0 under a
        constant actuator force (its mass times a); θj − θi (or the slide s)
        = sign·q_drive, with sign +1 when the joint's child is its body_j."""
        m, d, eq, clock = self.m, self.d, self.model.drive_eqs[k], self.clock_jnts[k]
        item = drive_item(self.mech, spec)
        note = "From the clock's start state, its constant actuator force / mass, and the joint equality."
        jnt_name = {jid: name for name, jid in self.model.jid.items()}
        drive_jnt, other = int(m.eq_obj1id[eq]), int(m.eq_obj2id[eq])
        joint = jnt_name.get(drive_jnt, f"MuJoCo joint {drive_jnt}")
        text = joint if other == clock else f"{joint} (not tied to its clock)"
        if not self.active(eq):
            text += " (inactive)"
        readings = [Reading(item, "joint", text, "MuJoCo joint equality between the driven joint and its clock")]
        if joint not in self.model.jid or other != clock:
            return readings
        mech_joint = self.mech.joint(joint)
        sign = 1.0 if self.body_name[int(m.jnt_bodyid[drive_jnt])] == mech_joint.body_j else -1.0
        c = m.eq_data[eq, :5]
        q0, v0 = d.qpos[m.jnt_qposadr[clock]], d.qvel[m.jnt_dofadr[clock]]
        a = self.clock_acceleration(clock)
        ts = float(np.asarray(self.start["t"]).reshape(-1)[0])
        readings += [Reading(item, "phi0", float(sign * (c[0] + c[1] * (q0 - v0 * ts + 0.5 * a * ts * ts))), note),
                     Reading(item, "omega0", float(sign * c[1] * (v0 - a * ts)), note),
                     Reading(item, "alpha", float(sign * c[1] * a), note)]
        if np.any(c[2:] != 0):
            readings.append(Reading(item, "higher-order coupling", " ".join(f"{v:g}" for v in c[2:])))
        return readings

    def clock_acceleration(self, clock: int) -> float:
        m = self.m
        force = 0.0
        if not self.disabled(DSBL.mjDSBL_ACTUATION):
            for act in self.clock_actuators(clock):
                force += m.actuator_biasprm[act, 0] * m.actuator_gear[act, 0]
        return float(force / m.body_mass[m.jnt_bodyid[clock]] + self.gravity()[2])

    def clock_actuators(self, clock: int | None = None) -> list[int]:
        """The actuators on one clock's joint, or on any clock's."""
        m, clocks = self.m, self.clock_jnts if clock is None else [clock]
        return [a for a in range(m.nu) if m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                and m.actuator_trnid[a, 0] in clocks]

    # -- force elements ----------------------------------------------------------------

    def force(self, k: int, spec: SpringDamper | BodyTorque) -> list[Reading]:
        return self.spring(k, spec) if isinstance(spec, SpringDamper) else self.torque(k, spec)

    def spring(self, k: int, spec: SpringDamper) -> list[Reading]:
        """A spatial tendon between two sites: its sites' bodies and world
        positions in those bodies' frames, stiffness, spring length (a
        deadband [ℓ0, ℓ0] is the plain spring; another is reported as the
        pair) and damping, as MuJoCo's passive force uses them."""
        m, d, t, item = self.m, self.d, self.model.tendon[k], force_item(spec)
        adr, num = m.tendon_adr[t], m.tendon_num[t]
        kinds = [int(m.wrap_type[w]) for w in range(adr, adr + num)]
        if kinds != [mujoco.mjtWrap.mjWRAP_SITE] * 2:
            return [Reading(item, "bodies", f"tendon {t} is not a straight line between two sites")]
        sites = [int(m.wrap_objid[w]) for w in range(adr, adr + num)]
        bodies = [self.body_name[int(m.site_bodyid[s])] for s in sites]
        readings = [Reading(item, "bodies", "–".join(bodies), "MuJoCo spatial tendon between two sites")]
        for end, body, site in zip("ab", bodies, sites):
            local = to_body(self.start, body, d.site_xpos[site])
            readings += [Reading(item, f"point {end} x", float(local[0])),
                         Reading(item, f"point {end} y", float(local[1]))]
        low, high = (float(v) for v in m.tendon_lengthspring[t])
        off = self.disabled
        stiffness = 0.0 if off(DSBL.mjDSBL_SPRING) else float(m.tendon_stiffness[t])
        damping = 0.0 if off(DSBL.mjDSBL_DAMPER) else float(m.tendon_damping[t])
        spring_note = "tendon_stiffness" + (" (springs disabled: mjDSBL_SPRING)" if off(DSBL.mjDSBL_SPRING) else "")
        readings += [Reading(item, "stiffness", stiffness, spring_note),
                     Reading(item, "free length", low if low == high else f"deadband {low:g}–{high:g}",
                             "tendon_lengthspring"),
                     Reading(item, "damping", damping, "tendon_damping")]
        return readings

    def torque(self, k: int, spec: BodyTorque) -> list[Reading]:
        """A constant actuator force on a fixed tendon whose length is a
        body's angle: the body is the one whose angular-velocity Jacobian
        (MuJoCo's own, z row) is the tendon's row; the torque is the
        actuator's constant bias force times its gear (no control gain, no
        state-dependent bias)."""
        m, item = self.m, force_item(spec)
        if k not in self.model.actuator:
            note = ("The body never turns (no hinge on its tree path): the torque does no work and MuJoCo gets no "
                    "element for it; the read-out adds it to the couples of the joints that carry it.")
            return [Reading(item, "body", spec.body, note, "note"), Reading(item, "torque", spec.torque, note, "note")]
        act, t = self.model.actuator[k], self.model.tendon[k]
        row = self.fixed_tendon_row(t)
        if row is None:
            return [Reading(item, "body", f"tendon {t} is not over joints")]
        if m.actuator_trntype[act] != mujoco.mjtTrn.mjTRN_TENDON or m.actuator_trnid[act, 0] != t:
            return [Reading(item, "body", f"actuator {act} does not act on tendon {t}")]
        body = next((b.name for b in self.mech.bodies if np.array_equal(self.jacobian(b.name)[1][2], row)),
                    "no body's angle")
        constant = not np.any(m.actuator_gainprm[act] != 0) and not np.any(m.actuator_biasprm[act, 1:] != 0)
        off = self.disabled(DSBL.mjDSBL_ACTUATION)
        torque = 0.0 if off else float(m.actuator_biasprm[act, 0] * m.actuator_gear[act, 0])
        note = "actuator bias force × gear on a fixed tendon over the body's path hinges"
        return [Reading(item, "body", body, "the tendon row equals the body's angular-velocity Jacobian"),
                Reading(item, "torque", torque if constant else "state-dependent", note)]

    def torque_law(self, k: int, law: TorqueLaw) -> list[Reading]:
        """An actuator on a fixed tendon whose row is the joint's relative
        rate ω_j − ω_i (MuJoCo's own Jacobians, `rate_row`), its force its
        activation (integrator dynamics, fixed gain, no bias). The law is in
        the rollout's controls, not in the model: its parameters are as
        set, and the torque the run applies at every step boundary, gear ×
        gain × the activation read from the start state plus the controls
        integrated, is checked against T(t) (a deviation reads 'differs')."""
        m, d, item = self.m, self.d, torque_law_item(law)
        act = self.model.law_actuators[k]
        if m.actuator_trntype[act] != mujoco.mjtTrn.mjTRN_TENDON:
            return [Reading(item, "joint", f"actuator {act} does not act on a tendon")]
        t = m.actuator_trnid[act, 0]
        row = self.fixed_tendon_row(t)
        if row is None:
            return [Reading(item, "joint", f"tendon {t} is not over joints")]
        joint = next((j.name for j in self.mech.joints if j.kind == "revolute"
                      and np.array_equal(self.rate_row(j), row)), "no joint's relative angle")
        readings = [Reading(item, "joint", joint, "the tendon row equals the joint's ω_j − ω_i Jacobian row")]
        shape = (m.actuator_dyntype[act] == mujoco.mjtDyn.mjDYN_INTEGRATOR
                 and m.actuator_gaintype[act] == mujoco.mjtGain.mjGAIN_FIXED
                 and m.actuator_biastype[act] == mujoco.mjtBias.mjBIAS_NONE
                 and not self.disabled(DSBL.mjDSBL_ACTUATION))
        nstep = self.model.nstep
        start = float(np.asarray(self.start["t"]).reshape(-1)[0])
        steps = start + self.model.dt * np.arange(nstep + 1)
        activation = d.act[m.actuator_actadr[act]] + np.concatenate(
            [[0.0], np.cumsum(self.model.dt * self.model.controls(nstep)[:, act])])
        applied = m.actuator_gear[act, 0] * m.actuator_gainprm[act, 0] * activation
        deviation = float(np.max(np.abs(applied - law.value(steps))))
        size = max(abs(law.torque), abs(law.amplitude)) or 1.0
        if not shape or not deviation <= AUDIT_RTOL * size:
            why = ("not an integrator-activation actuator with a fixed gain and no bias" if not shape else
                   f"the torque applied at the step boundaries is off T(t) by up to {deviation:.3g} N·m")
            return readings + [Reading(item, quantity, why) for quantity in LAW_PARAMETERS]
        note = (f"the rollout's controls (the law's slope per step); read back: gear × gain × activation is T(t) "
                f"at all {nstep + 1} step boundaries to {deviation:.1g} N·m, linear in between")
        return readings + [Reading(item, quantity, float(getattr(law, quantity)), note, "set")
                           for quantity in LAW_PARAMETERS]

    def gravity(self) -> np.ndarray:
        return np.zeros(3) if self.disabled(DSBL.mjDSBL_GRAVITY) else np.array(self.m.opt.gravity)

    def scene(self) -> list[Reading]:
        other_dampers = self.dampers()[1]
        m, d = self.m, self.d
        g = self.gravity()
        flag = f"opt.gravity {' '.join(f'{v:g}' for v in m.opt.gravity)}, gravity flag " + (
            "disabled" if self.disabled(DSBL.mjDSBL_GRAVITY) else "enabled")
        named = lambda field, what: [f"{what} {i}" for i in nonzero(getattr(m, field))]
        contacts_off = self.disabled(DSBL.mjDSBL_CONTACT) or (m.ngeom == 0 and m.nflex == 0)
        clock_acts = self.clock_actuators()
        motors = [f"actuator {a}" for a in range(m.nu) if a not in clock_acts and a not in self.torque_actuators]
        motors += [f"actuator {a} has a control gain" for a in clock_acts if np.any(m.actuator_gainprm[a] != 0)]
        loads = named("body_gravcomp", "gravity compensation on body") + named("jnt_actgravcomp", "actuator gravcomp on joint")
        loads += [f"{field} at the start" for field in ("qfrc_applied", "xfrc_applied") if np.any(getattr(d, field))]
        loads += [f"clock actuator {a}: force depends on the state" for a in clock_acts
                  if np.any(m.actuator_biasprm[a, 1:] != 0)]
        loads += [f"{m.nplugin} plugins"] if m.nplugin else []
        tree_joints = set(self.model.jid.values())
        constraints = [f"equality {e}" for e in range(m.neq)
                       if e not in self.model.loop_eqs and e not in self.model.drive_eqs]
        constraints += [f"MuJoCo joint {j} ({mujoco.mjtJoint(m.jnt_type[j]).name})" for j in range(m.njnt)
                        if j not in tree_joints]
        constraints += [f"{m.nflex} flexes"] if m.nflex else []
        fluid = [f"{name} {getattr(m.opt, name)}" for name in ("density", "viscosity") if getattr(m.opt, name)]
        fluid += ["wind"] if np.any(m.opt.wind) else []
        return [
            Reading(SCENE, "gravity x", float(g[0]), flag),
            Reading(SCENE, "gravity y", float(g[1]), flag),
            Reading(SCENE, "gravity z", float(g[2]), flag + "; z would act on the clock's slide"),
            Reading(SCENE, "contacts", "off" if contacts_off else "on",
                    f"{m.ngeom} geoms, contact flag {'disabled' if self.disabled(DSBL.mjDSBL_CONTACT) else 'enabled'}"),
            Reading(SCENE, "joint limits", listing(named("jnt_limited", "limited joint")
                                                   + named("tendon_limited", "limited tendon")), "jnt_limited, tendon_limited"),
            Reading(SCENE, "joint friction", listing(named("dof_frictionloss", "frictionloss on dof")
                                                     + named("tendon_frictionloss", "frictionloss on tendon")),
                    "dof_frictionloss, tendon_frictionloss"),
            Reading(SCENE, "joint springs", listing(
                named("jnt_stiffness", "stiffness on joint")
                + [f"stiffness on tendon {t}" for t in nonzero(m.tendon_stiffness) if t not in self.element_tendons]
                + named("jnt_stiffnesspoly", "stiffnesspoly on joint")
                + named("tendon_stiffnesspoly", "stiffnesspoly on tendon")),
                "jnt_stiffness(poly), tendon_stiffness(poly); the spring-dampers' tendons are audited as forces"),
            Reading(SCENE, "added inertia (armature)", listing(
                named("dof_armature", "armature on dof") + named("tendon_armature", "armature on tendon")
                + named("actuator_armature", "armature on actuator")), "dof/tendon/actuator armature"),
            Reading(SCENE, "motors other than the drive", listing(motors),
                    f"{m.nu} actuator(s); the clock's constant force is the drive (see the clock note)"),
            Reading(SCENE, "velocity damping of bodies", "none", "MuJoCo 4.0 has no per-body velocity damping"),
            Reading(SCENE, "fluid forces", listing(fluid), "opt.density, opt.viscosity, opt.wind"),
            Reading(SCENE, "velocity clamps", "none", "MuJoCo 4.0 has no velocity clamp"),
            Reading(SCENE, "sleeping (deactivation)", "on" if m.opt.enableflags & ENBL.mjENBL_SLEEP else "none",
                    "enable flag sleep"),
            Reading(SCENE, "other dampers", listing(other_dampers), "dampers whose rate is no joint's relative rate"),
            Reading(SCENE, "other loads", listing(loads), "gravity compensation, applied forces, plugins"),
            Reading(SCENE, "other constraints", listing(constraints),
                    "equalities other than the loop closure and the drive; joints other than the tree's and the clock's"),
        ]

    def notes(self) -> list[Reading]:
        m = self.m
        item = ENGINE
        solref = lambda eq: " ".join(f"{v:.6g}" for v in m.eq_solref[eq])
        solimp = lambda eq: " ".join(f"{v:g}" for v in m.eq_solimp[eq])
        integrator = mujoco.mjtIntegrator(m.opt.integrator).name
        if self.clock_jnts:
            clock = Reading(item, "clock body", f"{m.body_mass[m.jnt_bodyid[self.clock_jnts[0]]]:g} kg on a slide along z",
                            "Artificial: its coordinate is φ(t) (a constant force gives it α); the drive equality "
                            "ties the crank to it. Out of the plane, so in-plane gravity does not act on it; so "
                            "heavy that the drive's reaction barely moves it.", "note")
        else:
            clock = Reading(item, "clock body", "none", "No prescribed drive: no clock and no drive equality; every "
                                                        "degree of freedom is integrated from the start state.", "note")
        notes = [clock]
        if self.model.loop_eqs:
            notes.append(Reading(item, "loop closure", f"soft: solref {solref(self.model.loop_eq)}, "
                                                       f"solimp {solimp(self.model.loop_eq)}",
                                 "Numerical compliance of the connect equality (time constant, damping ratio).",
                                 "note"))
        if self.model.drive_eqs:
            notes.append(Reading(item, "drive constraint", f"soft: solref {solref(self.model.drive_eq)}, "
                                                           f"solimp {solimp(self.model.drive_eq)}",
                                 "Numerical compliance of the joint equality.", "note"))
        return notes + [Reading(item, "integrator", f"{integrator}, dt {m.opt.timestep:.6g} s, Newton tolerance "
                                                    f"{m.opt.tolerance:g}, {m.opt.iterations} iterations",
                                "Numerical.", "note")]
