"""Load and validate scenario files (docs/scenario-format.md) into `Scenario`s.

Every refusal is a `ScenarioError` naming the file, the dotted key and the
reason; nothing is half-loaded. Defaults for omitted optional tables: no
effects, the default tolerances, the engines' own derived settings.
"""

from __future__ import annotations

import math
import re
import reprlib
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
from mechval.scenario import (DEFAULT_TOLERANCE, EngineTable, LinkMass, Scenario,
                              ScenarioError, TimeGrid, Tolerance)

HERE = Path(__file__).resolve().parent
TOP_KEYS = {"name", "mechanism", "description", "tags", "geometry", "mass", "drive",
            "effects", "time", "tolerance", "engines"}
REQUIRED_TABLES = ("geometry", "mass", "drive", "time")
BRANCHES = {"fourbar": ("open", "crossed"), "slider_crank": ("right", "left"),
            "inverted_slider": ("left", "right")}
#: Largest magnitude accepted for any number (SI units): far beyond any
#: linkage, small enough that products like m·L²·ω² stay within float64.
MAX_MAGNITUDE = 1e50
#: The ground may be given a mass (as in the published four-bar study); it
#: does not move, so the value is checked and otherwise has no effect.
IGNORED_MASS_KEYS = {"ground"}


def builtin_names() -> list[str]:
    return sorted(p.stem for p in HERE.glob("*.toml"))


def builtin_path(name: str) -> Path:
    return HERE / f"{name}.toml"


def load(name_or_path: str | Path, engines: Collection[str] | None = None) -> Scenario:
    """Load a built-in scenario by name, or a scenario file by path
    (`engines`: see `parse`)."""
    text = str(name_or_path)
    path = Path(text)
    try:
        if not path.suffix and not path.exists() and builtin_path(text).exists():
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


def shown(value: Any) -> str:
    """A value quoted in an error: short, whatever its size or depth."""
    if isinstance(value, int) and not isinstance(value, bool):
        return shown_int(value)
    quote = reprlib.Repr()
    quote.maxlevel, quote.maxstring, quote.maxother, quote.maxlist, quote.maxdict = 3, 60, 60, 4, 4
    return quote.repr(value)


class _Reader:
    """Typed access to one table, with errors that name the dotted key."""

    def __init__(self, source, prefix: str, table: Mapping[str, Any]):
        self.source, self.prefix, self.table = source, prefix, table

    def key(self, name: str) -> str:
        return f"{self.prefix}.{name}" if self.prefix else name

    def fail(self, name: str, reason: str):
        raise ScenarioError(self.source, self.key(name), reason)

    def only(self, allowed) -> None:
        for name in self.table:
            if name not in allowed:
                self.fail(name, f"unknown key (allowed: {', '.join(sorted(allowed))})")

    def number(self, name: str, default=None, positive=False, nonnegative=False) -> float:
        if name not in self.table:
            if default is None:
                self.fail(name, "missing value")
            return default
        return self.check_number(name, self.table[name], positive, nonnegative)

    def check_number(self, name: str, value: Any, positive=False, nonnegative=False) -> float:
        """`value` (found under `name`) as a float, if it is an acceptable number."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(name, f"expected a number, got {type(value).__name__} {shown(value)}")
        if isinstance(value, float) and not math.isfinite(value):
            self.fail(name, f"must be finite, got {value}")
        if abs(value) > MAX_MAGNITUDE:      # exact for integers of any size
            magnitude = shown_int(value) if isinstance(value, int) else f"{value:g}"
            self.fail(name, f"magnitude {magnitude} exceeds {MAX_MAGNITUDE:g}: the reference squares and "
                            "multiplies such values beyond float64")
        if positive and value <= 0:
            self.fail(name, f"must be positive, got {value}")
        if nonnegative and value < 0:
            self.fail(name, f"must not be negative, got {value}")
        return float(value)

    def string(self, name: str, default=None, choices=None) -> str:
        if name not in self.table:
            if default is None:
                self.fail(name, "missing value")
            return default
        value = self.table[name]
        if not isinstance(value, str):
            self.fail(name, f"expected a string, got {type(value).__name__} {shown(value)}")
        if choices and value not in choices:
            self.fail(name, f"must be one of {', '.join(map(repr, choices))}, got {shown(value)}")
        return value

    def sub(self, name: str, required=False) -> "_Reader":
        if name not in self.table:
            if required:
                self.fail(name, "missing table")
            return _Reader(self.source, self.key(name), {})
        value = self.table[name]
        if not isinstance(value, dict):
            self.fail(name, f"expected a table, got {type(value).__name__} {shown(value)}")
        return _Reader(self.source, self.key(name), value)


def parse(data: Mapping[str, Any], source: str | Path | None = None,
          engines: Collection[str] | None = None) -> Scenario:
    """Validate a parsed TOML document into a `Scenario` (SI units).

    `engines`: the engine names an `[engines.NAME]` table may name (the
    harness passes its registry's); None accepts any name, and an adapter
    still refuses settings it does not know."""
    if data.get("mechanism") == "planar":       # bodies and joints: docs/scenario-format.md#planar-files
        from .planar import parse_planar
        return parse_planar(data, source, engines)
    top = _Reader(source, "", data)
    top.only(TOP_KEYS)
    name = top.string("name")
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
    drive_table = top.sub("drive")
    drive_table.only({"phi0", "omega0", "alpha"})
    drive = DriveLaw(drive_table.number("phi0", default=0.0), drive_table.number("omega0"),
                     drive_table.number("alpha", default=0.0))
    gravity, damping = _effects(top.sub("effects"), module)
    time_table = top.sub("time")
    time_table.only({"end", "samples"})
    samples = time_table.table.get("samples")
    if isinstance(samples, bool) or not isinstance(samples, int):
        time_table.fail("samples", f"expected a whole number, got {shown(samples)}" if samples is not None else "missing value")
    if samples < 2:
        time_table.fail("samples", f"must be at least 2, got {shown_int(samples)}")
    time = TimeGrid(time_table.number("end", positive=True), samples)
    tolerance = Tolerance().updated(_tolerance(top.sub("tolerance")))
    engine_tables = _engines(top.sub("engines"), engines)
    scenario = Scenario(name=name, mechanism=kind, description=description, geometry=geometry, mass=mass,
                        drive=drive, gravity=gravity, damping=damping, time=time, tolerance=tolerance,
                        engines=engine_tables, tags=tuple(tags), source=Path(source) if source else None)
    check_scene(scenario)       # before anything is evaluated at the samples
    module.check_closure(module.Geometry(**geometry), drive, _dense_times(time), source)
    check_trustworthy(scenario)
    return scenario


#: Most points of the dense grid: beyond the samples' own density at the
#: largest grid (MAX_SAMPLES); 20 per sample would be 160 MB per array there.
DENSE_MAX = 2_000_001


def _dense_times(time: TimeGrid):
    """The samples plus a dense grid, to locate where a loop fails to close."""
    return np.union1d(time.t, np.linspace(0.0, time.end, min(max(20 * time.samples, 20001), DENSE_MAX)))


def _geometry(table: _Reader, kind: str, module) -> dict[str, Any]:
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


def _masses(table: _Reader, module, geometry: Mapping[str, Any]) -> dict[str, LinkMass]:
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


def _effects(table: _Reader, module) -> tuple[tuple[float, float] | None, dict[str, float]]:
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


def _tolerance(table: _Reader) -> dict[str, float]:
    table.only(set(DEFAULT_TOLERANCE))
    return {k: table.number(k, positive=True) for k in table.table}


def _engine_tolerance(table: _Reader) -> tuple[dict[str, float], dict[str, str]]:
    """An [engines.NAME.tolerance] table: per class a bound, either a number
    or { bound = …, reason = "…" } (the reason is shown beside the bound in
    reports, so a loosened bound is never silent). Bounds and reasons."""
    table.only(set(DEFAULT_TOLERANCE))
    bounds, reasons = {}, {}
    for cls, value in table.table.items():
        if isinstance(value, dict):
            entry = table.sub(cls)
            entry.only({"bound", "reason"})
            bounds[cls] = entry.number("bound", positive=True)
            reasons[cls] = entry.string("reason")
            if not reasons[cls].strip():
                entry.fail("reason", "must not be empty (say why this engine needs a different bound)")
        else:
            bounds[cls] = table.number(cls, positive=True)
    return bounds, reasons


def _engines(table: _Reader, names: Collection[str] | None) -> dict[str, EngineTable]:
    if names is not None:
        table.only(set(names))
    engines = {}
    for engine in table.table:
        sub = table.sub(engine)
        settings = {k: v for k, v in sub.table.items() if k != "tolerance"}
        engines[engine] = EngineTable(settings, *_engine_tolerance(sub.sub("tolerance")))
    return engines
