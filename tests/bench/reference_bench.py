"""Benchmark: the vectorised four-bar reference at 10⁶ instants against the
published study's method, a per-instant loop that builds and solves the
9×9 system (Norton eq. 11.9) at every instant.

    .venv/bin/python tests/bench/reference_bench.py [--instants N] [--loop-instants M]

Prints the figures; it asserts nothing about time (a benchmark, not a test).
The loop is timed on M instants and its per-instant cost scaled to N.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

from mechval.reference.closed_forms.fourbar import kinematics  # noqa: E402
from mechval.reference.linkages import build_mechanism  # noqa: E402
from mechval.reference.adapter import raw_reference  # noqa: E402
from mechval.scenarios import load  # noqa: E402
from norton import norton_system  # noqa: E402
from timing import best_times, timed  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instants", type=int, default=1_000_000)
    parser.add_argument("--loop-instants", type=int, default=20_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    scenario = load("fourbar-seed")
    mech = build_mechanism(scenario)
    t = np.linspace(0.0, scenario.time.end, args.instants)
    vectorised, = best_times(args.repeats, timed(lambda: raw_reference(mech, t)))

    closed = scenario.closed_form
    geometry = closed.geometry
    m = {b.name: b for b in mech.bodies}
    t_loop = np.linspace(0.0, scenario.time.end, args.loop_instants)

    def loop():
        for tk in t_loop:
            k = {name: float(v[0]) for name, v in kinematics(geometry, closed.law, np.array([tk])).items()}
            A, rhs = norton_system(k, m["crank"].mass, m["coupler"].mass, m["rocker"].mass, m["crank"].izz,
                                   m["coupler"].izz, m["rocker"].izz, mech.gravity, geometry.crank,
                                   geometry.coupler, geometry.rocker, geometry.ground)
            np.linalg.solve(A, rhs)

    per_instant = timed(loop)() / args.loop_instants
    loop_total = per_instant * args.instants
    print(f"four-bar reference (kinematics + Newton–Euler), {args.instants:,} instants")
    print(f"  vectorised          {vectorised:8.3f} s   ({vectorised / args.instants * 1e9:7.1f} ns/instant)")
    print(f"  per-instant 9×9 loop{loop_total:8.3f} s   ({per_instant * 1e6:7.1f} µs/instant, "
          f"timed on {args.loop_instants:,} instants)")
    print(f"  speed-up            {loop_total / vectorised:8.1f} ×")


if __name__ == "__main__":
    main()
