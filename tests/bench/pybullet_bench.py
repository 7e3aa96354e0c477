"""Benchmark: the PyBullet adapter at its default settings on every built-in
scenario — wall time per simulated second, and the adapter's overhead as
the ratio of a whole `simulate` (settings, model building, stepping with
readings and dampers, conversion) to the bare engine loop on the same model
and settings (only the drive target and `stepSimulation` per step).

    .venv/bin/python tests/bench/pybullet_bench.py [--repeats N] [SCENARIO ...]

Prints the figures; it asserts nothing about time (a benchmark, not a test).
Each figure is the best of N runs.
"""

from __future__ import annotations

import time

import numpy as np

from mechval.engines.pybullet.adapter import PybulletAdapter
from mechval.engines.pybullet.model import NO_CAP, build, p
from mechval.reference.linkages import build_mechanism
from mechval.scenarios import load
from mechval.harness.simulate import simulate
from timing import best_times, scenario_arguments


def whole_run(adapter: PybulletAdapter, scenario) -> float:
    start = time.perf_counter()
    simulate(scenario, adapter)
    return time.perf_counter() - start


def bare_loop(adapter: PybulletAdapter, scenario) -> float:
    """The same number of steps on the model the adapter would build, with
    nothing but the motor target and the step in the loop."""
    mechanism = build_mechanism(scenario)
    settings = adapter.settings_for(scenario, mechanism)
    t = scenario.time.t
    interval = float(t[1] - t[0])
    per_sample = int(np.ceil(interval / settings["timestep"] - 1e-9))
    dt = interval / per_sample
    preroll = settings["preroll_steps"]
    model = build(mechanism, dt, settings["layout"], float(t[0]) - preroll * dt)
    try:
        drive = model.tree_joints[mechanism.drive.joint].handle
        steps = preroll + (len(t) - 1) * per_sample + 1
        t_next = t[0] + (np.arange(steps) - preroll + 1) * dt
        law = mechanism.drive.law
        target = law.angle(t_next) - dt * law.rate(t_next)
        rate = law.rate(t_next)
        start = time.perf_counter()
        for n in range(steps):
            p.setJointMotorControl2(drive.uid, drive.link, p.POSITION_CONTROL, targetPosition=target[n],
                                    targetVelocity=rate[n], positionGain=1.0, velocityGain=1.0,
                                    force=NO_CAP, physicsClientId=model.client)
            p.stepSimulation(physicsClientId=model.client)
        return time.perf_counter() - start
    finally:
        p.disconnect(model.client)


def main() -> None:
    args = scenario_arguments(__doc__, repeats=1)
    adapter = PybulletAdapter()
    print(f"pybullet {adapter.version()}")
    print(f"{'scenario':24s} {'timestep':>10s} {'s/sim s':>9s} {'bare s/sim s':>13s} {'overhead':>9s}")
    for name in args.scenarios:
        scenario = load(name)
        mechanism = build_mechanism(scenario)
        dt = adapter.default_settings(mechanism, scenario.time.t)["timestep"]
        whole, bare = best_times(args.repeats, lambda: whole_run(adapter, scenario),
                                 lambda: bare_loop(adapter, scenario))
        span = scenario.time.end
        print(f"{name:24s} {dt:10.3g} {whole / span:9.3f} {bare / span:13.3f} {whole / bare:9.2f}")


if __name__ == "__main__":
    main()
