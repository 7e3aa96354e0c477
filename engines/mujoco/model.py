"""MJCF for a generic planar `Mechanism` (MuJoCo 4.0) and the maps between
MuJoCo's coordinates and the mechanism's bodies and joints.

Model layout (docs/engines.md, MuJoCo):
- A spanning tree of the joints from the ground: every body is the child of
  the body it is joined to on the way from the ground, on a hinge (revolute)
  or slide (prismatic) joint. A prismatic joint between two moving bodies is
  simply a slide joint whose parent is not the world.
- Each independent loop is closed at one revolute pin that is not driven
  (the "cuts", `topology`), with an equality `connect` between a site on
  each side.
- Every body frame is the mechanism's body frame; in the zero configuration a
  child's frame has the rotation of its parent (hinge) or the fixed relative
  rotation of the prismatic pair, and the joint points coincide. So a hinge
  coordinate is the relative angle θchild − θparent and a slide coordinate is
  the travel of the joint point along the axis.
- Each drive (revolute or prismatic) has its own clock and joint equality,
  as follows. The drive is a heavy "clock" body on a z slide (out of the plane, so in-plane
  gravity does not act on it) whose coordinate is φ(t): it starts at φ, φ̇
  and a constant actuator bias force gives it φ̈ = alpha; a joint equality
  with a linear polycoef ties the drive hinge to it. Nothing runs in Python
  per step, so `mujoco.rollout` can integrate.
- Dampers are fixed tendons over the hinge/slide coordinates whose rate is the
  joint's relative rate (for the cut pin the path sums, ω_j − ω_i), so every
  damper is evaluated in every RK4 stage and none hides in a joint default.
- A spring-damper is a spatial tendon between two sites with stiffness,
  springlength [ℓ0, ℓ0] and damping: MuJoCo's passive force
  −k·(ℓ − ℓ0) − c·ℓ̇ along the line. A body torque is an actuator with a
  constant bias force (the torque, no control gain) on a fixed tendon over
  the hinges of the body's tree path, whose rate is the body's ω.
- A torque law (T on body_j, −T on body_i) is an actuator on a fixed tendon
  whose length is the joint's relative angle θj − θi (`angle_coefficients`:
  the joint's own hinge, or path sums for a cut pin), its force its
  activation (integrator dynamics), fed the law's slope per step
  (`torque_law_controls`). A degree of freedom that no drive prescribes
  gets no clock and no equality.
- No geoms, contacts disabled, autoreset disabled, radians, explicit
  inertials, no joint damping/armature/friction/stiffness/limits. `refsafe`
  is off so that solref is used as written (it would raise the drive's
  1·dt time constant to 2·dt; see the adapter's default settings).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import pandas as pd

from mechval.model.kinematics import rotate, slide_motion
from mechval.model.mechanism import GROUND, Joint, Mechanism, SpringDamper

from mechval.engines.base import Unrepresentable
from mechval.settings import Number, Numbers
from mechval.engines.spanning_tree import cut_joints

CLOCK = "mechval_clock"
#: The equalities: the loop closure at the cut pin, the drive.
LOOP, DRIVE = "loop", "drive"
#: Integrators (setting "integrator"), by their MJCF names.
INTEGRATORS = ("RK4", "Euler", "implicit", "implicitfast")
#: The soft constraints' impedance (setting "solimp"), within the range
#: MuJoCo uses (it silently clamps dmin, dmax and midpoint to [1e-4, 0.9999],
#: width to ≥ 0 and power to ≥ 1: a value outside would be recorded but
#: not simulated).
SOLIMP = Numbers((("dmin", Number(1e-4, 0.9999)), ("dmax", Number(1e-4, 0.9999)), ("width", Number(0.0)),
                  ("midpoint", Number(1e-4, 0.9999)), ("power", Number(1.0))))
#: MuJoCo refuses a moving body whose mass or smallest principal inertia is
#: below mjMINVAL = 1e-15 (kg, kg·m²). Bodies get ixx = iyy = izz/2, so a
#: turning body needs izz ≥ 2e-15; MIN_IZZ keeps a margin.
MIN_MASS, MIN_IZZ = 1e-15, 1e-14


@dataclass(frozen=True)
class TreeJoint:
    """A mechanism joint as a MuJoCo tree joint from `parent` to `child`.

    `sign` = +1 when the child is the joint's body_j: the MuJoCo coordinate
    is then the motion of body_j relative to body_i; −1 when reversed.
    `rel0` is the child's rotation relative to the parent in the zero
    configuration (0 for a hinge; the fixed pair angle for a slide).
    """

    joint: Joint
    parent: str
    child: str
    rel0: float = 0.0

    @property
    def sign(self) -> float:
        return 1.0 if self.child == self.joint.body_j else -1.0

    @property
    def point_parent(self) -> tuple[float, float]:
        return self.joint.point_i if self.sign > 0 else self.joint.point_j

    @property
    def point_child(self) -> tuple[float, float]:
        return self.joint.point_j if self.sign > 0 else self.joint.point_i


@dataclass(frozen=True)
class Topology:
    """The spanning tree (parents before children) and the loop-closing
    pins, one per independent loop (`cuts`)."""

    tree: tuple[TreeJoint, ...]
    cuts: tuple[Joint, ...]

    def of_child(self, body: str) -> TreeJoint:
        return next(tj for tj in self.tree if tj.child == body)

    def of_joint(self, name: str) -> TreeJoint:
        return next(tj for tj in self.tree if tj.joint.name == name)

    def subtree(self, body: str) -> set[str]:
        """`body` and every body below it in the tree."""
        below = {body}
        for tj in self.tree:                     # parents come before children
            if tj.parent in below:
                below.add(tj.child)
        return below

    def path(self, body: str) -> list[TreeJoint]:
        """Tree joints from the ground to `body`."""
        path = []
        while body != GROUND:
            tj = self.of_child(body)
            path.insert(0, tj)
            body = tj.parent
        return path


def topology(mech: Mechanism, motion0: Mapping[str, np.ndarray]) -> Topology:
    """A spanning tree and one cut revolute pin per loop; `motion0` (one
    instant) fixes prismatic pairs' relative rotation.

    Joints enter the tree greedily (Kruskal): the drives first (a drive is
    a joint equality on a tree coordinate), then the prismatic joints (a cut
    can only be a pin: a `connect`), then the pins in the mechanism's
    order, so that each loop is cut at its last pin; the tree is then laid
    out breadth-first from the ground in the mechanism's joint order."""
    drives = {d.joint for d in mech.drives}
    rank = lambda j: (0 if j.name in drives else 1 if j.kind == "prismatic" else 2)
    cuts = cut_joints(mech, rank)
    for j in cuts:
        if j.kind != "revolute" or j.name in drives:
            raise Unrepresentable(f"joint.{j.name}", "MuJoCo adapter closes each loop at a revolute pin that is not "
                                                     "driven, and this loop has none")
    cut_names = {j.name for j in cuts}
    tree = _spanning_tree(mech, [j for j in mech.joints if j.name not in cut_names], motion0)
    if tree is None:
        raise ValueError(f"{mech.name}: MuJoCo adapter found no spanning tree of the joints")
    return Topology(tree, tuple(j for j in mech.joints if j.name in cut_names))


def _spanning_tree(mech: Mechanism, joints: list[Joint],
                   motion0: Mapping[str, np.ndarray]) -> tuple[TreeJoint, ...] | None:
    remaining = list(joints)
    reached, order, queue = {GROUND}, [], deque([GROUND])
    while queue:
        body = queue.popleft()
        for j in [j for j in remaining if body in (j.body_i, j.body_j)]:
            remaining.remove(j)
            child = j.body_j if j.body_i == body else j.body_i
            if child in reached:
                return None                      # a second loop
            rel0 = 0.0
            if j.kind == "prismatic":
                rel0 = _angle(motion0, child) - _angle(motion0, body)
            order.append(TreeJoint(j, body, child, rel0))
            reached.add(child)
            queue.append(child)
    return tuple(order) if not remaining and len(reached) == len(mech.bodies) + 1 else None


def _angle(motion: Mapping[str, np.ndarray], body: str) -> float:
    return 0.0 if body == GROUND else float(motion[f"{body}.theta"][0])


def raw_columns(motion: pd.DataFrame) -> dict[str, np.ndarray]:
    """The reference motion as raw column name → array: column access on a
    DataFrame costs microseconds each, and the model build does hundreds."""
    return dict(zip(motion.columns, motion.to_numpy().T))


def _quat_z(angle: float) -> str:
    return f"{np.cos(angle / 2):.17g} 0 0 {np.sin(angle / 2):.17g}"


def _vec(*values: float) -> str:
    return " ".join(f"{float(v):.17g}" for v in values)


@dataclass(frozen=True)
class Names:
    """MuJoCo element names: generated identifiers, so that no user string
    reaches the MJCF (a quote, `<` or NUL in a name can neither change nor
    break the model). Body k of the mechanism is "b{k}", joint k is "j{k}"
    and its sites "j{k}i" (on body_i) and "j{k}j" (on body_j)."""

    body: Mapping[str, str]
    joint: Mapping[str, str]

    @classmethod
    def of(cls, mech: Mechanism) -> "Names":
        return cls({b.name: f"b{k}" for k, b in enumerate(mech.bodies)},
                   {j.name: f"j{k}" for k, j in enumerate(mech.joints)})

    def sites(self, joint: Joint) -> tuple[str, str]:
        """The joint's sites on body_i and on body_j."""
        return f"{self.joint[joint.name]}i", f"{self.joint[joint.name]}j"


def clock_name(k: int) -> str:
    """The clock joint (and body, actuator) of drive k."""
    return CLOCK if k == 0 else f"{CLOCK}{k}"


def drive_name(k: int) -> str:
    """The joint equality of drive k."""
    return DRIVE if k == 0 else f"{DRIVE}{k}"


def loop_name(k: int) -> str:
    """The connect equality of cut pin k."""
    return LOOP if k == 0 else f"{LOOP}{k}"


def force_sites(k: int) -> tuple[str, str]:
    """The sites of spring-damper k (force element k) on body_a and body_b."""
    return f"f{k}a", f"f{k}b"


def force_name(k: int) -> str:
    """The tendon of force element k (and the actuator of a body torque)."""
    return f"f{k}"


def torque_law_name(k: int) -> str:
    """The tendon and the actuator of torque law k."""
    return f"t{k}"


def torque_coefficients(topo: Topology, body: str) -> dict[str, float]:
    """Joint-coordinate coefficients of a body's angle θ: 1 on every hinge
    of its tree path (slides do not turn). A constant torque τ on the body
    is the generalized force τ on each of them (its Jacobian), which is
    constant: one fixed tendon and a constant actuator force. A body that
    never turns has none: its torque does no work and only loads the
    couples of its joints, so MuJoCo gets no element for it."""
    return {tj.joint.name: 1.0 for tj in topo.path(body) if tj.joint.kind == "revolute"}


def angle_coefficients(topo: Topology, joint: Joint) -> dict[str, float]:
    """Joint-coordinate coefficients of a revolute joint's relative angle
    θj − θi, as sums over the hinges of both bodies' tree paths (±1 on the
    joint's own hinge when it is in the tree). A torque T on body_j and −T
    on body_i is the generalized force T times these (its Jacobian)."""
    coef: dict[str, float] = {}
    for body, sign in ((joint.body_j, 1.0), (joint.body_i, -1.0)):
        for name, c in torque_coefficients(topo, body).items():
            coef[name] = coef.get(name, 0.0) + sign * c
    return {name: c for name, c in coef.items() if c != 0.0}


def damper_coefficients(topo: Topology, joint: Joint) -> dict[str, float]:
    """Joint-coordinate coefficients of the damper rate of `joint`: its own
    coordinate for a tree joint, ω_j − ω_i as path sums for the cut pin."""
    return angle_coefficients(topo, joint) if joint in topo.cuts else {joint.name: 1.0}


def turning_groups(mech: Mechanism) -> list[set[str]]:
    """Bodies that turn together: those joined by prismatic joints (a
    slide keeps their relative rotation), e.g. the slotted lever's block and
    lever. The group holding the ground does not turn."""
    group = {name: {name} for name in [GROUND] + [b.name for b in mech.bodies]}
    for j in mech.joints:
        if j.kind == "prismatic" and group[j.body_i] is not group[j.body_j]:
            merged = group[j.body_i] | group[j.body_j]
            for name in merged:
                group[name] = merged
    return list({id(g): g for g in group.values()}.values())


def planar_inertias(mech: Mechanism) -> dict[str, float]:
    """The izz each body gets in MuJoCo (kg·m²), which refuses a moving
    body whose principal inertia is below mjMINVAL (`MIN_IZZ`).

    - A body that never turns (slides on the ground): any izz is exact for
      it; a point mass (izz = 0) gets its mass·(1 m)².
    - A turning body below MIN_IZZ, e.g. a point-mass block (izz = 0) that
      turns with its slotted lever: it gets MIN_IZZ, taken from the body of
      its group with the largest izz. The motion depends only on the
      group's total izz (its bodies turn as one), which is kept, so every
      signal is exact except the couple M of a slide inside the group,
      which carries the shifted inertia times α; the read-out takes it
      out (`Model.inertia_shift_couple`).
    Raises Unrepresentable when a body cannot be represented (no body of
    its group has the inertia to lend, or a mass below mjMINVAL)."""
    izz = {b.name: b.izz for b in mech.bodies}
    for body in mech.bodies:
        if body.mass < MIN_MASS:
            raise Unrepresentable(f"mass.{body.name}", f"MuJoCo refuses a moving body lighter than "
                                                       f"{MIN_MASS:g} kg, got {body.mass!r}")
    for group in turning_groups(mech):
        if GROUND in group:
            for name in group - {GROUND}:
                izz[name] = izz[name] if izz[name] > 0.0 else mech.body(name).mass   # mass·(1 m)²
            continue
        small = sorted(name for name in group if izz[name] < MIN_IZZ)
        if not small:
            continue
        lender = max(group, key=lambda name: izz[name])
        lent = sum(MIN_IZZ - izz[name] for name in small)
        if lender in small or izz[lender] - lent < MIN_IZZ:
            others = ", ".join(sorted(group - {small[0]}))
            raise Unrepresentable(f"mass.{small[0]}", f"MuJoCo needs izz ≥ {MIN_IZZ:g} kg·m² on every turning "
                                                      f"body, got {izz[small[0]]!r}, and the bodies turning with it "
                                                      f"({others or 'none'}) have too little to lend")
        for name in small:
            izz[name] = MIN_IZZ
        izz[lender] -= lent
    return izz


def inertia_shift(mech: Mechanism) -> dict[str, float]:
    """Per turning body whose izz MuJoCo gets differs from the scene's
    (`planar_inertias`), the difference (kg·m²)."""
    inertias = planar_inertias(mech)
    turning = set().union(*(g for g in turning_groups(mech) if GROUND not in g))
    return {b.name: inertias[b.name] - b.izz for b in mech.bodies
            if b.name in turning and inertias[b.name] != b.izz}


def mjcf(mech: Mechanism, topo: Topology, settings: Mapping[str, Any], dt: float, names: Names) -> str:
    """The MJCF text of the mechanism with the given adapter settings and
    the step `dt` MuJoCo takes (s). Only generated names (`names`) and
    numbers formatted from floats (`_vec`, %.17g round-trips) reach it,
    never a string from the scene or the settings."""
    gx, gy = mech.gravity
    site_xml: dict[str, list[str]] = {}
    for j in mech.joints:
        for body, point, name in zip((j.body_i, j.body_j), (j.point_i, j.point_j), names.sites(j)):
            site_xml.setdefault(body, []).append(f'<site name="{name}" pos="{_vec(*point, 0)}"/>')
    inertias = planar_inertias(mech)

    def body_xml(tj: TreeJoint) -> str:
        b = mech.body(tj.child)
        px, py = tj.point_parent
        cx, cy = rotate(np.asarray(tj.rel0), tj.point_child)
        joint_name = names.joint[tj.joint.name]
        if tj.joint.kind == "revolute":
            joint = f'<joint name="{joint_name}" type="hinge" pos="{_vec(*tj.point_child, 0)}" axis="0 0 1"/>'
        else:
            # The axis is given in body_i's frame; MuJoCo wants it in the child's.
            ax, ay = rotate(np.asarray(-tj.rel0 if tj.sign > 0 else 0.0), tj.joint.axis)
            joint = (f'<joint name="{joint_name}" type="slide" pos="{_vec(*tj.point_child, 0)}" '
                     f'axis="{_vec(ax, ay, 0)}"/>')
        izz = inertias[b.name]
        # Only izz acts in the plane; ixx = iyy = izz/2 keeps the tensor valid.
        inertial = (f'<inertial pos="{_vec(*b.com, 0)}" mass="{_vec(b.mass)}" '
                    f'diaginertia="{_vec(izz / 2, izz / 2, izz)}"/>')
        children = "".join(body_xml(c) for c in topo.tree if c.parent == tj.child)
        return (f'<body name="{names.body[b.name]}" pos="{_vec(px - float(cx), py - float(cy), 0)}" '
                f'quat="{_quat_z(tj.rel0)}">{joint}{inertial}{"".join(site_xml.get(b.name, []))}{children}</body>')

    solref = _vec(settings["solref_steps"] * dt, settings["solref_dampratio"])
    drive_solref = _vec(settings["drive_solref_steps"] * dt, settings["solref_dampratio"])
    solimp = _vec(*SOLIMP.values(settings["solimp"]))
    integrator = settings["integrator"]
    if integrator not in INTEGRATORS:
        raise ValueError(f"mujoco: integrator must be one of {INTEGRATORS}, got {integrator!r}")
    clock_mass = float(settings["clock_mass"])
    tendons, actuators, clocks, loops, drives = [], [], [], [], []
    for j in mech.damped_joints:
        coef = "".join(f'<joint joint="{names.joint[n]}" coef="{_vec(c)}"/>'
                       for n, c in damper_coefficients(topo, j).items())
        tendons.append(f'<fixed damping="{_vec(j.damping)}">{coef}</fixed>')
    for k, force in enumerate(mech.forces):
        if isinstance(force, SpringDamper):
            # Passive tendon force −stiffness·(ℓ − springlength) − damping·ℓ̇
            # along the line (a deadband [ℓ0, ℓ0] is the plain spring).
            site_a, site_b = force_sites(k)
            site_xml.setdefault(force.body_a, []).append(f'<site name="{site_a}" pos="{_vec(*force.point_a, 0)}"/>')
            site_xml.setdefault(force.body_b, []).append(f'<site name="{site_b}" pos="{_vec(*force.point_b, 0)}"/>')
            tendons.append(f'<spatial name="{force_name(k)}" stiffness="{_vec(force.stiffness)}" '
                           f'springlength="{_vec(force.free_length, force.free_length)}" '
                           f'damping="{_vec(force.damping)}"><site site="{site_a}"/><site site="{site_b}"/></spatial>')
        elif torque_coefficients(topo, force.body):
            coef = "".join(f'<joint joint="{names.joint[n]}" coef="{_vec(c)}"/>'
                           for n, c in torque_coefficients(topo, force.body).items())
            tendons.append(f'<fixed name="{force_name(k)}">{coef}</fixed>')
            actuators.append(f'<general name="{force_name(k)}" tendon="{force_name(k)}" gainprm="0" biastype="affine" '
                             f'biasprm="{_vec(force.torque)} 0 0" ctrllimited="false" forcelimited="false"/>')
    for k, law in enumerate(mech.torque_drives):
        # Force = activation, whose rate is the control: the rollout's
        # controls make it the law at every step boundary and linear in
        # between, in every RK4 stage (`torque_law_controls`).
        coef = "".join(f'<joint joint="{names.joint[n]}" coef="{_vec(c)}"/>'
                       for n, c in angle_coefficients(topo, mech.joint(law.joint)).items())
        tendons.append(f'<fixed name="{torque_law_name(k)}">{coef}</fixed>')
        actuators.append(f'<general name="{torque_law_name(k)}" tendon="{torque_law_name(k)}" dyntype="integrator" '
                         'gainprm="1" biastype="none" ctrllimited="false" forcelimited="false" actlimited="false"/>')
    for k, cut in enumerate(topo.cuts):
        i_site, j_site = names.sites(cut)
        loops.append(f'<connect name="{loop_name(k)}" site1="{j_site}" site2="{i_site}" solref="{solref}" '
                     f'solimp="{solimp}"/>')
    for k, drive_spec in enumerate(mech.drives):
        drive, clock = topo.of_joint(drive_spec.joint), clock_name(k)
        clocks.append(f'<body name="{clock}">\n      <joint name="{clock}" type="slide" axis="0 0 1"/>\n      '
                      f'<inertial pos="0 0 0" mass="{_vec(clock_mass)}" diaginertia="1 1 1"/>\n    </body>')
        drives.append(f'<joint name="{drive_name(k)}" joint1="{names.joint[drive.joint.name]}" joint2="{clock}"\n'
                      f'           polycoef="0 {_vec(drive.sign)} 0 0 0" solref="{drive_solref}" solimp="{solimp}"/>')
        actuators.insert(k, f'<general name="{clock}" joint="{clock}" gainprm="0" biastype="affine"\n'
                            f'             biasprm="{_vec(clock_mass * drive_spec.law.alpha)} 0 0" ctrllimited="false" '
                            'forcelimited="false"/>')
    roots = "".join(body_xml(tj) for tj in topo.tree if tj.parent == GROUND)
    return f"""<mujoco model="mechval">
  <compiler angle="radian" inertiafromgeom="false" autolimits="true" boundmass="0" boundinertia="0"/>
  <option timestep="{_vec(dt)}" integrator="{integrator}"
          gravity="{_vec(gx, gy, 0)}" density="0" viscosity="0" wind="0 0 0"
          solver="Newton" tolerance="{_vec(settings['tolerance'])}" iterations="{int(settings['iterations'])}"
          noslip_iterations="0">
    <flag contact="disable" autoreset="disable" refsafe="disable" gravity="{'enable' if mech.has_gravity else 'disable'}"/>
  </option>
  <default>
    <joint damping="0" armature="0" frictionloss="0" stiffness="0" limited="false"/>
  </default>
  <worldbody>
    {"".join(site_xml.get(GROUND, []))}
    {roots}
    {"".join(clocks)}
  </worldbody>
  <equality>
    {"".join(loops)}
    {"".join(drives)}
  </equality>
  <tendon>{"".join(tendons)}</tendon>
  <actuator>
    {"".join(actuators)}
  </actuator>
</mujoco>"""


def coordinates(mech: Mechanism, topo: Topology,
                motion: Mapping[str, np.ndarray]) -> dict[str, tuple[np.ndarray, ...]]:
    """Reference (q, q̇, q̈) of every tree joint and the clock, from the
    reference body motion (used for the initial state and inverse mode).

    Hinge: q = θchild − θparent. Slide: q = sign·s with s the travel of P_j
    from P_i along the axis (`mechval.model.kinematics.slide_motion`).
    """
    t = motion["t"]
    zero = np.zeros(len(t))
    rate = lambda b, q: zero if b == GROUND else motion[f"{b}.{q}"]
    out = {}
    for tj in topo.tree:
        j = tj.joint
        if j.kind == "revolute":
            out[j.name] = tuple(tj.sign * (rate(j.body_j, q) - rate(j.body_i, q)) for q in ("theta", "omega", "alpha"))
            continue
        slide = slide_motion(motion, j)
        out[j.name] = tuple(tj.sign * slide[q] for q in ("s", "v", "a"))
    for k, drive in enumerate(mech.drives):
        law = drive.law
        out[clock_name(k)] = (law.angle(t), law.rate(t), law.acceleration(t))
    return out


def torque_law_controls(mech: Mechanism, start: float, dt: float, nstep: int) -> np.ndarray:
    """(nstep, laws): the control of each torque law's actuator per step,
    the slope (T(t_n+1) − T(t_n))/dt of its law over step n (t_n = start +
    n·dt). Its activation, the actuator force, starts at T(start) and is
    integrated by MuJoCo in every stage: the law at each step boundary and
    linear in between (exact for a constant torque)."""
    t = start + dt * np.arange(nstep + 1)
    return np.column_stack([np.diff(law.value(t)) / dt for law in mech.torque_drives]) if mech.torque_drives \
        else np.zeros((nstep, 0))
