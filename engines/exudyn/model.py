"""Build the planar Exudyn model of a generic `Mechanism` (Exudyn 1.13.6).

One `NodeRigidBody2D` at each body's centre of mass with an
`ObjectRigidBody2D`; each revolute joint an `ObjectJointRevolute2D` between
`MarkerBodyPosition`s at the joint points, each prismatic joint an
`ObjectJointPrismatic2D(constrainRotation=True)` between `MarkerBodyRigid`s
(it needs the bodies' orientation). The drive is an
`ObjectConnectorCoordinate` on the relative rotation of the drive joint's
bodies with both offset user functions (index-3 uses the offset, index-2 its
time derivative; without `offsetUserFunction_t` index-2 silently holds the
crank still — docs/engines.md). Only the scene's effects are added: gravity as
`LoadMassProportional` when the scene has gravity, and a zero-stiffness
`ObjectConnectorCoordinateSpringDamper` per damped joint (on the two
rotation coordinates, or on the relative translation along a guide, which
turns with body_i: `MarkerBodiesRelativeTranslationCoordinate`). A torque
law is a pair of `LoadTorqueVector`s, T(t) on body_j and −T(t) on body_i
(none on the ground), whose `loadVectorUserFunction` evaluates the law at
the solver's time: an applied torque, exact in time, not a servo. A degree
of freedom no drive prescribes gets no constraint at all.

Every reaction and every node state is recorded by a sensor kept in memory
(`storeInternal=True`, `writeToFile=False`); `simulation_settings` makes
them record every step and keeps Exudyn from writing files or printing.
Only this module imports the engine library, so importing the adapter
(the registry does, to read its metadata) does not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import exudyn as exu
import exudyn.itemInterface as eii
import numpy as np
import pandas as pd

from mechval.engines.base import reference_motion
from mechval.records.audit import force_item, torque_law_item
from mechval.model.kinematics import point_motion, rotate
from mechval.model.mechanism import GROUND, Body, BodyTorque, Drive, Joint, Mechanism, SpringDamper, TorqueLaw

#: The adapter's solver names (setting "solver") → Exudyn's solvers.
SOLVERS = {"index2": exu.DynamicSolverType.TrapezoidalIndex2, "index3": exu.DynamicSolverType.GeneralizedAlpha}
#: Node sensor outputs: position/rotation, their rates and accelerations.
NODE_OUTPUTS = {
    "q": exu.OutputVariableType.Coordinates,
    "v": exu.OutputVariableType.Coordinates_t,
    "a": exu.OutputVariableType.Coordinates_tt,
}


@dataclass
class ExudynModel:
    """An assembled Exudyn system and the sensor numbers to read back.

    `body_sensors[body][kind]` with kind in NODE_OUTPUTS record the node's
    displacement coordinates (of x_G, y_G, θ at the centre of mass) from
    `reference`, and their rates. `joint_sensors[joint]` records a revolute
    joint's `Force` (Fij, world axes) or a prismatic joint's `ForceLocal`
    (Fji in body_i's frame); `drive_sensors[drive]` records λ of each
    drive constraint.
    """

    system: exu.SystemContainer
    mbs: exu.MainSystem
    #: The state it starts from (`start_state`), raw motion columns.
    start: pd.DataFrame | None = None
    reference: dict[str, np.ndarray] = field(default_factory=dict)
    body_sensors: dict[str, dict[str, int]] = field(default_factory=dict)
    joint_sensors: dict[str, int] = field(default_factory=dict)
    #: Per drive (by its name, in `Mechanism.drives` order) the sensor of
    #: its constraint's λ.
    drive_sensors: dict[str, int] = field(default_factory=dict)
    #: Per torque law (by its name) the sensor of one of its loads and that
    #: load's sign (+1 on body_j, −1 on body_i): sign × its z component is
    #: the torque T(t) the solver applied.
    torque_sensors: dict[str, tuple[int, float]] = field(default_factory=dict)

    @property
    def drive_sensor(self) -> int:
        """The first drive's λ sensor."""
        return next(iter(self.drive_sensors.values()))

    @property
    def clock_sensor(self) -> int:
        """A sensor whose first column is the solver's time at every step
        (every sensor records every step; every mechanism has a body)."""
        return next(iter(next(iter(self.body_sensors.values())).values()))


def start_state(mechanism: Mechanism, t0: float) -> pd.DataFrame:
    """The reference state at t0 as raw motion columns (one row): the
    prescribed motion, or for a torque-driven or free mechanism (which
    starts at its first instant) the forward-dynamics reference's
    consistent initial state with its accelerations."""
    if mechanism.forward_dynamics:
        return reference_motion(mechanism, np.array([t0]))
    start = mechanism.motion(np.array([t0]))
    if not np.all(np.isfinite(start.to_numpy(dtype=float))):
        raise ValueError(f"exudyn: the reference cannot give a consistent state at the pre-roll start "
                         f"t = {t0!r} (the loop cannot close there); shorten the pre-roll")
    return start


def build_model(mechanism: Mechanism, t0: float, start: pd.DataFrame | None = None) -> ExudynModel:
    """The Exudyn model of `mechanism`, in the reference state at t0
    (`start`, raw motion columns of that one instant; by default
    `start_state`); the solver's time 0 is t0.

    Reference coordinates are the reference pose at t0 and initial
    velocities the reference velocities, so the start is consistent; the
    initial accelerations are the reference accelerations too, because
    Exudyn's own initial-acceleration solve ignores φ'' of the drive (the
    adapter switches that solve off unless told otherwise).
    """
    system = exu.SystemContainer()
    mbs = system.AddSystem()
    start = start_state(mechanism, t0) if start is None else start
    model = ExudynModel(system, mbs, start)

    ground = mbs.AddObject(eii.ObjectGround())
    ground_node = mbs.AddNode(eii.NodePointGround())
    ground_coordinate = mbs.AddMarker(eii.MarkerNodeCoordinate(nodeNumber=ground_node, coordinate=0))
    objects = {GROUND: ground}
    rotation = {GROUND: ground_coordinate}
    accelerations = []
    for body in mechanism.bodies:
        objects[body.name], rotation[body.name] = _add_body(model, mechanism, body, start, accelerations)

    for joint in mechanism.joints:
        model.joint_sensors[joint.name] = _add_joint(mbs, mechanism, joint, objects, start)
        if joint.damping:
            _add_damper(mbs, mechanism, joint, objects, rotation, ground_coordinate)
    for drive in mechanism.drives:
        model.drive_sensors[drive.name] = _add_drive(mbs, mechanism, drive, objects, rotation, ground_coordinate,
                                                     model.reference, t0)
    for force in mechanism.forces:
        if isinstance(force, SpringDamper):
            _add_spring(mbs, mechanism, force, objects)
        else:
            _add_torque(mbs, force, objects)
    for law in mechanism.torque_drives:
        model.torque_sensors[law.name] = _add_torque_law(mbs, mechanism, law, objects, t0)
    mbs.Assemble()
    # Bodies' nodes are the only ones with ODE2 coordinates, in this order.
    mbs.systemData.SetODE2Coordinates_tt(accelerations, configuration=exu.ConfigurationType.Initial)
    return model


def _add_body(model: ExudynModel, mechanism: Mechanism, body: Body, start: pd.DataFrame,
              accelerations: list[float]) -> tuple[int, int]:
    """Node, rigid body, state sensors and (if the scene has gravity) weight
    of one body, in the reference state `start`; appends the body's initial
    accelerations. Returns the body's object and rotation-coordinate marker."""
    mbs = model.mbs
    g = point_motion(start, body.name, body.com)
    q0 = np.array([g["x"][0], g["y"][0], start[f"{body.name}.theta"].iloc[0]], dtype=float)
    node = mbs.AddNode(eii.NodeRigidBody2D(
        referenceCoordinates=q0.tolist(), initialCoordinates=[0.0, 0.0, 0.0],
        initialVelocities=[float(g["vx"][0]), float(g["vy"][0]), float(start[f"{body.name}.omega"].iloc[0])]))
    accelerations += [float(g["ax"][0]), float(g["ay"][0]), float(start[f"{body.name}.alpha"].iloc[0])]
    number = mbs.AddObject(eii.ObjectRigidBody2D(nodeNumber=node, mass=body.mass, inertia=body.izz))
    model.reference[body.name] = q0
    model.body_sensors[body.name] = {
        kind: mbs.AddSensor(eii.SensorNode(nodeNumber=node, outputVariableType=output,
                                           storeInternal=True, writeToFile=False))
        for kind, output in NODE_OUTPUTS.items()}
    if mechanism.has_gravity:
        mass_marker = mbs.AddMarker(eii.MarkerBodyMass(bodyNumber=number))
        mbs.AddLoad(eii.LoadMassProportional(markerNumber=mass_marker, loadVector=[*mechanism.gravity, 0.0]))
    return number, mbs.AddMarker(eii.MarkerNodeCoordinate(nodeNumber=node, coordinate=2))


def _local(mechanism: Mechanism, body: str, point: tuple[float, float]) -> list[float]:
    """A body-frame point relative to the node (the centre of mass); the
    ground's points are world points."""
    if body == GROUND:
        return [point[0], point[1], 0.0]
    com = mechanism.body(body).com
    return [point[0] - com[0], point[1] - com[1], 0.0]


def _add_joint(mbs: exu.MainSystem, mechanism: Mechanism, joint: Joint, objects: dict[str, int],
               start: pd.DataFrame) -> int:
    """The joint and the sensor of its reaction. A revolute joint's markers
    are ordered [body_j, body_i] so that its `Force` (on the marker-0 body,
    world axes) is Fij directly. A prismatic joint needs the axis holder
    body_i as marker 0; its `ForceLocal` is Fji in body_i's frame (Exudyn
    1.13.6 has no `Force` output for it and reports no couple)."""
    marker_type = eii.MarkerBodyPosition if joint.kind == "revolute" else eii.MarkerBodyRigid
    marker_i = mbs.AddMarker(marker_type(bodyNumber=objects[joint.body_i],
                                         localPosition=_local(mechanism, joint.body_i, joint.point_i)))
    marker_j = mbs.AddMarker(marker_type(bodyNumber=objects[joint.body_j],
                                         localPosition=_local(mechanism, joint.body_j, joint.point_j)))
    if joint.kind == "revolute":
        output = exu.OutputVariableType.Force
        number = mbs.AddObject(eii.ObjectJointRevolute2D(markerNumbers=[marker_j, marker_i]))
    else:
        output = exu.OutputVariableType.ForceLocal
        # The normal in body_j's frame: the axis normal in body_i's frame
        # turned by the (constant) relative rotation θi − θj.
        relative = _angle(start, joint.body_i) - _angle(start, joint.body_j)
        nx, ny = rotate(np.float64(relative), (-joint.axis[1], joint.axis[0]))
        number = mbs.AddObject(eii.ObjectJointPrismatic2D(
            markerNumbers=[marker_i, marker_j], axisMarker0=[*joint.axis, 0.0],
            normalMarker1=[float(nx), float(ny), 0.0], constrainRotation=True))
    return mbs.AddSensor(eii.SensorObject(objectNumber=number, outputVariableType=output,
                                          storeInternal=True, writeToFile=False))


def _angle(start: pd.DataFrame, body: str) -> float:
    return 0.0 if body == GROUND else float(start[f"{body}.theta"].iloc[0])


def _slide_marker(mbs: exu.MainSystem, mechanism: Mechanism, joint: Joint, objects: dict[str, int]) -> int:
    """The relative translation of a prismatic joint's points along its
    axis (a unit vector, fixed in body_i, so it turns with body_i): the
    slide s."""
    return mbs.AddMarker(eii.MarkerBodiesRelativeTranslationCoordinate(
        bodyNumbers=[objects[joint.body_i], objects[joint.body_j]],
        localPosition0=_local(mechanism, joint.body_i, joint.point_i),
        localPosition1=_local(mechanism, joint.body_j, joint.point_j), axis0=[*joint.axis, 0.0]))


def _add_damper(mbs: exu.MainSystem, mechanism: Mechanism, joint: Joint, objects: dict[str, int],
                rotation: dict[str, int], ground_coordinate: int) -> None:
    """A zero-stiffness coordinate spring-damper: on the relative rotation
    of a revolute joint, on the relative translation along a guide."""
    if joint.kind == "revolute":
        markers = [rotation[joint.body_i], rotation[joint.body_j]]
    else:
        markers = [ground_coordinate, _slide_marker(mbs, mechanism, joint, objects)]
    mbs.AddObject(eii.ObjectConnectorCoordinateSpringDamper(markerNumbers=markers, stiffness=0.0,
                                                            damping=joint.damping))


def _add_drive(mbs: exu.MainSystem, mechanism: Mechanism, drive: Drive, objects: dict[str, int],
               rotation: dict[str, int], ground_coordinate: int, reference: dict[str, np.ndarray],
               t0: float) -> int:
    """The drive's law as a coordinate constraint q1 − q0 = offset(t), t =
    t0 + the solver's time (Exudyn refuses a negative start time, so its
    clock starts at 0 at t0). Returns the sensor of its λ.

    Revolute: on the rotation displacements, θj − θi = φ(t), i.e. q_j − q_i
    = φ(t) − (θj_ref − θi_ref). Prismatic: the slide marker's coordinate is
    the current s itself (not a displacement), constrained against a
    ground coordinate (0): s = φ(t).
    """
    joint = mechanism.joint(drive.joint)
    law = drive.law
    if joint.kind == "revolute":
        theta_ref = {body: float(q0[2]) for body, q0 in reference.items()} | {GROUND: 0.0}
        base = theta_ref[joint.body_j] - theta_ref[joint.body_i]
        markers = [rotation[joint.body_i], rotation[joint.body_j]]
    else:
        base = 0.0
        markers = [ground_coordinate, _slide_marker(mbs, mechanism, joint, objects)]

    # DriveLaw's φ and φ̇ in plain floats: these run at every Newton
    # iteration, where numpy's per-call cost on scalars would take a large
    # share of a run (tests/bench/exudyn_bench.py times the adapter). The
    # adapter's "drive_error_max" checks the result against DriveLaw itself.
    phi0, omega0, alpha = float(law.phi0) - base, float(law.omega0), float(law.alpha)

    def offset(mbs, t, item, l_offset):  # noqa: ARG001 - Exudyn's signature
        t += t0
        return phi0 + omega0 * t + 0.5 * alpha * t * t

    def offset_t(mbs, t, item, l_offset):  # noqa: ARG001 - Exudyn's signature
        return omega0 + alpha * (t + t0)

    number = mbs.AddObject(eii.ObjectConnectorCoordinate(
        markerNumbers=markers, offsetUserFunction=offset, offsetUserFunction_t=offset_t))
    return mbs.AddSensor(eii.SensorObject(objectNumber=number, outputVariableType=exu.OutputVariableType.Force,
                                          storeInternal=True, writeToFile=False))


def _add_spring(mbs: exu.MainSystem, mechanism: Mechanism, spring: SpringDamper, objects: dict[str, int]) -> None:
    """An `ObjectConnectorSpringDamper` between the two points: tension
    stiffness·(ℓ − referenceLength) + damping·ℓ̇ along the line (its force
    offset and velocity offset stay 0). Named after the force, so that the
    audit finds it."""
    markers = [mbs.AddMarker(eii.MarkerBodyPosition(bodyNumber=objects[body],
                                                    localPosition=_local(mechanism, body, point)))
               for body, point in ((spring.body_a, spring.point_a), (spring.body_b, spring.point_b))]
    mbs.AddObject(eii.ObjectConnectorSpringDamper(
        name=force_item(spring), markerNumbers=markers, stiffness=spring.stiffness, damping=spring.damping,
        referenceLength=spring.free_length))


def _add_torque(mbs: exu.MainSystem, torque: BodyTorque, objects: dict[str, int]) -> None:
    """A constant `LoadTorqueVector` about z on the body (named after the
    force, for the audit)."""
    marker = mbs.AddMarker(eii.MarkerBodyRigid(bodyNumber=objects[torque.body], localPosition=[0.0, 0.0, 0.0]))
    mbs.AddLoad(eii.LoadTorqueVector(name=force_item(torque), markerNumber=marker,
                                     loadVector=[0.0, 0.0, float(torque.torque)]))


class TorqueLawLoad:
    """A torque law as Exudyn's `loadVectorUserFunction` (mbs, t, load) →
    [0, 0, sign·T(t0 + t)]: the solver's time t starts at 0 at t0. Plain
    floats: it runs at every Newton iteration. Its parameters are kept on
    it for the model audit."""

    def __init__(self, law: TorqueLaw, sign: float, t0: float):
        self.law, self.sign, self.t0 = law, sign, t0
        self._c = sign * float(law.torque)
        self._a = sign * float(law.amplitude)
        self._w = 2.0 * math.pi * float(law.frequency)
        self._p = float(law.phase)

    def __call__(self, mbs, t, load):  # noqa: ARG002 - Exudyn's signature
        return [0.0, 0.0, self._c + self._a * math.sin(self._w * (t + self.t0) + self._p)]


def torque_law_load_names(law: TorqueLaw) -> dict[float, str]:
    """The names of a torque law's two loads, by sign (+1 on body_j, −1 on
    body_i): Exudyn refuses a second load of the same name, and a law
    between two moving bodies has both."""
    item = torque_law_item(law)
    return {1.0: f"{item} on body_j", -1.0: f"{item} on body_i"}


def _add_torque_law(mbs: exu.MainSystem, mechanism: Mechanism, law: TorqueLaw, objects: dict[str, int],
                    t0: float) -> tuple[int, float]:
    """T(t) on body_j and −T(t) on body_i (`LoadTorqueVector`s named after
    the law and the side, `torque_law_load_names`, with `TorqueLawLoad`;
    none on the ground). Returns the sensor of the first load and its sign."""
    joint = mechanism.joint(law.joint)
    names = torque_law_load_names(law)
    sensors = []
    for body, sign in ((joint.body_j, 1.0), (joint.body_i, -1.0)):
        if body == GROUND:
            continue
        marker = mbs.AddMarker(eii.MarkerBodyRigid(bodyNumber=objects[body], localPosition=[0.0, 0.0, 0.0]))
        load = mbs.AddLoad(eii.LoadTorqueVector(name=names[sign], markerNumber=marker,
                                                loadVector=[0.0, 0.0, 0.0],
                                                loadVectorUserFunction=TorqueLawLoad(law, sign, t0)))
        sensors.append((mbs.AddSensor(eii.SensorLoad(loadNumber=load, storeInternal=True, writeToFile=False)), sign))
    return sensors[0]


def simulation_settings(settings: Mapping[str, Any], duration: float, dt: float) -> exu.SimulationSettings:
    """Exudyn settings for a fixed-step run of `duration` from the solver's
    time 0 that records every step in memory and writes no file and no
    console output."""
    s = exu.SimulationSettings()
    ti = s.timeIntegration
    ti.startTime, ti.endTime = 0.0, duration
    ti.numberOfSteps = int(round(duration / dt))
    ti.adaptiveStep = bool(settings["adaptive_step"])
    ti.verboseMode = 0
    ti.newton.useModifiedNewton = not settings["full_newton"]
    ti.newton.relativeTolerance = float(settings["newton_relative_tolerance"])
    ti.newton.absoluteTolerance = float(settings["newton_absolute_tolerance"])
    alpha = ti.generalizedAlpha
    alpha.computeInitialAccelerations = bool(settings["compute_initial_accelerations"])
    alpha.resetAccelerations = False
    alpha.spectralRadius = float(settings["spectral_radius"])
    s.solution.file.write = False
    # 0: record every step (the default 0.01 s silently thins the sensors).
    s.solution.sensors.writePeriod = 0.0
    s.show.computationTime = False
    s.show.statistics = False
    return s


def solve(model: ExudynModel, simulation: exu.SimulationSettings,
          solver: str) -> exu.MainSolverImplicitSecondOrder:
    """Run the solver with Exudyn's console output off; raise on failure.

    A stop signal (KeyboardInterrupt, the harness's `Interrupted`) raised
    inside a user function reaches the caller as itself, not as the
    `ModelError` Exudyn wraps it in ("Error in Python USER FUNCTION"):
    Exudyn turns every exception of a user function into its own, keeping
    the original as the cause."""
    printing = exu.config.printToConsole
    exu.config.printToConsole = False
    try:
        model.mbs.SolveDynamic(simulation, solverType=SOLVERS[solver], storeSolver=True)
    except Exception as failure:
        stop = _stop_inside(failure)
        if stop is not None:
            raise stop from None
        raise
    finally:
        exu.config.printToConsole = printing
    return model.mbs.sys["dynamicSolver"]


def _stop_inside(failure: BaseException) -> BaseException | None:
    """The first exception in the failure's chain of causes that is not an
    `Exception` (a KeyboardInterrupt or SystemExit), if any."""
    seen = set()
    cause = failure.__cause__ or failure.__context__
    while cause is not None and id(cause) not in seen:
        if not isinstance(cause, Exception):
            return cause
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return None
