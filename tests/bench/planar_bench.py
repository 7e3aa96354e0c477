"""Benchmark: the general planar reference against the closed form on the
seed four-bar at 10⁶ instants (goal: within 3× its time), and Andrews'
squeezing mechanism at 10⁵ instants (goal: under 2 s).

    .venv/bin/python tests/bench/planar_bench.py [--instants N] [--andrews-instants M] [--repeats R]

Prints the figures; it asserts nothing about time (a benchmark, not a test).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

from andrews import andrews_mechanism  # noqa: E402
from mechval.linkages import build_mechanism  # noqa: E402
from mechval.planar_solver import raw_planar  # noqa: E402
from mechval.reference import raw_reference  # noqa: E402
from mechval.scenarios import load  # noqa: E402
from timing import best_times, timed  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instants", type=int, default=1_000_000)
    parser.add_argument("--andrews-instants", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    scenario = load("fourbar-seed")
    mech = build_mechanism(scenario)
    t = np.linspace(0.0, scenario.time.end, args.instants)
    closed, general = best_times(args.repeats, timed(lambda: raw_reference(mech, t)),
                                 timed(lambda: raw_planar(mech, t)))
    print(f"fourbar-seed, {args.instants:,} instants over {scenario.time.end:g} s")
    print(f"  closed form (raw_reference)   {closed:8.3f} s")
    print(f"  general (raw_planar)          {general:8.3f} s   "
          f"({general / closed:.2f} × the closed form; goal ≤ 3 ×)")

    andrews = andrews_mechanism()
    ta = np.linspace(0.0, 0.03, args.andrews_instants)
    squeezer, = best_times(args.repeats, timed(lambda: raw_planar(andrews, ta)))
    print(f"Andrews' squeezing mechanism, {args.andrews_instants:,} instants over 0.03 s")
    print(f"  general (raw_planar)          {squeezer:8.3f} s   (goal < 2 s)")


if __name__ == "__main__":
    main()
