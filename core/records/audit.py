"""The compiled-model audit: what an engine will simulate, read back from
its built model and set against the `Mechanism` (docs/adapters.md: "only the
effects the scene lists are simulated", as a table).

`expected_model(mechanism)` lists, from the Mechanism alone, what every
engine model must hold: per body mass, centre of mass (body frame) and izz
(with no out-of-plane products of inertia, so z stays a principal axis);
per joint its kind, bodies, point on each body, a prismatic joint's axis
(body_i frame) and locked relative rotation, and its damping; the drive
(joint, φ0, ω0, α); each torque law (joint, torque, amplitude, frequency,
phase) and, for each joint whose motion is integrated from an initial
value, that nothing prescribes it; gravity (0 when the scene has none; z
always 0); and a fixed list of effects that must be absent
(`ABSENT_EFFECTS`).

Engine audits (`mechval.engines.<engine>.audit`) build the model with the
adapter's own build functions and read it with a `ModelReader` (one
protocol for every engine), which returns `Reading`s under the same
(item, quantity) keys, converted to the Mechanism's frame conventions (each
states how). `audit(expected, readings)` joins the two into one row per
quantity with a verdict:

- "match": the engine holds the expected value, read back from its model;
- "as set": the engine cannot report the value (PyBullet has no getter for
  damping, speed clamps or motors); it is the value the adapter's build
  passed to the engine (recorded from the calls) and equals the expected one;
- "differs": the values differ, or the engine holds something the
  Mechanism does not (an extra element is a reading with no expectation);
- "note": an engine element or setting with no Mechanism counterpart
  (MuJoCo's clock body, soft-constraint time constants, Exudyn's numerical
  damping), or a quantity that is not in the model at all (PyBullet's drive
  law, applied by the stepping loop), listed with its explanation;
- "missing": an expected quantity the engine audit did not read (a gap in
  the audit itself; counts as a failure like "differs").

Numbers match when |actual − expected| ≤ rtol·max(|expected|, scale): the
scale is the size that makes a rounding error meaningful (the mechanism's
length for positions, 1 for unit vectors); effects that must be absent have
scale 0, so the engine must hold exactly 0.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Literal, Mapping, Sequence

import numpy as np
import pandas as pd

from mechval.model.kinematics import rotate
from mechval.model.mechanism import GROUND, BodyTorque, Drive, Joint, Mechanism, SpringDamper, TorqueLaw

#: Engines store what they are given in float64 (PyBullet too; only its
#: `getLinkState` link-frame output is float32, and the audits do not use it)
#: and the audit converts world-frame values back with a few rotations, so a
#: faithful model agrees to a few ulps (`tests/bench/audit_bench.py` prints
#: the largest deviation over the built-in scenes). 1e-12 leaves three
#: decades for other geometry; a modelling slip is far larger.
AUDIT_RTOL = 1e-12

Value = float | str
Source = Literal["read", "set", "note"]
MATCH, AS_SET, DIFFERS, NOTE, MISSING = "match", "as set", "differs", "note", "missing"
FAILING = (DIFFERS, MISSING)

#: Effects the Mechanism never asks for: each engine must show each absent
#: ("none"/"off"), or name what it holds.
ABSENT_EFFECTS: Mapping[str, str] = {
    "contacts": "off",
    "joint limits": "none",
    "joint friction": "none",
    "joint springs": "none",
    "added inertia (armature)": "none",
    "motors other than the drive": "none",
    "velocity damping of bodies": "none",
    "fluid forces": "none",
    "velocity clamps": "none",
    "sleeping (deactivation)": "none",
    "other dampers": "none",
    "other loads": "none",
    "other constraints": "none",
}
SCENE = "scene"
DRIVE = "drive"
COLUMNS = ["item", "quantity", "expected", "actual", "unit", "verdict", "deviation", "note"]


@dataclass(frozen=True)
class Expectation:
    """A quantity every engine model must hold."""

    item: str
    quantity: str
    value: Value
    unit: str = ""
    scale: float = 0.0


@dataclass(frozen=True)
class Reading:
    """What an engine model holds for (item, quantity): read back ("read"),
    recorded from the build's calls because the engine cannot report it
    ("set"), or an explanation with no Mechanism counterpart ("note")."""

    item: str
    quantity: str
    value: Value
    note: str = ""
    source: Source = "read"
    unit: str = ""


class ModelReader(ABC):
    """Reads one engine's built model in the state a run starts from: the
    protocol every engine audit implements (the same methods, the same
    signatures). The engine's `audit_model(mechanism, times, settings)`
    builds the model as its adapter does and hands the reader everything
    it needs; `table()` is the audit."""

    mech: Mechanism

    @abstractmethod
    def body(self, name: str) -> list[Reading]:
        """The body's mass, centre of mass (body frame) and izz."""

    @abstractmethod
    def joint(self, joint: Joint) -> list[Reading]:
        """The joint's kind, bodies, points (and a slide's axis)."""

    @abstractmethod
    def scene(self) -> list[Reading]:
        """Gravity and every effect that must be absent (`ABSENT_EFFECTS`)."""

    @abstractmethod
    def notes(self) -> list[Reading]:
        """Engine elements and settings with no Mechanism counterpart."""

    @abstractmethod
    def readings(self) -> list[Reading]:
        """Every reading of the model, the scene's and the notes included."""

    def table(self) -> pd.DataFrame:
        """The audit table: the readings set against `expected_model`."""
        return audit(expected_model(self.mech), self.readings())


@dataclass(frozen=True)
class AuditRow:
    item: str
    quantity: str
    expected: Value
    actual: Value
    unit: str
    verdict: str
    deviation: float
    note: str


def body_item(name: str) -> str:
    return f"body {name}"


def joint_item(name: str) -> str:
    return f"joint {name}"


def point_quantity(body: str, axis: str) -> str:
    return f"point on {body} {axis}"


def length_scale(mech: Mechanism) -> float:
    """The mechanism's size (m): the largest distance of a centre of mass or
    joint point from its frame origin."""
    points = [b.com for b in mech.bodies] + [p for j in mech.joints for p in (j.point_i, j.point_j)]
    return max(float(np.hypot(*p)) for p in points) or 1.0


def expected_model(mech: Mechanism) -> list[Expectation]:
    """Every quantity an engine model of `mech` must hold (see the module
    docstring); from the Mechanism alone."""
    length = length_scale(mech)
    rows: list[Expectation] = []
    for b in mech.bodies:
        item = body_item(b.name)
        inertia = max(b.izz, b.mass * length**2)
        rows += [Expectation(item, "mass", b.mass, "kg", b.mass),
                 Expectation(item, "com x", b.com[0], "m", length),
                 Expectation(item, "com y", b.com[1], "m", length),
                 Expectation(item, "izz", b.izz, "kg·m²", inertia),
                 Expectation(item, "ixz", 0.0, "kg·m²", inertia),
                 Expectation(item, "iyz", 0.0, "kg·m²", inertia)]
    for j in mech.joints:
        item = joint_item(j.name)
        rows += [Expectation(item, "kind", j.kind), Expectation(item, "bodies", f"{j.body_i}–{j.body_j}")]
        for body, point in ((j.body_i, j.point_i), (j.body_j, j.point_j)):
            rows += [Expectation(item, point_quantity(body, "x"), point[0], "m", length),
                     Expectation(item, point_quantity(body, "y"), point[1], "m", length)]
        if j.kind == "prismatic":
            axis = np.asarray(j.axis) / np.hypot(*j.axis)
            rows += [Expectation(item, "axis x", float(axis[0]), "", 1.0),
                     Expectation(item, "axis y", float(axis[1]), "", 1.0),
                     Expectation(item, "relative rotation", "locked")]
        unit = "N·m·s/rad" if j.kind == "revolute" else "N·s/m"
        rows.append(Expectation(item, "damping", j.damping, unit, abs(j.damping)))
    for drive in mech.drives:
        item = drive_item(mech, drive)
        law = drive.law
        size = max(abs(law.phi0), abs(law.omega0), abs(law.alpha)) or 1.0
        unit = "rad" if mech.joint(drive.joint).kind == "revolute" else "m"
        rows += [Expectation(item, "joint", drive.joint),
                 Expectation(item, "phi0", law.phi0, unit, size),
                 Expectation(item, "omega0", law.omega0, f"{unit}/s", size),
                 Expectation(item, "alpha", law.alpha, f"{unit}/s²", size)]
    for force in mech.forces:
        rows += _force_expectations(force, length)
    for law in mech.torque_drives:
        rows += _torque_law_expectations(law)
    # A degree of freedom the run integrates carries no constraint of its own.
    rows += [Expectation(joint_item(v.joint), "prescribed motion", "none") for v in mech.initial_values]
    g = float(np.hypot(*mech.gravity))
    rows += [Expectation(SCENE, "gravity x", mech.gravity[0], "m/s²", g),
             Expectation(SCENE, "gravity y", mech.gravity[1], "m/s²", g),
             Expectation(SCENE, "gravity z", 0.0, "m/s²", g)]
    rows += [Expectation(SCENE, effect, absent) for effect, absent in ABSENT_EFFECTS.items()]
    return rows


def drive_item(mech: Mechanism, drive: Drive) -> str:
    """The first drive's rows are "drive" (as before several drives); the
    others' "drive NAME"."""
    return DRIVE if drive == mech.drive else f"{DRIVE} {drive.name}"


def force_item(force: SpringDamper | BodyTorque) -> str:
    return f"{'spring' if isinstance(force, SpringDamper) else 'torque'} {force.name}"


def torque_law_item(law: TorqueLaw) -> str:
    return f"torque law {law.name}"


def _torque_law_expectations(law: TorqueLaw) -> list[Expectation]:
    """A torque law's joint and its T(t) = torque + amplitude·sin(2π·
    frequency·t + phase) (T on body_j, −T on body_i)."""
    item = torque_law_item(law)
    size = max(abs(law.torque), abs(law.amplitude)) or 1.0
    return [Expectation(item, "joint", law.joint),
            Expectation(item, "torque", law.torque, "N·m", size),
            Expectation(item, "amplitude", law.amplitude, "N·m", size),
            Expectation(item, "frequency", law.frequency, "Hz", abs(law.frequency)),
            Expectation(item, "phase", law.phase, "rad", 1.0)]


def _force_expectations(force: SpringDamper | BodyTorque, length: float) -> list[Expectation]:
    """A spring-damper's bodies, points (a and b, body frames), stiffness,
    free length and damping; a body torque's body and torque."""
    item = force_item(force)
    if isinstance(force, BodyTorque):
        return [Expectation(item, "body", force.body),
                Expectation(item, "torque", force.torque, "N·m", abs(force.torque))]
    rows = [Expectation(item, "bodies", f"{force.body_a}–{force.body_b}")]
    for end, point in (("a", force.point_a), ("b", force.point_b)):
        rows += [Expectation(item, f"point {end} x", point[0], "m", length),
                 Expectation(item, f"point {end} y", point[1], "m", length)]
    return rows + [Expectation(item, "stiffness", force.stiffness, "N/m", abs(force.stiffness)),
                   Expectation(item, "free length", force.free_length, "m", length),
                   Expectation(item, "damping", force.damping, "N·s/m", abs(force.damping))]


def _verdict(expected: Expectation, reading: Reading, rtol: float) -> tuple[str, float]:
    """(verdict, deviation relative to the row's scale; NaN for text)."""
    if reading.source == "note":
        return NOTE, float("nan")
    agree = AS_SET if reading.source == "set" else MATCH
    e, a = expected.value, reading.value
    if isinstance(e, str) or isinstance(a, str):
        return (agree if e == a else DIFFERS), float("nan")
    size = max(abs(e), expected.scale)
    deviation = abs(a - e) / size if size > 0 else (0.0 if a == e else float("inf"))
    return (agree if abs(a - e) <= rtol * size else DIFFERS), deviation


def audit(expected: Sequence[Expectation], readings: Sequence[Reading], rtol: float = AUDIT_RTOL) -> pd.DataFrame:
    """One row per quantity (the `COLUMNS`): expected rows in their order,
    then engine rows that have no expectation (notes, or extra elements,
    which differ)."""
    by_key: dict[tuple[str, str], Reading] = {}
    for r in readings:
        key = (r.item, r.quantity)
        if key in by_key:
            raise ValueError(f"audit: two readings of {r.item} {r.quantity}")
        by_key[key] = r
    rows = []
    for e in expected:
        r = by_key.pop((e.item, e.quantity), None)
        if r is None:
            rows.append(AuditRow(e.item, e.quantity, e.value, "", e.unit, MISSING, float("nan"),
                                 "the engine audit did not read this"))
            continue
        verdict, deviation = _verdict(e, r, rtol)
        rows.append(AuditRow(e.item, e.quantity, e.value, r.value, e.unit or r.unit, verdict, deviation, r.note))
    for r in by_key.values():
        verdict = NOTE if r.source == "note" else DIFFERS
        note = r.note if r.source == "note" else f"not in the Mechanism. {r.note}".strip()
        rows.append(AuditRow(r.item, r.quantity, "", r.value, r.unit, verdict, float("nan"), note))
    return pd.DataFrame([vars(row) for row in rows], columns=COLUMNS)


def failures(table: pd.DataFrame) -> pd.DataFrame:
    """The rows that say the engine model is not the Mechanism."""
    return table[table["verdict"].isin(FAILING)]


def format_audit(table: pd.DataFrame) -> str:
    """The table as plain text (full precision for numbers)."""
    text = table.copy()
    for column in ("expected", "actual"):
        text[column] = [f"{v:.15g}" if isinstance(v, float) else str(v) for v in text[column]]
    text["deviation"] = [f"{v:.1e}" if np.isfinite(v) else "" for v in text["deviation"]]
    return text.to_string(index=False, justify="left")


# -- frame conversions shared by the engine audits ------------------------------

def pose(start: Mapping[str, object], body: str) -> tuple[np.ndarray, float]:
    """Origin (world, m) and angle (rad) of `body`'s frame in the reference
    motion `start` (raw columns of one instant; the ground's is the world)."""
    if body == GROUND:
        return np.zeros(2), 0.0
    value = lambda q: float(np.asarray(start[f"{body}.{q}"]).reshape(-1)[0])
    return np.array([value("x"), value("y")]), value("theta")


def to_body(start: Mapping[str, object], body: str, world_point) -> np.ndarray:
    """A world point expressed in `body`'s frame at the reference pose:
    p_B = R(θ_B)ᵀ·(p_W − o_B)."""
    origin, theta = pose(start, body)
    return np.array(rotate(-theta, np.asarray(world_point, dtype=float)[:2] - origin))


def to_body_direction(start: Mapping[str, object], body: str, world_vector) -> np.ndarray:
    """A world direction expressed in `body`'s axes at the reference pose."""
    return np.array(rotate(-pose(start, body)[1], np.asarray(world_vector, dtype=float)[:2]))


def to_world(start: Mapping[str, object], body: str, body_point) -> np.ndarray:
    """A body-frame point in world at the reference pose."""
    origin, theta = pose(start, body)
    return origin + np.array(rotate(theta, np.asarray(body_point, dtype=float)[:2]))


def nearest_on_line(point, through, direction) -> np.ndarray:
    """The point of the line (through, direction) nearest to `point` (2-D)."""
    through, direction = np.asarray(through, dtype=float)[:2], np.asarray(direction, dtype=float)[:2]
    u = direction / np.hypot(*direction)
    return through + np.dot(np.asarray(point, dtype=float)[:2] - through, u) * u


def point_readings(mech: Mechanism, start: Mapping[str, object], joint: str, anchors: Mapping[str, object],
                   line_direction=None, note: str = "") -> list[Reading]:
    """Readings of a joint's point on each body from the engine's world
    anchor per body (initial state). For a prismatic joint every point of
    the guide line (world direction `line_direction`) serves: the point of
    the engine's line nearest to the Mechanism's point is reported."""
    j = mech.joint(joint)
    readings = []
    for body, point in ((j.body_i, j.point_i), (j.body_j, j.point_j)):
        world = np.asarray(anchors[body], dtype=float)[:2]
        if line_direction is not None:
            world = nearest_on_line(to_world(start, body, point), world, line_direction)
        local = to_body(start, body, world)
        readings += [Reading(joint_item(joint), point_quantity(body, axis), float(v), note)
                     for axis, v in zip("xy", local)]
    return readings


def axis_readings(mech: Mechanism, start: Mapping[str, object], joint: str, world_axis,
                  note: str = "") -> list[Reading]:
    """A prismatic joint's axis in body_i's frame from the engine's world
    direction, normalised; its sign only orients the coordinate, so it is
    turned to point along the Mechanism's axis."""
    j = mech.joint(joint)
    axis = to_body_direction(start, j.body_i, world_axis)
    axis = axis / np.hypot(*axis)
    if np.dot(axis, j.axis) < 0:
        axis = -axis
    text = (note + " " if note else "") + "Direction only (the sign orients the coordinate)."
    return [Reading(joint_item(joint), f"axis {c}", float(v), text) for c, v in zip("xy", axis)]


def inertia_readings(body: str, world_inertia: np.ndarray, note: str = "") -> list[Reading]:
    """izz and the out-of-plane products of a 3×3 world inertia tensor about
    the centre of mass (the body frame's z is the world's)."""
    item = body_item(body)
    return [Reading(item, "izz", float(world_inertia[2, 2]), note),
            Reading(item, "ixz", float(world_inertia[0, 2]), note),
            Reading(item, "iyz", float(world_inertia[1, 2]), note)]


def bodies_text(joint: Joint, pair: Sequence[str]) -> str:
    """The 'bodies' reading of a joint the engine places between `pair`:
    the Mechanism's text when the pair is the joint's, in either order."""
    if set(pair) == {joint.body_i, joint.body_j} and len(pair) == 2:
        return f"{joint.body_i}–{joint.body_j}"
    return "–".join(pair)


def listing(found: Sequence[str], absent: str = "none") -> str:
    """`absent` when nothing was found, else the found items joined."""
    return "; ".join(found) if found else absent


@dataclass(frozen=True)
class AuditResult:
    """One engine's audit table on one scenario, or why there is none."""

    scenario: str
    engine: str
    table: pd.DataFrame | None = field(default=None, compare=False)
    error: str = ""
    seconds: float = 0.0

    @property
    def failing(self) -> int:
        return len(failures(self.table)) if self.table is not None else 0

    @property
    def ok(self) -> bool:
        return self.table is not None and self.failing == 0
