"""Benchmark: the MuJoCo adapter at its default setting on every built-in
scenario, against a bare `mujoco.rollout` of the same model and settings.

    .venv/bin/python tests/bench/mujoco_bench.py [--repeats N] [SCENARIO ...]

Per scenario: steps, samples, wall time of the adapter's `run` (model
build, rollout, read-out at the samples) per simulated second and the bare
rollout's (best of N interleaved rounds); the adapter's overhead over the
bare rollout and its two parts, model build and read-out, from the adapter's
own timings (medians over the rounds); and the ratio of the two runs (goal
≤ 1.25): of their best times, and the median over the rounds of each
round's ratio (the two runs of a round see the same load, so this one
shrugs off a machine that is shared or changes speed). Prints the figures;
it asserts nothing about time (a benchmark, not a test).
"""

from __future__ import annotations

import time

import numpy as np
from mujoco import rollout

from mechval.engines.mujoco.adapter import MujocoAdapter
from mechval.engines.mujoco.run import Model
from mechval.reference.linkages import build_mechanism
from mechval.scenarios import load
from timing import interleaved_times, scenario_arguments, timed


def main() -> None:
    args = scenario_arguments(__doc__)

    adapter = MujocoAdapter()
    print(f"mujoco {adapter.version()}, default settings, {args.repeats} interleaved rounds")
    print(f"{'scenario':22s} {'dt':>9s} {'steps':>7s} {'samples':>7s} {'adapter s/s':>12s} {'rollout s/s':>12s} "
          f"{'overhead ms':>12s} {'build ms':>9s} {'read-out ms':>12s} {'ratio':>6s} {'median':>7s}")
    for name in args.scenarios:
        scenario = load(name)
        mech = build_mechanism(scenario)
        t = scenario.time.t
        settings = adapter.settings_for(scenario, mech)
        model = Model(mech, t, settings)
        state0 = model.initial_state()
        parts: list[tuple[float, float]] = []          # (build, read-out) of each adapter run

        def adapter_run() -> float:
            start = time.perf_counter()
            info = adapter.run(mech, t, settings).info
            elapsed = time.perf_counter() - start
            parts.append((info["build_time_s"], elapsed - info["build_time_s"] - info["wall_time_s"]))
            return elapsed

        bares, fulls = interleaved_times(
            args.repeats, timed(lambda: rollout.rollout(model.m, model.d, state0[None, :], nstep=model.nstep)),
            adapter_run)
        bare, full = min(bares), min(fulls)
        median = lambda values: float(np.median(values))
        overhead = median(np.subtract(fulls, bares))
        build, read_out = median([b for b, _ in parts]), median([r for _, r in parts])
        span = float(t[-1] - t[0])
        print(f"{name:22s} {settings['timestep']:9.3g} {model.nstep:7d} {len(t):7d} {full / span:12.4f} "
              f"{bare / span:12.4f} {overhead * 1e3:12.1f} {build * 1e3:9.1f} {read_out * 1e3:12.1f} "
              f"{full / bare:6.3f} {median(np.divide(fulls, bares)):7.3f}")


if __name__ == "__main__":
    main()
