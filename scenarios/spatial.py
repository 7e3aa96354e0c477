"""Spatial files (`mechanism = "spatial"`, docs/scenario-format.md#spatial-files):
rigid bodies in three dimensions, joints of the seven kinds of
`mechval.reference.spatial.system`, drives, torque laws, spring-dampers,
body forces and torques, gravity as a 3-vector, and for a torque-driven or
free scene the bodies' velocities at t = 0; validated into a `Scenario`
whose scene is the `SpatialSystem` the file states.

Kept as close to planar files (`scenarios.planar`) as three dimensions
allow: the same tables and key names for the same things (`[ground]`
points, `[[body]]` with `points`, `[[joint]]` with `between`, `[[drive]]`
laws, `[[torque]]` laws, `[[force]]`, `[assembly]`, `[effects]`), a
3-vector where a planar file has a pair. Every refusal is a
`ScenarioError` naming the file, the key and the reason; what needs the
assembled mechanism (mobility, closure over the run, a consistent initial
state) is checked by `scenarios.spatial_checks`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Collection, Mapping

import numpy as np

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND
from mechval.model.scenario import Scenario, ScenarioError
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.rotation import exp_map, frame_from_axis, quaternion_to_matrix
from mechval.reference.spatial.system import (DRIVEN_KINDS, JOINT_KINDS, BodyLoad, JointTorque, SpatialBody,
                                              SpatialDrive, SpatialJoint, SpatialSystem, Spring, check_inertia)

from .planar import NAME, _array, _between as planar_between, _name, _named, _torques as planar_torques
from .spatial_checks import check_spatial
from .tables import Reader, heading, run_tables, shown

TOP_KEYS = {"name", "mechanism", "description", "tags", "ground", "body", "joint", "drive", "torque",
            "initial", "force", "assembly", "effects", "time", "tolerance", "engines"}
#: A rotation given as three rows, or principal axes, must be orthonormal
#: to this (then it is made exactly so): a matrix written with 10
#: significant digits passes, a typo does not.
ORTHONORMAL = 1e-9
#: Joint kinds whose frames matter, and so need an `axis` (a fixed joint's
#: default frames are its bodies' axes; a spherical joint has none).
AXIS_KINDS = ("revolute", "prismatic", "cylindrical", "universal", "planar")

Vec3 = tuple[float, float, float]


def parse_spatial(data: Mapping[str, Any], source: str | Path | None = None,
                  engines: Collection[str] | None = None) -> Scenario:
    """Validate a spatial file's parsed TOML into a `Scenario` (SI units)."""
    top = Reader(source, "", data)
    top.only(TOP_KEYS)
    name, _, description, tags = heading(top)
    ground = top.sub("ground")
    points, axes = {GROUND: _points(ground, reserved="axes")}, {GROUND: _axes(ground.sub("axes"))}
    masses = _bodies(top, points, axes)
    poses = _assembly(top.sub("assembly"), list(masses))
    bodies = tuple(SpatialBody(n, mass, com, inertia, *poses[n]) for n, (mass, com, inertia) in masses.items())
    joints = _joints(top, points, axes)
    drives = _drives(top, joints)
    torques = _torques(top, joints, drives)
    springs, loads = _forces(top, points)
    velocities = _initial(top.sub("initial"), list(masses))
    gravity = _gravity(top.sub("effects"))
    time, tolerance, engine_tables = run_tables(top, engines)
    try:
        system = SpatialSystem(name, bodies, joints, drives, gravity, springs, loads, torques, velocities)
    except MechanismError as exc:        # checked above key by key: a safety net, keyed as the file
        raise ScenarioError(source, exc.key, exc.reason) from None
    scenario = Scenario(name=name, description=description, scene=system, time=time, tolerance=tolerance,
                        engines=engine_tables, tags=tags, source=Path(source) if source else None,
                        keys=_file_keys(data, system))
    check_spatial(scenario)
    return scenario


def _file_keys(data: Mapping[str, Any], system: SpatialSystem) -> dict[str, str]:
    """The file's key of each element the reference names otherwise
    (`Scenario.keys`)."""
    keys = {f"drive.{d.name}": f"drive[{k}]" for k, d in enumerate(system.drives)}
    for b, entry in zip(system.bodies, data["body"]):
        keys[f"body.{b.name}.rotation"] = f"assembly.{b.name}"
        if "principal" in entry:
            keys[f"body.{b.name}.inertia"] = f"body.{b.name}.principal"
    for j, entry in zip(system.joints, data.get("joint", [])):
        keys[f"joint.{j.name}.frame_i"] = f"joint.{j.name}.axis"
        keys[f"joint.{j.name}.frame_j"] = f"joint.{j.name}.{'axis_j' if 'axis_j' in entry else 'axis'}"
    return keys


# -- values ----------------------------------------------------------------------------------------

def vector(table: Reader, key: str, what: str = "[x, y, z] in m", value: Any = None) -> Vec3:
    """Three finite numbers under `key` (or `value`, found there)."""
    value = table.table.get(key) if value is None else value
    if not isinstance(value, list) or len(value) != 3:
        table.fail(key, f"expected three finite numbers {what}, got {shown(value)}")
    return tuple(table.check_number(f"{key}[{k}]", v) for k, v in enumerate(value))


def direction(table: Reader, key: str, what: str, named: Mapping[str, Vec3] | None = None,
              body: str = "") -> np.ndarray:
    """A non-zero 3-vector (any length): a direction; or, with `named`
    (`body`'s named axes), the name "body.AXIS" of one."""
    value = table.table.get(key)
    if named is not None and isinstance(value, str):
        if value.count(".") != 1 or value.split(".")[0] != body:
            table.fail(key, f"expected [x, y, z] or \"{body}.AXIS\" (an axis of {body!r}), got {shown(value)}")
        axis = value.split(".")[1]
        if axis not in named:
            table.fail(key, f"{body!r} has no axis {axis!r} (its axes: {', '.join(sorted(named)) or 'none'})")
        value = list(named[axis])
    v = np.array(vector(table, key, what, value))
    if not np.abs(v).max() > 0:
        table.fail(key, "a degenerate direction: all three components are zero")
    # scaled by a power of two (exactly) to a largest component in [½, 1):
    # any non-zero length is a direction, and the unit vector is the same
    return np.ldexp(v, -np.frexp(np.abs(v).max())[1])


def rows(table: Reader, key: str, what: str) -> np.ndarray:
    """Three rows of three numbers, orthonormal to ORTHONORMAL, as a
    rotation-like matrix (rows as written)."""
    value = table.table.get(key)
    if not isinstance(value, list) or len(value) != 3:
        table.fail(key, f"expected three rows of three numbers ({what}), got {shown(value)}")
    M = np.array([vector(table, f"{key}[{k}]", "(a row)", row) for k, row in enumerate(value)])
    if not np.allclose(M @ M.T, np.eye(3), rtol=0, atol=ORTHONORMAL):
        table.fail(key, f"the rows are not orthonormal ({what}): M·Mᵀ differs from the identity by "
                        f"{np.abs(M @ M.T - np.eye(3)).max():.3g}")
    return M


def _axes(table: Reader) -> dict[str, Vec3]:
    """A body's (or the ground's) named axes: non-zero directions."""
    for key in table.table:
        if not NAME.match(key):
            table.fail(key, f"{key!r} is not a usable axis name")
        direction(table, key, "in the body's axes")
    return {key: vector(table, key) for key in table.table}


def _points(table: Reader, reserved: str = "") -> dict[str, Vec3]:
    """Named points; `reserved`, a key that is not one (the ground's axes)."""
    points = {}
    for key in table.table:
        if key == reserved:
            continue
        if not NAME.match(key):
            table.fail(key, f"{key!r} is not a usable point name")
        points[key] = vector(table, key)
    return points


def _between(reader: Reader, points: dict) -> tuple[tuple[str, Vec3], tuple[str, Vec3]]:
    """The planar files' "between" (two "body.point"s), on two bodies."""
    ends = planar_between(reader, points)
    if ends[0][0] == ends[1][0]:
        reader.fail("between", f"joins {ends[0][0]!r} to itself")
    return ends


# -- the scene -------------------------------------------------------------------------------------

def _bodies(top: Reader, points: dict, axes: dict) -> dict[str, tuple[float, Vec3, np.ndarray]]:
    """Per body its mass, centre of mass and inertia tensor; its named
    points and axes added to `points` and `axes`."""
    bodies = {}
    for name, body in _named(_array(top, "body", required=True), "body"):
        body.only({"name", "mass", "com", "inertia", "principal", "principal_axes", "points", "axes"})
        axes[name] = _axes(body.sub("axes"))
        mass = body.number("mass", positive=True)
        com = vector(body, "com")
        bodies[name] = (mass, com, _inertia(body, mass))
        points[name] = _points(body.sub("points"))
    return bodies


def _inertia(body: Reader, mass: float) -> np.ndarray:
    """`inertia` = [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (the tensor's entries), or
    `principal` = [I1, I2, I3] about `principal_axes` (rows; default the
    body's axes). About the centre of mass, body axes, kg·m²."""
    if ("inertia" in body.table) == ("principal" in body.table):
        body.fail("inertia", "give either `inertia` (six entries) or `principal` (three moments), not both"
                  if "inertia" in body.table else "missing value (`inertia` or `principal`)")
    if "principal_axes" in body.table and "principal" not in body.table:
        body.fail("principal_axes", "goes with `principal`")
    if "inertia" in body.table:
        key, value = "inertia", body.table["inertia"]
        if not isinstance(value, list) or len(value) != 6:
            body.fail(key, f"expected six numbers [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] in kg·m², got {shown(value)}")
        xx, yy, zz, xy, xz, yz = (body.check_number(f"{key}[{k}]", v) for k, v in enumerate(value))
        I = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    else:
        key = "principal"
        moments = vector(body, key, "[I1, I2, I3] in kg·m²")
        axes = rows(body, "principal_axes", "one principal axis per row") if "principal_axes" in body.table \
            else np.eye(3)
        I = axes.T @ np.diag(moments) @ axes
    try:
        check_inertia(body.key(key), mass, I)
    except MechanismError as exc:
        raise ScenarioError(body.source, exc.key, exc.reason) from None
    return I


def _assembly(table: Reader, names: list[str]) -> dict[str, tuple[Vec3, np.ndarray]]:
    """Per body its frame's approximate pose at t = 0: `position` (m,
    world) and a rotation (body axes to world) given by `axis` and
    `angle`, a `quaternion` [w, x, y, z] or the three `rotation` rows;
    a body not named has its frame on the world's."""
    table.only(set(names))
    poses = {}
    for name in names:
        entry = table.sub(name)
        entry.only({"position", "axis", "angle", "quaternion", "rotation"})
        position = vector(entry, "position") if "position" in entry.table else (0.0, 0.0, 0.0)
        given = [k for k in ("axis", "quaternion", "rotation") if k in entry.table]
        if len(given) > 1:
            entry.fail(given[1], f"give one rotation: `axis` and `angle`, `quaternion` or `rotation` "
                                 f"(not both {given[0]} and {given[1]})")
        if ("axis" in entry.table) != ("angle" in entry.table):
            entry.fail("angle" if "axis" in entry.table else "axis", "`axis` and `angle` go together")
        if "axis" in entry.table:
            axis = direction(entry, "axis", "[x, y, z]: the rotation's axis, world")
            R = exp_map(axis / np.linalg.norm(axis) * entry.number("angle"))
        elif "quaternion" in entry.table:
            value = entry.table["quaternion"]
            if not isinstance(value, list) or len(value) != 4:
                entry.fail("quaternion", f"expected four numbers [w, x, y, z], got {shown(value)}")
            q = np.array([entry.check_number(f"quaternion[{k}]", v) for k, v in enumerate(value)])
            if not np.abs(q).max() > 0:
                entry.fail("quaternion", "all four components are zero")
            R = quaternion_to_matrix(q / np.abs(q).max())
        elif "rotation" in entry.table:
            R = rows(entry, "rotation", "the rotation matrix from body axes to world axes")
            if np.linalg.det(R) < 0:
                entry.fail("rotation", "is a reflection (determinant −1), not a rotation")
        else:
            R = np.eye(3)
        poses[name] = (position, R)
    return poses


def _frame(joint: Reader, axis_key: str, reference_key: str, body: str, axes: dict,
           fallback: np.ndarray | None = None) -> np.ndarray:
    """The joint frame on `body` whose z is `axis_key` and x
    `reference_key` made orthogonal to it (default: any perpendicular),
    each a vector or one of the body's named axes; `fallback` if no axis."""
    if axis_key not in joint.table and fallback is not None:
        return fallback
    what = f"in {body!r}'s axes"
    axis = direction(joint, axis_key, what, axes[body], body)
    reference = direction(joint, reference_key, what, axes[body], body) if reference_key in joint.table else None
    try:
        return frame_from_axis(axis, reference, joint.key(axis_key))
    except ValueError:
        joint.fail(reference_key, "is parallel to the axis: it cannot set the frame's x direction")


def _joints(top: Reader, points: dict, axes: dict) -> tuple[SpatialJoint, ...]:
    joints = []
    for name, joint in _named(_array(top, "joint"), "joint"):
        kind = joint.string("type", choices=JOINT_KINDS)
        frames = {"axis", "reference", "axis_j", "reference_j"}
        joint.only({"name", "type", "between"} | (set() if kind == "spherical" else frames)
                   | ({"damping"} if kind in DRIVEN_KINDS else set()))
        (body_i, p_i), (body_j, p_j) = _between(joint, points)
        if kind in AXIS_KINDS and "axis" not in joint.table:
            joint.fail("axis", f"missing value: a {kind} joint's axis [x, y, z] in {body_i!r}'s axes")
        if kind == "universal" and "axis_j" not in joint.table:
            joint.fail("axis_j", f"missing value: the universal joint's second pin [x, y, z] in {body_j!r}'s axes")
        for key in ("reference", "axis_j", "reference_j"):
            if key in joint.table and "axis" not in joint.table:
                joint.fail(key, "goes with `axis`")
        if "reference_j" in joint.table and "axis_j" not in joint.table:
            joint.fail("reference_j", "goes with `axis_j`")
        frame_i = _frame(joint, "axis", "reference", body_i, axes, np.eye(3))
        frame_j = _frame(joint, "axis_j", "reference_j", body_j, axes, frame_i)
        damping = joint.number("damping", default=0.0, nonnegative=True)
        joints.append(SpatialJoint(name, kind, body_i, body_j, p_i, p_j, frame_i, frame_j, damping))
    return tuple(joints)


def _drives(top: Reader, joints: tuple[SpatialJoint, ...]) -> tuple[SpatialDrive, ...]:
    """[[drive]] as in planar files: a revolute joint's angle from xi to xj
    about zi, or a prismatic joint's slide along zi, follows
    φ(t) = phi0 + omega0·t + ½·alpha·t²."""
    kinds = {j.name: j.kind for j in joints}
    drives, driven = [], set()
    for drive in _array(top, "drive"):
        drive.only({"joint", "phi0", "omega0", "alpha"})
        joint = drive.string("joint")
        if joint not in kinds:
            drive.fail("joint", f"unknown joint {joint!r} (joints: {', '.join(sorted(kinds))})")
        if kinds[joint] not in DRIVEN_KINDS:
            drive.fail("joint", f"joint {joint!r} is {kinds[joint]}: drives act on revolute or prismatic joints")
        if joint in driven:
            drive.fail("joint", f"a second drive on joint {joint!r}")
        driven.add(joint)
        law = DriveLaw(drive.number("phi0", default=0.0), drive.number("omega0"), drive.number("alpha", default=0.0))
        drives.append(SpatialDrive(joint, law, name="drive" if not drives else joint))
    return tuple(drives)


def _torques(top: Reader, joints: tuple[SpatialJoint, ...],
             drives: tuple[SpatialDrive, ...]) -> tuple[JointTorque, ...]:
    """[[torque]] as in planar files: T(t) about a revolute joint's axis zi."""
    return tuple(JointTorque(law.joint, law, law.name) for law in planar_torques(top, joints, drives))


def _forces(top: Reader, points: dict) -> tuple[tuple[Spring, ...], tuple[BodyLoad, ...]]:
    springs, loads, names = [], [], set()
    bodies = sorted(set(points) - {GROUND})
    for k, force in enumerate(_array(top, "force")):
        name = _name(force) if "name" in force.table else f"force{k + 1}"
        if name in names:
            force.fail("name", f"a second force named {name!r}")
        names.add(name)
        kind = force.string("type", choices=("spring", "force", "torque"))
        if kind == "spring":
            force.only({"name", "type", "between", "stiffness", "free_length", "damping"})
            (body_a, p_a), (body_b, p_b) = _between(force, points)
            springs.append(Spring(name, body_a, p_a, body_b, p_b, force.number("stiffness", nonnegative=True),
                                  force.number("free_length", nonnegative=True),
                                  force.number("damping", default=0.0, nonnegative=True)))
            continue
        force.only({"name", "type", "body", kind})
        body = force.string("body")
        if body not in bodies:
            force.fail("body", f"unknown body {body!r} (bodies: {', '.join(bodies)})")
        value = vector(force, kind, "[x, y, z] in N, world axes" if kind == "force" else "[x, y, z] in N·m, world axes")
        loads.append(BodyLoad(name, body, **{kind: value}))
    return tuple(springs), tuple(loads)


def _initial(table: Reader, names: list[str]) -> dict[str, tuple[Vec3, Vec3]]:
    """[initial.BODY]: `velocity` of the body frame's origin (m/s) and
    `omega` (rad/s), world axes, at t = 0; bodies not named start at rest."""
    table.only(set(names))
    velocities = {}
    for name in table.table:
        entry = table.sub(name)
        entry.only({"velocity", "omega"})
        if not entry.table:
            entry.fail("velocity", "missing value: give `velocity` or `omega` (or leave the body out: at rest)")
        velocities[name] = (vector(entry, "velocity", "[vx, vy, vz] in m/s") if "velocity" in entry.table
                            else (0.0, 0.0, 0.0),
                            vector(entry, "omega", "[wx, wy, wz] in rad/s") if "omega" in entry.table
                            else (0.0, 0.0, 0.0))
    return velocities


def _gravity(table: Reader) -> Vec3:
    table.only({"gravity"})
    return vector(table, "gravity", "[gx, gy, gz] in m/s²") if "gravity" in table.table else (0.0, 0.0, 0.0)
