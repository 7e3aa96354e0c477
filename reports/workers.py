"""The report's "Engine versions on the workers" section: shown only when
runs of one engine reported different versions, as happens on a cluster
whose workers have different releases installed (`mechval run --dask`).
Each version is listed with the workers that ran it, so the odd worker is
named; every run's version and worker are also in runs.csv."""

from __future__ import annotations

from typing import Iterable

from markupsafe import Markup, escape

from mechval.records.outcome import Outcome

from .build import Section

#: How a run on this machine (not on a Dask worker) is named.
HERE = "this machine"


def versions_by_worker(outcomes: Iterable[Outcome]) -> dict[str, dict[str, set[str]]]:
    """Per engine whose runs reported more than one version: version →
    the workers that ran it (their addresses, or HERE)."""
    seen: dict[str, dict[str, set[str]]] = {}
    for o in outcomes:
        if o.signals is not None and o.signals.version:
            seen.setdefault(o.task.engine, {}).setdefault(o.signals.version, set()).add(o.worker or HERE)
    return {engine: versions for engine, versions in seen.items() if len(versions) > 1}


def version_section(outcomes: Iterable[Outcome]) -> Section | None:
    """None when every engine ran at one version."""
    spread = versions_by_worker(outcomes)
    if not spread:
        return None
    rows = "".join(
        f'<tr><td class="text">{escape(engine)}</td><td class="text bad">{escape(version)}</td>'
        f'<td class="text">{escape(", ".join(sorted(workers)))}</td></tr>'
        for engine, versions in spread.items() for version, workers in sorted(versions.items()))
    return Section("worker-versions", "Engine versions on the workers", Markup(
        "<p>Runs of one engine reported different versions: their results are not comparable with each other. "
        "Install one release on every worker.</p>"
        f"<table><tr><th>engine</th><th>version</th><th>workers that ran it</th></tr>{rows}</table>"))


def version_warnings(outcomes: Iterable[Outcome]) -> list[str]:
    """One line per engine whose runs reported different versions."""
    return [f"{engine} ran at different versions: " + "; ".join(
        f"{version} on {', '.join(sorted(workers))}" for version, workers in sorted(versions.items()))
        for engine, versions in versions_by_worker(outcomes).items()]
