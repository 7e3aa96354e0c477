"""A seeded mutator of TOML documents, for fuzzing the scenario loader.

Generic over any parsed document (tables, arrays, arrays of tables): it
knows nothing of scenario keys, so every scenario format, present or added
later, is covered as soon as it has a built-in file. One case = a document,
a few structural mutations (`mutate`), then optionally one mutation of the
TOML text itself (`mutate_text`: what a serialiser cannot produce, such as
an integer Python refuses to read, nesting too deep, or broken syntax).
"""

from __future__ import annotations

import copy
import math
import random
import re
from dataclasses import dataclass
from typing import Any, Callable

import tomli_w

NUMBERS = (0, -1, 1, 2, 0.0, -0.0, 1e-300, 5e-324, -5e-324, 1e-9, 1e50, -1e50, 1e51, 1e300, 1e308, -1e308,
           math.nan, math.inf, -math.inf, 2**31, 2**63 - 1, -(2**63), 10**18, 10**400)
STRINGS = ("", " ", "x" * 100_000, "é|ü\n\t\u202e\x00", "a | b\nc", "open", "crossed", "right", "left",
           "hard", "1.0", "nan", "[[x]]", "ground", "reference")
KEYS = ("colour", "k" * 100_000, "é|\nü", "ground", "tolerance", "timestep", "refine", "samples", "mass", "1")


@dataclass
class Case:
    """A mutated document (or text) and what was done to it."""

    doc: dict[str, Any]
    steps: list[str]
    text: str | None = None

    def toml(self) -> str:
        return self.text if self.text is not None else tomli_w.dumps(self.doc)


def slots(node: Any, path: tuple = ()) -> list[tuple[Any, Any, tuple]]:
    """(container, key or index, path) of every value in the document."""
    found = []
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        found.append((node, key, path + (key,)))
        found += slots(value, path + (key,))
    return found


def tables(node: Any, path: tuple = ()) -> list[tuple[dict, tuple]]:
    """Every table (the document itself included) and its path."""
    found = [(node, path)] if isinstance(node, dict) else []
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        found += tables(value, path + (key,))
    return found


def _random_value(rng: random.Random, like: Any) -> Any:
    """A value of another kind than `like`, or an extreme one of its kind."""
    kind = rng.choice(["number", "number", "string", "bool", "list", "table", "nested"])
    if kind == "number":
        if isinstance(like, (int, float)) and not isinstance(like, bool) and rng.random() < 0.5:
            return _scaled(rng, like)
        return rng.choice(NUMBERS)
    if kind == "string":
        return rng.choice(STRINGS)
    if kind == "bool":
        return rng.choice([True, False])
    if kind == "list":
        return rng.choice([[], [like], [like, like, like], [1.0, "a"], [[1.0, 2.0]], [{"a": 1}]])
    if kind == "table":
        return rng.choice([{}, {"mass": like}, {"x": {"y": like}}])
    nested: Any = like
    for _ in range(rng.randint(5, 60)):
        nested = rng.choice([[nested], {"a": nested}])
    return nested


def _scaled(rng: random.Random, number: int | float) -> int | float:
    """The number multiplied by ±10^k, negated, nudged by one ulp or made 0."""
    how = rng.choice(["scale", "negate", "ulp", "zero"])
    if how == "negate":
        return -number
    if how == "zero":
        return type(number)(0)
    if how == "ulp" and abs(number) < 1e300:
        return math.nextafter(float(number), math.inf)
    k = rng.choice([-300, -30, -12, -6, -3, -1, 1, 3, 6, 12, 30, 300])
    if isinstance(number, int):
        return number * 10**k if k > 0 else number
    return number * 10.0**k


def _delete(rng, doc):
    container, key, path = rng.choice(slots(doc))
    del container[key]
    return f"delete {path}"


def _replace(rng, doc):
    container, key, path = rng.choice(slots(doc))
    container[key] = _random_value(rng, container[key])
    return f"replace {path} with {_short(container[key])}"


def _extreme(rng, doc):
    numbers = [s for s in slots(doc) if isinstance(s[0][s[1]], (int, float)) and not isinstance(s[0][s[1]], bool)]
    if not numbers:
        return _replace(rng, doc)
    container, key, path = rng.choice(numbers)
    container[key] = rng.choice(NUMBERS) if rng.random() < 0.5 else _scaled(rng, container[key])
    return f"set {path} = {_short(container[key])}"


def _nudge(rng, doc):
    """A mild change (most such scenes stay valid: both outcomes get tested)."""
    numbers = [s for s in slots(doc) if isinstance(s[0][s[1]], (int, float)) and not isinstance(s[0][s[1]], bool)]
    if not numbers:
        return _replace(rng, doc)
    container, key, path = rng.choice(numbers)
    value = container[key]
    container[key] = value + rng.choice([-1, 1, 2]) if isinstance(value, int) else value * rng.uniform(0.5, 2.0)
    return f"nudge {path} to {_short(container[key])}"


def _add_key(rng, doc):
    table, path = rng.choice(tables(doc))
    key = rng.choice(KEYS)
    table[key] = _random_value(rng, 1.0)
    return f"add {path + (_short(key),)} = {_short(table[key])}"


def _swap(rng, doc):
    (c1, k1, p1), (c2, k2, p2) = rng.choice(slots(doc)), rng.choice(slots(doc))
    if p1[:len(p2)] == p2 or p2[:len(p1)] == p1:   # one holds the other
        return _replace(rng, doc)
    c1[k1], c2[k2] = c2[k2], c1[k1]
    return f"swap {p1} and {p2}"


def _copy_table(rng, doc):
    (source, p1), (target, p2) = rng.choice(tables(doc)), rng.choice(tables(doc))
    key = rng.choice(KEYS)
    target[key] = copy.deepcopy(source)
    return f"copy {p1} to {p2 + (_short(key),)}"


MUTATIONS: tuple[Callable[[random.Random, dict], str], ...] = (
    _delete, _replace, _extreme, _extreme, _nudge, _nudge, _nudge, _add_key, _swap, _copy_table)


def mutate(doc: dict[str, Any], rng: random.Random, count: int) -> Case:
    """`count` structural mutations of a copy of `doc`."""
    doc = copy.deepcopy(doc)
    steps = [rng.choice(MUTATIONS)(rng, doc) for _ in range(count) if slots(doc)]
    return Case(doc, steps)


def mutate_text(case: Case, rng: random.Random) -> Case:
    """One mutation of the serialised text that no document can express."""
    text = case.toml()
    lines = text.splitlines()
    numeric = [i for i, line in enumerate(lines) if re.search(r"=\s*-?[0-9]", line)]
    how = rng.choice(["digits", "deep-array", "deep-table", "truncate", "duplicate"])
    if how == "digits" and numeric:
        i = rng.choice(numeric)
        lines[i] = re.sub(r"=\s*-?[0-9][^,}\]]*", "= " + "9" * rng.choice([4301, 5000, 20000]), lines[i], count=1)
    elif how in ("deep-array", "deep-table"):
        depth = rng.choice([200, 1000, 5000])
        value = "[" * depth + "]" * depth if how == "deep-array" else "{a = " * depth + "1" + "}" * depth
        lines.insert(rng.randrange(len(lines) + 1), f"deep = {value}")
    elif how == "duplicate" and lines:
        i = rng.randrange(len(lines))
        lines.insert(i, lines[i])
    else:
        return Case(case.doc, case.steps + ["truncate the text"], text[:rng.randrange(len(text) + 1)])
    return Case(case.doc, case.steps + [f"text: {how}"], "\n".join(lines) + "\n")


def _short(value: Any) -> str:
    text = repr(value) if not isinstance(value, int) or abs(value) < 10**30 else f"<int of {len(str(value))} digits>"
    return text if len(text) <= 40 else text[:37] + "..."
