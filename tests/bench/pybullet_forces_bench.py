"""Benchmark: what PyBullet's per-step Python loads cost. PyBullet has no
spring element between bodies and keeps no external load from one step to
the next, so the adapter applies the Mechanism's spring-dampers and body
torques before every step. This prints the stepping wall time per step of
the scenes of tests/planar_scenes.py with their force elements and
with them removed (same model, settings and steps), and the difference.

    .venv/bin/python tests/bench/pybullet_forces_bench.py [--repeats N]

Prints the figures; asserts nothing about time. Best of N runs each.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mechval.engines.pybullet.adapter import PybulletAdapter   # noqa: E402
from mechval.engines.pybullet.run import run_model   # noqa: E402
from mechval.reference.linkages import build_mechanism                       # noqa: E402
from mechval.testing.planar_scenes import SCENES, scene                             # noqa: E402


def stepping_time(mechanism, times, settings) -> tuple[float, int]:
    raw = run_model(mechanism, times, settings)
    return raw.info.wall_time_s, raw.info.steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    repeats = parser.parse_args().repeats
    adapter = PybulletAdapter()
    print(f"{'scene':16} {'steps':>6} {'with (µs/step)':>15} {'without':>9} {'cost':>7}")
    for name in SCENES:
        scenario = scene(name)
        mechanism = build_mechanism(scenario)
        if not mechanism.forces:
            continue
        settings = adapter.settings_for(scenario, mechanism)
        bare = dataclasses.replace(mechanism, forces=())
        with_forces = min(stepping_time(mechanism, scenario.time.t, settings)[0] for _ in range(repeats))
        without, steps = min(stepping_time(bare, scenario.time.t, settings) for _ in range(repeats))
        per = 1e6 / steps
        print(f"{name:16} {steps:6d} {with_forces * per:15.1f} {without * per:9.1f} {(with_forces - without) * per:7.1f}")


if __name__ == "__main__":
    main()
