"""The engine findings' probes, by engine (`mechval.records.findings`).

Registered by module path like the adapters, so that nothing imports an
engine library until its probes run; an engine that is not installed is
not probed.
"""

from __future__ import annotations

import importlib
from typing import Iterable

from mechval.records.findings import Measurement

from mechval.engines.registry import EngineUnavailable, adapter

#: Engine name → module with FINDINGS (records) and PROBES (key → probe).
PROBE_MODULES = {"pybullet": "mechval.engines.pybullet.findings", "pinocchio": "mechval.engines.pinocchio.findings",
                 "opensim": "mechval.engines.opensim.findings", "drake": "mechval.engines.drake.findings"}


def measure_findings(engines: Iterable[str]) -> list[Measurement]:
    """Run every probe of the given engines on their installed versions.
    A probe that fails (an engine API that changed) gives a measurement
    with the reason instead of a figure; it never stops the caller."""
    measurements = []
    for engine in engines:
        if engine not in PROBE_MODULES:
            continue
        try:
            version = adapter(engine).version()
        except EngineUnavailable:
            continue
        module = importlib.import_module(PROBE_MODULES[engine])
        for finding in module.FINDINGS:
            try:
                measurements.append(module.PROBES[finding.key]())
            except Exception as exc:        # noqa: BLE001 — reported in the measurement
                measurements.append(Measurement(finding, version, error=f"{type(exc).__name__}: {exc}"))
    return measurements
