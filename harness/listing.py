"""What `mechval list` shows of a scenario file, read from its header alone
(`name`, `mechanism`, `tags`, `description`): listing builds and solves
nothing, and imports nothing heavy (a scene is checked in full when it is
loaded to run, `mechval.scenarios.load`)."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path


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
