"""What a comparison run or a cost sweep is made of: a task (scenario ×
engine × setting, with its overrides and resolved settings) and its
outcome (signals, or the reason there are none). The harness produces
them; reports and tests read them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

from mechval.records.engine_inputs import Feed
from mechval.model.scenario import Scenario
from mechval.records.signals import Signals


@dataclass(frozen=True)
class Task:
    """One engine run to make: a comparison run's (scenario × engine ×
    variant) or one point of a cost sweep (× time step)."""

    scenario: Scenario
    engine: str
    setting: str = "default"
    overrides: Mapping[str, Any] = field(default_factory=dict)
    #: Engine steps the run takes (its declared run size, `planned_steps`:
    #: a refined step and a pre-roll counted), its expected cost:
    #: `run_tasks` starts the longest runs first.
    steps: float = 0.0
    #: A regression check's recorded settings and reference reads, fed to
    #: the engine instead of being derived anew (`mechval.records.engine_inputs`).
    feed: Feed | None = None
    #: The engine's settings, resolved once when the run was planned
    #: (`mechval.harness.plan`): the worker runs with them and derives
    #: nothing (None: derived by the worker).
    settings: Mapping[str, Any] | None = None
    #: The time step a cost sweep's point sets (s; NaN: the engine's own).
    step: float = math.nan
    #: Whether a cost sweep's point is the engine's default setting.
    default: bool = False
    #: Why the engine declares it cannot build the scene (`Plan.refusal`):
    #: such a task is not run; its one record says so, verdict "missing".
    refused: str = ""

    @property
    def label(self) -> str:
        suffix = "" if self.setting == "default" else f"[{self.setting}]"
        return f"{self.scenario.name} × {self.engine}{suffix}"


@dataclass(frozen=True)
class Outcome:
    """What one task produced: signals, or the reason there are none."""

    task: Task
    signals: Signals | None
    error: str = ""
    wall_time: float = 0.0
    #: CPU time of the run's worker process (s): unlike the wall time, not
    #: stretched by other work sharing the machine.
    cpu_time: float = 0.0
    #: Per signal, how far it moved when the run's inputs moved by an ulp
    #: (measured by `baseline save` only).
    sensitivity: Mapping[str, float] | None = None
    #: The Dask worker that ran it (its address); "" on this machine.
    worker: str = ""
