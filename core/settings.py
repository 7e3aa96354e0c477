"""What each engine setting accepts: declared per adapter (`EngineAdapter.
settings_spec`), checked in one place (`EngineAdapter.settings_for`) before
any run.

A spec's `parse(value)` returns the value as the adapter uses it or raises
`ValueError` with the reason; the caller turns that into a `ScenarioError`
naming the file and the key. Every reason shows the value with `repr`, so
a quote, a newline or a NUL in it cannot break the one-line message.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Union

#: Largest magnitude any numeric setting may have unless its own range is
#: narrower: the scenario loader's bound for every number (a setting beyond
#: it is a typo, and products with it leave float64).
MAX_MAGNITUDE = 1e50


def _describe(value: Any) -> str:
    return f"{type(value).__name__} {value!r}"


@dataclass(frozen=True)
class Number:
    """A finite number in [low, high]; `low_open`/`high_open` exclude the
    end; `whole`: an integer (a TOML integer, not 2.0)."""

    low: float = -MAX_MAGNITUDE
    high: float = MAX_MAGNITUDE
    low_open: bool = False
    high_open: bool = False
    whole: bool = False

    def parse(self, value: Any) -> float | int:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"expected {'a whole number' if self.whole else 'a number'}, got {_describe(value)}")
        if self.whole and not isinstance(value, int):
            raise ValueError(f"expected a whole number, got {value!r}")
        if not math.isfinite(value):
            raise ValueError(f"must be finite, got {value!r}")
        if self.low == 0.0 and self.low_open and value <= 0:
            raise ValueError(f"must be positive, got {value!r}")
        if value < self.low or (self.low_open and value == self.low):
            raise ValueError(f"must be {'above' if self.low_open else 'at least'} {self.low:g}, got {value!r}")
        if value > self.high or (self.high_open and value == self.high):
            raise ValueError(f"must be {'below' if self.high_open else 'at most'} {self.high:g}, got {value!r}")
        return int(value) if self.whole else float(value)


@dataclass(frozen=True)
class Choice:
    """One of a few strings."""

    options: tuple[str, ...]

    def parse(self, value: Any) -> str:
        if not isinstance(value, str) or value not in self.options:
            raise ValueError(f"must be one of {', '.join(map(repr, self.options))}, got {value!r}")
        return value


@dataclass(frozen=True)
class Flag:
    """true or false."""

    def parse(self, value: Any) -> bool:
        if not isinstance(value, bool):
            raise ValueError(f"expected true or false, got {_describe(value)}")
        return value


@dataclass(frozen=True)
class Numbers:
    """A fixed list of named numbers, each with its range (e.g. MuJoCo's
    solimp), written as a TOML list or as one string of numbers separated
    by spaces (the MJCF way). The value kept is that string, rebuilt from
    the checked floats (`repr` round-trips them); `values` reads it back."""

    parts: tuple[tuple[str, Number], ...]

    def values(self, value: Any) -> tuple[float, ...]:
        """The checked numbers of a list or a string (ValueError if bad)."""
        names = " ".join(name for name, _ in self.parts)
        shape = (f"expected {len(self.parts)} numbers ({names}) as a list or a string of numbers "
                 f"separated by spaces, got {_describe(value)}")
        if isinstance(value, str):
            items: list[Any] = []
            for word in value.split():
                try:
                    items.append(float(word))
                except ValueError:
                    raise ValueError(shape) from None
        elif isinstance(value, list):
            items = value
        else:
            raise ValueError(shape)
        if len(items) != len(self.parts):
            raise ValueError(shape)
        checked = []
        for (name, spec), item in zip(self.parts, items):
            try:
                checked.append(float(spec.parse(item)))
            except ValueError as exc:
                raise ValueError(f"{name} (item {len(checked) + 1}) {exc}") from None
        return tuple(checked)

    def parse(self, value: Any) -> str:
        return " ".join(repr(v) for v in self.values(value))


Setting = Union[Number, Choice, Flag, Numbers]

#: A time step (s): positive; `settings_for` also checks that it divides
#: the sample interval.
TIMESTEP = Number(0.0, MAX_MAGNITUDE, low_open=True)
