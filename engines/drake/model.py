"""A generic planar `Mechanism` as a discrete Drake 1.51 MultibodyPlant
(docs/engines.md, Drake).

- A discrete plant (time_step = dt) with the SAP solver: Drake refuses
  constraints in continuous mode, and SAP is the discrete approximation
  that takes a ball constraint and a PD-controlled actuator implicitly.
- Every moving body a `RigidBody` whose frame is the mechanism's body frame
  (mass, centre of mass, izz; ixx = iyy = izz/2 keep the tensor valid and
  never act: nothing turns about x or y). Names are generated ("b0", "j0",
  …): no user string reaches Drake.
- The spanning tree (`topology`) as `RevoluteJoint`s about z and
  `PrismaticJoint`s along the in-plane axis, each between a frame at the
  parent's joint point and one at the child's, so a hinge coordinate is
  θchild − θparent and a slide coordinate the travel along the axis. No
  limits (±∞), Drake's joint damping only where the scene has a damper.
- Each loop closed at its cut pin by `AddBallConstraint` (its z row is
  redundant in the plane, which SAP's regularisation absorbs).
- Each prescribed drive a `JointActuator` with PD gains (Drake's
  PD-controlled actuator, implicit in SAP: u = −Kp(q_{n+1} − q_d) −
  Kd(v_{n+1} − v_d), q_{n+1} = q_n + dt·v_{n+1}), no effort limit, no
  rotor inertia or gear ratio. Its desired state is fed ahead of time: the
  step from t_n reads its inputs at t_n, so a source holds (φ(t+dt),
  φ̇(t+dt)) at t (`desired_states`). Kp = drive_stiffness·m/dt² with m the
  drive coordinate's own mass-matrix entry at the start, Kd =
  drive_damping·m/dt: the drive lags by about T/Kp (docs/engines.md).
- Spring-dampers are Drake's `LinearSpringDamper`; body torques, torque
  laws and the dampers of cut pins are spatial forces applied by
  `AppliedForces` (evaluated at the start of each step, as SAP takes every
  non-constraint force), so that Drake's reaction forces see them.
- Gravity (gx, gy, 0), nothing else: no geometry, hence no contact.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import (DiscreteContactApproximation, ExternallyAppliedSpatialForce_, MultibodyPlant)
from pydrake.multibody.tree import (FixedOffsetFrame, LinearSpringDamper, PdControllerGains, PrismaticJoint,
                                    RevoluteJoint, RotationalInertia, SpatialInertia)
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from mechval.model.kinematics import point_position
from mechval.model.mechanism import GROUND, BodyTorque, Mechanism, SpringDamper

from mechval.engines.drake.topology import Topology

Z = np.array([0.0, 0.0, 1.0])


@dataclass
class DrakeModel:
    """The built diagram and what the read-out needs of it."""

    plant: MultibodyPlant
    diagram: Any
    topo: Topology
    bodies: Mapping[str, Any]            # mechanism body → RigidBody (the ground: the world body)
    joints: Mapping[str, Any]            # tree joint name → Drake joint
    actuators: tuple                     # per drive its JointActuator
    constraints: tuple                   # per cut its ball constraint id
    springs: tuple                       # per spring-damper its LinearSpringDamper
    gains: tuple                         # per drive (Kp, Kd)
    dt: float
    #: The drives' desired states; kept here because pydrake's
    #: TrajectorySource holds only a reference to it (a freed trajectory
    #: crashes the next step).
    desired: Any = None


def build(mech: Mechanism, topo: Topology, settings: Mapping[str, Any], t0: float, t_end: float,
          start_motion: Mapping[str, np.ndarray]) -> DrakeModel:
    """The plant and its diagram for a run from t0 to t_end; `start_motion`
    (the reference's raw columns at t0) is the pose the drive gains are
    taken at."""
    dt = float(settings["timestep"]) / int(settings["refine"])
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultibodyPlant(time_step=dt))
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    plant.set_sap_near_rigid_threshold(float(settings["near_rigid_threshold"]))
    # Live output ports: the accelerations, reactions and actuation they
    # give at x_n are those of the step from t_n (positions q_n), the forces
    # at t_n; sampled ones (Drake's default) give the previous step's, the
    # forces at t_{n−1} (docs/engines.md, Drake).
    plant.SetUseSampledOutputPorts(False)
    instance = plant.AddModelInstance("mechval")
    gx, gy = mech.gravity
    plant.mutable_gravity_field().set_gravity_vector([gx, gy, 0.0])

    bodies: dict[str, Any] = {GROUND: plant.world_body()}
    for k, b in enumerate(mech.bodies):
        inertia = SpatialInertia.MakeFromCentralInertia(
            b.mass, [b.com[0], b.com[1], 0.0], RotationalInertia(b.izz / 2, b.izz / 2, b.izz))
        bodies[b.name] = plant.AddRigidBody(f"b{k}", instance, inertia)
    index = {j.name: k for k, j in enumerate(mech.joints)}

    def frame(body: str, point, angle: float, name: str):
        pose = RigidTransform(RotationMatrix.MakeZRotation(angle), [point[0], point[1], 0.0])
        return plant.AddFrame(FixedOffsetFrame(name, bodies[body].body_frame(), pose))

    joints = {}
    for tj in topo.tree:
        j, name = tj.joint, f"j{index[tj.joint.name]}"
        if j.kind == "revolute":
            parent_point = j.point_i if tj.sign > 0 else j.point_j
            child_point = j.point_j if tj.sign > 0 else j.point_i
            jp, jc = frame(tj.parent, parent_point, 0.0, f"{name}p"), frame(tj.child, child_point, 0.0, f"{name}c")
            joints[j.name] = plant.AddJoint(RevoluteJoint(name, jp, jc, Z, j.damping))
        else:
            # Both frames take body_i's orientation (body_j's turned by
            # −held angle), so the joint keeps the pair's relative rotation
            # and the axis is the same vector in both.
            held = j.held_angle
            fi, fj = (j.body_i, j.point_i, 0.0), (j.body_j, j.point_j, -held)
            (pb, pp, pa), (cb, cp, ca) = (fi, fj) if tj.sign > 0 else (fj, fi)
            jp, jc = frame(pb, pp, pa, f"{name}p"), frame(cb, cp, ca, f"{name}c")
            joints[j.name] = plant.AddJoint(PrismaticJoint(name, jp, jc, [j.axis[0], j.axis[1], 0.0],
                                                           -np.inf, np.inf, j.damping))
    springs = []
    for force in mech.forces:
        if isinstance(force, SpringDamper):
            springs.append(plant.AddForceElement(LinearSpringDamper(
                bodies[force.body_a], [*force.point_a, 0.0], bodies[force.body_b], [*force.point_b, 0.0],
                force.free_length, force.stiffness, force.damping)))
    constraints = tuple(plant.AddBallConstraint(bodies[c.body_i], [*c.point_i, 0.0], bodies[c.body_j],
                                                [*c.point_j, 0.0]) for c in topo.cuts)
    actuators = []
    for k, drive in enumerate(mech.drives):
        actuators.append(plant.AddJointActuator(f"d{k}", joints[drive.joint], np.inf))
    gains = drive_gains(mech, topo, settings, start_motion, dt)
    for actuator, (kp, kd) in zip(actuators, gains):
        # Before Finalize: the discrete solver sizes its PD constraints then.
        actuator.set_controller_gains(PdControllerGains(p=kp, d=kd))
    plant.Finalize()
    if actuators:
        desired = desired_states(mech, topo, t0, t_end, dt)
        source = builder.AddSystem(TrajectorySource(desired))
        builder.Connect(source.get_output_port(), plant.get_desired_state_input_port(instance))
        feed_forward = builder.AddSystem(ConstantVectorSource(np.zeros(len(actuators))))
        builder.Connect(feed_forward.get_output_port(), plant.get_actuation_input_port(instance))
    if mech.torque_drives or any(isinstance(f, BodyTorque) for f in mech.forces) or \
            any(c.damping for c in topo.cuts):
        applied = builder.AddSystem(AppliedForces(mech, topo, plant, bodies, joints, t0))
        builder.Connect(plant.get_state_output_port(), applied.get_input_port())
        builder.Connect(applied.get_output_port(), plant.get_applied_spatial_force_input_port())
    diagram = builder.Build()
    return DrakeModel(plant, diagram, topo, bodies, joints, tuple(actuators), constraints, tuple(springs),
                      tuple(gains), dt, desired if actuators else None)


def drive_gains(mech: Mechanism, topo: Topology, settings: Mapping[str, Any], start_motion: Mapping[str, np.ndarray],
                dt: float) -> list[tuple[float, float]]:
    """Per drive (Kp, Kd): drive_stiffness·m/dt² and drive_damping·m/dt,
    m the drive coordinate's own entry of the mass matrix at the start pose
    (`coordinate_inertia`): the gains scale with what the drive moves and
    with the step, so the lag T/Kp is the same fraction of one step's
    motion in every scene (docs/engines.md)."""
    out = []
    for drive in mech.drives:
        m = coordinate_inertia(mech, topo, topo.of_joint(drive.joint), start_motion)
        out.append((float(settings["drive_stiffness"]) * m / dt ** 2, float(settings["drive_damping"]) * m / dt))
    return out


def coordinate_inertia(mech: Mechanism, topo: Topology, tj, motion: Mapping[str, np.ndarray]) -> float:
    """The diagonal mass-matrix entry of a tree joint's coordinate (every
    other coordinate held): the subtree's mass for a slide, its inertia
    about the pin, Σ izz + m·|G − P|², for a hinge (kg or kg·m²)."""
    below, total = {tj.child}, 0.0
    for other in topo.tree:                     # parents come before children
        if other.parent in below:
            below.add(other.child)
    point = tj.joint.point_i if tj.sign > 0 else tj.joint.point_j
    px, py = (point_position(motion, tj.parent, point)[q] for q in ("x", "y"))
    for b in mech.bodies:
        if b.name in below:
            if tj.joint.kind == "prismatic":
                total += b.mass
                continue
            g = point_position(motion, b.name, b.com)
            total += b.izz + b.mass * float((g["x"][0] - px[0]) ** 2 + (g["y"][0] - py[0]) ** 2)
    return total


def set_position(joint, context, q: float) -> None:
    (joint.set_angle if joint.type_name() == "revolute" else joint.set_translation)(context, q)


def set_rate(joint, context, v: float) -> None:
    (joint.set_angular_rate if joint.type_name() == "revolute" else joint.set_translation_rate)(context, v)


def desired_states(mech: Mechanism, topo: Topology, t0: float, t_end: float, dt: float) -> PiecewisePolynomial:
    """The desired state of every drive as a source of Drake's time (0 at
    t0): at a step's start t_n it holds where the step must end, q_d =
    φ(t_n + dt), and the velocity that takes it there, v_d = (φ(t_n + dt) −
    φ(t_n))/dt: Drake's step sets q_{n+1} = q_n + dt·v_{n+1}, so v_{n+1} is
    the mean rate over the step, and a v_d of φ̇(t_n + dt) would pull
    against q_d (a lag of φ̈·dt/4 each step). Knots at every step, linear
    between: exact at every instant a step reads it."""
    n = int(np.ceil((t_end - t0) / dt - 1e-9)) + 2
    clock = dt * np.arange(n)                 # Drake's time: 0 at t0 (`run`)
    sign = [topo.of_joint(d.joint).sign for d in mech.drives]
    ahead = [s * d.law.angle(t0 + clock + dt) for s, d in zip(sign, mech.drives)]
    now = [s * d.law.angle(t0 + clock) for s, d in zip(sign, mech.drives)]
    rates = [(a - b) / dt for a, b in zip(ahead, now)]
    return PiecewisePolynomial.FirstOrderHold(clock, np.array(ahead + rates))


class AppliedForces(LeafSystem):
    """The spatial forces Drake applies that are not its own elements:
    each body torque, each torque law (T on body_j, −T on body_i, its law
    at the step's start time), each cut pin's damper (−c·(ω_j − ω_i) on
    body_j, the opposite on body_i, from the step's start state: a body's
    ω is the sum of the hinge rates on its tree path, `cut_rates`). Input:
    the plant's state; output: a list of ExternallyAppliedSpatialForce."""

    def __init__(self, mech: Mechanism, topo: Topology, plant: MultibodyPlant, bodies: Mapping[str, Any],
                 joints: Mapping[str, Any], t0: float):
        super().__init__()
        self.mech, self.t0 = mech, t0
        self.moving = [b.name for b in mech.bodies]
        self.index = {name: bodies[name].index() for name in self.moving}
        self.nq = plant.num_positions()
        self.constant = dict.fromkeys(self.moving, 0.0)
        for force in mech.forces:
            if isinstance(force, BodyTorque):
                self.constant[force.body] += force.torque
        self.cuts = [c for c in topo.cuts if c.damping]
        self.cut_rates = np.zeros((len(self.cuts), plant.num_velocities()))
        for k, cut in enumerate(self.cuts):
            for name, coef in topo.angle_coefficients(cut).items():
                self.cut_rates[k, joints[name].velocity_start()] += coef
        self.DeclareVectorInputPort("state", plant.num_multibody_states())
        self.DeclareAbstractOutputPort("forces", lambda: AbstractValue.Make([ExternallyAppliedSpatialForce_[float]()]),
                                       self.calc)

    def torques(self, t: float, velocities: np.ndarray | None) -> dict[str, float]:
        """z torque per moving body at time t (velocities: the plant's, for
        cut dampers)."""
        out = dict(self.constant)
        add = lambda body, tau: out.__setitem__(body, out[body] + tau) if body != GROUND else None
        for law in self.mech.torque_drives:
            joint, value = self.mech.joint(law.joint), float(law.value(t))
            add(joint.body_j, value)
            add(joint.body_i, -value)
        if self.cuts:
            for cut, rate in zip(self.cuts, self.cut_rates @ velocities):
                add(cut.body_j, -cut.damping * rate)
                add(cut.body_i, cut.damping * rate)
        return out

    def calc(self, context, output) -> None:
        velocities = self.get_input_port().Eval(context)[self.nq:] if self.cuts else None
        forces = []
        for body, tau in self.torques(self.t0 + context.get_time(), velocities).items():
            if tau == 0.0:
                continue
            f = ExternallyAppliedSpatialForce_[float]()
            f.body_index = self.index[body]
            f.p_BoBq_B = np.zeros(3)
            f.F_Bq_W = SpatialForce([0.0, 0.0, tau], [0.0, 0.0, 0.0])
            forces.append(f)
        output.set_value(forces)
