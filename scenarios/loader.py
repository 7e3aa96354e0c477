"""Load and validate scenario files (docs/scenario-format.md) into `Scenario`s.

Every refusal is a `ScenarioError` naming the file, the dotted key and the
reason; nothing is half-loaded. Defaults for omitted optional tables: no
effects, the default tolerances, the engines' own derived settings.
"""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path
from typing import Any, Collection, Mapping

from mechval.model.scenario import Scenario, ScenarioError

from .kinds import parse_kind
from .planar import parse_planar
from .spatial import parse_spatial
from .tables import MAX_MAGNITUDE

HERE = Path(__file__).resolve().parent


def builtin_names() -> list[str]:
    return sorted(p.stem for p in HERE.glob("*.toml"))


#: A spatial built-in with this tag is left out of a run of all built-ins:
#: an engine cannot meet it at its default settings (docs/engines.md).
EXTRA = "extra"


def spatial_builtin_names() -> list[str]:
    """The spatial built-ins (scenarios/spatial/NAME.toml, named "spatial/NAME")."""
    return [f"spatial/{p.stem}" for p in sorted((HERE / "spatial").glob("*.toml"))]


def default_run_names() -> list[str]:
    """The built-ins a run of all built-ins takes: the planar ones
    (`builtin_names`) and the spatial ones not tagged EXTRA."""
    return builtin_names() + [n for n in spatial_builtin_names()
                              if EXTRA not in read_toml(builtin_path(n)).get("tags", [])]


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
    """Validate a parsed TOML document into a `Scenario` (SI units), by the
    front end its `mechanism` names: a planar file's scene as written
    (docs/scenario-format.md#planar-files), or a closed-form kind's scene
    expanded from its few numbers, or a spatial file's
    (docs/scenario-format.md#spatial-files).

    `engines`: the engine names an `[engines.NAME]` table may name (the
    harness passes its registry's); None accepts any name, and an adapter
    still refuses settings it does not know."""
    if data.get("mechanism") == "planar":
        return parse_planar(data, source, engines)
    if data.get("mechanism") == "spatial":
        return parse_spatial(data, source, engines)
    return parse_kind(data, source, engines)
