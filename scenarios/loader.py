"""Load and validate scenario files (docs/scenario-format.md) into `Scenario`s.

Every refusal is a `ScenarioError` naming the file, the dotted key and the
reason; nothing is half-loaded. Defaults for omitted optional tables: no
effects, the default tolerances, the engines' own derived settings.
"""

from __future__ import annotations

import re
import sys
import tomllib
from dataclasses import fields
from pathlib import Path
from typing import Any, Collection, Mapping

import numpy as np

from mechval.drive import DriveLaw
from mechval.analysis import check_trustworthy
from mechval.limits import check_scene, shown_int
from mechval.linkages import LINKAGES
from mechval.mechanism import InitialValue, TorqueLaw
from mechval.scenario import LinkMass, Scenario, ScenarioError, TimeGrid, Tolerance

from .dynamic import check_initial_state
from .planar import parse_planar
from .tables import MAX_MAGNITUDE, Reader, engine_tables, scenario_name, shown, tolerance

HERE = Path(__file__).resolve().parent
#: The crank's pivot joint in every closed-form kind's Mechanism.
CRANK_PIVOT = "O2"
TOP_KEYS = {"name", "mechanism", "description", "tags", "geometry", "mass", "drive",
            "effects", "time", "tolerance", "engines"}
REQUIRED_TABLES = ("geometry", "mass", "drive", "time")
BRANCHES = {"fourbar": ("open", "crossed"), "slider_crank": ("right", "left"),
            "inverted_slider": ("left", "right")}
#: The ground may be given a mass (as in the published four-bar study); it
#: does not move, so the value is checked and otherwise has no effect.
IGNORED_MASS_KEYS = {"ground"}


def builtin_names() -> list[str]:
    return sorted(p.stem for p in HERE.glob("*.toml"))


def builtin_path(name: str) -> Path:
    return HERE / f"{name}.toml"


#: A built-in name: plain names (letters, digits, _ . -, not starting with
#: . or -) joined by /, so that it names a file under scenarios/ and no
#: other (`../../x` is no built-in name: a path outside needs its .toml).
BUILTIN_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*(/[A-Za-z0-9_][A-Za-z0-9_.-]*)*")


def load(name_or_path: str | Path, engines: Collection[str] | None = None) -> Scenario:
    """Load a built-in scenario by name (BUILTIN_NAME), or a scenario file
    by path (`engines`: see `parse`)."""
    text = str(name_or_path)
    path = Path(text)
    try:
        if (not path.suffix and not path.exists() and BUILTIN_NAME.fullmatch(text)
                and builtin_path(text).exists()):
            path = builtin_path(text)
        found = path.is_file()
    except OSError as exc:              # e.g. a folder on the way that may not be searched
        raise ScenarioError(text, "file", f"cannot read: {exc.strerror or exc}") from None
    if not found:
        known = ", ".join(builtin_names())
        raise ScenarioError(text, "file", f"no such scenario file or built-in scenario (built-in: {known})")
    return parse(read_toml(path), path, engines)


def read_toml(path: Path) -> dict[str, Any]:
    """The parsed TOML document, or a ScenarioError saying why not."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(path, "file", f"cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ScenarioError(path, "file", f"not valid TOML: {exc}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(path, "file", f"not valid TOML: {exc}") from None
    except RecursionError:
        raise ScenarioError(path, "file", "tables or arrays nested too deeply to read") from None
    except ValueError as exc:           # Python reads at most 4300 decimal digits per integer
        where = _long_integer(text)
        if where is None:
            raise ScenarioError(path, "file", f"not valid TOML: {exc}") from None
        key, digits = where
        raise ScenarioError(path, key, f"an integer of {digits} digits; its magnitude exceeds "
                                       f"{MAX_MAGNITUDE:g}") from None


def _long_integer(text: str) -> tuple[str, int] | None:
    """The dotted key (as written, under its [table]) and digit count of the
    first decimal integer too long for Python to read, or None."""
    limit = sys.get_int_max_str_digits()
    table = ""
    for line in text.splitlines() if limit else ():
        header = re.match(r"\s*\[+([^\]]*)\]+", line)
        if header:
            table = header.group(1).strip()
        number = re.search(r"[0-9_]{%d,}" % (limit + 1), line)
        if number:
            digits = len(number.group(0).replace("_", ""))
            key = re.match(r"\s*([^=]+?)\s*=", line)
            return (".".join(filter(None, (table, key.group(1)))) if key else "file"), digits
    return None


def parse(data: Mapping[str, Any], source: str | Path | None = None,
          engines: Collection[str] | None = None) -> Scenario:
    """Validate a parsed TOML document into a `Scenario` (SI units).

    `engines`: the engine names an `[engines.NAME]` table may name (the
    harness passes its registry's); None accepts any name, and an adapter
    still refuses settings it does not know."""
    if data.get("mechanism") == "planar":       # bodies and joints: docs/scenario-format.md#planar-files
        return parse_planar(data, source, engines)
    top = Reader(source, "", data)
    top.only(TOP_KEYS)
    name = scenario_name(top)
    kind = top.string("mechanism", choices=(*LINKAGES, "planar"))
    description = top.string("description", default="")
    tags = data.get("tags", [])
    if not isinstance(tags, list) or not all(isinstance(t, str) for t in tags):
        top.fail("tags", f"expected a list of strings, got {shown(tags)}")
    for table in REQUIRED_TABLES:
        top.sub(table, required=True)
    module = LINKAGES[kind]
    geometry = _geometry(top.sub("geometry"), kind, module)
    mass = _masses(top.sub("mass"), module, geometry)
    drive, torque_laws, initial_values = _drive(top.sub("drive"))
    gravity, damping = _effects(top.sub("effects"), module)
    time_table = top.sub("time")
    time_table.only({"end", "samples"})
    samples = time_table.table.get("samples")
    if isinstance(samples, bool) or not isinstance(samples, int):
        time_table.fail("samples", f"expected a whole number, got {shown(samples)}" if samples is not None else "missing value")
    if samples < 2:
        time_table.fail("samples", f"must be at least 2, got {shown_int(samples)}")
    time = TimeGrid(time_table.number("end", positive=True), samples)
    scenario = Scenario(name=name, mechanism=kind, description=description, geometry=geometry, mass=mass,
                        drive=drive, gravity=gravity, damping=damping, time=time,
                        tolerance=Tolerance().updated(tolerance(top.sub("tolerance"))),
                        engines=engine_tables(top.sub("engines"), engines), tags=tuple(tags), source=Path(source) if source else None,
                        torque_laws=torque_laws, initial_values=initial_values)
    check_scene(scenario)       # before anything is evaluated at the samples
    if drive is None:           # the crank's motion is integrated: its start must assemble
        start = DriveLaw(initial_values[0].value)
        module.check_closure(module.Geometry(**geometry), start, np.zeros(1), source, key="drive.phi0")
        check_initial_state(scenario, {"initial": "drive.phi0", "torque": "drive"})
        return scenario
    module.check_closure(module.Geometry(**geometry), drive, _dense_times(time), source)
    check_trustworthy(scenario)
    return scenario


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


def _dense_times(time: TimeGrid):
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


def _masses(table: Reader, module, geometry: Mapping[str, Any]) -> dict[str, LinkMass]:
    table.only(set(module.LINKS) | IGNORED_MASS_KEYS)
    if "ground" in table.table:
        table.number("ground", positive=True)
    masses = {}
    for link in module.LINKS:
        value = table.table.get(link)
        if value is None:
            table.fail(link, "missing value (a mass in kg, or a table {mass=, com=, izz=})")
        length = geometry.get(link)
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
