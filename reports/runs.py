"""The report's "Runs and settings": what each engine run was asked to do
(its settings, the keys of a scene's `[engines.NAME]` table) kept apart
from what it did (its `RunInfo`: times, steps, warnings, measured facts),
named, with units, to 4 significant digits; and `runs.csv`, every setting
and fact of every run at full precision.

A report never imports an engine, so the units of the engines' settings
and facts are a table here (`UNITS`, from docs/engines.md); a key it does
not know is shown plainly, without a unit.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from markupsafe import Markup

from mechval.records.outcome import Outcome

from .csv_files import neutralised

#: The setting that is the time step (every adapter's `step_setting`, or
#: none); it and the step count lead every table.
STEP_SETTING = "timestep"
#: Units of settings and run facts by key (docs/engines.md); keys not
#: here have no unit (counts, ratios, choices) or a mixed one.
UNITS: Mapping[str, str] = {
    "timestep": "s", "clock_mass": "kg", "newton_absolute_tolerance": "N",
    "build_time_s": "s", "wall_time_s": "s", "step": "s", "timestep_used": "s", "pre_roll_start": "s",
    "time_stamp_error_max": "s", "closure_gap_max": "m", "task_wall_time_s": "s", "task_cpu_time_s": "s",
}
#: Column names for `RunInfo`'s own fields and the outcome's times.
NAMES: Mapping[str, str] = {
    "timestep": "time step", "steps": "steps", "build_time_s": "build time", "wall_time_s": "engine time",
    "warnings": "warnings", "task_wall_time_s": "task time", "task_cpu_time_s": "task CPU time",
}
#: What a column means (the header's tooltip), where its key does not say.
DESCRIPTIONS: Mapping[str, str] = {
    "timestep": "the setting timestep: the engine's time step",
    "steps": "engine steps the run took (pre-roll included)",
    "build_time_s": "time to build the engine's model",
    "wall_time_s": "time the engine took to simulate",
    "task_wall_time_s": "wall time of the whole task in its worker process",
    "task_cpu_time_s": "CPU time of the task's worker process",
    "worker": "the Dask worker that ran it (mechval run --dask)",
    "drive_error_max": "largest error of the drive's coordinate against its law (rad; m for a slide drive)",
    "closure_gap_max": "largest loop-closure gap at the samples",
}
#: A text fact longer than this is a note under the facts table, not a column.
NOTE_LENGTH = 40


def show(value: Any, unit: str = "") -> str:
    """A value for the page: floats to 4 significant digits (each number of
    a string of numbers too, e.g. MuJoCo's solimp), counts whole, with the
    unit; None as empty."""
    if value is None:
        return ""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, int):
        text = str(value)
    elif isinstance(value, float):
        text = "NaN" if math.isnan(value) else f"{value:.4g}"
    else:
        text = str(value)
        words = text.split()
        if words and all(_is_number(word) for word in words):
            text = " ".join(f"{float(word):.4g}" for word in words)
    return f"{text} {unit}" if unit and text else text


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def _column(key: str) -> dict[str, Any]:
    name = NAMES.get(key, key)
    # A key may break after an underscore, so long names do not widen a table.
    return dict(key=key, name=Markup("_<wbr>").join(name.split("_")), title=DESCRIPTIONS.get(key, key))


def _facts(outcome: Outcome) -> dict[str, Any]:
    """A run's facts: the task's times (a CPU time of 0: not measured),
    then `RunInfo` (its fields, then the engine's facts)."""
    facts: dict[str, Any] = {"task_wall_time_s": outcome.wall_time,
                             "task_cpu_time_s": outcome.cpu_time or None, "worker": outcome.worker or None}
    return {**facts, **outcome.signals.info.as_dict()} if outcome.signals is not None else facts


def _is_note(value: Any) -> bool:
    return isinstance(value, str) and len(value) > NOTE_LENGTH


def _split(records: Sequence[Mapping[str, Any]], skip: Iterable[str]) -> tuple[dict[str, Any], list[str]]:
    """The keys of several runs' records (in order of first appearance, none
    of `skip`, no long text): those of one value in every run (when there
    are several runs) with it, and the others."""
    keys = [k for k in dict.fromkeys(k for r in records for k in r)
            if k not in skip and not any(_is_note(r.get(k)) for r in records)]
    shared = {k: records[0][k] for k in keys if len(records) > 1
              and all(k in r and r[k] is not None and r[k] == records[0][k] for r in records)}
    return shared, [k for k in keys if k not in shared and any(r.get(k) is not None for r in records)]


def _engine_block(engine: str, outcomes: Sequence[Outcome]) -> dict:
    """One engine's runs: a settings table (time step and steps first, then
    the settings that differ between its runs; those the same in every run
    are listed once above it), a facts table likewise, and long text facts
    as notes."""
    ran = [o for o in outcomes if o.signals is not None]
    shared, varying = _split([o.signals.settings for o in ran], skip={STEP_SETTING})
    facts = {id(o): _facts(o) for o in ran}
    shared_facts, fact_keys = _split(list(facts.values()), skip={"steps"})
    rows, fact_rows, notes = [], [], {}
    for o in outcomes:
        head = dict(scenario=o.task.scenario.name, setting=o.task.setting, error=o.error if o.signals is None else "")
        if o.signals is None:
            rows.append(dict(head, cells=[]))
            fact_rows.append(dict(head, cells=[]))
            continue
        settings = o.signals.settings
        rows.append(dict(head, cells=[show(settings.get(STEP_SETTING), UNITS.get(STEP_SETTING, "")) or "—",
                                      show(o.signals.info.steps)]
                         + [show(settings.get(k), UNITS.get(k, "")) for k in varying]))
        fact_rows.append(dict(head, cells=[show(facts[id(o)].get(k), UNITS.get(k, "")) for k in fact_keys]))
        for key, value in facts[id(o)].items():
            if _is_note(value):
                notes.setdefault((key, value), []).append(f"{o.task.scenario.name} [{o.task.setting}]")
    versions = sorted({o.signals.version for o in ran if o.signals.version})
    listed = lambda values: [dict(_column(k), value=show(v, UNITS.get(k, ""))) for k, v in values.items()]
    return dict(engine=engine, version=", ".join(versions), runs=len(outcomes),
                columns=[_column(STEP_SETTING), _column("steps")] + [_column(k) for k in varying],
                same=listed(shared), rows=rows,
                fact_columns=[_column(k) for k in fact_keys], same_facts=listed(shared_facts), fact_rows=fact_rows,
                notes=[dict(key=key, text=text, runs="every run" if len(runs) == len(ran) > 1 else ", ".join(runs))
                       for (key, text), runs in notes.items()])


def run_tables(outcomes: Iterable[Outcome]) -> list[dict]:
    """Per engine, in order of first appearance, its runs' tables."""
    engines: dict[str, list[Outcome]] = {}
    for o in outcomes:
        engines.setdefault(o.task.engine, []).append(o)
    return [_engine_block(engine, runs) for engine, runs in engines.items()]


CSV_COLUMNS = ("scenario", "engine", "setting", "version", "kind", "name", "value")


def write_runs_csv(path: Path, outcomes: Iterable[Outcome]) -> None:
    """Every run's settings and facts, one per line (kind "setting",
    "fact" or "error"), floats with `repr` (they round-trip)."""
    with path.open("w", newline="", encoding="utf-8") as stream:
        # As the report's other CSV files (`csv_files`): text that a
        # spreadsheet would take for a formula is neutralised, numbers not.
        writer = csv.writer(stream, lineterminator="\r\n")
        writer.writerow(CSV_COLUMNS)
        for o in outcomes:
            head = [neutralised(str(v)) for v in
                    (o.task.scenario.name, o.task.engine, o.task.setting, o.signals.version if o.signals else "")]
            if o.signals is None:
                writer.writerow(head + ["error", "", neutralised(o.error)])
            items = [("setting", k, v) for k, v in (o.signals.settings if o.signals else {}).items()]
            items += [("fact", k, v) for k, v in _facts(o).items() if v is not None]
            writer.writerows(head + [kind, neutralised(key), _csv_value(v)] for kind, key, v in items)


def _csv_value(value: Any) -> str:
    """A float with `repr` (it round-trips), a number as it is, text
    neutralised."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    return neutralised(str(value))

