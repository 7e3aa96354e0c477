"""The engine registry: names → adapter classes, imported only when used.

Registering by module path keeps `mechval list`, scenario loading and test
collection free of engine imports (xarray's backend registry does the same).

Every engine is an entry point of the group `mechval.engines`, mechval's
own included (pyproject.toml registers MuJoCo, PyBullet and Exudyn exactly
as a third party registers a plug-in): an engine team ships its adapter in
a package of its own, declaring e.g.
`[project.entry-points."mechval.engines"] drake = "mechval_drake:DrakeAdapter"`,
and mechval finds it without being forked. mechval's own engines come
first and keep their names: a plug-in that takes one (or "reference") is
ignored with a warning that says which one is used.

An engine is available when its adapter imports and the engine library it
names (`EngineAdapter.library`, the library's own import name) imports;
it is installed (`installed`, what `mechval list` shows) when that library
is found on the path and its distribution has a version, neither imported.
"""

from __future__ import annotations

import ast
import functools
import importlib
import importlib.metadata
import importlib.util
import warnings
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mechval.engines.base import EngineAdapter

#: The analytic reference is an adapter too; it is not an engine to compare.
REFERENCE = "reference"
REFERENCE_ADAPTER = "mechval.reference.adapter:ReferenceAdapter"
ENTRY_POINT_GROUP = "mechval.engines"
#: The distribution whose entry points are the built-in engines.
OWN_DISTRIBUTION = "mechval"


class UnknownEngine(ValueError):
    def __init__(self, name: str):
        super().__init__(f"unknown engine {name!r} (available: reference, {', '.join(engine_names())})")


class EngineUnavailable(RuntimeError):
    """The engine's library is not installed or fails to import."""


class EngineNameTaken(UserWarning):
    """Two installed distributions register one engine name; one is used."""


def _origin(entry: importlib.metadata.EntryPoint) -> str:
    dist = getattr(entry, "dist", None)
    return f"{dist.name} {dist.version}" if dist is not None else "an unknown distribution"


def _is_builtin(entry: importlib.metadata.EntryPoint) -> bool:
    dist = getattr(entry, "dist", None)
    return dist is not None and dist.name == OWN_DISTRIBUTION


@functools.lru_cache(maxsize=1)
def targets() -> dict[str, str]:
    """Every engine name → "module:Class" from the `mechval.engines` entry
    points: mechval's own first, then plug-ins in the order found. A name
    registered twice keeps the built-in (else the first found) and warns,
    naming both; "reference" is never a plug-in's."""
    entries = sorted(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda e: not _is_builtin(e))
    kept: dict[str, importlib.metadata.EntryPoint] = {}
    for entry in entries:
        if entry.name == REFERENCE:
            warnings.warn(f"{ENTRY_POINT_GROUP}: {entry.name!r} = {entry.value!r} of {_origin(entry)} is ignored: "
                          f"{REFERENCE!r} is mechval's analytic reference", EngineNameTaken, stacklevel=2)
            continue
        first = kept.setdefault(entry.name, entry)
        if first is not entry:
            which = "mechval's built-in engine" if _is_builtin(first) else f"the one of {_origin(first)}"
            warnings.warn(f"{ENTRY_POINT_GROUP}: {entry.name!r} = {entry.value!r} of {_origin(entry)} is ignored: "
                          f"{which}, {first.value!r}, has that name and is used", EngineNameTaken, stacklevel=2)
    return {name: entry.value for name, entry in kept.items()}


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


def _named_library(target: str) -> tuple[str, str] | None:
    """The `library` and `distribution` an adapter class names as string
    constants in its own body, read from its module's source without
    importing it (None: not both named there, e.g. inherited)."""
    module_name, _, class_name = target.partition(":")
    try:
        spec = importlib.util.find_spec(module_name)
        source = spec.loader.get_source(module_name) if spec and spec.loader else None
    except (ImportError, ValueError, AttributeError, OSError):
        return None
    if not source:
        return None
    named = {}
    for node in ast.parse(source).body:
        if isinstance(node, ast.ClassDef) and node.name == class_name:
            for line in node.body:
                value = line.value if isinstance(line, (ast.Assign, ast.AnnAssign)) else None
                names = line.targets if isinstance(line, ast.Assign) else [getattr(line, "target", None)]
                if isinstance(value, ast.Constant) and isinstance(value.value, str):
                    named.update({n.id: value.value for n in names if isinstance(n, ast.Name)})
    return (named["library"], named["distribution"]) if {"library", "distribution"} <= named.keys() else None


def installed() -> dict[str, str]:
    """Engine name → its library's version if installed, else "not installed:
    REASON". Installed: the library is found (`importlib.util.find_spec`)
    and its distribution has a version (`importlib.metadata.version`),
    neither imported, nor the adapter where its class names both in its
    own body (`mechval list`, which must stay fast). Whether the library
    imports (a broken installation) is checked where an engine is used
    (`adapter`, `availability`)."""
    result = {}
    for name, target in targets().items():
        try:
            library, distribution = _named_library(target) or _library_of(name)
            if not _found(library):
                raise EngineUnavailable(f"{name}: {library} is not installed")
            result[name] = f"{distribution} {importlib.metadata.version(distribution)}"
        except importlib.metadata.PackageNotFoundError:
            result[name] = f"not installed: {name}: no distribution {distribution!r} is installed"
        except EngineUnavailable as exc:    # a bug in the adapter module is raised, as by `adapter`
            result[name] = f"not installed: {exc}"
    return result


def library_and_distribution(name: str) -> tuple[str, str]:
    """The engine's library (import name) and its distribution, read from
    the adapter's source where it names both, else from its class (which
    imports the adapter module, not the library)."""
    target = targets().get(name)
    if target is None:
        raise UnknownEngine(name)
    return _named_library(target) or _library_of(name)


def _library_of(name: str) -> tuple[str, str]:
    cls = adapter_class(name)
    return cls.library, cls.distribution


def _found(library: str) -> bool:
    """Whether `library` is on the path (a dotted name's parents are
    imported to look, as Python's import does)."""
    try:
        return importlib.util.find_spec(library) is not None
    except ModuleNotFoundError:         # a parent package missing
        return False
