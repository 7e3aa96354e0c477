"""The planar twin of a built-in: its scene written as a planar file by
`mechval.scenarios.export` (the same bodies, frames and joints; the closed
form's pose at t = 0 as the assembly pose), for tests that need a planar
file of a known closed form. They replace the hand-written files of
scenarios/planar-twins/ (issue 24)."""

from __future__ import annotations

import functools
import tomllib

from mechval.scenarios import load, parse
from mechval.scenarios.export import planar_file


@functools.lru_cache(maxsize=None)
def twin_text(name: str) -> str:
    return planar_file(load(name))


def twin_document(name: str) -> dict:
    """A fresh parsed copy (callers edit it)."""
    return tomllib.loads(twin_text(name))


def twin(name: str):
    return parse(twin_document(name), f"{name}-planar.toml")
