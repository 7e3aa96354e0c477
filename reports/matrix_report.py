"""The release matrix as a report folder (`mechval matrix`): index.html
(scenes × releases, failures first; the look of the run report, plotly.js
inlined), releases.csv, accuracy.csv and changes.csv (full precision) and
summary.md, written whole or not at all.

The harness hands it three tables: `releases` (version, status, runs,
failed, facts), `accuracy` (version, scenario, setting, class, error,
verdict, reason: per run and signal class against the reference) and
`changes` (old, new, scenario, setting, verdict, size, signal, t,
accuracy, reason, one column per class: from one release to the next).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd
from jinja2 import Environment, FileSystemLoader, select_autoescape
from markupsafe import Markup

from mechval.records.outputs import write_folder_atomically

from .build import provenance
from .csv_files import write_csv
from .plots import page_scripts

TEMPLATES = Path(__file__).resolve().parent / "templates"
#: Row order of the matrix: a scene with a failed run first, then one that changed.
RANK = {"fail": 0, "failed": 0, "changed": 1, "within": 2, "n/a": 3, "bit-identical": 4, "": 5}


def _label(scenario: str, setting: str) -> str:
    return scenario if setting == "default" else f"{scenario} [{setting}]"


def brief(reason: str, length: int = 130) -> str:
    """A failure's reason for a cell: without the scenario file's path that
    a scenario error starts with (the cause follows it), at most `length`
    characters (the cell's title holds it whole)."""
    text = re.sub(r"(\w+Error: )?\S+\.toml: ", "", str(reason), count=1)
    return text if len(text) <= length else text[:length - 1] + "…"


def _first_cell(accuracy: pd.DataFrame) -> dict:
    """A scene's cell in the first release that ran it: its accuracy."""
    if accuracy.empty:
        return dict(verdict="—", detail="", css="missing", title="no run", rank="")
    if (accuracy["class"] == "(run)").any():
        reason = str(accuracy["reason"].iloc[0])
        return dict(verdict="run failed", detail=brief(reason), css="bad", title=reason, rank="fail")
    worst = accuracy.loc[accuracy["error"].idxmax()]
    failed = accuracy[accuracy["verdict"] == "fail"]
    detail = f"max {worst['error']:.2g} ({worst['class']})"
    if len(failed):
        return dict(verdict="out of tolerance", detail=detail, css="bad", title="; ".join(failed["reason"]), rank="")
    return dict(verdict="within tolerance", detail=detail, css="ok1", title=detail, rank="")


def _change_cell(change: pd.Series | None, accuracy: pd.DataFrame) -> dict:
    """A scene's cell in a later release: what changed from the previous one."""
    if change is None:
        return _first_cell(accuracy) if not accuracy.empty else dict(verdict="—", detail="", css="missing",
                                                                      title="no run", rank="")
    verdict = change["verdict"]
    if verdict == "failed":
        return dict(verdict="run failed", detail=brief(change["reason"]), css="bad", title=str(change["reason"]),
                    rank=verdict)
    if verdict == "n/a":        # this release ran the scene, the previous one did not
        cell = _first_cell(accuracy)
        return dict(cell, detail=f"{cell['detail']}; nothing to compare with ({change['old']} did not run it)",
                    title=str(change["reason"]), rank="n/a")
    out_of_tolerance = not accuracy.empty and (accuracy["verdict"] == "fail").any()
    tolerance = "; out of tolerance" if out_of_tolerance else "; within tolerance"
    if verdict == "bit-identical":
        detail, css = "all signals", "ok1"
    else:
        detail = f"{change['size']:.2g} of peak ({change['signal']}); accuracy {change['accuracy']}"
        css = "ok2" if verdict == "within" else "bad" if change["accuracy"] in ("worse", "mixed") else "ok3"
    return dict(verdict=verdict, detail=detail + tolerance, css="bad" if out_of_tolerance else css,
                title=f"{change['changed_signals']:g} of {change['signals']:g} signals moved; {change['reason']}",
                rank=verdict)


def matrix_rows(versions: Sequence[str], accuracy: pd.DataFrame, changes: pd.DataFrame) -> list[dict]:
    """One row per scene [setting]: a cell per release; failures first."""
    keys = list(dict.fromkeys(zip(accuracy["scenario"], accuracy["setting"]))) if len(accuracy) else []
    rows = []
    for scenario, setting in keys:
        mine = accuracy[(accuracy["scenario"] == scenario) & (accuracy["setting"] == setting)]
        cells, seen = [], False
        for version in versions:
            own = mine[mine["version"] == version]
            change = None
            if len(changes):
                hit = changes[(changes["new"] == version) & (changes["scenario"] == scenario)
                              & (changes["setting"] == setting)]
                change = hit.iloc[0] if len(hit) else None
            cells.append(_change_cell(change, own) if seen else _first_cell(own))
            seen = seen or not own.empty
        rank = min(RANK.get(c["rank"], 5) for c in cells)
        rows.append(dict(label=_label(scenario, setting), cells=cells, rank=rank))
    return sorted(rows, key=lambda r: r["rank"])


def change_figure(versions: Sequence[str], changes: pd.DataFrame) -> dict | None:
    """A heat map: log10 of each change's size, scenes × release steps
    (bit-identical shown as blank, its text says so)."""
    if changes.empty or "size" not in changes:
        return None
    steps = [f"{o} → {n}" for o, n in dict.fromkeys(zip(changes["old"], changes["new"]))]
    labels = list(dict.fromkeys(_label(s, t) for s, t in zip(changes["scenario"], changes["setting"])))
    z = np.full((len(labels), len(steps)), np.nan)
    text = [["" for _ in steps] for _ in labels]
    for _, c in changes.iterrows():
        i, j = labels.index(_label(c["scenario"], c["setting"])), steps.index(f"{c['old']} → {c['new']}")
        text[i][j] = c["verdict"]
        if isinstance(c.get("size"), float) and c["size"] > 0:
            z[i, j] = np.log10(c["size"])
    return {"data": [{"type": "heatmap", "z": [[None if np.isnan(v) else v for v in row] for row in z], "x": steps,
                      "y": labels, "text": text, "colorscale": "YlOrRd", "reversescale": True,
                      "hovertemplate": "%{y}<br>%{x}<br>%{text}<br>log10(|change| / peak) = %{z:.2f}<extra></extra>",
                      "colorbar": {"title": {"text": "log10 |change| / peak"}}}],
            "layout": {"height": 160 + 22 * len(labels), "margin": {"l": 220, "r": 20, "t": 30, "b": 60},
                       "title": {"text": "size of each release's change"}}}


def accuracy_table(accuracy: pd.DataFrame) -> Markup:
    if accuracy.empty:
        return Markup("<p>No run.</p>")
    runs = accuracy[accuracy["class"] != "(run)"]
    wide = runs.pivot_table(index=["scenario", "setting", "class"], columns="version", values="error", aggfunc="max",
                            sort=False)
    return Markup(wide.to_html(float_format=lambda v: f"{v:.3g}", na_rep="—"))


def summary_markdown(engine: str, releases: pd.DataFrame, changes: pd.DataFrame) -> str:
    lines = [f"# mechval release matrix: {engine}", "", "| release | status | runs | failed runs |",
             "|---|---|---|---|"]
    lines += [f"| {r.version} | {r.status} | {r.runs} | {r.failed} |" for r in releases.itertuples()]
    if len(changes):
        lines += ["", "| from → to | scene [setting] | verdict | size (of peak) | signal | accuracy |",
                  "|---|---|---|---|---|---|"]
        for c in changes.itertuples():
            size = getattr(c, "size", np.nan)
            if pd.isna(size):
                lines.append(f"| {c.old} → {c.new} | {_label(c.scenario, c.setting)} | {c.verdict}: "
                             f"{brief(c.reason, 150)} | | | |")
                continue
            lines.append(f"| {c.old} → {c.new} | {_label(c.scenario, c.setting)} | {c.verdict} | {size:.3g} | "
                         f"{c.signal} | {c.accuracy} |")
    return "\n".join(lines) + "\n"


def write_matrix_report(out: Path, engine: str, versions: Sequence[str], releases: pd.DataFrame,
                        accuracy: pd.DataFrame, changes: pd.DataFrame, envs_dir: Path,
                        rule: Mapping[str, float], signals: Callable[[Path], None] = lambda folder: None) -> Path:
    """Write the folder `out` (which must not exist yet), whole or not at
    all. `rule`: the regression rule's constants (margin, floor,
    accuracy_change) the page states; `signals(folder)` writes the runs'
    signals into it (the harness's baseline layout)."""
    def fill(folder: Path) -> None:
        signals(folder)
        for name, frame in (("releases.csv", releases), ("accuracy.csv", accuracy), ("changes.csv", changes)):
            write_csv(frame, folder / name)
        (folder / "summary.md").write_text(summary_markdown(engine, releases, changes), encoding="utf-8")
        env = Environment(loader=FileSystemLoader(TEMPLATES), autoescape=select_autoescape(["html", "j2"]))
        ordered = releases.assign(order=(releases["status"] != "ok") * -2 - (releases["failed"] > 0)).sort_values(
            "order", kind="stable")
        html = env.get_template("matrix.html.j2").render(
            engine=engine, versions=list(versions), meta=provenance(), envs_dir=str(envs_dir),
            releases=ordered.to_dict("records"), rows=matrix_rows(versions, accuracy, changes),
            figure=change_figure(versions, changes), accuracy_table=accuracy_table(accuracy),
            scripts=page_scripts(), **rule)
        (folder / "index.html").write_text(html, encoding="utf-8")

    return write_folder_atomically(out, fill)
