"""Figures: each engine at its default settings on the planar scenes of
tests/planar_scenes.py (two drives, a prismatic drive, a spring-damper,
body torques, a six-bar), against the general reference: per scene the
worst ratio to the default bound and the worst relative error per class,
the adapter's drive tracking error, and the wall time of the engine run.

    .venv/bin/python tests/bench/planar_figures.py [--engine NAME ...]

Prints the figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

from mechval.judging.compare import compare  # noqa: E402
from mechval.engines.registry import engine_names  # noqa: E402
from mechval.harness.simulate import simulate  # noqa: E402
from mechval.testing.planar_scenes import SCENES, scene  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engine", action="append", choices=engine_names())
    engines = parser.parse_args().engine or list(engine_names())
    for engine in engines:
        for name in SCENES:
            scenario = scene(name)
            reference = simulate(scenario, "reference")
            start = time.perf_counter()
            run = simulate(scenario, engine)
            wall = time.perf_counter() - start
            records = compare(reference, run, scenario.tolerance_for(engine), scenario=scenario.name)
            worst = records.sort_values("ratio", ascending=False).iloc[0]
            by_class = records[records["class"] != "health"].groupby("class")
            classes = ", ".join(f"{c} {v:.2g}" for c, v in by_class["relative_error"].max().items()
                                if c not in ("angle", "position"))
            absolute = ", ".join(f"{c} {v:.2g}" for c, v in by_class["max_error"].max().items()
                                 if c in ("angle", "position"))
            drive = run.info.facts.get("drive_error_max")
            print(f"{engine:8s} {name:14s} worst ratio {worst['ratio']:.3g} ({worst['signal']}); relative: "
                  f"{classes}; absolute: {absolute}; drive error "
                  f"{'n/a' if drive is None else format(drive, '.2g')}; steps {run.info.steps}, {wall:.2f} s")


if __name__ == "__main__":
    main()
