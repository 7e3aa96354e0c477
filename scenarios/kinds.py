"""The four closed-form kinds' front end (`mechanism = "fourbar"`,
`"slider_crank"`, `"slotted_lever"`, `"inverted_slider"`;
docs/scenario-format.md): a file's few numbers — geometry, masses, the
crank's drive, effects — expanded into the scene every scenario becomes
(`mechval.model.scene`), with the kind's closed form beside it
(`mechval.reference.linkages.ClosedForm`), which the reference then uses.

Every refusal is a `ScenarioError` naming the file, the dotted key and the
reason. Beyond each key's own checks: a loop that cannot close at some
instant of the run, a sample too close to a singular configuration, and
for a torque-driven or free crank an initial state that does not assemble.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path
from typing import Any, Collection, Mapping

import numpy as np

from mechval.reference.analysis import check_trustworthy
from mechval.model.drive import DriveLaw
from mechval.reference.limits import check_scene
from mechval.reference.linkages import CRANK_PIVOT, LINKAGES, ClosedForm, crank_drive
from mechval.model.mechanism import InitialValue, TorqueLaw
from mechval.model.scenario import LinkMass, Scenario
from mechval.model.scene import Scene

from .dynamic import check_initial_state
from .tables import Reader, heading, run_tables, shown

TOP_KEYS = {"name", "mechanism", "description", "tags", "geometry", "mass", "drive",
            "effects", "time", "tolerance", "engines"}
REQUIRED_TABLES = ("geometry", "mass", "drive", "time")
BRANCHES = {"fourbar": ("open", "crossed"), "slider_crank": ("right", "left"),
            "inverted_slider": ("left", "right")}
#: The ground may be given a mass (as in the published four-bar study); it
#: does not move, so the value is checked and otherwise has no effect.
IGNORED_MASS_KEYS = {"ground"}


def parse_kind(data: Mapping[str, Any], source: str | Path | None = None,
               engines: Collection[str] | None = None) -> Scenario:
    """Validate a closed-form kind's parsed TOML into a `Scenario` (SI units)."""
    top = Reader(source, "", data)
    top.only(TOP_KEYS)
    name, kind, description, tags = heading(top)
    for table in REQUIRED_TABLES:
        top.sub(table, required=True)
    module = LINKAGES[kind]
    geometry = module.Geometry(**_geometry(top.sub("geometry"), kind, module))
    mass = _masses(top.sub("mass"), module, geometry)
    drive, torque_laws, initial_values = _drive(top.sub("drive"))
    gravity, damping = _effects(top.sub("effects"), module)
    time, tolerance, engine_tables = run_tables(top, engines)
    bodies, joints = module.scene_parts(geometry, mass, damping)
    scene = Scene(bodies, joints, drives=(crank_drive(drive),) if drive else (), gravity=gravity or (0.0, 0.0),
                  torques=torque_laws, initial=initial_values)
    # Without a prescribed law the closed form follows a stand-in from the
    # crank's initial angle and rate: it picks the branch the run starts on.
    law = drive or DriveLaw(initial_values[0].value, initial_values[0].rate)
    closed = ClosedForm(kind, geometry, law)
    scenario = Scenario(name=name, description=description, scene=scene, time=time, tolerance=tolerance,
                        engines=engine_tables, tags=tags, source=Path(source) if source else None,
                        closed_form=closed, keys=_file_keys(module))
    check_scene(scenario)       # before anything is evaluated at the samples
    if drive is None:           # the crank's motion is integrated: its start must assemble
        ClosedForm(kind, geometry, DriveLaw(law.phi0)).check_closure(np.zeros(1), source, key="drive.phi0")
        check_initial_state(scenario, {"initial": "drive.phi0", "torque": "drive"})
        return scenario
    closed.check_closure(_dense_times(time), source)
    check_trustworthy(scenario, closed)
    return scenario


def _file_keys(module) -> dict[str, str]:
    """This format's key of each scene element a refusal may name."""
    keys = {"drive[0]": "drive", f"initial.{CRANK_PIVOT}": "drive.phi0", "initial": "drive.type"}
    for k, link in enumerate(module.LINKS):
        keys.update({f"body[{k}]": f"mass.{link}", f"body[{k}].com": f"mass.{link}"})
    return keys


#: The keys of each [drive] type of the four kinds.
DRIVE_KEYS = {"prescribed": {"phi0", "omega0", "alpha"},
              "torque": {"phi0", "omega0", "torque", "amplitude", "frequency", "phase"},
              "free": {"phi0", "omega0"}}


def _drive(table: Reader) -> tuple[DriveLaw | None, tuple[TorqueLaw, ...], tuple[InitialValue, ...]]:
    """The crank at O2: a prescribed law φ(t) (`type = "prescribed"`, the
    default), or a torque law (`"torque"`) or nothing (`"free"`) from the
    initial angle phi0 and rate omega0 (docs/scenario-format.md#drive)."""
    kind = table.string("type", default="prescribed", choices=tuple(DRIVE_KEYS))
    table.only(DRIVE_KEYS[kind] | {"type"})
    if kind == "prescribed":
        return (DriveLaw(table.number("phi0", default=0.0), table.number("omega0"),
                         table.number("alpha", default=0.0)), (), ())
    initial = (InitialValue(CRANK_PIVOT, table.number("phi0", default=0.0), table.number("omega0", default=0.0)),)
    if kind == "free":
        return None, (), initial
    law = TorqueLaw(CRANK_PIVOT, table.number("torque"), table.number("amplitude", default=0.0),
                    table.number("frequency", default=0.0, nonnegative=True), table.number("phase", default=0.0))
    return None, (law,), initial


#: Most points of the dense grid: beyond the samples' own density at the
#: largest grid (MAX_SAMPLES); 20 per sample would be 160 MB per array there.
DENSE_MAX = 2_000_001


def _dense_times(time):
    """The samples plus a dense grid, to locate where a loop fails to close."""
    return np.union1d(time.t, np.linspace(0.0, time.end, min(max(20 * time.samples, 20001), DENSE_MAX)))


def _geometry(table: Reader, kind: str, module) -> dict[str, Any]:
    table.only({f.name for f in fields(module.Geometry)})
    values: dict[str, Any] = {}
    for f in fields(module.Geometry):
        if f.name == "branch":
            values["branch"] = table.string("branch", default=f.default, choices=BRANCHES[kind])
        elif f.name == "offset":
            values["offset"] = table.number("offset", default=f.default)
        else:
            values[f.name] = table.number(f.name, positive=True)
    return values


def _masses(table: Reader, module, geometry) -> dict[str, LinkMass]:
    table.only(set(module.LINKS) | IGNORED_MASS_KEYS)
    if "ground" in table.table:
        table.number("ground", positive=True)
    masses = {}
    for link in module.LINKS:
        value = table.table.get(link)
        if value is None:
            table.fail(link, "missing value (a mass in kg, or a table {mass=, com=, izz=})")
        length = getattr(geometry, link, None)
        if isinstance(value, dict):
            sub = table.sub(link)
            if length is None:      # the slider: a point mass at its pin
                sub.only({"mass", "izz"})
                mass = sub.number("mass", positive=True)
                masses[link] = LinkMass(mass, 0.0, sub.number("izz", default=0.0, nonnegative=True))
            else:
                sub.only({"mass", "com", "izz"})
                mass = sub.number("mass", positive=True)
                masses[link] = LinkMass(mass, sub.number("com", default=length / 2),
                                        sub.number("izz", default=mass * length**2 / 12, positive=True))
        else:
            mass = table.number(link, positive=True)
            # A number means a uniform bar (com at mid-length, izz = m·L²/12)
            # or, for the slider, a point mass at its pin.
            masses[link] = (LinkMass(mass, 0.0, 0.0) if length is None
                            else LinkMass(mass, length / 2, mass * length**2 / 12))
    return masses


def _effects(table: Reader, module) -> tuple[tuple[float, float] | None, dict[str, float]]:
    table.only({"gravity", "damping"})
    gravity = None
    if "gravity" in table.table:
        value = table.table["gravity"]
        if not isinstance(value, list) or len(value) != 2:
            table.fail("gravity", f"expected two finite numbers [gx, gy] in m/s², got {shown(value)}")
        gravity = (table.check_number("gravity[0]", value[0]), table.check_number("gravity[1]", value[1]))
    damping_table = table.sub("damping")
    damping_table.only(set(module.PINS))
    damping = {pin: damping_table.number(pin, nonnegative=True) for pin in module.PINS if pin in damping_table.table}
    return gravity, damping
