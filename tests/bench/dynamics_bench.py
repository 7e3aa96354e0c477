"""Benchmark: the forward-dynamics reference (mechval.reference.dynamics) on Andrews'
squeezing mechanism over 0–0.03 s at the default rtol (wall time, steps,
evaluations, and each published coordinate's error at 0.03 s), and the
seed four-bar released from rest under gravity, falling for 10 s (wall
time, steps, energy drift, constraint drift); then the built-in
torque-driven and free scene files through the reference adapter (the
path `mechval run` takes; fourbar-falling stretched to the same 10 s):
wall time, steps, evaluations and time per evaluation; and the seed
four-bar spun over 15 turns by two torque laws (tests/test_dynamics_accuracy.py),
its share of the evaluation limit (mechval.reference.dynamics.MAX_EVALUATIONS).

    .venv/bin/python tests/bench/dynamics_bench.py [--method DOP853|Radau] [--rtol R] [--repeats N]
                                                   [--fall SECONDS] [--samples N]

Prints the figures; it asserts nothing about time (a benchmark, not a test).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

import andrews as A  # noqa: E402
import dynamic_mechanisms as dm  # noqa: E402
from mechval.reference import dynamics  # noqa: E402
from mechval.reference.dynamics import MAX_EVALUATIONS, METHODS, RTOL, raw_dynamics  # noqa: E402
from mechval.judging.energy import kinetic_energy, potential_energy  # noqa: E402
from mechval.judging.health import joint_gaps  # noqa: E402
from mechval.reference.planar.positions import mechanism_size as size  # noqa: E402

NAMES = ("β", "Θ", "γ", "Φ", "δ", "Ω", "ε")


def best_run(case, t, rtol, method, repeats):
    """The run with the best wall time of `repeats` (the solution is the same each time)."""
    best, kept = np.inf, None
    for _ in range(repeats):
        dynamics._runs.clear()           # measure the run, not the cache of runs
        start = time.perf_counter()
        solution = raw_dynamics(case.mech, t, case.initial, case.pose, rtol=rtol, method=method)
        wall = time.perf_counter() - start
        if wall < best:
            best, kept = wall, solution
    return best, kept


def andrews(args) -> None:
    case = dm.motored_andrews()
    wall, solution = best_run(case, np.array([0.0, A.T1]), args.rtol, args.method, args.repeats)
    facts, raw = solution.facts, solution.frame
    print(f"Andrews' squeezer under mom = {A.mom} N·m, 0–{A.T1} s, {args.method} at rtol {args.rtol:g}")
    print(f"  wall {wall:.3f} s (integration {facts['integration_time_s']:.3f} s), {facts['steps']} steps, "
          f"{facts['evaluations']} evaluations, constraint drift {facts['constraint_drift_max']:.2g}")
    q = A.test_set_coordinates(raw)[:, -1]
    qdot = A.test_set_coordinates(raw, "omega")[:, -1]
    print("  relative error at 0.03 s against the Test Set's published solution:")
    print("    coordinate   position     velocity")
    for k, name in enumerate(NAMES):
        print(f"    {name:10s} {abs(q[k] - A.Q1[k]) / abs(A.Q1[k]):10.2e}  "
              f"{abs(qdot[k] - A.QDOT1[k]) / abs(A.QDOT1[k]):10.2e}")


def fall(args) -> None:
    case = dm.free_fourbar()
    t = np.linspace(0.0, args.fall, args.samples)
    wall, solution = best_run(case, t, args.rtol, args.method, args.repeats)
    facts, raw = solution.facts, solution.frame
    kinetic, potential = kinetic_energy(case.mech, raw), potential_energy(case.mech, raw)
    energy = kinetic + potential
    drift = np.abs(energy - energy[0])
    gaps = joint_gaps(case.mech, raw) / size(case.mech)
    print(f"Seed four-bar released from rest under gravity, 0–{args.fall:g} s, {args.samples} samples, "
          f"{args.method} at rtol {args.rtol:g}")
    print(f"  wall {wall:.3f} s (integration {facts['integration_time_s']:.3f} s), {facts['steps']} steps, "
          f"{facts['evaluations']} evaluations")
    print(f"  energy drift max |E(t) − E(0)| = {drift.max():.3g} J = {drift.max() / kinetic.max():.3g} of the "
          f"peak kinetic energy {kinetic.max():.4g} J (at the end: {drift[-1] / kinetic.max():.3g})")
    print(f"  constraint drift max {gaps.max():.2g} of the size (the run's own measure: "
          f"{facts['constraint_drift_max']:.2g})")


def scenes(args) -> None:
    """Each built-in torque-driven or free scene file, as `mechval` runs it."""
    import tomllib
    from mechval.scenarios import builtin_names, builtin_path, load, parse
    print(f"Built-in torque-driven and free scenes through the reference adapter (best of {args.repeats})")
    for name in builtin_names():
        scenario = load(name)
        if not scenario.forward_dynamics:
            continue
        if name == "fourbar-falling":        # the seed four-bar, falling for --fall seconds
            doc = tomllib.loads(builtin_path(name).read_text(encoding="utf-8"))
            doc["time"] = {"end": args.fall, "samples": args.samples}
            scenario = parse(doc, name)
        best, facts = best_reference_run(scenario, args.repeats)
        print(f"  {name:24s} 0–{scenario.time.end:g} s, {scenario.time.samples} samples: wall {best:.3f} s, "
              f"{facts['steps']} steps, {facts['evaluations']} evaluations, "
              f"{1e3 * facts['integration_time_s'] / max(facts['evaluations'], 1):.2f} ms per evaluation")


def best_reference_run(scenario, repeats: int) -> tuple[float, dict]:
    """The reference adapter's best wall time on the scenario over
    `repeats` runs (the run cache cleared before each), and its facts."""
    from mechval.reference.linkages import build_mechanism
    from mechval.reference.adapter import ReferenceAdapter
    mech, best, facts = build_mechanism(scenario), np.inf, {}
    for _ in range(repeats):
        dynamics._runs.clear()
        start = time.perf_counter()
        facts = ReferenceAdapter().run(mech, scenario.time.t, {}).info.facts
        best = min(best, time.perf_counter() - start)
    return best, facts


def spun(args) -> None:
    from test_dynamics_accuracy import spun_fourbar
    scenario = spun_fourbar(2.2)
    best, facts = best_reference_run(scenario, args.repeats)
    print(f"  {'spun four-bar, 15 turns':24s} 0–{scenario.time.end:g} s, {scenario.time.samples} samples: wall {best:.3f} s, "
          f"{facts['steps']} steps, {facts['evaluations']} evaluations ({facts['evaluations'] / MAX_EVALUATIONS:.0%} of "
          f"the limit), {1e3 * facts['integration_time_s'] / max(facts['evaluations'], 1):.2f} ms per evaluation")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--method", choices=METHODS, default="DOP853")
    parser.add_argument("--rtol", type=float, default=RTOL)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--fall", type=float, default=10.0, help="seconds the four-bar falls")
    parser.add_argument("--samples", type=int, default=1001)
    args = parser.parse_args()
    andrews(args)
    fall(args)
    scenes(args)
    spun(args)


if __name__ == "__main__":
    main()
