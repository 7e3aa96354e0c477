"""Build the Exudyn model of a spatial scene (`SpatialSystem`, Exudyn 1.13.6).

Bodies: one `NodeRigidBodyEP` (Euler parameters: 3 position coordinates
and a unit quaternion, with the node's own norm constraint) per body, at
the body frame's ORIGIN, with an `ObjectRigidBody` whose `centerOfMass` is
the scene's com and whose inertia is taken about that origin (parallel-axis
theorem). Euler parameters because they have no singular attitude (the
T-handle and the top turn through every attitude; a rotation vector is
singular at 2π, Tait–Bryan angles at ±90°) and they are what Exudyn pairs
with its implicit solvers (the `ObjectRigidBody` docstring); the Lie-group
rotation-vector node is meant for its explicit integrators. Node at the
origin: its position, velocity and acceleration are the raw columns as
they are.

Joints: every kind one `ObjectJointGeneric` between `MarkerBodyRigid`s
whose local frames are the joint frames (marker 0 on body_i with frame_i,
marker 1 on body_j with frame_j), with `constrainedAxes` per kind
(`CONSTRAINED_AXES`). The universal joint's free axes are J0's y and J1's
z (Exudyn's constraint y0·z1 = 0), so marker 0's frame is frame_i with its
axes turned cyclically (`TO_Y`): J0's y is zi.

Drives: an `ObjectConnectorCoordinate` q1 − q0 = offset(t) between a
ground coordinate and a `MarkerBodiesRelativeRotationCoordinate` (about
zi, unwrapped by a `NodeGenericData`) or `...RelativeTranslationCoordinate`
(along zi): offset = the marker's value at the start + φ(t) − φ(t0), so
that the marker's own zero does not matter. Joint damping: the same
markers with a zero-stiffness `ObjectConnectorCoordinateSpringDamper`.

Forces, only those of the scene: gravity as a `LoadForceVector` m·g at the
com; `Spring` an `ObjectConnectorSpringDamper`; `BodyLoad` a
`LoadForceVector` at the com and a `LoadTorqueVector` (world); a torque
law a body-fixed `LoadTorqueVector` T(t)·zj on body_j and −T(t)·zi on
body_i (zi ∥ zj on a revolute joint), evaluated by a user function.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import exudyn as exu
import exudyn.itemInterface as eii
import numpy as np
import pandas as pd

from mechval.adapter import Unrepresentable
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.rotation import quaternion_rate
from mechval.reference.spatial.system import SpatialJoint, SpatialSystem

#: Per joint kind: translations x, y, z and rotations x, y, z of the joint
#: frame J0, 1 = constrained (`ObjectJointGeneric.constrainedAxes`).
CONSTRAINED_AXES = {
    "revolute": (1, 1, 1, 1, 1, 0),
    "prismatic": (1, 1, 0, 1, 1, 1),
    "cylindrical": (1, 1, 0, 1, 1, 0),
    "spherical": (1, 1, 1, 0, 0, 0),
    "universal": (1, 1, 1, 1, 0, 0),
    "planar": (0, 0, 1, 1, 1, 0),
    "fixed": (1, 1, 1, 1, 1, 1),
}
#: Columns x, y, z of J0 = frame_i's y, z, x (right-handed): J0's y is zi.
TO_Y = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
#: Node sensor outputs (all world axes, the node is the body frame origin).
NODE_OUTPUTS = ("Position", "Velocity", "Acceleration", "RotationMatrix", "AngularVelocity", "AngularAcceleration")


@dataclass
class SpatialModel:
    system: exu.SystemContainer
    mbs: exu.MainSystem
    #: Per body: output name → sensor.
    body_sensors: dict[str, dict[str, int]] = field(default_factory=dict)
    #: Per joint: (ForceLocal sensor, TorqueLocal sensor).
    joint_sensors: dict[str, tuple[int, int]] = field(default_factory=dict)
    #: Per joint: the joint frames J0 (in body_i axes) and J1 (in body_j axes).
    joint_frames: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    drive_sensors: dict[str, int] = field(default_factory=dict)
    #: Per torque law: (load sensor, sign, the load's axis in its body's axes).
    torque_sensors: dict[str, tuple[int, float, np.ndarray]] = field(default_factory=dict)
    #: Object numbers of the bodies (and the ground) and of the joints.
    objects: dict[str, int] = field(default_factory=dict)
    joint_objects: dict[str, int] = field(default_factory=dict)
    #: Per body: its gravity load m·g (none without gravity).
    gravity_loads: dict[str, int] = field(default_factory=dict)

    @property
    def clock_sensor(self) -> int:
        return next(iter(next(iter(self.body_sensors.values())).values()))


def inertia_about_origin(mass: float, com, inertia) -> list[float]:
    """Exudyn's [Jxx, Jyy, Jzz, Jyz, Jxz, Jxy] about the body frame origin
    from the tensor about the centre of mass (Steiner)."""
    c = np.asarray(com, dtype=float)
    J = np.asarray(inertia, dtype=float) + mass * ((c @ c) * np.eye(3) - np.outer(c, c))
    return [J[0, 0], J[1, 1], J[2, 2], J[1, 2], J[0, 2], J[0, 1]]


def quaternion_acceleration(p: np.ndarray, omega: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """p̈ = ½·(0, α) ⊗ p − ¼·|ω|²·p (from ṗ = ½·(0, ω) ⊗ p, world ω)."""
    w, v = p[0], p[1:]
    half = 0.5 * np.concatenate([[-alpha @ v], w * alpha + np.cross(alpha, v)])
    return half - 0.25 * (omega @ omega) * p


def _row(start: pd.DataFrame, body: str, names: str) -> np.ndarray:
    return np.array([float(start[f"{body}.{n}"].iloc[0]) for n in names.split()])


def build_spatial(system: SpatialSystem, start: pd.DataFrame, t0: float) -> SpatialModel:
    """The model in the state `start` (raw reference columns, one row at
    t0, accelerations included: Exudyn's own initial-acceleration solve
    ignores φ'' of a drive); the solver's time 0 is t0 (Exudyn refuses
    negative times)."""
    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    model = SpatialModel(sc, mbs)
    ground = mbs.AddObject(eii.ObjectGround())
    ground_node = mbs.AddNode(eii.NodePointGround())
    ground_coordinate = mbs.AddMarker(eii.MarkerNodeCoordinate(nodeNumber=ground_node, coordinate=0))
    objects = model.objects
    objects[GROUND] = ground
    accelerations: list[float] = []
    for body in system.bodies:
        p = _row(start, body.name, "qw qx qy qz")
        omega, alpha = _row(start, body.name, "wx wy wz"), _row(start, body.name, "alphax alphay alphaz")
        node = mbs.AddNode(eii.NodeRigidBodyEP(
            referenceCoordinates=[*_row(start, body.name, "x y z"), *p],
            initialVelocities=[*_row(start, body.name, "vx vy vz"), *quaternion_rate(p, omega)]))
        accelerations += [*_row(start, body.name, "ax ay az"), *quaternion_acceleration(p, omega, alpha)]
        number = mbs.AddObject(eii.ObjectRigidBody(
            mass=body.mass, inertia=inertia_about_origin(body.mass, body.com, body.inertia),
            centerOfMass=list(map(float, body.com)), nodeNumber=node))
        objects[body.name] = number
        model.body_sensors[body.name] = {
            name: mbs.AddSensor(eii.SensorNode(nodeNumber=node, outputVariableType=getattr(exu.OutputVariableType, name),
                                               storeInternal=True, writeToFile=False)) for name in NODE_OUTPUTS}
        if any(system.gravity):
            com = mbs.AddMarker(eii.MarkerBodyPosition(bodyNumber=number, localPosition=list(map(float, body.com))))
            model.gravity_loads[body.name] = mbs.AddLoad(eii.LoadForceVector(
                markerNumber=com, loadVector=[body.mass * g for g in system.gravity]))

    for joint in system.joints:
        _add_joint(model, joint, objects)
    coordinate_markers = {}

    def coordinate_marker(joint: SpatialJoint) -> int:
        if joint.name not in coordinate_markers:
            coordinate_markers[joint.name] = _coordinate_marker(mbs, joint, objects)
        return coordinate_markers[joint.name]

    for joint in system.joints:
        if joint.damping:
            if joint.kind not in ("revolute", "prismatic"):
                raise Unrepresentable(f"joint.{joint.name}.damping", "damping is on revolute or prismatic joints only")
            mbs.AddObject(eii.ObjectConnectorCoordinateSpringDamper(
                markerNumbers=[ground_coordinate, coordinate_marker(joint)], stiffness=0.0, damping=joint.damping))
    drives = []
    for drive in system.drives:
        marker = coordinate_marker(system.joint(drive.joint))
        number = mbs.AddObject(eii.ObjectConnectorCoordinate(markerNumbers=[ground_coordinate, marker]))
        drives.append((drive, marker, number))
        model.drive_sensors[drive.name] = mbs.AddSensor(eii.SensorObject(
            objectNumber=number, outputVariableType=exu.OutputVariableType.Force, storeInternal=True,
            writeToFile=False))
    for spring in system.springs:
        markers = [mbs.AddMarker(eii.MarkerBodyPosition(bodyNumber=objects[b], localPosition=list(map(float, p))))
                   for b, p in ((spring.body_a, spring.point_a), (spring.body_b, spring.point_b))]
        mbs.AddObject(eii.ObjectConnectorSpringDamper(markerNumbers=markers, stiffness=spring.stiffness,
                                                      damping=spring.damping, referenceLength=spring.free_length))
    for load in (load for load in system.loads if load.body != GROUND):     # a load on the ground does nothing
        com = mbs.AddMarker(eii.MarkerBodyRigid(bodyNumber=objects[load.body],
                                                localPosition=list(map(float, system.body(load.body).com))))
        mbs.AddLoad(eii.LoadForceVector(markerNumber=com, loadVector=list(map(float, load.force))))
        mbs.AddLoad(eii.LoadTorqueVector(markerNumber=com, loadVector=list(map(float, load.torque))))
    for law in system.torques:
        model.torque_sensors[law.name] = _add_torque_law(mbs, system.joint(law.joint), law, objects, t0)
    mbs.Assemble()
    # Drive offsets from the markers' values in the assembled start state.
    for drive, marker, number in drives:
        base = float(mbs.GetMarkerOutput(marker, exu.OutputVariableType.Coordinates)[0])
        _set_drive(mbs, number, drive.law, base, t0)
    # Body nodes are the only ones with ODE2 coordinates, in this order.
    mbs.systemData.SetODE2Coordinates_tt(accelerations, configuration=exu.ConfigurationType.Initial)
    return model


def joint_frames(joint: SpatialJoint) -> tuple[np.ndarray, np.ndarray]:
    """The Exudyn joint frames J0 (body_i axes) and J1 (body_j axes)."""
    frame_i = np.asarray(joint.frame_i, dtype=float)
    return (frame_i @ TO_Y if joint.kind == "universal" else frame_i), np.asarray(joint.frame_j, dtype=float)


def _add_joint(model: SpatialModel, joint: SpatialJoint, objects: dict[str, int]) -> None:
    mbs = model.mbs
    J0, J1 = joint_frames(joint)
    markers = [mbs.AddMarker(eii.MarkerBodyRigid(bodyNumber=objects[body],
                                                 localHT=exu.HT(rotation=frame, translation=list(map(float, point)))))
               for body, point, frame in ((joint.body_i, joint.point_i, J0), (joint.body_j, joint.point_j, J1))]
    number = mbs.AddObject(eii.ObjectJointGeneric(markerNumbers=markers,
                                                  constrainedAxes=list(CONSTRAINED_AXES[joint.kind])))
    model.joint_sensors[joint.name] = tuple(
        mbs.AddSensor(eii.SensorObject(objectNumber=number, outputVariableType=output, storeInternal=True,
                                       writeToFile=False))
        for output in (exu.OutputVariableType.ForceLocal, exu.OutputVariableType.TorqueLocal))
    model.joint_frames[joint.name] = (J0, J1)
    model.joint_objects[joint.name] = number


def _coordinate_marker(mbs: exu.MainSystem, joint: SpatialJoint, objects: dict[str, int]) -> int:
    """The joint's coordinate about (revolute) or along (prismatic) zi."""
    axis = [float(a) for a in np.asarray(joint.frame_i, dtype=float)[:, 2]]
    common = dict(bodyNumbers=[objects[joint.body_i], objects[joint.body_j]],
                  localPosition0=list(map(float, joint.point_i)), localPosition1=list(map(float, joint.point_j)),
                  axis0=axis)
    if joint.kind == "revolute":
        unwrap = mbs.AddNode(eii.NodeGenericData(numberOfDataCoordinates=1, initialCoordinates=[0.0]))
        return mbs.AddMarker(eii.MarkerBodiesRelativeRotationCoordinate(nodeNumber=unwrap, **common))
    return mbs.AddMarker(eii.MarkerBodiesRelativeTranslationCoordinate(**common))


def _set_drive(mbs: exu.MainSystem, number: int, law, base: float, t0: float) -> None:
    """offset(t) = base + φ(t0 + t) − φ(t0), its rate φ̇(t0 + t)."""
    phi_start = float(law.angle(t0))

    def offset(mbs, t, item, l_offset):  # noqa: ARG001 - Exudyn's signature
        return base + float(law.angle(t0 + t)) - phi_start

    def offset_t(mbs, t, item, l_offset):  # noqa: ARG001 - Exudyn's signature
        return float(law.rate(t0 + t))

    mbs.SetObjectParameter(number, "offsetUserFunction", offset)
    mbs.SetObjectParameter(number, "offsetUserFunction_t", offset_t)


def _add_torque_law(mbs: exu.MainSystem, joint: SpatialJoint, law, objects: dict[str, int], t0: float
                    ) -> tuple[int, float, np.ndarray]:
    """T(t)·zj on body_j, −T(t)·zi on body_i, body-fixed (none on the
    ground). Returns the first load's sensor, its sign and its axis."""
    sensors = []
    for body, point, frame, sign in ((joint.body_j, joint.point_j, joint.frame_j, 1.0),
                                     (joint.body_i, joint.point_i, joint.frame_i, -1.0)):
        if body == GROUND:
            continue
        axis = np.asarray(frame, dtype=float)[:, 2]

        def torque(mbs, t, load, axis=axis, sign=sign):  # noqa: ARG001 - Exudyn's signature
            return list(sign * float(law.law.value(t0 + t)) * axis)

        marker = mbs.AddMarker(eii.MarkerBodyRigid(bodyNumber=objects[body], localPosition=list(map(float, point))))
        load = mbs.AddLoad(eii.LoadTorqueVector(markerNumber=marker, loadVector=[0.0, 0.0, 0.0], bodyFixed=True,
                                                loadVectorUserFunction=torque))
        sensors.append((mbs.AddSensor(eii.SensorLoad(loadNumber=load, storeInternal=True, writeToFile=False)),
                        sign, axis))
    return sensors[0]
