"""The OpenSim (Simbody) model of a planar `Mechanism`: a tree of
`PinJoint`/`SliderJoint` from the ground, each loop closed by a Simbody
`PointConstraint` at one of its pins.

The tree (`spanning_tree`) takes the drives' joints first, then the slides
and the torque laws' joints: a prescribed coordinate, a slide and a
`CoordinateActuator` need a mobilizer, while a pin can be cut and closed by
a point constraint. A loop that only a slide could close is refused
(`Unrepresentable`, key "joint"). Not a fourth `PinJoint` for the loop:
OpenSim's automatic loop breaking then gives wrong reactions
(`mechval.engines.opensim.findings`).

Every element gets a generated name (b0, j0, …): no user string reaches
OpenSim's component names, whose syntax is OpenSim's.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field

import opensim as osim

from mechval.adapter import Unrepresentable
from mechval.model.mechanism import GROUND, BodyTorque, Drive, Joint, Mechanism, SpringDamper, TorqueLaw
from mechval.engines.spanning_tree import cut_joints

# OpenSim's logger writes opensim.log into the working directory at its
# first message: mechval writes no file outside the folder its user names.
osim.Logger.removeFileSink()


@contextlib.contextmanager
def quiet():
    """OpenSim's console log (the Manager's summary of every integration)
    off: set once and left off, since setting a level back logs a line
    itself ("Set log level to Info.")."""
    osim.Logger.setLevel(osim.Logger.Level_Off)
    yield


@dataclass(frozen=True)
class TreeJoint:
    """A mechanism joint built as an OpenSim mobilizer: its parent and child
    bodies, and whether the parent is the joint's body_j (`reversed`): its
    coordinate is then −(θj − θi) or −s, and its reaction acts on body_i."""

    joint: Joint
    parent: str
    child: str
    reversed: bool

    @property
    def sign(self) -> float:
        return -1.0 if self.reversed else 1.0


@dataclass
class OpensimModel:
    """The built model and where each mechanism element went."""

    model: osim.Model
    bodies: dict[str, osim.Body] = field(default_factory=dict)
    tree: dict[str, TreeJoint] = field(default_factory=dict)
    joints: dict[str, osim.Joint] = field(default_factory=dict)        # tree joints by mechanism name
    closures: dict[str, osim.PointConstraint] = field(default_factory=dict)
    actuators: dict[str, osim.CoordinateActuator] = field(default_factory=dict)   # by torque law name
    forces: dict[str, osim.Force] = field(default_factory=dict)         # by force element or damper name
    loop_pins: dict[str, osim.PinJoint] = field(default_factory=dict)   # closure "pin" only

    def coordinate(self, joint: str) -> osim.Coordinate:
        return self.joints[joint].get_coordinates(0)


def spanning_tree(mechanism: Mechanism) -> tuple[list[TreeJoint], list[Joint]]:
    """The tree joints, each oriented from the ground outwards and in an
    order where a parent comes before its child, and the joints that close
    loops (Kruskal's rule on the joints ordered by need of a mobilizer)."""
    driven = {d.joint for d in mechanism.drives} | {law.joint for law in mechanism.torque_drives}
    rank = lambda j: (0 if j.name in driven else 1 if j.kind == "prismatic" else 2)    # noqa: E731
    closing = cut_joints(mechanism, rank)
    edges = [joint for joint in sorted(mechanism.joints, key=rank) if joint not in closing]
    placed, tree = {GROUND}, []
    while edges:
        joint = next((j for j in edges if j.body_i in placed or j.body_j in placed), None)
        if joint is None:       # a body with no path to the ground
            raise Unrepresentable("joint", f"body {edges[0].body_j!r} is not connected to the ground")
        edges.remove(joint)
        reversed_ = joint.body_i not in placed
        parent, child = (joint.body_j, joint.body_i) if reversed_ else (joint.body_i, joint.body_j)
        tree.append(TreeJoint(joint, parent, child, reversed_))
        placed.add(child)
    for joint in closing:
        if joint.name in driven:
            raise Unrepresentable("drive", f"the drive or torque law at joint {joint.name!r} closes a loop: "
                                           "OpenSim drives only a tree coordinate")
        if joint.kind == "prismatic":
            raise Unrepresentable("joint", f"the slide {joint.name!r} closes a loop that no pin can close: "
                                           "the adapter closes loops with point constraints at pins")
    unplaced = {b.name for b in mechanism.bodies} - placed
    if unplaced:
        raise Unrepresentable("joint", f"body {sorted(unplaced)[0]!r} is not connected to the ground")
    return tree, closing


def vec3(x: float, y: float, z: float = 0.0) -> osim.Vec3:
    return osim.Vec3(float(x), float(y), float(z))


def build_model(mechanism: Mechanism, closure: str = "point") -> OpensimModel:
    """The model with nothing but the scene's bodies, joints, drives,
    gravity and force elements (no muscles, no joint limits, no contact).
    `closure` "pin" closes each loop with a further `PinJoint` instead
    (OpenSim's automatic loop breaking): only the finding's probe asks
    for it (`findings`)."""
    built = OpensimModel(osim.Model())
    model = built.model
    model.setName("mechval")
    model.setGravity(vec3(*mechanism.gravity))
    for k, body in enumerate(mechanism.bodies):
        # Ixx = Iyy = izz: any valid inertia will do out of the plane, where
        # the pins and slides leave no freedom.
        b = osim.Body(f"b{k}", body.mass, vec3(*body.com), osim.Inertia(body.izz, body.izz, body.izz))
        model.addBody(b)
        built.bodies[body.name] = b
    tree, closing = spanning_tree(mechanism)
    for k, tj in enumerate(tree):
        _add_tree_joint(built, mechanism, tj, f"j{k}")
    for k, joint in enumerate(closing):
        if closure == "pin":
            pin = osim.PinJoint(f"c{k}", _frame(built, model, joint.body_i), vec3(*joint.point_i), vec3(0, 0, 0),
                                _frame(built, model, joint.body_j), vec3(*joint.point_j), vec3(0, 0, 0))
            model.addJoint(pin)
            built.loop_pins[joint.name] = pin
            continue
        constraint = osim.PointConstraint(_frame(built, model, joint.body_i), vec3(*joint.point_i),
                                          _frame(built, model, joint.body_j), vec3(*joint.point_j))
        constraint.setName(f"c{k}")
        model.addConstraint(constraint)
        built.closures[joint.name] = constraint
    for drive in mechanism.drives:
        _prescribe(built, drive)
    for k, joint in enumerate(mechanism.damped_joints):
        _add_damper(built, model, joint, f"d{k}")
    for k, law in enumerate(mechanism.torque_drives):
        _add_torque_law(built, model, law, f"a{k}")
    for k, force in enumerate(mechanism.forces):
        if isinstance(force, SpringDamper):
            _add_spring(built, model, force, f"s{k}")
        else:
            _add_body_torque(built, model, force, f"t{k}")
    return built


def _frame(built: OpensimModel, model: osim.Model, body: str) -> osim.PhysicalFrame:
    return model.getGround() if body == GROUND else built.bodies[body]


def _point_and_angle(tj: TreeJoint, side: str) -> tuple[tuple[float, float], float]:
    """A tree joint's offset frame on its parent or child: the joint point
    and, for a slide, the axis angle in that body (body_j's frame holds the
    axis turned back by the held angle)."""
    joint = tj.joint
    body = tj.parent if side == "parent" else tj.child
    on_i = body == joint.body_i
    point = joint.point_i if on_i else joint.point_j
    if joint.kind == "revolute":
        return point, 0.0
    axis = math.atan2(joint.axis[1], joint.axis[0])
    return point, axis if on_i else axis - joint.held_angle


def _add_tree_joint(built: OpensimModel, mechanism: Mechanism, tj: TreeJoint, name: str) -> None:
    model = built.model
    (pp, ap), (pc, ac) = _point_and_angle(tj, "parent"), _point_and_angle(tj, "child")
    kind = osim.PinJoint if tj.joint.kind == "revolute" else osim.SliderJoint
    joint = kind(name, _frame(built, model, tj.parent), vec3(*pp), vec3(0, 0, ap),
                 _frame(built, model, tj.child), vec3(*pc), vec3(0, 0, ac))
    coordinate = joint.upd_coordinates(0)
    coordinate.setName(f"{name}_q")
    coordinate.setDefaultClamped(False)     # a crank turns many times: no range applies
    model.addJoint(joint)
    built.tree[tj.joint.name] = tj
    built.joints[tj.joint.name] = joint


def drive_function(law, sign: float) -> osim.PolynomialFunction:
    """sign·φ(t) as OpenSim's polynomial (highest power first)."""
    return osim.PolynomialFunction(osim.Vector([sign * 0.5 * law.alpha, sign * law.omega0, sign * law.phi0]))


def _prescribe(built: OpensimModel, drive: Drive) -> None:
    coordinate = built.coordinate(drive.joint)
    coordinate.setPrescribedFunction(drive_function(drive.law, built.tree[drive.joint].sign))
    coordinate.setDefaultIsPrescribed(True)


def _add_damper(built: OpensimModel, model: osim.Model, joint: Joint, name: str) -> None:
    """A viscous damper on the joint's relative rate: on a tree joint's
    coordinate (the sign of a reversed coordinate drops out of −c·q̇·δq);
    at a loop-closing pin, a bushing with rotational damping alone."""
    if joint.name in built.tree:
        damper = osim.SpringGeneralizedForce(built.coordinate(joint.name).getName())
        damper.setStiffness(0.0)
        damper.setViscosity(joint.damping)
    else:
        # Translational and rotational stiffness 0, translational damping
        # 0, rotational damping c about z (the constructor's order).
        damper = osim.BushingForce(name, _frame(built, model, joint.body_i), osim.Transform(vec3(*joint.point_i)),
                                   _frame(built, model, joint.body_j), osim.Transform(vec3(*joint.point_j)),
                                   vec3(0, 0, 0), vec3(0, 0, 0), vec3(0, 0, 0), vec3(0, 0, joint.damping))
    damper.setName(name)
    model.addForce(damper)
    built.forces[joint.name] = damper


def torque_function(law: TorqueLaw, sign: float) -> osim.Sine:
    """sign·T(t), OpenSim's Sine: amplitude·sin(ω·t + phase) + offset."""
    return osim.Sine(sign * law.amplitude, 2 * math.pi * law.frequency, law.phase, sign * law.torque)


def _add_torque_law(built: OpensimModel, model: osim.Model, law: TorqueLaw, name: str) -> None:
    """A CoordinateActuator of optimal force 1 N·m whose control a
    PrescribedController sets to the law: its actuation is T on body_j."""
    actuator = osim.CoordinateActuator(built.coordinate(law.joint).getName())
    actuator.setName(name)
    actuator.setOptimalForce(1.0)
    actuator.setMinControl(-math.inf)
    actuator.setMaxControl(math.inf)
    model.addForce(actuator)
    controller = osim.PrescribedController()
    controller.setName(f"{name}_control")
    controller.addActuator(actuator)
    controller.prescribeControlForActuator(name, torque_function(law, built.tree[law.joint].sign))
    model.addController(controller)
    built.actuators[law.name] = actuator


def spring_expression(spring: SpringDamper) -> str:
    """Tension k·(d − ℓ0) + c·ḋ in Lepton's syntax (floats to 17 digits).
    OpenSim's force pulls the points together when positive (the tests'
    static check)."""
    k, l0, c = (f"{v:.17g}" for v in (spring.stiffness, spring.free_length, spring.damping))
    return f"{k}*(d-({l0}))+{c}*ddot"


def _add_spring(built: OpensimModel, model: osim.Model, spring: SpringDamper, name: str) -> None:
    force = osim.ExpressionBasedPointToPointForce()
    force.setName(name)
    force.set_body1(_frame(built, model, spring.body_a).getName())
    force.set_point1(vec3(*spring.point_a))
    force.set_body2(_frame(built, model, spring.body_b).getName())
    force.set_point2(vec3(*spring.point_b))
    force.setExpression(spring_expression(spring))
    model.addForce(force)
    built.forces[spring.name] = force


def _add_body_torque(built: OpensimModel, model: osim.Model, torque: BodyTorque, name: str) -> None:
    force = osim.PrescribedForce(name, built.bodies[torque.body])
    force.setForceIsInGlobalFrame(True)
    force.setTorqueFunctions(osim.Constant(0.0), osim.Constant(0.0), osim.Constant(float(torque.torque)))
    model.addForce(force)
    built.forces[torque.name] = force
