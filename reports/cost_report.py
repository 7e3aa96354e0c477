"""The cost sweep as a report: work-precision diagrams and tables, either as
a section of the run report or as a folder of its own (`mechval cost`).

The folder holds index.html (self-contained), cost.csv (one row per engine
× setting × signal class, full precision, empty cells where a value does
not apply), convergence.csv and cheapest.csv; the page draws an interactive
work-precision diagram per scenario (plotly.js inlined). It is written to a temporary sibling folder and moved into place,
like the run report.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from jinja2 import Environment
from markupsafe import Markup

from mechval.judging.cost_tables import CLASS_ORDER, HEADLINE, MIN_ORDER, ORDER_SPREAD, REFERENCE, pivot_cells
from mechval.records.signals import write_folder_atomically

from .build import Section, anchor, provenance
from .csv_files import write_csv
from .plots import colours, page_scripts

ANCHOR = "cost"
TITLE = "Cost: accuracy against wall time"
PAGE = Environment(autoescape=True).from_string("""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>mechval cost</title>
<style>body{font-family:sans-serif;margin:2em;max-width:90em}table{border-collapse:collapse;font-size:90%}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}.plot{width:100%}</style></head><body>
<h1>mechval — {{ title }}</h1>
<p>{% for k, v in meta.items() %}{{ k }}: {{ v }}{% if not loop.last %} · {% endif %}{% endfor %}</p>
<p>Files: <a href="cost.csv">cost.csv</a>, <a href="convergence.csv">convergence.csv</a>,
<a href="cheapest.csv">cheapest.csv</a>.</p>
{{ body }}
{{ scripts }}
</body></html>
""")
SECTION = Environment(autoescape=True).from_string("""
<p>Each engine runs a ladder of time steps (two decades, each dividing the sample interval) crossed with
its variants; time is wall time per simulated second inside the worker (median of the repeats, model build
excluded, reading the signals out included), also as a ratio to the analytic reference's own time for the
same samples. Errors: the largest of a class, relative to the signal's peak ({{ headline }}: the larger of
force and torque), absolute for angle (rad) and position (m). ★ marks an engine's default setting.
Observed order: least-squares slope of log error against log step over the asymptotic range, the longest
run of neighbouring steps whose local orders are all ≥ {{ min_order }} (the error still falls) and within
{{ spread }} of each other (steady); no order with fewer than 3 points.</p>
{% for s in scenarios %}
<h3>{{ s.name }}</h3>
<p>Reference (closed form): {{ s.reference }} s per simulated second.</p>
<div class="plot" data-figure="{{ s.anchor }}" data-kind="plotly" data-group="{{ s.anchor }}" role="img"
     aria-label="work-precision diagram of {{ s.name }}"></div>
<script type="application/json" id="{{ s.anchor }}">{{ s.figure|tojson }}</script>
<h4>Cheapest setting reaching a {{ headline }} error of …</h4>{{ s.headline | safe }}
<h4>Per class</h4>{{ s.per_class | safe }}
<h4>Observed convergence order</h4>{{ s.orders | safe }}
{% if s.failures %}<h4>Failed points</h4>{{ s.failures | safe }}{% endif %}
{% endfor %}
""")


def _label(engine: str, variant: str) -> str:
    return f"{engine} [{variant}]"


def diagram(table: pd.DataFrame, scenario: str) -> dict:
    """Work-precision diagram of one scenario (a Plotly figure): one panel
    per class (the headline first), log error against log time per
    simulated second, one line per engine/variant ordered by step, ★ at the
    default setting, the reference's time as a dashed vertical line."""
    mine = table[table["scenario"] == scenario]
    engines = mine[mine["engine"] != REFERENCE]
    usable = engines[(engines["failure"].fillna("") == "") & (engines["error"] > 0)]
    present = set(usable["class"])
    classes = [c for c in (HEADLINE,) + CLASS_ORDER[:-1] if c in present]
    cols = min(3, max(1, len(classes)))
    rows = int(np.ceil(len(classes) / cols)) or 1
    reference = mine[mine["engine"] == REFERENCE]["s_per_sim_s"]
    lines = list(dict.fromkeys(zip(engines["engine"], engines["variant"])))
    colour = colours(engines["engine"])
    dashes = ["solid", "dash", "dot", "dashdot"]
    traces, annotations, shapes = [], [], []
    layout = dict(grid=dict(rows=rows, columns=cols, pattern="independent", xgap=0.12, ygap=0.3),
                  height=100 + 300 * rows, margin=dict(l=60, r=20, t=90, b=50), hovermode="closest",
                  legend=dict(orientation="h", x=0, y=1, yanchor="top", yref="container"),
                  annotations=annotations, shapes=shapes)
    for k, cls in enumerate(classes):
        axis = "" if k == 0 else str(k + 1)
        points = usable[usable["class"] == cls]
        kind = points["error_kind"].iloc[0] if len(points) else ""
        layout[f"xaxis{axis}"] = dict(type="log", exponentformat="e",
                                      title=dict(text="wall time per simulated second [s]", font=dict(size=11)))
        layout[f"yaxis{axis}"] = dict(type="log", exponentformat="e", title=dict(text="max error", font=dict(size=11)))
        annotations.append(dict(text=f"{cls} ({kind})", xref=f"x{axis} domain", yref=f"y{axis} domain", x=0.5,
                                y=1, yanchor="bottom", showarrow=False, font=dict(size=12)))
        if len(reference):
            shapes.append(dict(type="line", xref=f"x{axis}", yref=f"y{axis} domain", x0=float(reference.iloc[0]),
                               x1=float(reference.iloc[0]), y0=0, y1=1, line=dict(color="#666", dash="dash", width=1)))
            annotations.append(dict(text="reference", xref=f"x{axis}", yref=f"y{axis} domain",
                                    x=float(np.log10(reference.iloc[0])), y=0, xanchor="left", yanchor="bottom",
                                    showarrow=False, font=dict(size=10, color="#666")))
        for engine, variant in lines:
            line = points[(points["engine"] == engine) & (points["variant"] == variant)].sort_values("step_s")
            if line.empty:
                continue
            nth = [v for e, v in lines if e == engine].index(variant)
            name = _label(engine, variant)
            common = dict(xaxis=f"x{axis}", yaxis=f"y{axis}", legendgroup=name, name=name,
                          customdata=line["step_s"].tolist())
            traces.append(dict(common, x=line["s_per_sim_s"].tolist(), y=line["error"].tolist(),
                               mode="lines+markers", showlegend=k == 0,
                               line=dict(color=colour[engine], dash=dashes[nth % 4]), marker=dict(size=5),
                               hovertemplate=f"{name}: error %{{y:.3g}}, %{{x:.3g}} s per s, step %{{customdata:.3g}} s"
                                             "<extra></extra>"))
            default = line[line["default"].astype(bool)]
            traces.append(dict(common, x=default["s_per_sim_s"].tolist(), y=default["error"].tolist(), mode="markers",
                               showlegend=False, customdata=default["step_s"].tolist(),
                               marker=dict(symbol="star", size=15, color=colour[engine],
                                           line=dict(color="black", width=1)),
                               hovertemplate=f"{name} default: error %{{y:.3g}}, %{{x:.3g}} s per s, "
                                             "step %{customdata:.3g} s<extra></extra>"))
    return {"data": traces, "layout": layout}


def _cheapest_html(cheap: pd.DataFrame, index: list[str]) -> str:
    return pivot_cells(cheap, index).to_html(escape=True) if len(cheap) else "<p>no usable point</p>"


def _scenario_parts(table: pd.DataFrame, orders: pd.DataFrame, cheap: pd.DataFrame, scenario: str) -> dict:
    mine, here = table[table["scenario"] == scenario], cheap[cheap["scenario"] == scenario]
    order_grid = orders[orders["scenario"] == scenario].pivot_table(
        index=["engine", "variant"], columns="class", values="order", aggfunc="first", sort=False, dropna=False)
    order_grid = order_grid[[c for c in CLASS_ORDER if c in order_grid.columns]]
    failed = mine[(mine["failure"].fillna("") != "") & (mine["class"] == HEADLINE)]
    return dict(
        name=scenario, anchor="cost-" + anchor(scenario), figure=diagram(table, scenario),
        reference=f"{mine[mine['engine'] == REFERENCE]['s_per_sim_s'].iloc[0]:.3g}",
        headline=_cheapest_html(here[here["class"] == HEADLINE], ["engine"]),
        per_class=_cheapest_html(here[here["class"] != HEADLINE], ["engine", "class"]),
        orders=order_grid.to_html(float_format=lambda v: f"{v:.2f}", na_rep="") if len(order_grid) else "",
        failures=failed[["engine", "variant", "step_s", "failure"]].to_html(index=False) if len(failed) else "",
    )


def section_html(table: pd.DataFrame, orders: pd.DataFrame, cheap: pd.DataFrame) -> Markup:
    """The sweep's diagrams and tables (the page needs `page_scripts`)."""
    scenarios = [_scenario_parts(table, orders, cheap, s) for s in dict.fromkeys(table["scenario"])]
    return Markup(SECTION.render(scenarios=scenarios, headline=HEADLINE, min_order=MIN_ORDER, spread=ORDER_SPREAD))


def cost_section(table: pd.DataFrame, orders: pd.DataFrame, cheap: pd.DataFrame) -> Section:
    """The sweep as an extra section of the run report."""
    return Section(ANCHOR, TITLE, section_html(table, orders, cheap))


def write_table(table: pd.DataFrame, path: Path) -> None:
    """Full precision (%.17g); NaN as an empty cell; text a spreadsheet
    would take for a formula neutralised (reports.csv_files)."""
    write_csv(table, path)


def write_cost_report(out: Path, table: pd.DataFrame, orders: pd.DataFrame, cheap: pd.DataFrame) -> Path:
    """Write the cost report folder `out` (which must not exist yet), whole
    or not at all."""
    def fill(folder: Path) -> None:
        for name, frame in (("cost.csv", table), ("convergence.csv", orders), ("cheapest.csv", cheap)):
            write_table(frame, folder / name)
        html = PAGE.render(title=TITLE, meta=provenance(), body=section_html(table, orders, cheap),
                           scripts=page_scripts())
        (folder / "index.html").write_text(html, encoding="utf-8")

    return write_folder_atomically(out, fill)
