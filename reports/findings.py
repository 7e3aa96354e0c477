"""The report's engine-findings section: per finding, the engine version
measured, the figure and whether the misbehaviour is present."""

from __future__ import annotations

from typing import Sequence

from jinja2 import Environment, FileSystemLoader, select_autoescape
from markupsafe import Markup

from mechval.records.findings import Measurement

from .build import TEMPLATES, Section


def _row(m: Measurement) -> dict:
    f = m.finding
    return dict(engine=f.engine, version=m.version or "—", title=f.title, wrong=f.wrong, how=f.how,
                since=f.since, until=f.until, workaround=f.workaround, figure_name=f.figure,
                figure=m.describe(), status=m.status,
                css="missing" if m.error else "ok3" if m.present else "ok1")


def findings_section(measurements: Sequence[Measurement]) -> Section | None:
    """None when no finding was probed (no engine with findings in the run)."""
    if not measurements:
        return None
    env = Environment(loader=FileSystemLoader(TEMPLATES), autoescape=select_autoescape(["html", "j2"]))
    html = env.get_template("findings.html.j2").render(rows=[_row(m) for m in measurements])
    return Section("findings", "Engine findings", Markup(html))
