"""Benchmark: the MuJoCo adapter at its default setting on every built-in
scenario, against a bare `mujoco.rollout` of the same model and settings.

    .venv/bin/python tests/bench/mujoco_bench.py [--repeats N] [SCENARIO ...]

Per scenario: steps, samples, wall time of the adapter's `run` (model
build, rollout, read-out at the samples) per simulated second, the bare
rollout's, the difference split into model build and read-out (from the
fastest adapter run's own timings), and the ratio of the two (goal ≤ 1.25):
of the best times of N interleaved rounds, and the median over the rounds
of each round's ratio (the two runs of a round see the same load, so this
one shrugs off a machine that is shared or changes speed). Prints the
figures; it asserts nothing about time (a benchmark, not a test).
"""

from __future__ import annotations

import time

import numpy as np
from mujoco import rollout

from mechval.engines.mujoco import Model, MujocoAdapter
from mechval.linkages import build_mechanism
from mechval.scenarios import load
from timing import interleaved_times, scenario_arguments, timed


def main() -> None:
    args = scenario_arguments(__doc__)

    adapter = MujocoAdapter()
    print(f"mujoco {adapter.version()}, default settings, best of {args.repeats}")
    print(f"{'scenario':22s} {'dt':>9s} {'steps':>7s} {'samples':>7s} {'adapter s/s':>12s} {'rollout s/s':>12s} "
          f"{'overhead ms':>12s} {'build ms':>9s} {'read-out ms':>12s} {'ratio':>6s} {'median':>7s}")
    for name in args.scenarios:
        scenario = load(name)
        mech = build_mechanism(scenario)
        t = scenario.time.t
        settings = adapter.settings_for(scenario, mech)
        model = Model(mech, t, settings)
        state0 = model.initial_state()
        fastest: dict = {}

        def adapter_run() -> float:
            start = time.perf_counter()
            info = adapter.run(mech, t, settings).info
            elapsed = time.perf_counter() - start
            if elapsed < fastest.get("elapsed", float("inf")):
                fastest.update(info, elapsed=elapsed)
            return elapsed

        bares, fulls = interleaved_times(
            args.repeats, timed(lambda: rollout.rollout(model.m, model.d, state0[None, :], nstep=model.nstep)),
            adapter_run)
        bare, full = min(bares), min(fulls)
        median_ratio = float(np.median(np.divide(fulls, bares)))
        build = fastest["build_time_s"]
        read_out = fastest["elapsed"] - build - fastest["wall_time_s"]
        span = float(t[-1] - t[0])
        print(f"{name:22s} {settings['timestep']:9.3g} {model.nstep:7d} {len(t):7d} {full / span:12.4f} "
              f"{bare / span:12.4f} {(full - bare) * 1e3:12.1f} {build * 1e3:9.1f} {read_out * 1e3:12.1f} "
              f"{full / bare:6.3f} {median_ratio:7.3f}")


if __name__ == "__main__":
    main()
