"""Reading a cost table (`mechval.harness.cost`): observed convergence orders, the
cheapest setting that reaches each error target, and both as terminal text.

Observed order: the least-squares slope of log error against log step over
the asymptotic range of an engine/variant/class line. Between neighbouring
steps the local order is Δlog error / Δlog step; the asymptotic range is the
longest run of neighbours whose local orders are all ≥ MIN_ORDER (the error
still falls: this cuts off the floor where round-off or a soft-constraint
limit takes over) and lie within ORDER_SPREAD of each other (this cuts off
coarse, pre-asymptotic steps where the order is not yet steady); of equally
long runs the finer one. Fewer than three points in it: no order.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import pandas as pd

#: The cost table's columns (`mechval.harness.cost.sweep` fills it).
COLUMNS = ["scenario", "engine", "version", "variant", "step_s", "steps_per_sample", "default", "class", "error",
           "error_kind", "worst_signal", "s_per_sim_s", "s_per_sim_s_min", "s_per_sim_s_max",
           "vs_reference", "build_s", "engine_s_per_sim_s", "repeats", "failure"]
REFERENCE = "reference"
HEADLINE = "force+torque"
CLASS_ORDER = ("angle", "position", "velocity", "acceleration", "force", "torque", HEADLINE)
#: Error targets of the cheapest-setting table (relative, or rad / m).
TARGETS = (1e-2, 1e-3, 1e-4, 1e-6)

MIN_ORDER = 0.5
ORDER_SPREAD = 0.5
ORDER_COLUMNS = ["scenario", "engine", "variant", "class", "order", "points", "step_min", "step_max"]
CHEAPEST_COLUMNS = ["scenario", "engine", "class", "target", "reached", "variant", "step_s", "s_per_sim_s",
                    "vs_reference", "error"]
LINE = ["scenario", "engine", "variant", "class"]


def usable(table: pd.DataFrame) -> pd.DataFrame:
    """Engine rows whose point did not fail and whose error is known."""
    rows = table[(table["engine"] != REFERENCE) & (table["failure"].fillna("") == "")]
    return rows[np.isfinite(rows["error"].astype(float))]


def asymptotic_range(steps: np.ndarray, errors: np.ndarray) -> np.ndarray:
    """Indices (into steps sorted ascending) of the asymptotic range."""
    with np.errstate(divide="ignore", invalid="ignore"):
        local = np.diff(np.log(errors)) / np.diff(np.log(steps))
    best = np.arange(0)
    for first in range(len(local)):
        for last in range(first, len(local)):
            run = local[first:last + 1]
            if not (np.all(run >= MIN_ORDER) and run.max() - run.min() <= ORDER_SPREAD):
                break
            if last - first + 2 > len(best):       # finer runs come first: ties keep them
                best = np.arange(first, last + 2)
    return best


def convergence(table: pd.DataFrame) -> pd.DataFrame:
    """Observed order per scenario × engine × variant × class (ORDER_COLUMNS;
    order empty when there is no asymptotic range of ≥ 3 points)."""
    rows = []
    for key, line in usable(table).groupby(LINE, sort=False):
        line = line[line["error"] > 0].sort_values("step_s")
        steps, errors = line["step_s"].to_numpy(float), line["error"].to_numpy(float)
        used = asymptotic_range(steps, errors) if len(line) >= 3 else np.arange(0)
        row = dict(zip(LINE, key), order=np.nan, points=len(used), step_min=np.nan, step_max=np.nan)
        if len(used) >= 3:
            row.update(order=float(np.polyfit(np.log(steps[used]), np.log(errors[used]), 1)[0]),
                       step_min=float(steps[used].min()), step_max=float(steps[used].max()))
        rows.append(row)
    return pd.DataFrame(rows, columns=ORDER_COLUMNS)


def cheapest(table: pd.DataFrame, targets: Sequence[float] = TARGETS) -> pd.DataFrame:
    """Per scenario × engine × class and target: the setting with the least
    time per simulated second whose error is within the target, or, when
    none is (reached False), the setting with the smallest error."""
    rows = []
    for (scenario, engine, cls), points in usable(table).groupby(["scenario", "engine", "class"], sort=False):
        for target in targets:
            within = points[points["error"] <= target]
            pick = (within.loc[within["s_per_sim_s"].idxmin()] if len(within)
                    else points.loc[points["error"].idxmin()])
            rows.append(dict(scenario=scenario, engine=engine, **{"class": cls}, target=target,
                             reached=bool(len(within)),
                             **{c: pick[c] for c in ("variant", "step_s", "s_per_sim_s", "vs_reference", "error")}))
    return pd.DataFrame(rows, columns=CHEAPEST_COLUMNS)


def _cell(row: pd.Series) -> str:
    if not row["reached"]:
        return f"not reached (best {row['error']:.1e}: {row['variant']} dt {row['step_s']:.3g})"
    return f"{row['variant']} dt {row['step_s']:.3g}: {row['s_per_sim_s']:.2g} s/s {row['vs_reference']:.3g}×ref"


def pivot_cells(cheap: pd.DataFrame, index: list[str]) -> pd.DataFrame:
    """The cheapest settings as text cells: index rows × target columns."""
    cells = cheap.assign(cell=cheap.apply(_cell, axis=1), target=cheap["target"].map(lambda t: f"≤ {t:g}"))
    return cells.pivot_table(index=index, columns="target", values="cell", aggfunc="first", sort=False)


def format_tables(table: pd.DataFrame, orders: pd.DataFrame, cheap: pd.DataFrame) -> str:
    """The sweep as terminal text, per scenario: reference cost, every point
    (headline error), the cheapest settings (headline, then per class) and
    the observed orders."""
    out = []
    pd_options = ("display.width", 250, "display.max_colwidth", 80, "display.max_rows", 500)
    with pd.option_context(*pd_options):
        for scenario, mine in table.groupby("scenario", sort=False):
            ref = mine[mine["engine"] == REFERENCE].iloc[0]
            out.append(f"== {scenario}: reference (closed form) {ref['s_per_sim_s']:.3g} s per simulated second "
                       f"(median of {ref['repeats']})")
            points = mine[(mine["class"] == HEADLINE)].assign(
                default=lambda d: np.where(d["default"], "*", ""))
            columns = ["engine", "variant", "step_s", "default", "s_per_sim_s", "vs_reference", "build_s",
                       "error", "failure"]
            out += ["", f"Points ({HEADLINE} error relative to peak; * = the engine's default setting):",
                    points[columns].rename(columns={"error": f"{HEADLINE} error"})
                    .to_string(index=False, float_format=lambda v: f"{v:.3g}")]
            here = cheap[cheap["scenario"] == scenario]
            headline = here[here["class"] == HEADLINE]
            if len(headline):
                out += ["", f"Cheapest setting reaching a {HEADLINE} error (max relative to peak) of:",
                        pivot_cells(headline, ["engine"]).to_string()]
                per_class = here[here["class"] != HEADLINE].copy()
                per_class["order"] = per_class["class"].map(CLASS_ORDER.index)
                per_class = per_class.sort_values(["engine", "order"], kind="stable")
                out += ["", "Per class (angle in rad and position in m absolute; the others relative to peak):",
                        pivot_cells(per_class, ["engine", "class"]).to_string()]
            mine_orders = orders[(orders["scenario"] == scenario) & orders["order"].notna()]
            if not len(mine_orders):
                out += ["", "Observed convergence order: none (no line has an asymptotic range of ≥ 3 points)"]
            else:
                grid = mine_orders.pivot_table(index=["engine", "variant"], columns="class", values="order",
                                               aggfunc="first", sort=False)
                grid = grid[[c for c in CLASS_ORDER if c in grid.columns]]
                out += ["", "Observed convergence order (slope of log error vs log step over the asymptotic "
                            "range; empty: no such range of ≥ 3 points):",
                        grid.to_string(float_format=lambda v: f"{v:.2f}", na_rep="")]
            out.append("")
    return "\n".join(out)
