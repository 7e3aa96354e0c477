"""Benchmark: the MuJoCo adapter at its default setting on every built-in
scenario, against a bare `mujoco.rollout` of the same model and settings.

    .venv/bin/python tests/bench/mujoco_bench.py [--repeats N] [SCENARIO ...]

Per scenario: steps, wall time of the adapter's `run` (model build, rollout,
read-out at the samples) per simulated second, the bare rollout's, the
difference and their ratio (goal ≤ 1.25). Best of N interleaved repeats,
since the machine may be shared. Prints
the figures; it asserts nothing about time (a benchmark, not a test).
"""

from __future__ import annotations


from mujoco import rollout

from mechval.engines.mujoco import Model, MujocoAdapter
from mechval.linkages import build_mechanism
from mechval.scenarios import load
from timing import best_times, scenario_arguments, timed


def main() -> None:
    args = scenario_arguments(__doc__)

    adapter = MujocoAdapter()
    print(f"mujoco {adapter.version()}, default settings, best of {args.repeats}")
    print(f"{'scenario':22s} {'dt':>9s} {'steps':>7s} {'adapter s/s':>12s} {'rollout s/s':>12s} "
          f"{'overhead ms':>12s} {'ratio':>6s}")
    for name in args.scenarios:
        scenario = load(name)
        mech = build_mechanism(scenario)
        t = scenario.time.t
        settings = adapter.settings_for(scenario, mech)
        model = Model(mech, t, settings)
        state0 = model.initial_state()
        bare, full = best_times(args.repeats,
                                timed(lambda: rollout.rollout(model.m, model.d, state0[None, :], nstep=model.nstep)),
                                timed(lambda: adapter.run(mech, t, settings)))
        span = float(t[-1] - t[0])
        print(f"{name:22s} {settings['timestep']:9.3g} {model.nstep:7d} {full / span:12.4f} "
              f"{bare / span:12.4f} {(full - bare) * 1e3:12.1f} {full / bare:6.3f}")


if __name__ == "__main__":
    main()
