"""The OpenSim (Simbody) model of a spatial scene (`SpatialSystem`): a tree
of OpenSim joints from the ground, loops closed by Simbody constraints.

Joint kinds as OpenSim joints (their frames are the scene's joint frames,
turned where OpenSim's axis is another one):
- revolute `PinJoint` (about z), prismatic `SliderJoint` (along x: the
  frames turned so that x is the scene's z), universal `UniversalJoint`
  (about the parent frame's x, then the child frame's y: frames turned so
  that those are zi and zj), planar `PlanarJoint`, fixed `WeldJoint`,
  cylindrical a `CustomJoint` (rotation about and translation along z),
  spherical `BallJoint`; a body with no path to the ground hangs from it
  by a `FreeJoint`.
- OpenSim 4.6 sets Simbody's Ball and Free mobilizers to body-fixed X-Y-Z
  Euler angles (`Model::initSystem`), singular where the second angle is
  ±90°: their chart (the parent frame's orientation) is chosen so that the
  angles are zero at the state they start from, and the run re-anchors the
  chart when the second angle passes `RECHART_ANGLE` (`spatial_run`).

The tree (Kruskal's rule) keeps drives, torque laws and the joints no
constraint closes (prismatic, cylindrical, planar); the loop closures
prefer spherical joints (a `PointConstraint`), then revolute ones (two
`PointConstraint`s on the axis: the sixth equation is redundant and
Simbody's projection and least-squares multipliers take it), universal
ones (a `PointConstraint` and a `ConstantDistanceConstraint` that keeps
zi ⊥ zj) and fixed ones (`WeldConstraint`). Not a further joint for the
loop: OpenSim's loop breaking then gives wrong reactions
(`mechval.engines.opensim.findings`). Names are generated (b0, j0, …).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import opensim as osim

from mechval.adapter import Unrepresentable
from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND, TorqueLaw
from mechval.reference.spatial.system import SpatialJoint, SpatialSystem

from mechval.engines.opensim.model import torque_function

#: Frame turns: columns are the new axes in the old frame. X_FROM_Z puts
#: the new x on the old z (slider axis, the universal's first pin);
#: Y_FROM_Z the new y on the old z (the universal's second pin).
X_FROM_Z = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
Y_FROM_Z = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
#: Closures as constraints, in order of preference for the cut; the
#: other kinds must be tree joints.
CLOSABLE = ("spherical", "revolute", "universal", "fixed")
#: A joint damper's coordinate per kind (the reference's damper: about zi
#: at a revolute joint, along zi elsewhere, where only a cylindrical joint
#: has a slide along zi left to damp).
DAMPED = {"revolute": 0, "prismatic": 0, "cylindrical": 1}
#: Kinds whose chart (Euler angles) the run re-anchors.
CHARTED = ("spherical", "free")


@dataclass(frozen=True)
class Mobilizer:
    """One OpenSim joint of the tree: the scene joint (None for a floating
    body's free joint), its parent and child bodies, whether the parent is
    the joint's body_j (`reversed`), and the offset frames (point, rotation
    in body axes) on parent and child."""

    name: str
    kind: str
    joint: SpatialJoint | None
    parent: str
    child: str
    reversed: bool
    parent_point: np.ndarray
    parent_frame: np.ndarray
    child_point: np.ndarray
    child_frame: np.ndarray

    @property
    def sign(self) -> float:
        return -1.0 if self.reversed else 1.0


@dataclass
class SpatialModel:
    """The built model and where each scene element went."""

    model: osim.Model
    bodies: dict[str, osim.Body] = field(default_factory=dict)
    mobilizers: dict[str, Mobilizer] = field(default_factory=dict)     # by OpenSim joint name
    joints: dict[str, osim.Joint] = field(default_factory=dict)        # by OpenSim joint name
    tree: dict[str, str] = field(default_factory=dict)                 # scene joint → OpenSim joint name
    closures: dict[str, list] = field(default_factory=dict)            # cut scene joint → constraints
    actuators: dict[str, osim.CoordinateActuator] = field(default_factory=dict)   # by torque name
    dampers: dict[str, osim.SpringGeneralizedForce] = field(default_factory=dict)  # by scene joint

    def coordinates(self, name: str) -> list[osim.Coordinate]:
        joint = self.joints[name]
        return [joint.get_coordinates(k) for k in range(joint.numCoordinates())]


def vec3(v) -> osim.Vec3:
    return osim.Vec3(float(v[0]), float(v[1]), float(v[2]))


def euler_xyz(R: np.ndarray) -> tuple[float, float, float]:
    """Body-fixed X-Y-Z angles (a, b, c) with R = Rx(a)·Ry(b)·Rz(c), as
    OpenSim's frame orientations and Simbody's Euler mobilizers read them
    (atan2 throughout: no digits lost near b = ±90°)."""
    b = math.atan2(R[0, 2], math.hypot(R[0, 0], R[0, 1]))
    if math.hypot(R[0, 0], R[0, 1]) < 1e-12:        # gimbal lock: c = 0 takes the whole turn
        return math.atan2(R[2, 1], R[1, 1]), b, 0.0
    return math.atan2(-R[1, 2], R[2, 2]), b, math.atan2(-R[0, 1], R[0, 0])


def cut_joints(system: SpatialSystem) -> tuple[list[SpatialJoint], list[SpatialJoint]]:
    """(tree joints, cut joints) by Kruskal's rule on the joints ordered by
    need of a mobilizer: driven first, then the kinds no constraint closes,
    then CLOSABLE backwards (a spherical joint is cut first)."""
    driven = {d.joint for d in system.drives} | {t.joint for t in system.torques}
    damped = {j.name for j in system.joints if j.damping and j.kind in DAMPED}

    def rank(j: SpatialJoint) -> int:
        if j.name in driven or j.name in damped or j.kind not in CLOSABLE:
            return 0
        return len(CLOSABLE) - CLOSABLE.index(j.kind)

    parent = {b.name: b.name for b in system.bodies} | {GROUND: GROUND}

    def root(b: str) -> str:
        while parent[b] != b:
            parent[b] = parent[parent[b]]
            b = parent[b]
        return b

    tree, cut = [], []
    for joint in sorted(system.joints, key=rank):
        a, b = root(joint.body_i), root(joint.body_j)
        if a == b:
            cut.append(joint)
            continue
        parent[a] = b
        tree.append(joint)
    for joint in cut:
        if rank(joint) == 0:
            what = "a drive, torque law or damper" if joint.kind in CLOSABLE else f"a {joint.kind} joint"
            raise Unrepresentable(f"joint.{joint.name}.kind",
                                  f"{what} closes a loop: OpenSim drives and damps only tree coordinates, and "
                                  f"the adapter closes loops only at {', '.join(CLOSABLE)} joints")
    return tree, cut


def spanning_tree(system: SpatialSystem, start: dict) -> list[Mobilizer]:
    """Mobilizers from the ground outwards (a parent before its child);
    `start` (body → (R, origin, v, ω)) picks the charts of the Ball and
    Free joints: Euler angles zero there."""
    tree, _ = cut_joints(system)
    placed, out = {GROUND}, []
    edges = list(tree)
    bodies = [b.name for b in system.bodies]
    while len(placed) <= len(bodies):           # placed holds the ground too
        joint = next((j for j in edges if j.body_i in placed or j.body_j in placed), None)
        if joint is None:                       # a part with no path to the ground: free root
            free = next(b for b in bodies if b not in placed)
            R = start[free][0]
            out.append(Mobilizer(f"j{len(out)}", "free", None, GROUND, free, False, np.zeros(3), R, np.zeros(3),
                                 np.eye(3)))
            placed.add(free)
            continue
        edges.remove(joint)
        rev = joint.body_i not in placed
        out.append(_mobilizer(f"j{len(out)}", joint, rev, start))
        placed.add(joint.body_i if rev else joint.body_j)
    return out


def _mobilizer(name: str, joint: SpatialJoint, rev: bool, start: dict) -> Mobilizer:
    sides = [(joint.body_i, np.asarray(joint.point_i, float), np.asarray(joint.frame_i, float)),
             (joint.body_j, np.asarray(joint.point_j, float), np.asarray(joint.frame_j, float))]
    (parent, pp, pf), (child, cp, cf) = sides[::-1] if rev else sides
    if joint.kind == "prismatic":
        pf, cf = pf @ X_FROM_Z, cf @ X_FROM_Z
    elif joint.kind == "universal":
        pf, cf = pf @ X_FROM_Z, cf @ Y_FROM_Z
    elif joint.kind == "spherical":
        # chart: the parent frame where the child frame is at the start
        cf = np.eye(3)
        rp = np.eye(3) if parent == GROUND else start[parent][0]
        pf = rp.T @ start[child][0]
    return Mobilizer(name, joint.kind, joint, parent, child, rev, pp, pf, cp, cf)


def build_spatial_model(system: SpatialSystem, start: dict, length: float) -> SpatialModel:
    """The model with nothing but the scene's bodies, joints, drives,
    gravity and force elements (no muscles, limits, contact); `start` as for
    `spanning_tree`, `length` the scene's size (the revolute closures'
    second point lies that far along the axis)."""
    built = SpatialModel(osim.Model())
    model = built.model
    model.setName("mechval")
    model.setGravity(vec3(system.gravity))
    for k, body in enumerate(system.bodies):
        I = np.asarray(body.inertia, dtype=float)
        inertia = osim.Inertia(I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2])
        b = osim.Body(f"b{k}", body.mass, vec3(body.com), inertia)
        model.addBody(b)
        built.bodies[body.name] = b
    for mob in spanning_tree(system, start):
        _add_joint(built, mob)
    _, cut = cut_joints(system)
    for k, joint in enumerate(cut):
        built.closures[joint.name] = _add_closure(built, joint, f"c{k}", length)
    for drive in system.drives:
        _prescribe(built, drive)
    for k, joint in enumerate(j for j in system.joints if j.damping and j.kind in DAMPED):
        _add_damper(built, joint, f"d{k}")
    for k, torque in enumerate(system.torques):
        _add_torque(built, torque, f"a{k}")
    for k, spring in enumerate(system.springs):
        _add_spring(built, spring, f"s{k}")
    for k, load in enumerate(system.loads):
        _add_load(built, load, f"l{k}")
    return built


def frame_of(built: SpatialModel, body: str) -> osim.PhysicalFrame:
    return built.model.getGround() if body == GROUND else built.bodies[body]


JOINT_CLASSES = {"revolute": osim.PinJoint, "prismatic": osim.SliderJoint, "universal": osim.UniversalJoint,
                 "planar": osim.PlanarJoint, "fixed": osim.WeldJoint, "spherical": osim.BallJoint,
                 "free": osim.FreeJoint}


def _add_joint(built: SpatialModel, mob: Mobilizer) -> None:
    frames = (mob.name, frame_of(built, mob.parent), vec3(mob.parent_point), vec3(euler_xyz(mob.parent_frame)),
              frame_of(built, mob.child), vec3(mob.child_point), vec3(euler_xyz(mob.child_frame)))
    if mob.kind == "cylindrical":
        joint = osim.CustomJoint(*frames, _cylinder_transform(mob.name))
    else:
        joint = JOINT_CLASSES[mob.kind](*frames)
    for k in range(joint.numCoordinates()):
        coordinate = joint.upd_coordinates(k)
        coordinate.setName(f"{mob.name}_q{k}")
        coordinate.setDefaultClamped(False)     # no range applies
    built.model.addJoint(joint)
    built.mobilizers[mob.name] = mob
    built.joints[mob.name] = joint
    if mob.joint is not None:
        built.tree[mob.joint.name] = mob.name


def _cylinder_transform(name: str) -> osim.SpatialTransform:
    """Rotation about z (coordinate q0) and translation along z (q1)."""
    transform = osim.SpatialTransform()
    axes = [(0, (0, 0, 1), f"{name}_q0"), (1, (1, 0, 0), None), (2, (0, 1, 0), None),
            (3, (0, 0, 1), f"{name}_q1"), (4, (1, 0, 0), None), (5, (0, 1, 0), None)]
    for index, axis, coordinate in axes:
        transform_axis = transform.updTransformAxis(index)
        transform_axis.setAxis(vec3(axis))
        if coordinate is not None:
            names = osim.ArrayStr()
            names.append(coordinate)
            transform_axis.setCoordinateNames(names)
            transform_axis.set_function(osim.LinearFunction())
        else:
            transform_axis.set_function(osim.Constant(0.0))
    return transform


def _add_closure(built: SpatialModel, joint: SpatialJoint, name: str, length: float) -> list:
    model = built.model
    fi, fj = frame_of(built, joint.body_i), frame_of(built, joint.body_j)
    Pi, Pj = np.asarray(joint.point_i, float), np.asarray(joint.point_j, float)
    if joint.kind == "fixed":
        weld = osim.WeldConstraint(name, fi, osim.Transform(_rotation(joint.frame_i), vec3(Pi)),
                                   fj, osim.Transform(_rotation(joint.frame_j), vec3(Pj)))
        model.addConstraint(weld)
        return [weld]
    parts = [osim.PointConstraint(fi, vec3(Pi), fj, vec3(Pj))]
    zi, zj = np.asarray(joint.frame_i)[:, 2], np.asarray(joint.frame_j)[:, 2]
    if joint.kind == "revolute":
        parts.append(osim.PointConstraint(fi, vec3(Pi + length * zi), fj, vec3(Pj + length * zj)))
    elif joint.kind == "universal":
        parts.append(osim.ConstantDistanceConstraint(fi, vec3(Pi + length * zi), fj, vec3(Pj + length * zj),
                                                     length * math.sqrt(2.0)))
    for k, part in enumerate(parts):
        part.setName(f"{name}_{k}")
        model.addConstraint(part)
    return parts


def _rotation(R) -> osim.Rotation:
    rotation = osim.Rotation()
    a, b, c = euler_xyz(np.asarray(R, dtype=float))
    rotation.setRotationToBodyFixedXYZ(osim.Vec3(a, b, c))
    return rotation


def _prescribe(built: SpatialModel, drive) -> None:
    law = drive.law
    if not isinstance(law, DriveLaw):
        raise Unrepresentable(f"drive.{drive.name}", "OpenSim's prescribed coordinate takes the polynomial "
                                                     f"DriveLaw only, not {type(law).__name__}")
    mob = built.mobilizers[built.tree[drive.joint]]
    s = mob.sign
    coordinate = built.coordinates(mob.name)[0]
    coordinate.setPrescribedFunction(osim.PolynomialFunction(osim.Vector(
        [s * 0.5 * law.alpha, s * law.omega0, s * law.phi0])))
    coordinate.setDefaultIsPrescribed(True)


def _add_damper(built: SpatialModel, joint: SpatialJoint, name: str) -> None:
    """−c·q̇ on the joint's coordinate `DAMPED` (the sign of a reversed
    one drops out). On the other kinds the reference's damper, along zi,
    meets no slide and does nothing: none is built."""
    mob = built.mobilizers[built.tree[joint.name]]
    damper = osim.SpringGeneralizedForce(built.coordinates(mob.name)[DAMPED[joint.kind]].getName())
    damper.setStiffness(0.0)
    damper.setViscosity(joint.damping)
    damper.setName(name)
    built.model.addForce(damper)
    built.dampers[joint.name] = damper


def _add_torque(built: SpatialModel, torque, name: str) -> None:
    """A CoordinateActuator of optimal force 1 N·m whose control a
    PrescribedController sets to the law."""
    if not isinstance(torque.law, TorqueLaw):
        raise Unrepresentable(f"torque.{torque.name}", "OpenSim's controller takes the sine TorqueLaw only, not "
                                                       f"{type(torque.law).__name__}")
    mob = built.mobilizers[built.tree[torque.joint]]
    actuator = osim.CoordinateActuator(built.coordinates(mob.name)[0].getName())
    actuator.setName(name)
    actuator.setOptimalForce(1.0)
    actuator.setMinControl(-math.inf)
    actuator.setMaxControl(math.inf)
    built.model.addForce(actuator)
    controller = osim.PrescribedController()
    controller.setName(f"{name}_control")
    controller.addActuator(actuator)
    controller.prescribeControlForActuator(name, torque_function(torque.law, mob.sign))
    built.model.addController(controller)
    built.actuators[torque.name] = actuator


def _add_spring(built: SpatialModel, spring, name: str) -> None:
    """Tension k·(d − ℓ0) + c·ḋ pulling the points together."""
    force = osim.ExpressionBasedPointToPointForce()
    force.setName(name)
    force.set_body1(frame_of(built, spring.body_a).getName())
    force.set_point1(vec3(spring.point_a))
    force.set_body2(frame_of(built, spring.body_b).getName())
    force.set_point2(vec3(spring.point_b))
    k, l0, c = (f"{v:.17g}" for v in (spring.stiffness, spring.free_length, spring.damping))
    force.setExpression(f"{k}*(d-({l0}))+{c}*ddot")
    built.model.addForce(force)


def _add_load(built: SpatialModel, load, name: str) -> None:
    """A constant force at the centre of mass and a torque, world axes."""
    if load.body == GROUND:
        return
    force = osim.PrescribedForce(name, built.bodies[load.body])
    force.setForceIsInGlobalFrame(True)
    force.setPointIsInGlobalFrame(False)
    com = built.bodies[load.body].getMassCenter()
    force.setPointFunctions(*(osim.Constant(float(com[k])) for k in range(3)))
    force.setForceFunctions(*(osim.Constant(float(v)) for v in load.force))
    force.setTorqueFunctions(*(osim.Constant(float(v)) for v in load.torque))
    built.model.addForce(force)

