"""Typed access to a scenario file's tables, and the one parser of what
both formats share (the four kinds, `kinds`; planar files, `planar`): the
top-level `name`, `mechanism`, `description` and `tags`, `[time]`,
`[tolerance]`, `[engines.NAME]` and every number. Every refusal a
`ScenarioError` naming the file, the dotted key and the reason; a value it
quotes is quoted short, whatever its size (`shown`).
"""

from __future__ import annotations

import math
import reprlib
from typing import Any, Collection, Mapping

from mechval.reference.limits import shown_int
from mechval.reference.linkages import LINKAGES
from mechval.model.scenario import DEFAULT_TOLERANCE, EngineTable, ScenarioError, TimeGrid, Tolerance

#: Largest magnitude accepted for any number (SI units): far beyond any
#: linkage, small enough that products like m·L²·ω² stay within float64.
MAX_MAGNITUDE = 1e50


#: Longest scenario name (characters): it is repeated in every row of a
#: report and in its page, so a megabyte of name makes a report of tens of
#: megabytes; and a baseline folder takes no more (docs/scenario-format.md).
MAX_NAME_LENGTH = 100


def scenario_name(top: "Reader") -> str:
    """The file's `name`: a string of at most MAX_NAME_LENGTH characters."""
    name = top.string("name")
    if len(name) > MAX_NAME_LENGTH:
        top.fail("name", f"at most {MAX_NAME_LENGTH} characters, got {len(name):,}")
    return name


#: The formats a file's `mechanism` may name.
MECHANISMS = (*LINKAGES, "planar", "spatial")


def heading(top: "Reader") -> tuple[str, str, str, tuple[str, ...]]:
    """The file's name, mechanism, description and tags."""
    name = scenario_name(top)
    kind = top.string("mechanism", choices=MECHANISMS)
    description = top.string("description", default="")
    tags = top.table.get("tags", [])
    if not isinstance(tags, list) or not all(isinstance(t, str) for t in tags):
        top.fail("tags", f"expected a list of strings, got {shown(tags)}")
    return name, kind, description, tuple(tags)


def run_tables(top: "Reader", engines: Collection[str] | None
               ) -> tuple[TimeGrid, Tolerance, dict[str, EngineTable]]:
    """The [time] grid, the [tolerance] and the [engines.NAME] tables."""
    return (time_grid(top.sub("time", required=True)), Tolerance().updated(tolerance(top.sub("tolerance"))),
            engine_tables(top.sub("engines"), engines))


def time_grid(table: "Reader") -> TimeGrid:
    table.only({"end", "samples"})
    samples = table.table.get("samples")
    if isinstance(samples, bool) or not isinstance(samples, int):
        table.fail("samples", f"expected a whole number, got {shown(samples)}" if samples is not None
                   else "missing value")
    if samples < 2:
        table.fail("samples", f"must be at least 2, got {shown_int(samples)}")
    return TimeGrid(table.number("end", positive=True), samples)


def shown(value: Any) -> str:
    """A value quoted in an error: short, whatever its size or depth."""
    if isinstance(value, int) and not isinstance(value, bool):
        return shown_int(value)
    quote = reprlib.Repr()
    quote.maxlevel, quote.maxstring, quote.maxother, quote.maxlist, quote.maxdict = 3, 60, 60, 4, 4
    return quote.repr(value)


class Reader:
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

    def sub(self, name: str, required=False) -> "Reader":
        if name not in self.table:
            if required:
                self.fail(name, "missing table")
            return Reader(self.source, self.key(name), {})
        value = self.table[name]
        if not isinstance(value, dict):
            self.fail(name, f"expected a table, got {type(value).__name__} {shown(value)}")
        return Reader(self.source, self.key(name), value)


def tolerance(table: Reader) -> dict[str, float]:
    table.only(set(DEFAULT_TOLERANCE))
    return {k: table.number(k, positive=True) for k in table.table}


def engine_tolerance(table: Reader) -> tuple[dict[str, float], dict[str, str]]:
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


def engine_tables(table: Reader, names: Collection[str] | None) -> dict[str, EngineTable]:
    if names is not None:
        table.only(set(names))
    engines = {}
    for engine in table.table:
        sub = table.sub(engine)
        settings = {k: v for k, v in sub.table.items() if k != "tolerance"}
        engines[engine] = EngineTable(settings, *engine_tolerance(sub.sub("tolerance")))
    return engines
