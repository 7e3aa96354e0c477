"""Figures: Exudyn at its default settings on the planar scenes of
tests/test_exudyn_planar.py (two drives, a prismatic drive, a spring-damper,
a body torque, a six-bar), against the general reference: per scene the
worst ratio to the default bound and the worst relative error per class,
the adapter's drive tracking error, and the wall time of the Exudyn run.

    .venv/bin/python tests/bench/exudyn_planar_figures.py

Prints the figures; asserts nothing.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

from mechval.compare import compare
from mechval.harness.simulate import simulate
from test_exudyn_planar import SCENES, scene


def main() -> None:
    for name in SCENES:
        scenario = scene(name)
        reference = simulate(scenario, "reference")
        start = time.perf_counter()
        run = simulate(scenario, "exudyn")
        wall = time.perf_counter() - start
        records = compare(reference, run, scenario.tolerance_for("exudyn"), scenario=scenario.name)
        worst = records.sort_values("ratio", ascending=False).iloc[0]
        by_class = records[records["class"] != "health"].groupby("class")
        classes = ", ".join(f"{c} {v:.2g}" for c, v in by_class["relative_error"].max().items()
                            if c not in ("angle", "position"))
        absolute = ", ".join(f"{c} {v:.2g}" for c, v in by_class["max_error"].max().items()
                             if c in ("angle", "position"))
        print(f"{name:14s} worst ratio {worst['ratio']:.3g} ({worst['signal']}); relative: {classes}; "
              f"absolute: {absolute}; drive error {run.info.facts['drive_error_max']:.2g}; "
              f"steps {run.info.steps}, {wall:.2f} s")


if __name__ == "__main__":
    main()
