"""The report of a pytest session's comparisons (`--mechval-report DIR`):
the page and files `mechval run` writes, from the comparisons the
`mechval_compare` fixture made."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import pandas as pd

from mechval.records.outcome import Outcome, Task
from mechval.reports.build import write_report
from mechval.reports.stability import stability_section

from .comparison import Comparison


def write_session_report(out: Path, comparisons: Sequence[Comparison]) -> tuple[Path, list[str]]:
    """Write the report into `out`; return it and a line per comparison left
    out. The report keys scenes by name: a second scene of a name already
    shown (another file, or another object of the same file) is left out."""
    scenarios, kept, left_out = {}, [], []
    for comparison in comparisons:
        scenario = comparison.scenario
        first = scenarios.setdefault(scenario.name, scenario)
        if first is scenario or (first.source is not None and first.source == scenario.source
                                 and first.time == scenario.time):
            kept.append(comparison)
        else:
            left_out.append(f"left out {comparison.engine} on {scenario.source or scenario.name}: its name "
                            f"{scenario.name!r} is also the name of {first.source or 'another scene'}")
    references = {c.scenario.name: c.reference for c in kept}
    outcomes = [Outcome(Task(c.scenario, c.engine, c.setting), c.signals, wall_time=c.wall_time) for c in kept]
    records = pd.concat([c.records for c in kept], ignore_index=True)
    shown = list(scenarios.values())
    sections = [s for s in (stability_section(records, shown),) if s]
    return write_report(out, shown, references, outcomes, records, sections), left_out
