"""Write a complete report folder: index.html, discrepancies.csv, runs.csv
and summary.md. Everything is written to a temporary sibling folder and moved
into place at the end, so an interrupted run leaves no half-written report.
"""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd
from jinja2 import Environment, FileSystemLoader, select_autoescape

import mechval
from mechval.judging.compare import GROWTH_COLUMNS, HEALTH_BOUNDS
from mechval.reference.linkages import build_mechanism
from mechval.records.outcome import Outcome
from mechval.model.scenario import Scenario, one_line
from mechval.records.signals import Signals, write_folder_atomically

from . import plots, runs
from .csv_files import write_csv

TEMPLATES = Path(__file__).resolve().parent / "templates"
#: The columns of a run's records on the page (its heading names the
#: engine and setting; discrepancies.csv has every column).
RECORD_COLUMNS = ["signal", "max_error", "t_max", "rms_error", "relative_error", "bound", "ratio", "verdict",
                  "missing", "reason", *GROWTH_COLUMNS]
TEXT_COLUMNS = {"signal", "verdict", "reason"}
#: Record verdicts the page filters by (mechval.judging.compare).
VERDICTS = ("fail", "pass", "missing")


@dataclass(frozen=True)
class Section:
    """An extra report section (stability, cost …) rendered by its owner."""

    anchor: str
    title: str
    html: str   # markupsafe.Markup: rendered (and escaped) by its owner


def provenance() -> dict[str, str]:
    """Where the results came from: project commit, machine, date, Python."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=Path(mechval.__file__).resolve().parent, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True,
                               text=True, cwd=Path(mechval.__file__).resolve().parent, timeout=10).stdout.strip()
        commit = (commit + ("+local changes" if dirty else "")) or "unknown"
    except (OSError, subprocess.SubprocessError):
        commit = "unknown"
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"),
        "mechval": mechval.__version__,
        "commit": commit,
        "machine": f"{platform.node()} · {platform.platform()} · {os.cpu_count()} cores",
        "python": platform.python_version(),
        "numpy": np.__version__,
        "pandas": pd.__version__,
    }


def _fmt(value) -> str:
    if isinstance(value, float):
        return "" if np.isnan(value) else f"{value:.3g}"
    return "" if value is None else str(value)


def _cell(records: pd.DataFrame) -> dict:
    if records.empty:
        return dict(text="—", css="missing", title="not run")
    run_failed = records["signal"].eq("(run)").any()
    if run_failed and (records["verdict"] == "missing").all():      # declared up front (`Task.refused`)
        return dict(text="not built", css="missing", title=records["reason"].iloc[0])
    if run_failed:
        reason = records["reason"].iloc[0]
        return dict(text="run failed", css="bad", title=reason)
    ratios = records["ratio"].replace([np.inf], 1e300).fillna(0.0)
    worst = records.loc[ratios.idxmax()]
    failed = (records["verdict"] == "fail").any()
    if failed and not np.isfinite(worst["ratio"]):
        return dict(text="NaN/inf", css="bad", title=f"{worst['signal']}: {worst['reason']}")
    ratio = float(worst["ratio"])
    css = "bad" if failed else ("ok1" if ratio <= 0.1 else "ok2" if ratio <= 0.5 else "ok3")
    return dict(text=f"{ratio:.3g}", css=css,
                title=f"worst: {worst['signal']} (max error {worst['max_error']:.3g} at t = {worst['t_max']:.4g} s)")


def by_run(records: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """Records grouped by engine run label ("mujoco", "exudyn [index3]"), in
    order of first appearance."""
    labels = pd.Series([label(e, s) for e, s in zip(records["engine"], records["setting"])], index=records.index)
    return {name: group for name, group in records.groupby(labels, sort=False)}


def matrix_rows(records: pd.DataFrame, scenarios: Sequence[Scenario], cell) -> dict:
    """Scenario × engine-run table with cell(records of one run) per cell;
    columns grouped by engine, its default setting first."""
    engines = list(dict.fromkeys(records["engine"]))
    runs = records[["engine", "setting"]].drop_duplicates()
    ordered = sorted(zip(runs["engine"], runs["setting"]),
                     key=lambda run: (engines.index(run[0]), run[1] != "default", run[1]))
    columns = [label(engine, setting) for engine, setting in ordered]
    empty = records.iloc[0:0]
    rows = []
    for scenario in scenarios:
        runs = by_run(records[records["scenario"] == scenario.name])
        rows.append(dict(scenario=scenario.name, anchor=anchor(scenario.name),
                         cells=[dict(cell(runs.get(column, empty)), href=run_anchor(scenario.name, column),
                                     engine=engine) for column, (engine, _) in zip(columns, ordered)]))
    return dict(columns=columns, engines=[engine for engine, _ in ordered], rows=rows)


def summary_matrix(records: pd.DataFrame, scenarios: Sequence[Scenario]) -> dict:
    return matrix_rows(records, scenarios, _cell)


def label(engine: str, setting: str) -> str:
    return engine if setting == "default" else f"{engine} [{setting}]"


def anchor(name: str) -> str:
    return "s-" + "".join(c if c.isalnum() else "-" for c in name)


def md_cell(value) -> str:
    """Text for one Markdown table cell: on one line, `|` escaped (names
    and reasons come from users' files and engines' messages)."""
    return one_line(_fmt(value)).replace("|", "\\|")


def reference_method(reference: Signals) -> str:
    """How the reference was computed, from its run facts: the method and,
    for an integrated (forward-dynamics) run, the integrator, its
    tolerance, steps and largest constraint residual."""
    facts = reference.info.facts
    if "integrator" not in facts:
        return str(facts.get("method", ""))
    return (f"{facts.get('method', '')}; {facts['integrator']}, rtol {facts['rtol']:g}, {facts.get('steps')} steps, "
            f"constraint residual ≤ {facts.get('constraint_drift_max', float('nan')):.2g} (scaled)")


def summary_markdown(records: pd.DataFrame, scenarios: Sequence[Scenario], meta: dict,
                     references: Mapping[str, Signals] | None = None, matrix: dict | None = None) -> str:
    """summary.md: the matrix (`summary_matrix`, made here unless given),
    the failures, what was not built and how references were integrated."""
    matrix = matrix or summary_matrix(records, scenarios)
    lines = [f"# mechval discrepancy summary ({meta['date']}, commit {meta['commit']})", "",
             "Worst ratio error / bound per scenario × engine (≤ 1 passes).", "",
             "| scenario | " + " | ".join(map(md_cell, matrix["columns"])) + " |",
             "|---" * (len(matrix["columns"]) + 1) + "|"]
    for row in matrix["rows"]:
        cells = [c["text"] + (" ✗" if c["css"] == "bad" else "") for c in row["cells"]]
        lines.append(f"| {md_cell(row['scenario'])} | " + " | ".join(cells) + " |")
    failures = records[records["verdict"] == "fail"]
    if not failures.empty:
        lines += ["", "## Out of tolerance", "",
                  "| scenario | engine | setting | signal | max error | ratio | first ¼ | last ¼ | growth | reason |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for _, r in failures.iterrows():
            lines.append(f"| {md_cell(r['scenario'])} | {md_cell(r['engine'])} | {md_cell(r['setting'])} | "
                         f"{md_cell(r['signal'])} | {_fmt(r['max_error'])} | {_fmt(r['ratio'])} | "
                         + " | ".join(_fmt(r.get(c)) for c in GROWTH_COLUMNS) + f" | {md_cell(r['reason'] or '')} |")
    refused = records[records["signal"].eq("(run)") & records["verdict"].eq("missing")]
    if not refused.empty:
        lines += ["", "## Not built (declared by the adapter)", "", "| scenario | engine | reason |", "|---|---|---|"]
        lines += [f"| {md_cell(r['scenario'])} | {md_cell(r['engine'])} | {md_cell(r['reason'])} |"
                  for _, r in refused.iterrows()]
    integrated = {s.name: reference_method(references[s.name]) for s in scenarios
                  if references and s.name in references and "integrator" in references[s.name].info.facts}
    if integrated:
        lines += ["", "## Reference integration (forward dynamics)", ""]
        lines += [f"- {md_cell(name)}: {md_cell(method)}" for name, method in integrated.items()]
    return "\n".join(lines) + "\n"


def run_anchor(scenario: str, run_label: str) -> str:
    """The id of one engine run's records inside a scenario's section."""
    return anchor(scenario) + "--" + "".join(c if c.isalnum() else "-" for c in run_label)


def override_notes(scenario: Scenario) -> dict[str, dict[str, str]]:
    """Engine → tolerance class → what its [engines.NAME.tolerance] entry
    changes and the reason the scene file gives, so that a loosened bound
    is never silent."""
    notes: dict[str, dict[str, str]] = {}
    for engine, table in scenario.engines.items():
        for cls, bound in table.tolerance.items():
            reason = table.reasons.get(cls) or "no reason given in the scene file"
            notes.setdefault(engine, {})[cls] = (
                f"{engine} override: {cls} {bound:.3g} (scenario {scenario.tolerance[cls]:.3g}): {reason}")
    return notes


def _verdict(records: pd.DataFrame) -> str:
    if records.empty:
        return "not run"
    return "fail" if (records["verdict"] == "fail").any() else "pass"


def _bound_class(signal: str, cls) -> str | None:
    """The tolerance class a record's bound comes from (health figures
    borrow theirs, mechval.judging.compare.HEALTH_BOUNDS)."""
    return HEALTH_BOUNDS.get(signal.removeprefix("health.")) if cls == "health" else cls


def _run_groups(scenario: Scenario, records: pd.DataFrame) -> list[dict]:
    notes = override_notes(scenario)
    groups = []
    for run, group in by_run(records).items():
        engine = group["engine"].iloc[0]
        rows = [dict(verdict=r["verdict"], cells={c: _fmt(r[c]) for c in RECORD_COLUMNS},
                     override=notes.get(engine, {}).get(_bound_class(r["signal"], r["class"]), ""))
                for r in group.to_dict("records")]
        groups.append(dict(label=run, engine=engine, anchor=run_anchor(scenario.name, run), verdict=_verdict(group),
                           summary=_cell(group), rows=rows, overrides=list(notes.get(engine, {}).values())))
    return groups


def _scenario_section(scenario: Scenario, reference: Signals, outcomes: list[Outcome],
                      records: pd.DataFrame, palette: Mapping[str, str], drawing: dict | None = None) -> dict:
    results = {label(o.task.engine, o.task.setting): o.signals for o in outcomes if o.signals is not None}
    mine = records[records["scenario"] == scenario.name]
    bounds = {run: dict(zip(group["signal"], group["bound"])) for run, group in by_run(mine).items()}
    return dict(
        name=scenario.name, anchor=anchor(scenario.name), mechanism=scenario.mechanism,
        description=scenario.description, tolerance=dict(scenario.tolerance.bounds),
        overrides=[note for engine in override_notes(scenario).values() for note in engine.values()],
        verdict=_verdict(mine),
        drawing=drawing if drawing is not None else plots.mechanism_figure(build_mechanism(scenario), scenario.time.t),
        signals=plots.signal_data(reference, results, bounds, palette),
        energy=plots.energy_data(reference, results, palette),
        reference_method=reference_method(reference),
        runs=_run_groups(scenario, mine),
    )


def write_report(out: Path, scenarios: Sequence[Scenario], references: dict[str, Signals],
                 outcomes: list[Outcome], records: pd.DataFrame,
                 extra_sections: Sequence[Section] = (),
                 extra_files: Mapping[str, Callable[[Path], None]] | None = None,
                 drawings: Mapping[str, dict] | None = None) -> Path:
    """Render the report into `out` (which must not exist yet), whole or not
    at all; extra_files maps a file name to a function writing that path;
    `drawings` holds scenes' linkage figures made already (scene name →
    `plots.mechanism_figure`, as `mechval run`'s workers make them)."""
    meta = provenance()

    def fill(folder: Path) -> None:
        env = Environment(loader=FileSystemLoader(TEMPLATES), autoescape=select_autoescape(["html", "j2"]),
                          trim_blocks=True, lstrip_blocks=True)
        palette = plots.colours(label(e, s) for e, s in zip(records["engine"], records["setting"]))
        sections = [_scenario_section(s, references[s.name], [o for o in outcomes if o.task.scenario.name == s.name],
                                      records, palette, (drawings or {}).get(s.name)) for s in scenarios]
        sections.sort(key=lambda section: section["verdict"] != "fail")       # failures first, else as given
        matrix = summary_matrix(records, scenarios)
        html = env.get_template("report.html.j2").render(
            meta=meta, matrix=matrix, scenarios=sections, engine_runs=runs.run_tables(outcomes),
            overall_pass=not (records["verdict"] == "fail").any(),
            failures=int(records[records["verdict"] == "fail"].groupby(["scenario", "engine", "setting"]).ngroups),
            engines=list(dict.fromkeys(records["engine"])), verdicts=VERDICTS,
            record_columns=RECORD_COLUMNS, text_columns=TEXT_COLUMNS, extra_sections=extra_sections,
            per_figure=plots.SIGNALS_PER_FIGURE, scripts=plots.page_scripts())
        (folder / "index.html").write_text(html, encoding="utf-8")
        write_csv(records, folder / "discrepancies.csv")
        runs.write_runs_csv(folder / "runs.csv", outcomes)
        (folder / "summary.md").write_text(summary_markdown(records, scenarios, meta, references, matrix),
                                             encoding="utf-8")
        for name, write in (extra_files or {}).items():
            write(folder / name)

    return write_folder_atomically(out, fill)
