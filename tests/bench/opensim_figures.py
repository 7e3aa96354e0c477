"""Figures: the OpenSim adapter's largest error on every built-in as a
fraction of its signal class's peak (the largest |reference| over the
signals of that class), and the CPU time of each run, at the default
settings or at given overrides.

    .venv/bin/python tests/bench/opensim_figures.py [--set KEY=VALUE ...] [SCENARIO ...]

Prints the figures (docs/engines.md, "OpenSim", quotes them); the tests
(tests/test_opensim.py) hold the goal of issue 25 on a few scenes.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from mechval.harness.simulate import simulate
from mechval.judging.compare import compare
from mechval.scenarios import builtin_names, load


def class_peak_errors(scenario, overrides) -> tuple[str, float, float]:
    """(worst signal, its max error / its class's peak, CPU seconds)."""
    reference = simulate(scenario, "reference")
    clock = time.process_time()
    result = simulate(scenario, "opensim", overrides)
    cpu = time.process_time() - clock
    records = compare(reference, result, scenario.tolerance_for("opensim"), scenario.name, "opensim")
    records = records[records["class"] != "health"]
    peaks = records.groupby("class")["peak"].transform("max")
    ratio = records["max_error"] / peaks
    worst = int(np.nanargmax(ratio.to_numpy()))
    return str(records["signal"].iloc[worst]), float(ratio.iloc[worst]), cpu


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("scenarios", nargs="*")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    overrides = {}
    for item in args.set:
        key, value = item.split("=", 1)
        overrides[key] = value if not value.replace(".", "").replace("e-", "").isdigit() else float(value)
    print(f"opensim {overrides or 'defaults'}: worst signal, max error / class peak, CPU s")
    for name in args.scenarios or builtin_names():
        scenario = load(name)
        kind = "dynamic" if scenario.forward_dynamics else "prescribed"
        try:
            signal, ratio, cpu = class_peak_errors(scenario, overrides)
            print(f"  {name:42s} {kind:10s} {signal:14s} {ratio:9.2e} {cpu:6.2f}")
        except Exception as exc:       # noqa: BLE001 - a figure script reports and goes on
            print(f"  {name:42s} {kind:10s} FAILED {type(exc).__name__}: {exc}")


if __name__ == "__main__":
    main()
