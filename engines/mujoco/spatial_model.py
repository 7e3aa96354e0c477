"""MJCF for a spatial scene (`mechval.reference.spatial.system.SpatialSystem`)
in MuJoCo 4.0: the spanning tree of MuJoCo joints, the loops' equality
constraints, drives, torque laws, dampers and springs (docs/engines.md,
MuJoCo, "Spatial scenes").

- Every body's MJCF frame is the scene's body frame, placed at the start
  pose (the reference's at the first instant MuJoCo integrates), so every
  hinge and slide coordinate is 0 there and every ball's quaternion the
  identity; a body not joined to the ground by the tree gets a free joint.
- Per scene joint in the tree, with the joint point on the child: revolute
  a hinge about zi; prismatic a slide along zi; cylindrical a slide and a
  hinge on zi; spherical a ball; universal two hinges, first the parent's
  pin then the child's (MuJoCo turns a body's later joint axes with its
  earlier joints, so the first pin stays fixed in the parent and the
  second in the child); planar two slides along xi, yi then a hinge about
  zi (the slides come first, so their axes stay in the parent); fixed no
  joint (a weld). Axes are the start's zi, xi, yi in the child's frame:
  a coordinate is +θ (slide +s) when the child is body_j, −θ when it is
  body_i (`TreeJoint.sign`).
- A loop is closed at a cut joint by equalities between a site on each
  side: spherical one `connect`; revolute a `connect` at the point and one
  at `lever` along the axis (6 rows, rank 5: MuJoCo's regularised solver
  takes the redundant row); universal a `connect` and a tendon equality
  holding the length of a spatial tendon from Pi + L·zi to Pj + L·zj at
  L·√2 (zi ⊥ zj). Other kinds are never cut (`cut_rank` keeps them in
  the tree) and a loop they alone close is refused.
- A drive is a heavy clock on a slide across gravity, coordinate φ(t) −
  φ(t_start), tied to its joint by a joint equality (as in the planar
  model); a torque law an integrator actuator on its hinge (force = the
  activation, whose rate is the control); a damper a fixed tendon on its
  coordinate; a spring a spatial tendon with stiffness, springlength and
  damping. No geoms; contact, joint limits, armature, damping and friction
  loss are off.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from mechval.adapter import Unrepresentable
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.rotation import matrix_to_quaternion
from mechval.reference.spatial.system import SpatialJoint, SpatialSystem

from mechval.engines.mujoco.model import INTEGRATORS, MIN_IZZ, MIN_MASS, SOLIMP
from mechval.engines.spanning_tree import TreeJoint

#: Which joints are cut first (higher first): those an equality closes.
CUT_KINDS = ("spherical", "revolute", "universal")


@dataclass(frozen=True)
class Pose:
    """A body's frame origin (world) and rotation (body → world)."""

    origin: np.ndarray
    rotation: np.ndarray


@dataclass(frozen=True)
class Tree:
    joints: tuple[TreeJoint, ...]
    cuts: tuple[SpatialJoint, ...]
    free: tuple[str, ...]          # bodies on a free joint (roots of a floating component)

    def of_joint(self, name: str) -> TreeJoint:
        return next(tj for tj in self.joints if tj.joint.name == name)

    def children(self, parent: str) -> list[TreeJoint]:
        return [tj for tj in self.joints if tj.parent == parent]

    def subtree(self, body: str) -> set[str]:
        below = {body}
        for tj in self.children(body):
            below |= self.subtree(tj.child)
        return below


def must_be_tree(system: SpatialSystem) -> set[str]:
    """Joints that need a tree coordinate: driven, torque-loaded, damped."""
    return {d.joint for d in system.drives} | {t.joint for t in system.torques} | \
        {j.name for j in system.joints if j.damping}


def cut_rank(system: SpatialSystem, joint: SpatialJoint) -> int:
    """Kruskal's order: what must be in the tree first, what an equality
    closes best (a ball: one `connect`) last."""
    if joint.name in must_be_tree(system) or joint.kind not in CUT_KINDS:
        return 0
    return 1 + CUT_KINDS[::-1].index(joint.kind)


def spanning_tree(system: SpatialSystem) -> Tree:
    """The tree grown greedily over the joints by `cut_rank` (stable), each
    component rooted at the ground or, floating, at its first body."""
    group = {name: name for name in [GROUND] + [b.name for b in system.bodies]}

    def root(name: str) -> str:
        while group[name] != name:
            name = group[name]
        return name

    tree_joints, cuts = [], []
    for j in sorted(system.joints, key=lambda j: cut_rank(system, j)):
        a, b = root(j.body_i), root(j.body_j)
        if a == b:
            cuts.append(j)
        else:
            group[a] = b
            tree_joints.append(j)
    for j in cuts:
        if j.kind not in CUT_KINDS or j.name in must_be_tree(system):
            what = "driven, damped or torque-loaded" if j.name in must_be_tree(system) else f"a {j.kind} joint"
            raise Unrepresentable(f"joint.{j.name}.kind", f"the MuJoCo model closes a loop only at a "
                                                          f"{', '.join(CUT_KINDS)} joint that is not driven, damped "
                                                          f"or torque-loaded; this loop's last choice, {j.name!r}, "
                                                          f"is {what}")
    oriented, reached, free = [], set(), []
    pending = list(tree_joints)
    for start in [GROUND] + [b.name for b in system.bodies]:
        if start in reached:
            continue
        if start != GROUND:
            free.append(start)
        reached.add(start)
        frontier = [start]
        while frontier:
            body = frontier.pop(0)
            for j in list(pending):
                if body in (j.body_i, j.body_j):
                    child = j.body_j if j.body_i == body else j.body_i
                    oriented.append(TreeJoint(j, body, child))
                    reached.add(child)
                    frontier.append(child)
                    pending.remove(j)
    return Tree(tuple(oriented), tuple(cuts), tuple(free))


def _vec(*values: float) -> str:
    return " ".join(f"{float(v):.17g}" for v in values)


def world_point(poses: Mapping[str, Pose], body: str, point) -> np.ndarray:
    p = np.asarray(point, dtype=float)
    return p if body == GROUND else poses[body].origin + poses[body].rotation @ p


def world_axis(poses: Mapping[str, Pose], body: str, frame: np.ndarray, k: int) -> np.ndarray:
    axis = np.asarray(frame, dtype=float)[:, k]
    return axis if body == GROUND else poses[body].rotation @ axis


def ground_pose() -> Pose:
    return Pose(np.zeros(3), np.eye(3))


def lever(system: SpatialSystem, poses: Mapping[str, Pose]) -> float:
    """The length L along a cut's axis of its second site: the scene's
    size (the largest distance between two joint points), at least 1 mm."""
    points = [world_point(poses, b, p) for j in system.joints for b, p in ((j.body_i, j.point_i), (j.body_j, j.point_j))]
    span = max((np.linalg.norm(a - b) for a in points for b in points), default=0.0)
    return max(float(span), 1e-3)


@dataclass(frozen=True)
class Names:
    """Generated MJCF names (no scene string reaches the MJCF)."""

    system: SpatialSystem

    def body(self, name: str) -> str:
        return f"b{[b.name for b in self.system.bodies].index(name)}"

    def joint(self, name: str) -> str:
        return f"j{[j.name for j in self.system.joints].index(name)}"


def drive_axis(gravity) -> np.ndarray:
    """A clock's slide: across gravity, so gravity does no work on it."""
    g = np.asarray(gravity, dtype=float)
    if not np.any(g):
        return np.array([0.0, 0.0, 1.0])
    across = np.cross(g, np.eye(3)[int(np.argmin(np.abs(g)))])
    return across / np.linalg.norm(across)


def mjcf(system: SpatialSystem, tree: Tree, poses: Mapping[str, Pose], settings: Mapping[str, Any], dt: float) -> str:
    """The MJCF text: bodies at `poses` (the start), the given step dt and
    adapter settings (`mechval.engines.mujoco.adapter`)."""
    names = Names(system)
    L = lever(system, poses)
    pose = lambda b: ground_pose() if b == GROUND else poses[b]     # noqa: E731
    sites: dict[str, list[str]] = {}

    def site(body: str, name: str, world: np.ndarray) -> None:
        local = pose(body).rotation.T @ (world - pose(body).origin)
        sites.setdefault(body, []).append(f'<site name="{name}" pos="{_vec(*local)}"/>')

    for j in system.joints:
        jn = names.joint(j.name)
        p_i, p_j = world_point(poses, j.body_i, j.point_i), world_point(poses, j.body_j, j.point_j)
        site(j.body_i, f"{jn}i", p_i)
        site(j.body_j, f"{jn}j", p_j)
        if j in tree.cuts and j.kind in ("revolute", "universal"):
            z_i, z_j = world_axis(poses, j.body_i, j.frame_i, 2), world_axis(poses, j.body_j, j.frame_j, 2)
            site(j.body_i, f"{jn}i1", p_i + L * z_i)
            site(j.body_j, f"{jn}j1", p_j + L * (z_i if j.kind == "revolute" else z_j))
    for s_idx, s in enumerate(system.springs):
        site(s.body_a, f"s{s_idx}a", world_point(poses, s.body_a, s.point_a))
        site(s.body_b, f"s{s_idx}b", world_point(poses, s.body_b, s.point_b))

    def joints_xml(tj: TreeJoint) -> str:
        j, child = tj.joint, tj.child
        R = pose(child).rotation
        point = j.point_j if child == j.body_j else j.point_i
        pos = _vec(*np.asarray(point, dtype=float))
        axis = lambda k: _vec(*(R.T @ world_axis(poses, j.body_i, j.frame_i, k)))     # noqa: E731
        jn = names.joint(j.name)
        hinge = lambda suffix, ax: f'<joint name="{jn}{suffix}" type="hinge" pos="{pos}" axis="{ax}"/>'  # noqa: E731
        slide = lambda suffix, ax: f'<joint name="{jn}{suffix}" type="slide" pos="{pos}" axis="{ax}"/>'  # noqa: E731
        if j.kind == "revolute":
            return hinge("", axis(2))
        if j.kind == "prismatic":
            return slide("", axis(2))
        if j.kind == "cylindrical":
            return slide("s", axis(2)) + hinge("", axis(2))
        if j.kind == "spherical":
            return f'<joint name="{jn}" type="ball" pos="{pos}"/>'
        if j.kind == "universal":
            z_i = R.T @ world_axis(poses, j.body_i, j.frame_i, 2)
            z_j = R.T @ world_axis(poses, j.body_j, j.frame_j, 2)
            first, second = (z_i, z_j) if child == j.body_j else (z_j, z_i)
            return hinge("", _vec(*first)) + hinge("b", _vec(*second))
        if j.kind == "planar":
            return slide("x", axis(0)) + slide("y", axis(1)) + hinge("", axis(2))
        return ""                                                   # fixed: a weld

    def body_xml(body: str, parent: str, joints: str) -> str:
        b = system.body(body)
        if b.mass < MIN_MASS:
            raise Unrepresentable(f"body.{body}.mass", f"MuJoCo refuses a moving body lighter than {MIN_MASS:g} kg, "
                                                      f"got {b.mass!r}")
        if np.linalg.eigvalsh(np.asarray(b.inertia, dtype=float)).min() < MIN_IZZ:
            raise Unrepresentable(f"body.{body}.inertia", f"MuJoCo needs every principal moment of a moving body "
                                                          f"≥ {MIN_IZZ:g} kg·m² (a point mass has none)")
        P, C = pose(parent), pose(body)
        rel_pos = P.rotation.T @ (C.origin - P.origin)
        rel_quat = matrix_to_quaternion(P.rotation.T @ C.rotation)
        I = np.asarray(b.inertia, dtype=float)
        inertial = (f'<inertial pos="{_vec(*b.com)}" mass="{_vec(b.mass)}" '
                    f'fullinertia="{_vec(I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2])}"/>')
        kids = "".join(body_xml(tj.child, body, joints_xml(tj)) for tj in tree.children(body))
        return (f'<body name="{names.body(body)}" pos="{_vec(*rel_pos)}" quat="{_vec(*rel_quat)}">'
                f'{joints}{inertial}{"".join(sites.get(body, []))}{kids}</body>')

    roots = "".join(body_xml(tj.child, GROUND, joints_xml(tj)) for tj in tree.children(GROUND))
    roots += "".join(body_xml(b, GROUND, '<freejoint name="free_' + names.body(b) + '"/>')
                     for b in tree.free)

    solref = _vec(settings["solref_steps"] * dt, settings["solref_dampratio"])
    drive_solref = _vec(settings["drive_solref_steps"] * dt, settings["solref_dampratio"])
    solimp = _vec(*SOLIMP.values(settings["solimp"]))
    if settings["integrator"] not in INTEGRATORS:
        raise ValueError(f"mujoco: integrator must be one of {INTEGRATORS}, got {settings['integrator']!r}")
    equalities, tendons, actuators, clocks = [], [], [], []
    for j in tree.cuts:
        jn = names.joint(j.name)
        equalities.append(f'<connect name="{jn}c" site1="{jn}j" site2="{jn}i" solref="{solref}" solimp="{solimp}"/>')
        if j.kind == "revolute":
            equalities.append(f'<connect name="{jn}c1" site1="{jn}j1" site2="{jn}i1" solref="{solref}" '
                              f'solimp="{solimp}"/>')
        elif j.kind == "universal":
            tendons.append(f'<spatial name="{jn}t"><site site="{jn}i1"/><site site="{jn}j1"/></spatial>')
            equalities.append(f'<tendon name="{jn}t" tendon1="{jn}t" solref="{solref}" solimp="{solimp}"/>')
    clock_mass = float(settings["clock_mass"])
    axis = drive_axis(system.gravity)
    for k, d in enumerate(system.drives):
        tj = tree.of_joint(d.joint)
        clocks.append(f'<body name="clock{k}"><joint name="clock{k}" type="slide" axis="{_vec(*axis)}"/>'
                      f'<inertial pos="0 0 0" mass="{_vec(clock_mass)}" diaginertia="1 1 1"/></body>')
        equalities.append(f'<joint name="drive{k}" joint1="{names.joint(d.joint)}" joint2="clock{k}" '
                          f'polycoef="0 {_vec(tj.sign)} 0 0 0" solref="{drive_solref}" solimp="{solimp}"/>')
        actuators.append(f'<general name="clock{k}" joint="clock{k}" gainprm="0" biastype="affine" '
                         f'biasprm="{_vec(clock_mass * constant_acceleration(d))} 0 0" ctrllimited="false" '
                         'forcelimited="false"/>')
    for k, law in enumerate(system.torques):
        tj = tree.of_joint(law.joint)
        actuators.append(f'<general name="torque{k}" joint="{names.joint(law.joint)}" gear="{_vec(tj.sign)}" '
                         'dyntype="integrator" gainprm="1" biastype="none" ctrllimited="false" '
                         'forcelimited="false" actlimited="false"/>')
    for j in system.joints:
        if j.damping and j.kind not in ("revolute", "prismatic"):
            raise Unrepresentable(f"joint.{j.name}.damping", f"the MuJoCo model damps revolute and prismatic joints "
                                                            f"only, not {j.kind}")
        if j.damping:
            tendons.append(f'<fixed name="{names.joint(j.name)}d" damping="{_vec(j.damping)}">'
                           f'<joint joint="{names.joint(j.name)}" coef="1"/></fixed>')
    for k, s in enumerate(system.springs):
        tendons.append(f'<spatial name="s{k}" stiffness="{_vec(s.stiffness)}" '
                       f'springlength="{_vec(s.free_length, s.free_length)}" damping="{_vec(s.damping)}">'
                       f'<site site="s{k}a"/><site site="s{k}b"/></spatial>')
    gravity = np.asarray(system.gravity, dtype=float)
    return f"""<mujoco model="mechval-spatial">
  <compiler angle="radian" inertiafromgeom="false" autolimits="true" boundmass="0" boundinertia="0"/>
  <option timestep="{_vec(dt)}" integrator="{settings['integrator']}" gravity="{_vec(*gravity)}"
          density="0" viscosity="0" wind="0 0 0" solver="Newton" tolerance="{_vec(settings['tolerance'])}"
          iterations="{int(settings['iterations'])}" noslip_iterations="0">
    <flag contact="disable" autoreset="disable" refsafe="disable" gravity="{'enable' if gravity.any() else 'disable'}"/>
  </option>
  <default>
    <joint damping="0" armature="0" frictionloss="0" stiffness="0" limited="false"/>
    <tendon damping="0" stiffness="0" frictionloss="0" limited="false"/>
  </default>
  <worldbody>{"".join(sites.get(GROUND, []))}{roots}{"".join(clocks)}</worldbody>
  <equality>{"".join(equalities)}</equality>
  <tendon>{"".join(tendons)}</tendon>
  <actuator>{"".join(actuators)}</actuator>
</mujoco>"""


def constant_acceleration(drive) -> float:
    """The drive law's φ̈, which the clock's constant force gives it; a law
    whose φ̈ is not constant cannot be followed that way."""
    samples = np.asarray(drive.law.acceleration(np.linspace(-10.0, 10.0, 21)), dtype=float)
    if not np.all(np.isfinite(samples)) or np.ptp(samples) > 1e-12 * max(1.0, float(np.abs(samples).max())):
        raise Unrepresentable(f"drive.{drive.name}", "the MuJoCo model's clock follows a law of constant "
                                                     "acceleration only")
    return float(samples[0])
