"""The engine registry: names → adapter classes, imported only when used.

Registering by module path keeps `mechval list`, scenario loading and test
collection free of engine imports (xarray's backend registry does the same).

Two sources, built-ins first:
- `ADAPTERS`: the adapters shipped with mechval;
- the entry-point group `mechval.engines` of every installed distribution:
  an engine team ships its adapter in a package of its own, declaring e.g.
  `[project.entry-points."mechval.engines"] drake = "mechval_drake:DrakeAdapter"`,
  and mechval finds it without being forked. A plug-in may not take a
  built-in's name.

An engine is available when its adapter imports and the engine library it
names (`EngineAdapter.library`, the library's own import name) imports.
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .base import EngineAdapter

#: Built-in engine name → "module:Class". "reference" is the analytic solution.
ADAPTERS = {
    "mujoco": "mechval.engines.mujoco:MujocoAdapter",
    "pybullet": "mechval.engines.pybullet:PybulletAdapter",
    "exudyn": "mechval.engines.exudyn:ExudynAdapter",
}
ENGINE_NAMES = tuple(ADAPTERS)
#: The analytic reference is an adapter too; it is not an engine to compare.
REFERENCE = "reference"
REFERENCE_ADAPTER = "mechval.reference:ReferenceAdapter"
ENTRY_POINT_GROUP = "mechval.engines"


class UnknownEngine(ValueError):
    def __init__(self, name: str):
        super().__init__(f"unknown engine {name!r} (available: reference, {', '.join(engine_names())})")


class EngineUnavailable(RuntimeError):
    """The engine's library is not installed or fails to import."""


@functools.lru_cache(maxsize=1)
def plugins() -> dict[str, str]:
    """Engine name → "module:Class" from the `mechval.engines` entry points
    (built-in names and "reference" are reserved and skipped)."""
    found = {}
    for entry in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        if entry.name not in ADAPTERS and entry.name != REFERENCE:
            found[entry.name] = entry.value
    return found


def targets() -> dict[str, str]:
    """Every engine name → "module:Class": built-ins, then plug-ins."""
    return {**ADAPTERS, **plugins()}


def engine_names() -> tuple[str, ...]:
    return tuple(targets())


def adapter_class(name: str) -> "type[EngineAdapter]":
    """The named adapter class (imports its module, not the engine library)."""
    target = REFERENCE_ADAPTER if name == REFERENCE else targets().get(name)
    if target is None:
        raise UnknownEngine(name)
    module_name, _, class_name = target.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        # A module missing outside the adapter's own package is the engine
        # library (or one of its dependencies): the engine is unavailable
        # and its tests skip. A module missing inside it is a bug: it fails.
        missing = (exc.name or "").split(".")[0]
        if not missing or missing == module_name.split(".")[0]:
            raise
        raise EngineUnavailable(f"{name}: {missing} cannot be imported ({exc})") from None
    return getattr(module, class_name)


def adapter(name: str) -> "EngineAdapter":
    """An instance of the named adapter ("reference" included); raises
    UnknownEngine/EngineUnavailable."""
    cls = adapter_class(name)
    reason = cls.unavailable_reason()
    if reason:
        raise EngineUnavailable(f"{name}: {reason}")
    return cls()


def availability() -> dict[str, str]:
    """Engine name → "" if usable, else the reason it is not."""
    result = {}
    for name in engine_names():
        try:
            adapter(name)
            result[name] = ""
        except EngineUnavailable as exc:
            result[name] = str(exc)
    return result
