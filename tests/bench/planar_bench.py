"""Benchmark: the general planar reference against the closed form on the
seed four-bar at 10⁶ instants (goal: within 3× its time), and Andrews'
squeezing mechanism at 10⁵ instants (goal: under 2 s).

    .venv/bin/python tests/bench/planar_bench.py [--instants N] [--andrews-instants M] [--repeats R]
                                                 [--chunks 12 13 14 15]

Prints the figures, best of R interleaved rounds, and the load average
(the closed form's own time varies by up to half between quiet runs of
this machine, so the ratio does too); with --chunks, the general solve's
time per batch size 2^k (`mechval.reference.planar.solver.CHUNK`). It asserts
nothing about time (a benchmark, not a test).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

import mechval.reference.planar.solver as planar_solver  # noqa: E402
from andrews import andrews_mechanism  # noqa: E402
from mechval.reference.linkages import build_mechanism  # noqa: E402
from mechval.reference.planar.solver import raw_planar  # noqa: E402
from mechval.reference.adapter import raw_reference  # noqa: E402
from mechval.scenarios import load  # noqa: E402
from timing import best_times, timed  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instants", type=int, default=1_000_000)
    parser.add_argument("--andrews-instants", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--chunks", type=int, nargs="*", default=[], metavar="K",
                        help="also time the general solve in batches of 2^K instants")
    args = parser.parse_args()
    print(f"load average (1 min) {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")

    scenario = load("fourbar-seed")
    mech = build_mechanism(scenario)
    t = np.linspace(0.0, scenario.time.end, args.instants)
    closed, general = best_times(args.repeats, timed(lambda: raw_reference(mech, t)),
                                 timed(lambda: raw_planar(mech, t)))
    print(f"fourbar-seed, {args.instants:,} instants over {scenario.time.end:g} s")
    print(f"  closed form (raw_reference)   {closed:8.3f} s")
    print(f"  general (raw_planar)          {general:8.3f} s   "
          f"({general / closed:.2f} × the closed form; goal ≤ 3 ×)")

    default = planar_solver.CHUNK
    for k in args.chunks:
        planar_solver.CHUNK = 1 << k
        chunked, = best_times(args.repeats, timed(lambda: raw_planar(mech, t)))
        print(f"  general, batches of 2^{k:<2d}       {chunked:8.3f} s"
              f"{'   (the default)' if 1 << k == default else ''}")
    planar_solver.CHUNK = default

    andrews = andrews_mechanism()
    ta = np.linspace(0.0, 0.03, args.andrews_instants)
    squeezer, = best_times(args.repeats, timed(lambda: raw_planar(andrews, ta)))
    print(f"Andrews' squeezing mechanism, {args.andrews_instants:,} instants over 0.03 s")
    print(f"  general (raw_planar)          {squeezer:8.3f} s   (goal < 2 s)")
    print(f"load average (1 min) {os.getloadavg()[0]:.2f} after")


if __name__ == "__main__":
    main()
