"""`mechval list`: the built-in scenarios from their files' headers (`name`,
`mechanism`, `tags`, `description`) and the engines installed. Listing
builds and solves nothing, and imports nothing heavy (no numpy, pandas,
scipy, engine library; tests/test_cli.py checks it): a scene is checked in
full when it is loaded to run (`mechval.scenarios.load`), an engine's
import when it is used."""

from __future__ import annotations

import importlib.util
import tomllib
from dataclasses import dataclass
from pathlib import Path

from mechval.engines.registry import installed


@dataclass(frozen=True)
class Header:
    mechanism: str
    tags: tuple[str, ...]
    description: str


def scenario_header(path: Path) -> Header:
    """The header of a scenario file (a built-in: its loader's tests check
    the whole file); what is not a string is shown as it is."""
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    tags = data.get("tags", [])
    return Header(str(data.get("mechanism", "")), tuple(str(t) for t in tags) if isinstance(tags, list) else (),
                  str(data.get("description", "")))


def builtin_files() -> dict[str, Path]:
    """The built-in scenario files by name, found where `mechval.scenarios`
    is installed without importing it (its loader imports the model);
    the same names as `mechval.scenarios.builtin_names` (a test checks)."""
    folder = Path(importlib.util.find_spec("mechval.scenarios").submodule_search_locations[0])
    return {path.stem: path for path in sorted(folder.glob("*.toml"), key=lambda path: path.stem)}


def spatial_files() -> dict[str, Path]:
    """The spatial built-ins by name ("spatial/NAME", scenarios/spatial/)."""
    folder = Path(importlib.util.find_spec("mechval.scenarios").submodule_search_locations[0]) / "spatial"
    return {f"spatial/{path.stem}": path for path in sorted(folder.glob("*.toml"), key=lambda path: path.stem)}


def one_line(text: str, limit: int | None = None) -> str:
    """`mechval.model.scenario.one_line` (a test checks they agree), which the
    listing cannot import: `text` with line breaks and other non-printable
    characters shown as escapes, cut to `limit` characters with "…"."""
    shown = "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in str(text))
    return shown if limit is None or len(shown) <= limit else shown[:limit - 1] + "…"


def list_command() -> int:
    print("scenarios:")
    for name, path in {**builtin_files(), **spatial_files()}.items():
        s = scenario_header(path)
        tags = f" [{', '.join(s.tags)}]" if s.tags else ""
        print(one_line(f"  {name:<28} {s.mechanism:<13}{tags} {s.description}"))
    print("engines (installed: the library found and its version, not imported; a run imports it):")
    print(f"  {'reference':<12} installed (analytic)")
    for engine, found in installed().items():
        print(f"  {engine:<12} {found if found.startswith('not installed') else 'installed (' + found + ')'}")
    return 0
