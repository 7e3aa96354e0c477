"""The cost sweep as a report: work-precision diagrams and tables, either as
a section of the run report or as a folder of its own (`mechval cost`).

The folder holds index.html (self-contained), cost.csv (one row per engine
× setting × signal class, full precision, empty cells where a value does
not apply), convergence.csv, cheapest.csv and one work-precision PNG per
scenario. It is written to a temporary sibling folder and moved into place,
like the run report.
"""

from __future__ import annotations

import base64
from pathlib import Path

import numpy as np
import pandas as pd
from jinja2 import Environment

from mechval.cost_tables import CLASS_ORDER, HEADLINE, MIN_ORDER, ORDER_SPREAD, REFERENCE, pivot_cells
from mechval.signals import write_folder_atomically

from .build import Section, provenance
from .plots import plt, to_png

ANCHOR = "cost"
TITLE = "Cost: accuracy against wall time"
PAGE = Environment(autoescape=True).from_string("""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>mechval cost</title>
<style>body{font-family:sans-serif;margin:2em;max-width:90em}table{border-collapse:collapse;font-size:90%}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}img{max-width:100%}</style></head><body>
<h1>mechval — {{ title }}</h1>
<p>{% for k, v in meta.items() %}{{ k }}: {{ v }}{% if not loop.last %} · {% endif %}{% endfor %}</p>
<p>Files: <a href="cost.csv">cost.csv</a>, <a href="convergence.csv">convergence.csv</a>,
<a href="cheapest.csv">cheapest.csv</a>.</p>
{{ body | safe }}
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
<img alt="work-precision diagram of {{ s.name }}" src="data:image/png;base64,{{ s.png }}">
<h4>Cheapest setting reaching a {{ headline }} error of …</h4>{{ s.headline | safe }}
<h4>Per class</h4>{{ s.per_class | safe }}
<h4>Observed convergence order</h4>{{ s.orders | safe }}
{% if s.failures %}<h4>Failed points</h4>{{ s.failures | safe }}{% endif %}
{% endfor %}
""")


def _label(engine: str, variant: str) -> str:
    return f"{engine} [{variant}]"


def diagram(table: pd.DataFrame, scenario: str) -> str:
    """Work-precision diagram of one scenario (base64 PNG): one panel per
    class (the headline first), log error against log time per simulated
    second, one line per engine/variant ordered by step, ★ at the default
    setting, the reference's time as a dashed vertical line."""
    mine = table[table["scenario"] == scenario]
    engines = mine[mine["engine"] != REFERENCE]
    usable = engines[(engines["failure"].fillna("") == "") & (engines["error"] > 0)]
    present = set(usable["class"])
    classes = [c for c in (HEADLINE,) + CLASS_ORDER[:-1] if c in present]
    cols = min(3, max(1, len(classes)))
    rows = int(np.ceil(len(classes) / cols)) or 1
    fig, axes = plt.subplots(rows, cols, figsize=(5 * cols, 3.8 * rows), squeeze=False)
    reference = mine[mine["engine"] == REFERENCE]["s_per_sim_s"]
    lines = list(dict.fromkeys(zip(engines["engine"], engines["variant"])))
    colours = {e: f"C{k}" for k, e in enumerate(dict.fromkeys(engines["engine"]))}
    styles = ["-", "--", ":", "-."]
    for ax, cls in zip(axes.flat, classes):
        points = usable[usable["class"] == cls]
        for engine, variant in lines:
            line = points[(points["engine"] == engine) & (points["variant"] == variant)].sort_values("step_s")
            if line.empty:
                continue
            nth = [v for e, v in lines if e == engine].index(variant)
            ax.loglog(line["s_per_sim_s"], line["error"], styles[nth % 4], marker="o", ms=3,
                      color=colours[engine], label=_label(engine, variant))
            default = line[line["default"].astype(bool)]
            ax.loglog(default["s_per_sim_s"], default["error"], "*", ms=14, color=colours[engine], mec="black")
        if len(reference):
            ax.axvline(float(reference.iloc[0]), color="0.4", ls="--", lw=1)
        kind = points["error_kind"].iloc[0] if len(points) else ""
        ax.set_title(f"{cls} ({kind})", fontsize=9)
        ax.set_xlabel("wall time per simulated second [s]  (dashed: reference)", fontsize=8)
        ax.set_ylabel("max error", fontsize=8)
        ax.grid(alpha=0.3, which="both")
        ax.tick_params(labelsize=7)
    for ax in axes.flat[len(classes):]:
        ax.set_visible(False)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, fontsize=8, loc="lower center", ncol=min(4, len(labels)),
                   bbox_to_anchor=(0.5, 1.0))
    fig.tight_layout()
    return to_png(fig)


def _cheapest_html(cheap: pd.DataFrame, index: list[str]) -> str:
    return pivot_cells(cheap, index).to_html(escape=True) if len(cheap) else "<p>no usable point</p>"


def _scenario_parts(table: pd.DataFrame, orders: pd.DataFrame, cheap: pd.DataFrame, scenario: str,
                    png: str) -> dict:
    mine, here = table[table["scenario"] == scenario], cheap[cheap["scenario"] == scenario]
    order_grid = orders[orders["scenario"] == scenario].pivot_table(
        index=["engine", "variant"], columns="class", values="order", aggfunc="first", sort=False, dropna=False)
    order_grid = order_grid[[c for c in CLASS_ORDER if c in order_grid.columns]]
    failed = mine[(mine["failure"].fillna("") != "") & (mine["class"] == HEADLINE)]
    return dict(
        name=scenario, png=png,
        reference=f"{mine[mine['engine'] == REFERENCE]['s_per_sim_s'].iloc[0]:.3g}",
        headline=_cheapest_html(here[here["class"] == HEADLINE], ["engine"]),
        per_class=_cheapest_html(here[here["class"] != HEADLINE], ["engine", "class"]),
        orders=order_grid.to_html(float_format=lambda v: f"{v:.2f}", na_rep="") if len(order_grid) else "",
        failures=failed[["engine", "variant", "step_s", "failure"]].to_html(index=False) if len(failed) else "",
    )


def diagrams(table: pd.DataFrame) -> dict[str, str]:
    """Scenario name → its work-precision diagram (base64 PNG)."""
    return {scenario: diagram(table, scenario) for scenario in dict.fromkeys(table["scenario"])}


def section_html(table: pd.DataFrame, orders: pd.DataFrame, cheap: pd.DataFrame,
                 pngs: dict[str, str] | None = None) -> str:
    pngs = pngs or diagrams(table)
    scenarios = [_scenario_parts(table, orders, cheap, s, png) for s, png in pngs.items()]
    return SECTION.render(scenarios=scenarios, headline=HEADLINE, min_order=MIN_ORDER, spread=ORDER_SPREAD)


def cost_section(table: pd.DataFrame, orders: pd.DataFrame, cheap: pd.DataFrame) -> Section:
    """The sweep as an extra section of the run report."""
    return Section(ANCHOR, TITLE, section_html(table, orders, cheap))


def write_table(table: pd.DataFrame, path: Path) -> None:
    """Full precision (%.17g); NaN as an empty cell."""
    table.to_csv(path, index=False, float_format="%.17g", na_rep="")


def write_cost_report(out: Path, table: pd.DataFrame, orders: pd.DataFrame, cheap: pd.DataFrame) -> Path:
    """Write the cost report folder `out` (which must not exist yet), whole
    or not at all."""
    def fill(folder: Path) -> None:
        for name, frame in (("cost.csv", table), ("convergence.csv", orders), ("cheapest.csv", cheap)):
            write_table(frame, folder / name)
        pngs = diagrams(table)
        for scenario, png in pngs.items():
            safe = "".join(c if c.isalnum() or c in "-_" else "-" for c in scenario)
            (folder / f"work-precision-{safe}.png").write_bytes(base64.b64decode(png))
        body = section_html(table, orders, cheap, pngs)
        (folder / "index.html").write_text(PAGE.render(title=TITLE, meta=provenance(), body=body), encoding="utf-8")

    return write_folder_atomically(out, fill)
