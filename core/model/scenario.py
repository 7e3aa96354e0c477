"""The validated scenario model (SI units) and the error bad input raises.

A `Scenario` is what a scenario file says, after `mechval.scenarios.load`
has checked every key: its scene and, for the four kinds, its closed form;
the `Mechanism` built from it is what adapters see.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping

import numpy as np

from mechval.model.scene import Scene

if TYPE_CHECKING:                       # the closed forms import this module
    from mechval.reference.linkages import ClosedForm


#: Longest key and reason shown in an error message: a key, or a value a
#: reason quotes, is user input and may be a megabyte long.
SHOWN_KEY_LENGTH = 60
SHOWN_REASON_LENGTH = 2000


def one_line(text: str, limit: int | None = None) -> str:
    """`text` safe to print on one line or in one table cell: line breaks
    and other non-printable characters shown as escapes (\\n, \\x00, …),
    and cut to `limit` characters with "…" when longer."""
    shown = "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in str(text))
    return shown if limit is None or len(shown) <= limit else shown[:limit - 1] + "…"


class ScenarioError(ValueError):
    """Bad scenario input: names the file, the key and the reason, on one
    line (key and reason shortened to SHOWN_KEY/REASON_LENGTH characters)."""

    def __init__(self, source: str | Path | None, key: str, reason: str):
        self.source, self.key = one_line(source or "<scenario>"), one_line(key, SHOWN_KEY_LENGTH)
        self.reason = one_line(reason, SHOWN_REASON_LENGTH)
        super().__init__(f"{self.source}: {self.key}: {self.reason}")

    def __reduce__(self):   # raised in worker processes, re-raised in the parent
        return type(self), (self.source, self.key, self.reason)


#: Tolerance classes and their defaults (docs/scenario-format.md; velocity and acceleration
#: are mechval extensions). Angles and positions are absolute (rad, m); the
#: other classes are max |error| / max |reference| over the run.
DEFAULT_TOLERANCE = {
    "angle": 1e-3,
    "position": 1e-4,
    "velocity": 1e-2,
    "acceleration": 1e-2,
    "force": 1e-2,
    "torque": 1e-2,
}
ABSOLUTE_CLASSES = frozenset({"angle", "position"})


@dataclass(frozen=True)
class Tolerance:
    """Pass/fail bound per signal class (see DEFAULT_TOLERANCE)."""

    bounds: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_TOLERANCE))

    def __getitem__(self, signal_class: str) -> float:
        return self.bounds[signal_class]

    def is_relative(self, signal_class: str) -> bool:
        return signal_class not in ABSOLUTE_CLASSES

    def updated(self, overrides: Mapping[str, float]) -> "Tolerance":
        return Tolerance({**self.bounds, **overrides})


@dataclass(frozen=True)
class LinkMass:
    """Mass (kg), centre of mass as distance from the link's first joint
    along the link (m), izz about the centre of mass (kg·m²)."""

    mass: float
    com: float
    izz: float


@dataclass(frozen=True)
class TimeGrid:
    end: float
    samples: int

    @property
    def t(self) -> np.ndarray:
        return np.linspace(0.0, self.end, self.samples)


@dataclass(frozen=True)
class EngineTable:
    """An [engines.NAME] table: settings for the adapter, tolerance overrides
    and, per overridden class, the reason the file gives for it."""

    settings: Mapping[str, Any] = field(default_factory=dict)
    tolerance: Mapping[str, float] = field(default_factory=dict)
    reasons: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Scenario:
    """A scenario file's facts (name, time grid, tolerances, engine tables)
    and its scene (`mechval.model.scene`; a spatial file's is a
    `mechval.reference.spatial.system.SpatialSystem`); a closed-form kind's
    file also gives the scene's closed form (`mechval.reference.linkages.ClosedForm`)."""

    name: str
    description: str
    scene: Scene
    time: TimeGrid
    tolerance: Tolerance
    engines: Mapping[str, EngineTable] = field(default_factory=dict)
    tags: tuple[str, ...] = ()
    source: Path | None = None
    closed_form: ClosedForm | None = None
    #: The file's own key of a scene element, where the front end names it
    #: otherwise than a planar file would ("body[0]" → "mass.crank"): bad
    #: input found in the scene is reported under the key the user wrote.
    keys: Mapping[str, str] = field(default_factory=dict)

    @property
    def mechanism(self) -> str:
        """The file's `mechanism`: the closed form's kind, "planar", or
        "spatial" (a `SpatialSystem` scene, `mechval.scenarios.spatial`)."""
        if self.closed_form:
            return self.closed_form.kind
        return "planar" if isinstance(self.scene, Scene) else "spatial"

    @property
    def forward_dynamics(self) -> bool:
        """True when the motion is integrated rather than prescribed
        (`Mechanism.forward_dynamics`)."""
        return self.scene.forward_dynamics

    def key(self, scene_key: str) -> str:
        """The file's key for the planar-file key `scene_key` (see `keys`)."""
        return self.keys.get(scene_key, scene_key)

    def tolerance_for(self, engine: str | None) -> Tolerance:
        """The scenario's tolerance with the engine's overrides applied."""
        table = self.engines.get(engine) if engine else None
        return self.tolerance.updated(table.tolerance) if table else self.tolerance

    def settings_for(self, engine: str) -> Mapping[str, Any]:
        table = self.engines.get(engine)
        return dict(table.settings) if table else {}


def require_unique_names(scenarios: Iterable[Scenario]) -> None:
    """Refuse two scenarios of one name in one command: references, report
    rows, discrepancies.csv and baseline folders are all keyed by the name,
    so the second would silently be judged against the first's reference."""
    first_of: dict[str, Scenario] = {}
    for scenario in scenarios:
        first = first_of.setdefault(scenario.name, scenario)
        if first is scenario:
            continue
        if first.source is not None and scenario.source is not None \
                and Path(first.source).resolve() == Path(scenario.source).resolve():
            reason = f"{scenario.name!r}: the same scenario is given twice"
        else:
            reason = (f"{scenario.name!r} is also the name of {first.source or 'another scenario'}; "
                      "scenario names must be unique in one command (rename one)")
        raise ScenarioError(scenario.source, "name", reason)
