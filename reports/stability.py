"""The report's stability section: health figures per engine × hard case."""

from __future__ import annotations

from typing import Sequence

import pandas as pd
from jinja2 import Environment, FileSystemLoader, select_autoescape
from markupsafe import Markup

from mechval.model.scenario import Scenario

from .build import TEMPLATES, Section, matrix_rows

FIGURES = (("health.gap", "gap", "m"), ("health.drive_error", "drive error", "rad"),
           ("health.power_residual", "power residual", ""), ("health.assembly_flip", "branch flips", ""),
           ("health.nonfinite", "NaN/inf", ""))


def _cell(records: pd.DataFrame) -> dict:
    if records.empty:
        return dict(verdict="not run", css="missing", figures=[])
    if records["signal"].eq("(run)").any():
        refused = (records["verdict"] == "missing").all()       # declared up front (`Task.refused`)
        return dict(verdict=("" if refused else "run failed: ") + str(records["reason"].iloc[0]),
                    css="missing" if refused else "bad", figures=[])
    health = records.set_index("signal")
    figures = []
    for signal, name, unit in FIGURES:
        if signal in health.index and pd.notna(health.loc[signal, "max_error"]):
            value = health.loc[signal, "max_error"]
            figures.append((name, f"{value:.2g} {unit}".strip() if isinstance(value, float) else str(value)))
    failed = (records["verdict"] == "fail").any()
    return dict(verdict="FAIL" if failed else "stable and accurate", css="bad" if failed else "ok1",
                figures=figures)


def stability_section(records: pd.DataFrame, scenarios: Sequence[Scenario]) -> Section | None:
    """None when no scenario of the run is tagged hard."""
    hard = [s for s in scenarios if "hard" in s.tags]
    if not hard or records.empty:
        return None
    table = matrix_rows(records, hard, _cell)
    env = Environment(loader=FileSystemLoader(TEMPLATES), autoescape=select_autoescape(["html", "j2"]))
    html = env.get_template("stability.html.j2").render(**table)
    return Section("stability", "Stability: hard cases", Markup(html))
