"""The engine registry: names → adapter classes, imported only when used.

Registering by module path keeps `mechval list`, scenario loading and test
collection free of engine imports (xarray's backend registry does the same).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .base import EngineAdapter

#: Engine name → "module:Class". "reference" is the analytic solution.
ADAPTERS = {
    "mujoco": "mechval.engines.mujoco:MujocoAdapter",
    "pybullet": "mechval.engines.pybullet:PybulletAdapter",
    "exudyn": "mechval.engines.exudyn:ExudynAdapter",
}
ENGINE_NAMES = tuple(ADAPTERS)


class UnknownEngine(ValueError):
    def __init__(self, name: str):
        super().__init__(f"unknown engine {name!r} (available: reference, {', '.join(ENGINE_NAMES)})")


class EngineUnavailable(RuntimeError):
    """The engine's library is not installed or fails to import."""


def adapter_class(name: str) -> "type[EngineAdapter]":
    """The named adapter class (imports its module, not the engine library)."""
    if name not in ADAPTERS:
        raise UnknownEngine(name)
    module_name, class_name = ADAPTERS[name].split(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        # Only the engine library itself missing or broken makes the engine
        # unavailable (and its tests skip); a bug in the adapter must fail.
        if (exc.name or "").split(".")[0] != name:
            raise
        raise EngineUnavailable(f"{name}: the {name} library cannot be imported ({exc})") from None
    return getattr(module, class_name)


def adapter(name: str) -> "EngineAdapter":
    """An instance of the named adapter; raises UnknownEngine/EngineUnavailable."""
    cls = adapter_class(name)
    reason = cls.unavailable_reason()
    if reason:
        raise EngineUnavailable(f"{name}: {reason}")
    return cls()


def availability() -> dict[str, str]:
    """Engine name → "" if usable, else the reason it is not."""
    result = {}
    for name in ENGINE_NAMES:
        try:
            adapter(name)
            result[name] = ""
        except EngineUnavailable as exc:
            result[name] = str(exc)
    return result
