"""Planar files (`mechanism = "planar"`, docs/scenario-format.md#planar-files):
any mechanism of rigid bodies, revolute and prismatic joints, drives and
force elements, validated into a `Scenario` whose scene is the file's as
written (`mechval.model.scene`; no closed form: the general reference solves it);
joints left undriven take applied torque laws (`[[torque]]`) and the
initial values a run starts from (`[[initial]]`), checked by assembling the
consistent initial state (`scenarios.dynamic`).

Every refusal is a `ScenarioError` naming the file, the key and the reason.
Beyond each key's own checks: an unknown body or point, a joint from a body
to itself, a body not connected to the ground, two drives on one joint;
then, by assembling the mechanism and following it over the run
(`mechval.reference.planar.solver`): drives that do not match the mobility (the
Grübler count and the Jacobian rank both stated), a pose that cannot be
assembled, an instant where the loop cannot close or the Jacobian is
singular (its time named).
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any, Collection, Mapping

from mechval.model.drive import DriveLaw
from mechval.reference.limits import check_scene
from mechval.reference.linkages import build_mechanism
from mechval.model.mechanism import GROUND, Body, BodyPose, BodyTorque, Drive, InitialValue, Joint, SpringDamper, TorqueLaw
from mechval.reference.planar.solver import MechanismError, PlanarSolver
from mechval.model.scenario import Scenario, ScenarioError
from mechval.model.scene import Scene

from .dynamic import check_initial_state
from .tables import Reader, heading, run_tables, shown

TOP_KEYS = {"name", "mechanism", "description", "tags", "ground", "body", "joint", "drive", "torque",
            "initial", "force", "assembly", "effects", "time", "tolerance", "engines"}
NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*\Z")
#: An `[assembly]` angle is approximate (often rounded: hand-pump's 1.57
#: for π/2): a prismatic joint without `angle` whose assembly pose is this
#: close (rad) to its axis's angle holds the axis's angle exactly.
AXIS_SNAP = 0.05


def parse_planar(data: Mapping[str, Any], source: str | Path | None = None,
                 engines: Collection[str] | None = None) -> Scenario:
    """Validate a planar file's parsed TOML into a `Scenario` (SI units)."""
    top = Reader(source, "", data)
    top.only(TOP_KEYS)
    name, _, description, tags = heading(top)
    ground = _points(top.sub("ground"))
    bodies, points = _bodies(top, ground)
    joints = _joints(top, points)
    _connected(top, bodies, joints)
    drives = _drives(top, joints)
    torques = _torques(top, joints, drives)
    initial = _initial(top, joints)
    forces = _forces(top, points)
    pose = _assembly(top.sub("assembly", required=True), bodies)
    joints = _held_angles(joints, pose)
    gravity = _gravity(top.sub("effects"))
    time, tolerance, engine_tables = run_tables(top, engines)
    scene = Scene(bodies, joints, drives, forces, pose, gravity, torques, initial)
    scenario = Scenario(name=name, description=description, scene=scene, time=time, tolerance=tolerance,
                        engines=engine_tables, tags=tags, source=Path(source) if source else None)
    check_scene(scenario)       # before the mechanism is followed over the run
    if scenario.forward_dynamics:
        check_initial_state(scenario)
    else:
        _solvable(scenario, source)
    return scenario


# -- values ----------------------------------------------------------------------------------------

def _pair(table: Reader, key: str, what: str = "[x, y] in m") -> tuple[float, float]:
    value = table.table.get(key)
    if not isinstance(value, list) or len(value) != 2:
        table.fail(key, f"expected two finite numbers {what}, got {shown(value)}")
    # each entry checked as every number is (finite, not a bool, not too large)
    return table.check_number(f"{key}[0]", value[0]), table.check_number(f"{key}[1]", value[1])


def _name(table: Reader, key: str = "name") -> str:
    value = table.string(key)
    if not NAME.match(value) or value == GROUND:
        table.fail(key, f"{value!r} is not a usable name (letters, digits, _ and -, not starting with a digit; "
                        f"not {GROUND!r})")
    return value


def _array(top: Reader, key: str, required: bool = False) -> list[Reader]:
    """The tables of an array of tables [[key]], each with a reader."""
    value = top.table.get(key, [])
    if required and not value:
        top.fail(key, f"missing: at least one [[{key}]] table")
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        top.fail(key, f"expected an array of tables [[{key}]], got {type(value).__name__}")
    return [Reader(top.source, f"{key}[{k}]", entry) for k, entry in enumerate(value)]


def _named(readers: list[Reader], kind: str) -> list[tuple[str, Reader]]:
    """(name, reader) pairs with each reader's errors keyed by the name,
    refusing duplicate names."""
    named, seen = [], set()
    for reader in readers:
        name = _name(reader)
        if name in seen:
            reader.fail("name", f"a second {kind} named {name!r}")
        seen.add(name)
        named.append((name, Reader(reader.source, f"{kind}.{name}", reader.table)))
    return named


def _points(table: Reader) -> dict[str, tuple[float, float]]:
    points = {}
    for key in table.table:
        if not NAME.match(key):
            table.fail(key, f"{key!r} is not a usable point name")
        points[key] = _pair(table, key)
    return points


# -- the scene -------------------------------------------------------------------------------------

def _bodies(top: Reader, ground: dict) -> tuple[tuple[Body, ...], dict[str, dict]]:
    """Bodies, and every body's named points (the ground's too)."""
    bodies, points = [], {GROUND: ground}
    for name, body in _named(_array(top, "body", required=True), "body"):
        body.only({"name", "mass", "length", "com", "izz", "points"})
        mass = body.number("mass", positive=True)
        own = _points(body.sub("points"))
        if "length" in body.table:
            length = body.number("length", positive=True)
            for end, at in (("start", (0.0, 0.0)), ("end", (length, 0.0))):
                if end in own:
                    body.fail(f"points.{end}", f"{end!r} is the bar's end given by `length`; name this point otherwise")
                own[end] = at
            com = _pair(body, "com") if "com" in body.table else (length / 2, 0.0)
            izz = body.number("izz", default=mass * length**2 / 12, nonnegative=True)
        else:
            for key in ("com", "izz"):
                if key not in body.table:
                    body.fail(key, "missing value (give `length` for a uniform bar, or `com` and `izz`)")
            com, izz = _pair(body, "com"), body.number("izz", nonnegative=True)
        bodies.append(Body(name, mass, com, izz))
        points[name] = own
    return tuple(bodies), points


def _point(reader: Reader, key: str, text: Any, points: dict) -> tuple[str, tuple[float, float]]:
    """Resolve "body.point" (the ground's points as "ground.point")."""
    if not isinstance(text, str) or text.count(".") != 1:
        reader.fail(key, f"expected \"body.point\", got {shown(text)}")
    body, point = text.split(".")
    if body not in points:
        reader.fail(key, f"unknown body {body!r} (bodies: {', '.join(sorted(points))})")
    if point not in points[body]:
        known = ", ".join(sorted(points[body])) or "none"
        reader.fail(key, f"{body!r} has no point {point!r} (its points: {known})")
    return body, points[body][point]


def _between(reader: Reader, points: dict) -> tuple[tuple[str, tuple], tuple[str, tuple]]:
    value = reader.table.get("between")
    if not isinstance(value, list) or len(value) != 2:
        reader.fail("between", f"expected two points [\"body.point\", \"body.point\"], got {shown(value)}")
    return _point(reader, "between", value[0], points), _point(reader, "between", value[1], points)


def _joints(top: Reader, points: dict) -> tuple[Joint, ...]:
    joints = []
    for name, joint in _named(_array(top, "joint", required=True), "joint"):
        kind = joint.string("type", choices=("revolute", "prismatic"))
        joint.only({"name", "type", "between", "damping"} | ({"axis", "angle"} if kind == "prismatic" else set()))
        (body_i, p_i), (body_j, p_j) = _between(joint, points)
        if body_i == body_j:
            joint.fail("between", f"joins {body_i!r} to itself")
        damping = joint.number("damping", default=0.0, nonnegative=True)
        if kind == "revolute":
            joints.append(Joint(name, kind, body_i, body_j, p_i, p_j, damping=damping))
            continue
        ax, ay = _pair(joint, "axis", "[x, y] in the first body's frame")
        norm = math.hypot(ax, ay)
        if norm == 0:
            joint.fail("axis", "must not be zero")
        angle = joint.number("angle") if "angle" in joint.table else None
        joints.append(Joint(name, kind, body_i, body_j, p_i, p_j, (ax / norm, ay / norm), damping, angle))
    return tuple(joints)


def _connected(top: Reader, bodies: tuple[Body, ...], joints: tuple[Joint, ...]) -> None:
    """Every body reaches the ground through joints."""
    reached, grew = {GROUND}, True
    while grew:
        grew = False
        for j in joints:
            if (j.body_i in reached) != (j.body_j in reached):
                reached |= {j.body_i, j.body_j}
                grew = True
    for body in bodies:
        if body.name not in reached:
            top.fail(f"body.{body.name}", "is not connected to the ground by any chain of joints")


def _drives(top: Reader, joints: tuple[Joint, ...]) -> tuple[Drive, ...]:
    known = {j.name for j in joints}
    drives, driven = [], set()
    for drive in _array(top, "drive"):
        drive.only({"joint", "phi0", "omega0", "alpha"})
        joint = drive.string("joint")
        if joint not in known:
            drive.fail("joint", f"unknown joint {joint!r} (joints: {', '.join(sorted(known))})")
        if joint in driven:
            drive.fail("joint", f"a second drive on joint {joint!r}")
        driven.add(joint)
        law = DriveLaw(drive.number("phi0", default=0.0), drive.number("omega0"), drive.number("alpha", default=0.0))
        # The first drive keeps the raw name every adapter writes ("drive.T");
        # its canonical signal, like the others', is named after its joint.
        drives.append(Drive(joint, law, name="drive" if not drives else joint))
    return tuple(drives)


def _torques(top: Reader, joints: tuple[Joint, ...], drives: tuple[Drive, ...]) -> tuple[TorqueLaw, ...]:
    """[[torque]]: applied torque laws T(t) = torque + amplitude·sin(2π·frequency·t + phase)
    at revolute joints, each named after its joint unless given a `name`
    (a spatial file's joints and drives too: they have the same names)."""
    kinds = {j.name: j.kind for j in joints}
    driven = {d.joint for d in drives}
    laws, names = [], {d.name for d in drives} | {d.joint for d in drives}
    for entry in _array(top, "torque"):
        entry.only({"name", "joint", "torque", "amplitude", "frequency", "phase"})
        joint = entry.string("joint")
        if joint not in kinds:
            entry.fail("joint", f"unknown joint {joint!r} (joints: {', '.join(sorted(kinds))})")
        name = _name(entry) if "name" in entry.table else joint
        law = Reader(entry.source, f"torque.{name}", entry.table)
        if kinds[joint] != "revolute":
            law.fail("joint", f"joint {joint!r} is {kinds[joint]}: a torque law acts at a revolute joint")
        if joint in driven:
            law.fail("joint", f"joint {joint!r} has a drive, which prescribes its motion whatever the torque")
        if name in names:
            law.fail("name", f"a drive or another torque law is named {name!r} (give this one a `name`)")
        names.add(name)
        laws.append(TorqueLaw(joint, law.number("torque"), law.number("amplitude", default=0.0),
                              law.number("frequency", default=0.0, nonnegative=True),
                              law.number("phase", default=0.0), name=name))
    return tuple(laws)


def _initial(top: Reader, joints: tuple[Joint, ...]) -> tuple[InitialValue, ...]:
    """[[initial]]: a joint's coordinate (rad or m) and rate at t = 0, one
    per degree of freedom the drives leave (checked with the assembly)."""
    known = {j.name for j in joints}
    values, seen = [], set()
    for entry in _array(top, "initial"):
        entry.only({"joint", "value", "rate"})
        joint = entry.string("joint")
        if joint not in known:
            entry.fail("joint", f"unknown joint {joint!r} (joints: {', '.join(sorted(known))})")
        value = Reader(entry.source, f"initial.{joint}", entry.table)
        if joint in seen:
            value.fail("joint", "a second initial value for this joint")
        seen.add(joint)
        values.append(InitialValue(joint, value.number("value"), value.number("rate", default=0.0)))
    return tuple(values)


def _forces(top: Reader, points: dict) -> tuple[SpringDamper | BodyTorque, ...]:
    forces = []
    for k, force in enumerate(_array(top, "force")):
        name = _name(force) if "name" in force.table else f"force{k + 1}"
        kind = force.string("type", choices=("spring", "torque"))
        if kind == "torque":
            force.only({"name", "type", "body", "torque"})
            body = force.string("body")
            if body not in points or body == GROUND:
                force.fail("body", f"unknown body {body!r} (bodies: {', '.join(sorted(set(points) - {GROUND}))})")
            forces.append(BodyTorque(name, body, force.number("torque")))
            continue
        force.only({"name", "type", "between", "stiffness", "free_length", "damping"})
        (body_a, p_a), (body_b, p_b) = _between(force, points)
        if body_a == body_b:
            force.fail("between", f"joins {body_a!r} to itself: it would exert no force")
        forces.append(SpringDamper(name, body_a, p_a, body_b, p_b, force.number("stiffness", nonnegative=True),
                                   force.number("free_length", nonnegative=True),
                                   force.number("damping", default=0.0, nonnegative=True)))
    return tuple(forces)


def _assembly(table: Reader, bodies: tuple[Body, ...]) -> dict[str, BodyPose]:
    names = {b.name for b in bodies}
    table.only(names)
    pose = {}
    for body in bodies:
        if body.name not in table.table:
            table.fail(body.name, "missing: every body needs an approximate angle at t = 0 (rad)")
        if isinstance(table.table[body.name], dict):
            entry = table.sub(body.name)
            entry.only({"theta", "x", "y"})
            if ("x" in entry.table) != ("y" in entry.table):
                entry.fail("x" if "x" in entry.table else "y", "give both x and y of the frame's origin, or neither")
            xy = (entry.number("x"), entry.number("y")) if "x" in entry.table else (None, None)
            pose[body.name] = BodyPose(entry.number("theta"), *xy)
        else:
            pose[body.name] = BodyPose(table.number(body.name))
    return pose


def _held_angles(joints: tuple[Joint, ...], pose: Mapping[str, BodyPose]) -> tuple[Joint, ...]:
    """A prismatic joint without `angle` holds θj − θi of the assembly
    pose, as drawn (a slider drawn aligned with the world stays so, whatever
    its axis), or — where the pose is within AXIS_SNAP of it — the axis's
    angle exactly (`Joint.angle` None: body_j's x axis along the slide)."""
    def theta(body: str) -> float:
        return 0.0 if body == GROUND else pose[body].theta

    held = []
    for joint in joints:
        if joint.kind == "prismatic" and joint.angle is None:
            relative = theta(joint.body_j) - theta(joint.body_i)
            if abs(math.remainder(relative - joint.held_angle, math.tau)) > AXIS_SNAP:
                joint = replace(joint, angle=relative)
        held.append(joint)
    return tuple(held)


def _gravity(table: Reader) -> tuple[float, float]:
    table.only({"gravity"})
    return _pair(table, "gravity", "[gx, gy] in m/s²") if "gravity" in table.table else (0.0, 0.0)


def _solvable(scenario: Scenario, source) -> None:
    """Assemble the mechanism and follow it over the run: refuses what the
    general reference cannot solve, naming the key and, for an instant,
    the time. (Each sample's own solve, at run time, refuses the same way.)"""
    try:
        PlanarSolver(build_mechanism(scenario)).check(0.0, scenario.time.end)
    except MechanismError as exc:
        raise ScenarioError(source, exc.key, exc.reason) from None
