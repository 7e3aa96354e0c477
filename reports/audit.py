"""The report's model-audit section: per scenario × engine, what the engine's
compiled model holds against the Mechanism (`mechval.records.audit`), as tables.

An overview matrix, then one table per scenario × engine, collapsed when
every row agrees and open when any differs (or the audit failed)."""

from __future__ import annotations

from typing import Sequence

import numpy as np
from jinja2 import Environment
from markupsafe import Markup

from mechval.records.audit import AUDIT_RTOL, FAILING
from mechval.records.audit import AuditResult

from .build import Section, anchor

ANCHOR = "audit"
TITLE = "Model audit: what each engine will simulate"
SECTION = Environment(autoescape=True).from_string("""
<style>table.audit td { text-align: left; } table.audit td:nth-child(-n+2) { white-space: nowrap; }</style>
<p>Each engine's model is built exactly as its run builds it and read back: every body's mass, centre of
mass (body frame) and izz (a spatial scene's: the whole inertia tensor about the centre of mass, body axes),
every joint's kind, bodies, points, axis (a spatial joint's on each of its bodies) and damping, the drive
law, springs, gravity, and the effects the scene does not ask for, which must be absent. Engine values are converted to the
Mechanism's frames (world positions in the model's start state, expressed in each body's frame at the
reference pose). <em>match</em>: read back and equal (within {{ rtol }} of the value's scale);
<em>as set</em>: the engine cannot report it, the value the build passed to it; <em>note</em>: an engine
element or numerical setting with no Mechanism counterpart, or a quantity that lives outside the model;
<em>differs</em>/<em>missing</em>: the model is not what the scene says.</p>
<table>
  <tr><th>scenario</th>{% for engine in engines %}<th>{{ engine }}</th>{% endfor %}</tr>
  {% for row in matrix %}
  <tr><th>{{ row.scenario }}</th>{% for cell in row.cells %}
    <td class="text {{ cell.css }}">{{ cell.text }}</td>{% endfor %}</tr>
  {% endfor %}
</table>
{% for t in tables %}
<details id="{{ t.anchor }}"{% if t.open %} open{% endif %}>
<summary><strong>{{ t.scenario }} × {{ t.engine }}</strong>: {{ t.summary }}</summary>
{% if t.rows %}
<table class="small audit">
<tr>{% for c in columns %}<th>{{ c }}</th>{% endfor %}</tr>
{% for r in t.rows %}<tr{% if r.css %} class="{{ r.css }}"{% endif %}>{% for c in columns %}<td>{{ r[c] }}</td>{% endfor %}</tr>
{% endfor %}</table>
{% endif %}
</details>
{% endfor %}
""")
COLUMNS = ("item", "quantity", "expected", "actual", "unit", "verdict", "deviation", "note")


def _text(value) -> str:
    if isinstance(value, float):
        return "" if np.isnan(value) else f"{value:.12g}"
    return str(value)


def _summary(result: AuditResult) -> tuple[str, str]:
    """(text, css class) of one audit."""
    if result.table is None:
        return f"no audit: {result.error}", "missing"
    if result.failing:
        return f"{result.failing} of {len(result.table)} rows differ", "bad"
    counts = result.table["verdict"].value_counts()
    return ", ".join(f"{n} {verdict}" for verdict, n in counts.items()), "ok1"


def audit_section(results: Sequence[AuditResult]) -> Section | None:
    """None when there is nothing audited."""
    if not results:
        return None
    engines = list(dict.fromkeys(r.engine for r in results))
    scenarios = list(dict.fromkeys(r.scenario for r in results))
    by_key = {(r.scenario, r.engine): r for r in results}
    matrix = []
    for scenario in scenarios:
        cells = []
        for engine in engines:
            result = by_key.get((scenario, engine))
            text, css = _summary(result) if result else ("not audited", "missing")
            cells.append(dict(text=text, css=css))
        matrix.append(dict(scenario=scenario, cells=cells))
    tables = []
    for r in results:
        text, _ = _summary(r)
        rows = []
        if r.table is not None:
            for record in r.table.to_dict("records"):
                row = {c: _text(record[c]) for c in COLUMNS}
                row["deviation"] = "" if np.isnan(record["deviation"]) else f"{record['deviation']:.1e}"
                row["css"] = "bad" if record["verdict"] in FAILING else ""
                rows.append(row)
        tables.append(dict(scenario=r.scenario, engine=r.engine, summary=f"{text} ({r.seconds * 1e3:.0f} ms)",
                           rows=rows, open=r.table is None or r.failing > 0,
                           anchor=f"audit-{anchor(r.scenario)}-{r.engine}"))
    html = SECTION.render(rtol=f"{AUDIT_RTOL:g}", engines=engines, matrix=matrix, tables=tables, columns=COLUMNS)
    return Section(ANCHOR, TITLE, Markup(html))
