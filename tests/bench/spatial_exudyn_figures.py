"""Figures: Exudyn at its default settings on the spatial scenes of
tests/spatial_exudyn_cases.py against the spatial reference: per scene the
solver the defaults pick, the step, Exudyn's count of redundant
constraints, the worst ratio to the default bound per class (and its
column), and the CPU time of the engine run (noisy on a shared machine).

    .venv/bin/python tests/bench/spatial_exudyn_figures.py [SCENE ...]

Prints the figures; asserts nothing.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

from spatial_exudyn_cases import CASES, worst_ratios  # noqa: E402
from mechval.engines.exudyn.adapter import ExudynAdapter  # noqa: E402
from mechval.reference.spatial.mechanism import spatial_mechanism, spatial_solution  # noqa: E402


def main() -> None:
    adapter = ExudynAdapter()
    for name in sys.argv[1:] or list(CASES):
        system, t = CASES[name]()
        mechanism = spatial_mechanism(system)
        settings = adapter.default_settings(mechanism, t)
        clock = time.process_time()
        run = adapter.run(mechanism, t, settings)
        cpu = time.process_time() - clock
        ref = spatial_solution(system, t)
        ratios = worst_ratios(run.frame, ref.frame, ref.missing, run.missing)
        worst = max(ratios.values())
        print(f"{name}: {settings['solver']}, dt {settings['timestep']:.3g} s, "
              f"{run.info.facts['redundant_constraints']} redundant, engine CPU {cpu:.2f} s; "
              f"worst ratio {worst[0]:.3g} ({worst[1]})")
        print("    " + ", ".join(f"{cls} {ratio:.2g}" for cls, (ratio, _) in ratios.items()))


if __name__ == "__main__":
    main()
