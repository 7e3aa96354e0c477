"""Benchmark: the spatial reference on the delta robot (3-RUU), the
spherical four-bar and the RSSR at 10⁵ instants (issue 26's goal for
batched spatial kinematics and inverse dynamics: the delta robot under
2 s on 2 cores) and on planar built-ins against the planar reference
(goal: within 3× of it).

    .venv/bin/python tests/bench/spatial_bench.py [--instants N] [--repeats R] [--chunk C]

--chunk sets the instants per batch (`solver.CHUNK`) to compare sizes.

Prints CPU and wall seconds, best of R rounds, and the load average (the
machine is shared: prefer the CPU figures and ratios). Asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

from mechval.reference.linkages import build_mechanism  # noqa: E402
from mechval.reference.planar.solver import raw_planar  # noqa: E402
from mechval.reference.spatial import solver  # noqa: E402
from mechval.reference.spatial.from_planar import spatial_from_planar  # noqa: E402
from mechval.reference.spatial.solver import SpatialSolver  # noqa: E402
from mechval.scenarios import load  # noqa: E402
from spatial_mechanisms import RSSR, Delta, SphericalFourBar  # noqa: E402


def best(task, repeats: int) -> tuple[float, float]:
    """Best CPU and wall seconds of `repeats` calls."""
    cpu, wall = [], []
    for _ in range(repeats):
        c, w = time.process_time(), time.perf_counter()
        task()
        cpu.append(time.process_time() - c)
        wall.append(time.perf_counter() - w)
    return min(cpu), min(wall)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instants", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--chunk", type=int, default=solver.CHUNK)
    args = parser.parse_args()
    solver.CHUNK = args.chunk
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; {args.chunk} instants a batch")
    t = np.linspace(0.0, 1.0, args.instants)
    for make in (Delta, SphericalFourBar, RSSR):
        system = make().system
        cpu, wall = best(lambda: SpatialSolver(system).solve(t), args.repeats)
        print(f"{system.name}: {args.instants} instants, {cpu:.2f} s CPU, {wall:.2f} s wall")
    for name in ("fourbar-seed", "slider-crank", "andrews-squeezer"):
        scenario = load(name)
        mech = build_mechanism(scenario)
        tt = scenario.time.t
        planar = raw_planar(mech, tt)
        poses = {b.name: tuple(float(planar.frame[f"{b.name}.{q}"].iloc[0]) for q in ("x", "y", "theta"))
                 for b in mech.bodies}
        system = spatial_from_planar(mech, poses)
        planar_cpu, _ = best(lambda: raw_planar(mech, tt), args.repeats)
        spatial_cpu, _ = best(lambda: SpatialSolver(system).solve(tt), args.repeats)
        print(f"{name}: {len(tt)} instants, planar {planar_cpu:.3f} s CPU, spatial {spatial_cpu:.3f} s CPU, "
              f"ratio {spatial_cpu / planar_cpu:.1f}")


if __name__ == "__main__":
    main()
