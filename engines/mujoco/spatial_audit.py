"""Audit of the compiled MuJoCo model of a spatial scene (`spatial_model`):
what the MjModel holds, read back from its arrays and set against the
`SpatialSystem` with the core audit's verdicts (`mechval.records.audit.audit`;
the expectations from the scene alone, `expected_spatial`).

MuJoCo's body frames are the scene's (each body at its start pose, relative
to its parent: `body_pos`, `body_quat`), so:
- a body: `body_mass`; the centre of mass `body_ipos`; the inertia tensor
  R·diag(`body_inertia`)·Rᵀ with R of `body_iquat` (MuJoCo keeps principal
  moments and axes).
- a tree joint: its MuJoCo joints in the child (a cylindrical joint is a
  slide and a hinge, a universal two hinges, a planar two slides and a
  hinge; a fixed joint none: the child is welded). The child's point is
  `jnt_pos` and its axis `jnt_axis`, the parent's are those carried
  through the child's `body_pos`/`body_quat` (the first of a body's joints
  is fixed in the parent: a universal joint's first hinge is the parent's
  pin, its second the child's). A slide's point on the parent is the
  point of its guide line (a planar joint's plane) nearest the scene's:
  any point of it serves. Damping: `dof_damping` plus the fixed tendons
  on the joint alone (coef²·`tendon_damping`).
- a cut joint: its equalities' sites (`eq_obj1id`/`eq_obj2id`: `site_pos`
  in `site_bodyid`): a ball one `connect`, a revolute a second `connect`
  along the axis, a universal a tendon equality between sites on each
  pin; an axis is the unit vector from a joint's site to its second site.
- a spring: its spatial tendon's sites, `tendon_stiffness`,
  `tendon_lengthspring` and `tendon_damping`.
- the scene: `opt.gravity` (0 with gravity disabled), contacts (the flag,
  `ngeom`) and limits (`jnt_limited`, `tendon_limited`).
Drive clocks, torque-law actuators, free joints and the equalities'
soft-constraint parameters are notes; any joint, equality, tendon or
actuator no scene element accounts for is an "other elements" row. A weld holds no point of its own:
its child's point and frame are the scene's ("as set") and the parent's
are where the weld puts them (read).
"""

from __future__ import annotations

from typing import Any, Mapping

import mujoco
import numpy as np
import pandas as pd

from mechval.adapter import Unrepresentable
from mechval.model.mechanism import GROUND
from mechval.records.audit import SCENE, Reading, audit, body_item, joint_item
from mechval.records.spatial_audit import INERTIA, axis_columns, expected_spatial
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.system import SpatialSystem

from mechval.engines.mujoco.spatial import SpatialModel

HINGE, SLIDE, BALL = mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_BALL
#: A tree joint's kind from its MuJoCo joints' types, in the child's order.
KINDS = {(HINGE,): "revolute", (SLIDE,): "prismatic", (SLIDE, HINGE): "cylindrical", (BALL,): "spherical",
         (HINGE, HINGE): "universal", (SLIDE, SLIDE, HINGE): "planar", (): "fixed"}
#: A cut joint's kind from its equalities' types.
CONNECT, TENDON_EQ = mujoco.mjtEq.mjEQ_CONNECT, mujoco.mjtEq.mjEQ_TENDON
CUT_KINDS = {(CONNECT,): "spherical", (CONNECT, CONNECT): "revolute", (CONNECT, TENDON_EQ): "universal"}
#: The suffixes of a scene joint's MuJoCo joints (`spatial_model.mjcf`).
JOINT_SUFFIXES = ("x", "y", "s", "", "b")


def _id(m, kind, name: str) -> int:
    return mujoco.mj_name2id(m, kind, name)


def _rotation(quat) -> np.ndarray:
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, dtype=float))
    return R.reshape(3, 3)


class Reader:
    """Reads one compiled model (`SpatialModel`) back in the scene's terms."""

    def __init__(self, model: SpatialModel):
        self.model, self.m, self.system = model, model.m, model.system
        self.scene_name = {0: GROUND} | {bid: name for name, bid in model.bid.items()}

    def body_name(self, bid: int) -> str:
        return self.scene_name.get(int(bid), f"MuJoCo body {int(bid)}")

    def bodies(self) -> list[Reading]:
        m, out = self.m, []
        for b in self.system.bodies:
            bid, item = self.model.bid[b.name], body_item(b.name)
            R = _rotation(m.body_iquat[bid])
            I = R @ np.diag(m.body_inertia[bid]) @ R.T
            note = "R·diag(body_inertia)·Rᵀ, R of body_iquat"
            out.append(Reading(item, "mass", float(m.body_mass[bid])))
            out += [Reading(item, f"com {c}", float(m.body_ipos[bid, k])) for k, c in enumerate("xyz")]
            out += [Reading(item, name, float(I[r, c]), note) for name, r, c in INERTIA]
        return out

    def tree_joint(self, tj) -> list[Reading]:
        m, j, item = self.m, tj.joint, joint_item(tj.joint.name)
        jn = self.model.names.joint(j.name)
        ids = [i for i in (_id(m, mujoco.mjtObj.mjOBJ_JOINT, jn + s) for s in JOINT_SUFFIXES) if i >= 0]
        ids.sort()                                  # the child's order: the first is fixed in the parent
        # The body the joints move (a weld has none: the child the tree names)
        holders = sorted({int(m.jnt_bodyid[i]) for i in ids}) or [self.model.bid[tj.child]]
        child = holders[0]
        parent = int(m.body_parentid[child])
        kind = KINDS.get(tuple(int(m.jnt_type[i]) for i in ids), "+".join(str(m.jnt_type[i]) for i in ids))
        if len(holders) > 1:
            kind += f" over {len(holders)} bodies"
        # The child's frame in the parent's (at the start: qpos0)
        R, o = _rotation(m.body_quat[child]), np.array(m.body_pos[child])
        out = [Reading(item, "kind", kind, "a slide and a hinge" if kind == "cylindrical" else
                       "two slides and a hinge" if kind == "planar" else "two hinges" if kind == "universal" else
                       "a weld: the child has no joint" if kind == "fixed" else ""),
               Reading(item, "bodies", self.pair_text(j, self.body_name(parent), self.body_name(child))),
               Reading(item, "damping", self.damping(ids))]
        parent_name = self.body_name(parent)           # as MuJoCo's tree holds it
        sides = (("i", j.body_i, np.asarray(j.point_i, float), np.asarray(j.frame_i, float)),
                 ("j", j.body_j, np.asarray(j.point_j, float), np.asarray(j.frame_j, float)))
        for side, body, point, frame in sides:
            parent_side = body == parent_name
            if kind == "fixed":
                # The weld's child point and frame are the scene's; the parent's are where it puts them.
                other = next(s for s in sides if s[1] != parent_name)
                p, F = other[2], other[3]
                value, axes, source = ((o + R @ p, R @ F, "read") if parent_side else (p, F, "set"))
                note = "where the weld puts the child's point" if parent_side else \
                    "a weld holds no point: the child's is the scene's"
                out += [Reading(item, f"point {side} {c}", float(value[k]), note, source) for k, c in enumerate("xyz")]
                for col in axis_columns(kind):
                    out += [Reading(item, f"axis {side} {'xyz'[col]}{c}", float(axes[k, col]), note, source)
                            for k, c in enumerate("xyz")]
                continue
            local = np.array(m.jnt_pos[ids[0]])
            value, note = (o + R @ local, "jnt_pos through body_pos/body_quat") if parent_side else (local, "jnt_pos")
            if kind in ("prismatic", "cylindrical", "planar") and parent_side:
                slides = [R @ m.jnt_axis[i] for i in ids if m.jnt_type[i] == SLIDE]
                value = nearest_in_span(point, value, slides)
                note = "the point of the guide line (plane) nearest the scene's: any point of it serves"
            out += [Reading(item, f"point {side} {c}", float(value[k]), note) for k, c in enumerate("xyz")]
            for col in axis_columns(kind):
                axis = self.tree_axis(kind, ids, parent_side, R)
                out += [Reading(item, f"axis {side} {'xyz'[col]}{c}", float(axis[k])) for k, c in enumerate("xyz")]
        return out

    def tree_axis(self, kind: str, ids: list[int], parent_side: bool, R: np.ndarray) -> np.ndarray:
        """A joint's axis on one side: a universal joint's first hinge is
        the parent's pin, its second the child's; the others' hinge (or
        slide) is the axis on both sides, carried into the parent's axes."""
        m = self.m
        if kind == "universal":
            return R @ m.jnt_axis[ids[0]] if parent_side else np.array(m.jnt_axis[ids[1]])
        axis = np.array(m.jnt_axis[ids[-1]])
        return R @ axis if parent_side else axis

    @staticmethod
    def pair_text(j, parent: str, child: str) -> str:
        """The scene's "body_i → body_j" when MuJoCo's pair is the joint's."""
        return f"{j.body_i} → {j.body_j}" if {parent, child} == {j.body_i, j.body_j} else f"{parent} → {child}"

    def damping(self, ids: list[int]) -> float:
        """The joints' `dof_damping` plus each fixed tendon on them alone
        (coef²·damping)."""
        m = self.m
        dofs = [m.jnt_dofadr[i] + k for i in ids for k in range(3 if m.jnt_type[i] == BALL else 1)]
        total = float(sum(m.dof_damping[d] for d in dofs))
        for t in range(m.ntendon):
            wraps = range(m.tendon_adr[t], m.tendon_adr[t] + m.tendon_num[t])
            if all(m.wrap_type[w] == mujoco.mjtWrap.mjWRAP_JOINT and m.wrap_objid[w] in ids for w in wraps):
                total += float(m.tendon_damping[t]) * sum(float(m.wrap_prm[w]) ** 2 for w in wraps)
        return total

    def site(self, sid: int) -> tuple[str, np.ndarray]:
        return self.body_name(self.m.site_bodyid[sid]), np.array(self.m.site_pos[sid])

    def cut_joint(self, j) -> list[Reading]:
        m, item, jn = self.m, joint_item(j.name), self.model.names.joint(j.name)
        eqs = [e for e in (_id(m, mujoco.mjtObj.mjOBJ_EQUALITY, jn + s) for s in ("c", "c1", "t")) if e >= 0]
        kind = CUT_KINDS.get(tuple(int(m.eq_type[e]) for e in eqs), "unknown")
        how = {"spherical": "a connect", "revolute": "two connects along the axis",
               "universal": "a connect and a tendon equality between the pins"}.get(kind, "")
        if any(m.eq_type[e] == CONNECT and m.eq_objtype[e] != mujoco.mjtObj.mjOBJ_SITE for e in eqs):
            return [Reading(item, "kind", f"{kind}, a connect between bodies", "this audit reads site connects")]
        ends = {}                                # body → (site point, second site point or None)
        connect = eqs[0]
        for sid in (m.eq_obj1id[connect], m.eq_obj2id[connect]):
            body, p = self.site(sid)
            ends[body] = [p, None]
        seconds = []
        if kind == "revolute":
            seconds = [m.eq_obj1id[eqs[1]], m.eq_obj2id[eqs[1]]]
        elif kind == "universal":
            t = m.eq_obj1id[eqs[1]]
            seconds = [m.wrap_objid[w] for w in range(m.tendon_adr[t], m.tendon_adr[t] + m.tendon_num[t])]
        for sid in seconds:
            body, p = self.site(sid)
            if body in ends:
                ends[body][1] = p
        pair = list(ends)
        out = [Reading(item, "kind", kind, f"closed by {how}"),
               Reading(item, "bodies", self.pair_text(j, pair[-1], pair[0]) if len(pair) == 2 else "–".join(pair)),
               Reading(item, "damping", 0.0, "an equality has no damping")]
        for side, body in (("i", j.body_i), ("j", j.body_j)):
            if body not in ends:
                continue
            p, second = ends[body]
            out += [Reading(item, f"point {side} {c}", float(p[k]), "site_pos") for k, c in enumerate("xyz")]
            if second is not None and kind in ("revolute", "universal"):
                axis = (second - p) / np.linalg.norm(second - p)
                out += [Reading(item, f"axis {side} z{c}", float(axis[k]), "from the site to the second site")
                        for k, c in enumerate("xyz")]
        return out

    def springs(self) -> list[Reading]:
        m, out = self.m, []
        for k, spring in enumerate(self.system.springs):
            t, item = _id(m, mujoco.mjtObj.mjOBJ_TENDON, f"s{k}"), f"spring {spring.name}"
            (a, pa), (b, pb) = (self.site(m.wrap_objid[w]) for w in range(m.tendon_adr[t], m.tendon_adr[t] + 2))
            low, high = (float(x) for x in m.tendon_lengthspring[t])
            out += [Reading(item, "bodies", f"{a} → {b}"),
                    Reading(item, "stiffness", float(m.tendon_stiffness[t])),
                    Reading(item, "free length", low if low == high else f"dead band {low:g}…{high:g}"),
                    Reading(item, "damping", float(m.tendon_damping[t]))]
            for end, p in (("a", pa), ("b", pb)):
                out += [Reading(item, f"point {end} {c}", float(p[i])) for i, c in enumerate("xyz")]
            if m.tendon_num[t] != 2:
                out.append(Reading(item, "path", f"{m.tendon_num[t]} sites", "not a straight spring"))
        return out

    def scene(self) -> list[Reading]:
        m, off = self.m, mujoco.mjtDisableBit
        g = np.zeros(3) if m.opt.disableflags & off.mjDSBL_GRAVITY else np.array(m.opt.gravity)
        out = [Reading(SCENE, f"gravity {c}", float(g[k])) for k, c in enumerate("xyz")]
        contacts = "off" if (m.opt.disableflags & off.mjDSBL_CONTACT) or m.ngeom == 0 else f"{m.ngeom} geoms"
        limits = int(np.sum(m.jnt_limited)) + int(np.sum(m.tendon_limited))
        out += [Reading(SCENE, "contacts", contacts),
                Reading(SCENE, "joint limits", "none" if not limits else f"{limits} limited joints or tendons")]
        return out

    def notes(self) -> list[Reading]:
        model, m, out = self.model, self.m, []
        for k, d in enumerate(self.system.drives):
            out.append(Reading(f"drive {d.name}", "clock", f"slide clock{k}, mass {m.body_mass[m.body(f'clock{k}').id]:g}",
                               "a clock body whose slide a joint equality couples to the driven joint", "note"))
        for k, law in enumerate(self.system.torques):
            out.append(Reading(f"torque law {law.name}", "actuator", f"torque{k}",
                               "an integrator actuator on the joint (its rate is the law's slope)", "note"))
        for body in model.tree.free:
            out.append(Reading(body_item(body), "free joint", "yes", "a floating body: MuJoCo's free joint", "note"))
        if m.neq:
            refs = sorted({f"{m.eq_solref[e, 0]:.3g} s, {m.eq_solref[e, 1]:g}" for e in range(m.neq)})
            out.append(Reading(SCENE, "equality solref", "; ".join(refs),
                               "soft constraints (time constant, damping ratio)", "note"))
        return out

    def others(self) -> list[Reading]:
        """Joints, equalities, tendons and actuators the scene's elements
        do not account for: a reading with no expectation (it differs),
        only when there are any."""
        m, names, system = self.m, self.model.names, self.system
        ours = {mujoco.mjtObj.mjOBJ_JOINT: {f"clock{k}" for k in range(len(system.drives))}
                | {f"free_{names.body(b)}" for b in self.model.tree.free}
                | {names.joint(j.name) + s for j in system.joints for s in JOINT_SUFFIXES},
                mujoco.mjtObj.mjOBJ_EQUALITY: {f"drive{k}" for k in range(len(system.drives))}
                | {names.joint(j.name) + s for j in system.joints for s in ("c", "c1", "t")},
                mujoco.mjtObj.mjOBJ_TENDON: {f"s{k}" for k in range(len(system.springs))}
                | {names.joint(j.name) + s for j in system.joints for s in ("d", "t")},
                mujoco.mjtObj.mjOBJ_ACTUATOR: {f"clock{k}" for k in range(len(system.drives))}
                | {f"torque{k}" for k in range(len(system.torques))}}
        counts = {mujoco.mjtObj.mjOBJ_JOINT: m.njnt, mujoco.mjtObj.mjOBJ_EQUALITY: m.neq,
                  mujoco.mjtObj.mjOBJ_TENDON: m.ntendon, mujoco.mjtObj.mjOBJ_ACTUATOR: m.nu}
        extra = [f"{kind.name[6:].lower()} {mujoco.mj_id2name(m, kind, i)!r}" for kind, n in counts.items()
                 for i in range(n) if mujoco.mj_id2name(m, kind, i) not in ours[kind]]
        return [Reading(SCENE, "other elements", "; ".join(extra))] if extra else []

    def readings(self) -> list[Reading]:
        out = self.bodies()
        for tj in self.model.tree.joints:
            out += self.tree_joint(tj)
        for j in self.model.tree.cuts:
            out += self.cut_joint(j)
        return out + self.springs() + self.scene() + self.notes() + self.others()


def nearest_in_span(point, through, directions) -> np.ndarray:
    """The point of the line (plane) through `through` spanned by
    `directions` nearest to `point`."""
    A = np.array(directions, dtype=float).T
    offset = np.asarray(point, float) - through
    return through + A @ np.linalg.lstsq(A, offset, rcond=None)[0]


def read_spatial(model: SpatialModel) -> list[Reading]:
    return Reader(model).readings()


def built(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> SpatialModel:
    """The compiled model the adapter's run starts from."""
    try:
        return SpatialModel(system, times, settings)
    except MechanismError as exc:
        raise Unrepresentable(exc.key, exc.reason) from None


def audit_spatial(system: SpatialSystem, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
    """The audit table of the MuJoCo model the adapter builds for `system`."""
    return audit(expected_spatial(system), read_spatial(built(system, times, settings)))
