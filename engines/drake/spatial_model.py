"""A `SpatialSystem` as a Drake 1.51 MultibodyPlant: discrete with the SAP
solver, or continuous (settings' `integrator` "rk3": no constraints, no
PD drives) (docs/engines.md, "Drake: spatial scenes").

- Every body a `RigidBody` whose frame is the scene's body frame: mass,
  centre of mass and the full inertia tensor about it (body axes). Names
  are generated ("b0", "j0", …): no user string reaches Drake.
- Tree joints (`spatial_tree`) between a frame F on the parent and M on
  the child, each at the joint's point with the joint's frame, so z is
  the joint axis: revolute → `RevoluteJoint` about z (its angle is the
  scene's, from xi to xj, for a child body_j), prismatic →
  `PrismaticJoint` along z, spherical → `BallRpyJoint` (its child frame
  the parent's at the start: zero angles there), universal →
  `UniversalJoint` (Drake's pins are Fx and My: F's x is the parent's
  pin, M's y the child's), planar → `PlanarJoint`, fixed → `WeldJoint`,
  cylindrical → a `PrismaticJoint` along z to a massless body and a
  `RevoluteJoint` about z from it (Drake has no cylindrical joint). A
  body no joint reaches floats on Drake's `QuaternionFloatingJoint`.
  No limits, Drake's joint damping only where the scene has a damper.
- Each loop's cut joint closed by constraints between its two moving
  bodies: spherical → `AddBallConstraint` at the point; revolute → two
  ball constraints, at the point and one `lever` along the axis;
  universal → a ball constraint and `AddDistanceConstraint` holding the
  pins' ends, one `lever` out along each, √2·lever apart (zi ⊥ zj);
  fixed → `AddWeldConstraint` of the joint frames.
- Prescribed drives as in the planar model (`model.desired_states`): a
  PD-controlled `JointActuator`, Kp = drive_stiffness·m/dt², m the drive
  coordinate's own mass-matrix entry at the start (`coordinate_inertia`).
- Springs are `LinearSpringDamper`s; body loads and joint torque laws are
  spatial forces (`SceneLoads`, evaluated at each step's start, as SAP
  takes every non-constraint force).
- Gravity as the scene's, nothing else: no geometry, hence no contact.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import DiscreteContactApproximation, ExternallyAppliedSpatialForce_, MultibodyPlant
from pydrake.multibody.tree import (BallRpyJoint, FixedOffsetFrame, LinearSpringDamper, PdControllerGains,
                                    PlanarJoint, PrismaticJoint, RevoluteJoint, RotationalInertia, SpatialInertia,
                                    UniversalJoint, UnitInertia, WeldJoint)
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from mechval.model.mechanism import GROUND
from mechval.reference.spatial.system import SpatialJoint, SpatialSystem

from mechval.engines.base import Unrepresentable
from mechval.engines.drake.spatial_tree import SpatialTopology, TreeJoint

Z = np.array([0.0, 0.0, 1.0])
#: Drake's universal joint turns about Fx then My: F's x and M's y are the
#: pins (the joint frames' z), by a cyclic turn of the axes.
PIN_AS_X = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])     # columns z, x, y
PIN_AS_Y = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])     # columns y, z, x


@dataclass
class SpatialModel:
    system: SpatialSystem
    plant: MultibodyPlant
    diagram: Any
    topo: SpatialTopology
    bodies: Mapping[str, Any]            # scene body → RigidBody (the ground: the world body)
    #: tree joint name → its Drake joints (two for a cylindrical joint,
    #: the last one's child is the tree child)
    joints: Mapping[str, tuple]
    actuators: tuple
    gains: tuple
    dt: float
    #: per ball constraint (id, body_i, point on it, body_j, point on it)
    balls: tuple = ()
    desired: Any = None                  # kept alive: TrajectorySource holds a reference only


def side(j: SpatialJoint, body_i_side: bool) -> tuple[str, np.ndarray, np.ndarray]:
    """(body, point, frame) of one side of a joint."""
    if body_i_side:
        return j.body_i, np.asarray(j.point_i, float), np.asarray(j.frame_i, float)
    return j.body_j, np.asarray(j.point_j, float), np.asarray(j.frame_j, float)


def joint_frames(tj: TreeJoint, start: Mapping[str, np.ndarray]) -> tuple[tuple, tuple]:
    """(body, point, frame) of the parent's and the child's side, the
    frames turned as Drake's joint of that kind reads them. A spherical
    joint has no axis: its child frame is the parent's at the start
    (`start`: the reference's raw columns), so that BallRpyJoint starts
    at zero angles, as far as it can be from its singular pitch of ±90°."""
    parent, child = side(tj.joint, tj.sign > 0), side(tj.joint, tj.sign < 0)
    if tj.joint.kind == "universal":
        parent = (parent[0], parent[1], parent[2] @ PIN_AS_X)
        child = (child[0], child[1], child[2] @ PIN_AS_Y)
    elif tj.joint.kind == "spherical":
        (_, Rp), (_, Rc) = world_pose(start, parent[0]), world_pose(start, child[0])
        child = (child[0], child[1], Rc.T @ Rp @ parent[2])
    return parent, child


def build(system: SpatialSystem, topo: SpatialTopology, settings: Mapping[str, Any], t0: float, t_end: float,
          start: Mapping[str, np.ndarray], lever: float) -> SpatialModel:
    """The plant and its diagram for a run from t0 to t_end; `start` (the
    reference's raw columns at t0) is the pose the drive gains are taken
    at; `lever` (m) the arm of the constraints that hold an axis."""
    dt = float(settings["timestep"]) / int(settings["refine"])
    builder = DiagramBuilder()
    continuous = settings.get("integrator", "sap") != "sap"
    plant = builder.AddSystem(MultibodyPlant(time_step=0.0 if continuous else dt))
    if not continuous:
        plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
        plant.set_sap_near_rigid_threshold(float(settings["near_rigid_threshold"]))
    plant.SetUseSampledOutputPorts(False)      # the step from t_n read at x_n (adapter docstring)
    instance = plant.AddModelInstance("mechval")
    plant.mutable_gravity_field().set_gravity_vector(list(system.gravity))
    bodies: dict[str, Any] = {GROUND: plant.world_body()}
    for k, b in enumerate(system.bodies):
        I = np.asarray(b.inertia, float)
        inertia = RotationalInertia(I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2])
        bodies[b.name] = plant.AddRigidBody(f"b{k}", instance,
                                            SpatialInertia.MakeFromCentralInertia(b.mass, list(b.com), inertia))
    index = {j.name: k for k, j in enumerate(system.joints)}

    def frame(body: str, point, rotation, name: str):
        pose = RigidTransform(RotationMatrix(rotation), point)
        return plant.AddFrame(FixedOffsetFrame(name, bodies[body].body_frame(), pose))

    joints = {}
    for tj in topo.tree:
        j, name = tj.joint, f"j{index[tj.joint.name]}"
        if j.damping and j.kind not in ("revolute", "prismatic"):
            raise Unrepresentable(f"joint.{j.name}.damping", f"damping on a {j.kind} joint has no axis to act on")
        (pb, pp, pf), (cb, cp, cf) = joint_frames(tj, start)
        F, M = frame(pb, pp, pf, f"{name}p"), frame(cb, cp, cf, f"{name}c")
        if j.kind == "revolute":
            joints[j.name] = (plant.AddJoint(RevoluteJoint(name, F, M, Z, j.damping)),)
        elif j.kind == "prismatic":
            joints[j.name] = (plant.AddJoint(PrismaticJoint(name, F, M, Z, -np.inf, np.inf, j.damping)),)
        elif j.kind == "spherical":
            joints[j.name] = (plant.AddJoint(BallRpyJoint(name, F, M)),)
        elif j.kind == "universal":
            joints[j.name] = (plant.AddJoint(UniversalJoint(name, F, M)),)
        elif j.kind == "planar":
            joints[j.name] = (plant.AddJoint(PlanarJoint(name, F, M)),)
        elif j.kind == "fixed":
            joints[j.name] = (plant.AddJoint(WeldJoint(name, F, M, RigidTransform())),)
        else:                                    # cylindrical: slide, then turn, through a massless body
            between = plant.AddRigidBody(f"{name}m", instance, SpatialInertia(0.0, np.zeros(3), UnitInertia(0, 0, 0)))
            joints[j.name] = (
                plant.AddJoint(PrismaticJoint(f"{name}s", F, between.body_frame(), Z, -np.inf, np.inf)),
                plant.AddJoint(RevoluteJoint(f"{name}r", between.body_frame(), M, Z)))
    for s in system.springs:
        plant.AddForceElement(LinearSpringDamper(bodies[s.body_a], list(s.point_a), bodies[s.body_b],
                                                 list(s.point_b), s.free_length, s.stiffness, s.damping))
    balls = [ball for c in topo.cuts for ball in close_loop(plant, bodies, c, lever)]
    actuators = tuple(plant.AddJointActuator(f"d{k}", joints[d.joint][0], np.inf) for k, d in enumerate(system.drives))
    gains = tuple(drive_gains(system, topo, settings, start, dt))
    for actuator, (kp, kd) in zip(actuators, gains):
        actuator.set_controller_gains(PdControllerGains(p=kp, d=kd))    # before Finalize (`model`)
    plant.Finalize()
    desired = None
    if actuators:
        desired = desired_states(system, topo, t0, t_end, dt)
        source = builder.AddSystem(TrajectorySource(desired))
        builder.Connect(source.get_output_port(), plant.get_desired_state_input_port(instance))
        feed_forward = builder.AddSystem(ConstantVectorSource(np.zeros(len(actuators))))
        builder.Connect(feed_forward.get_output_port(), plant.get_actuation_input_port(instance))
    if system.loads or system.torques:
        loads = builder.AddSystem(SceneLoads(system, bodies, t0))
        builder.Connect(plant.get_body_poses_output_port(), loads.get_input_port())
        builder.Connect(loads.get_output_port(), plant.get_applied_spatial_force_input_port())
    return SpatialModel(system, plant, builder.Build(), topo, bodies, joints, actuators, gains, dt, tuple(balls),
                        desired)


def close_loop(plant: MultibodyPlant, bodies: Mapping[str, Any], c: SpatialJoint, lever: float) -> list[tuple]:
    """The constraints of a cut joint (module docstring); its ball
    constraints as (id, body_i, point, body_j, point)."""
    bi, bj = bodies[c.body_i], bodies[c.body_j]
    pi, pj = np.asarray(c.point_i, float), np.asarray(c.point_j, float)
    zi, zj = np.asarray(c.frame_i, float)[:, 2], np.asarray(c.frame_j, float)[:, 2]
    if c.kind == "fixed":
        plant.AddWeldConstraint(bi, RigidTransform(RotationMatrix(np.asarray(c.frame_i, float)), pi),
                                bj, RigidTransform(RotationMatrix(np.asarray(c.frame_j, float)), pj))
        return []
    ball = lambda a, b: (plant.AddBallConstraint(bi, a, bj, b), bi, a, bj, b)
    balls = [ball(pi, pj)]
    if c.kind == "revolute":
        balls.append(ball(pi + lever * zi, pj + lever * zj))
    elif c.kind == "universal":
        plant.AddDistanceConstraint(bi, pi + lever * zi, bj, pj + lever * zj, np.sqrt(2.0) * lever)
    return balls


def drive_gains(system: SpatialSystem, topo: SpatialTopology, settings: Mapping[str, Any],
                start: Mapping[str, np.ndarray], dt: float) -> list[tuple[float, float]]:
    """Per drive (Kp, Kd) = (drive_stiffness·m/dt², drive_damping·m/dt), as
    the planar model's `drive_gains`."""
    out = []
    for d in system.drives:
        m = coordinate_inertia(system, topo, topo.of_joint(d.joint), start)
        out.append((float(settings["drive_stiffness"]) * m / dt ** 2, float(settings["drive_damping"]) * m / dt))
    return out


def world_pose(start: Mapping[str, np.ndarray], body: str) -> tuple[np.ndarray, np.ndarray]:
    """(origin, rotation) of a body from raw columns' first row."""
    from mechval.reference.spatial.rotation import quaternion_to_matrix
    if body == GROUND:
        return np.zeros(3), np.eye(3)
    p = np.array([float(start[f"{body}.{c}"][0]) for c in "xyz"])
    return p, quaternion_to_matrix(np.array([float(start[f"{body}.q{c}"][0]) for c in "wxyz"]))


def coordinate_inertia(system: SpatialSystem, topo: SpatialTopology, tj: TreeJoint,
                       start: Mapping[str, np.ndarray]) -> float:
    """The diagonal mass-matrix entry of a revolute or prismatic tree
    joint's coordinate (every other one held): the subtree's mass for a
    slide, its moment of inertia about the axis for a hinge."""
    below = {tj.child}
    for other in topo.tree:                     # parents come before children
        if other.parent in below:
            below.add(other.child)
    (pb, pp, pf), _ = joint_frames(tj, start)
    origin, R = world_pose(start, pb)
    point, axis = origin + R @ pp, R @ pf[:, 2]
    total = 0.0
    for b in system.bodies:
        if b.name not in below:
            continue
        if tj.joint.kind == "prismatic":
            total += b.mass
            continue
        o, A = world_pose(start, b.name)
        arm = o + A @ np.asarray(b.com, float) - point
        across = arm - (arm @ axis) * axis
        total += float(axis @ A @ np.asarray(b.inertia, float) @ A.T @ axis) + b.mass * float(across @ across)
    return total


def desired_states(system: SpatialSystem, topo: SpatialTopology, t0: float, t_end: float,
                   dt: float) -> PiecewisePolynomial:
    """The drives' desired states ahead of time, as `model.desired_states`
    (q_d = φ(t_n + dt), v_d = (φ(t_n + dt) − φ(t_n))/dt at t_n), each
    signed by its tree joint's orientation."""
    n = int(np.ceil((t_end - t0) / dt - 1e-9)) + 2
    clock = dt * np.arange(n)
    sign = [topo.of_joint(d.joint).sign for d in system.drives]
    ahead = [s * d.law.angle(t0 + clock + dt) for s, d in zip(sign, system.drives)]
    now = [s * d.law.angle(t0 + clock) for s, d in zip(sign, system.drives)]
    rates = [(a - b) / dt for a, b in zip(ahead, now)]
    return PiecewisePolynomial.FirstOrderHold(clock, np.array(ahead + rates))


def scene_loads(system: SpatialSystem, t: float, rotation) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(force at the centre of mass, torque), world axes, per moving body:
    the body loads and the joint torque laws at time t (T·zi on body_j,
    −T·zi on body_i); `rotation(body)` is a body's rotation matrix."""
    out = {b.name: (np.zeros(3), np.zeros(3)) for b in system.bodies}
    for load in system.loads:
        force, torque = out[load.body]
        out[load.body] = (force + np.asarray(load.force, float), torque + np.asarray(load.torque, float))
    for law in system.torques:
        j = system.joint(law.joint)
        axis = rotation(j.body_i) @ np.asarray(j.frame_i, float)[:, 2]
        value = float(np.asarray(law.law.value(np.array([t])), float).ravel()[0])
        for body, sign in ((j.body_j, 1.0), (j.body_i, -1.0)):
            if body != GROUND:
                out[body] = (out[body][0], out[body][1] + sign * value * axis)
    return out


class SceneLoads(LeafSystem):
    """`scene_loads` as Drake's applied spatial forces. Input: the plant's
    body poses; output: a list of ExternallyAppliedSpatialForce."""

    def __init__(self, system: SpatialSystem, bodies: Mapping[str, Any], t0: float):
        super().__init__()
        self.system, self.bodies, self.t0 = system, bodies, t0
        self.DeclareAbstractInputPort("poses", AbstractValue.Make([RigidTransform()]))
        self.DeclareAbstractOutputPort("forces", lambda: AbstractValue.Make([ExternallyAppliedSpatialForce_[float]()]),
                                       self.calc)

    def calc(self, context, output) -> None:
        poses = self.get_input_port().Eval(context)
        rotation = lambda body: np.eye(3) if body == GROUND else \
            poses[int(self.bodies[body].index())].rotation().matrix()
        forces, loads = [], scene_loads(self.system, self.t0 + context.get_time(), rotation)
        for b in self.system.bodies:
            force, torque = loads[b.name]
            if not (force.any() or torque.any()):
                continue
            f = ExternallyAppliedSpatialForce_[float]()
            f.body_index = self.bodies[b.name].index()
            f.p_BoBq_B = np.asarray(b.com, float)
            f.F_Bq_W = SpatialForce(torque, force)
            forces.append(f)
        output.set_value(forces)
