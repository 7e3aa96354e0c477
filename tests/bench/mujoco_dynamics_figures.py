"""Figures: MuJoCo on torque-driven and free mechanisms (issue 15), against
the forward-dynamics reference (mechval.reference.dynamics, DOP853 at its RTOL) from
the same initial state. Asserts nothing; docs/engines.md quotes them.

- per case of tests/dynamic_mechanisms.py at MuJoCo's default setting: the
  largest error as a fraction of the contract's default bound (angle 1e-3
  rad, position 1e-4 m, force 1e-2 of the column's peak) and its column,
  the worst angle error, the worst reaction/effort error relative to its
  peak, the step and the wall time;
- the integrators at the default step on the free four-bar;
- the energy drift of the free, undamped four-bar over 10 s;
- Andrews' squeezer under its motor (0–0.03 s): error over the whole run
  against the reference and at 30 ms against the Test Set's published
  coordinates, for four steps, with wall times (a work-precision line).

    .venv/bin/python tests/bench/mujoco_dynamics_figures.py [--quick]

--quick leaves out the 10 s energy run and the finest Andrews step.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

import andrews as A  # noqa: E402
import dynamic_mechanisms as dm  # noqa: E402
from mechval.testing.contract import ANGLE, dynamic_errors  # noqa: E402
from mechval.reference.dynamics import raw_dynamics  # noqa: E402
from mechval.judging.energy import kinetic_energy, potential_energy  # noqa: E402
from mechval.engines.mujoco.adapter import MujocoAdapter  # noqa: E402
from test_dynamics import SPANS  # noqa: E402

SAMPLES = 101
INTEGRATORS = {"RK4 (default)": {}, "Euler, solref 2·dt": {"integrator": "Euler", "solref_steps": 2.0},
               "implicitfast, solref 2·dt": {"integrator": "implicitfast", "solref_steps": 2.0}}


def case(name: str, span: float | None = None, samples: int = SAMPLES):
    """The case's mechanism (with its assembly pose, as the contract runs
    it) and its instants over `span` (default: tests/test_dynamics.py's)."""
    mech = dataclasses.replace(dm.CASES[name]().mech, assembly_pose=dm.CASES[name]().pose)
    return mech, np.linspace(0.0, SPANS[name] if span is None else span, samples)


def run(adapter: MujocoAdapter, mech, times, **overrides):
    settings = {**adapter.default_settings(mech, times), **overrides}
    start = time.perf_counter()
    raw = adapter.run(mech, times, settings)
    return raw, settings, time.perf_counter() - start


def summary(mech, reference, frame) -> str:
    ratios = dynamic_errors(mech, reference, frame)
    worst = max(ratios, key=ratios.get)
    angle = max(v for k, v in ratios.items() if k.endswith(".theta")) * ANGLE
    forces = [k for k in mech.reaction_columns() if k in ratios]
    force = f"{max(ratios[k] for k in forces) * 1e-2:.2g}" if forces else "none compared (the reference's are missing)"
    return f"worst {ratios[worst]:.3g} of its bound ({worst}); angle {angle:.2g} rad; force/effort {force}"


def cases(adapter: MujocoAdapter) -> None:
    print(f"each case at MuJoCo's default setting, {SAMPLES} samples, against the reference:")
    for name in SPANS:
        mech, times = case(name)
        reference = raw_dynamics(mech, times).frame
        raw, settings, wall = run(adapter, mech, times)
        print(f"  {name:22s} {SPANS[name]:g} s, dt {settings['timestep']:.3g} s: "
              f"{summary(mech, reference, raw.frame)}; {wall:.2f} s wall (rollout {raw.info.wall_time_s:.3f} s)")


def integrators(adapter: MujocoAdapter) -> None:
    mech, times = case("free-fourbar")
    reference = raw_dynamics(mech, times).frame
    print("free-fourbar, 2 s, integrators at the default step:")
    for label, overrides in INTEGRATORS.items():
        raw, settings, _ = run(adapter, mech, times, **overrides)
        print(f"  {label:26s} dt {settings['timestep']:.3g} s: {summary(mech, reference, raw.frame)}")


def energy_drift(adapter: MujocoAdapter, span: float = 10.0) -> None:
    mech, times = case("free-fourbar", span, 1001)
    raw, settings, wall = run(adapter, mech, times)
    reference = raw_dynamics(mech, times).frame
    print(f"free-fourbar (undamped) over {span:g} s, dt {settings['timestep']:.3g} s, {wall:.1f} s wall:")
    for label, frame in (("MuJoCo", raw.frame), ("reference", reference)):
        kinetic = kinetic_energy(mech, frame)
        energy = kinetic + potential_energy(mech, frame)
        drift = energy - energy[0]
        print(f"  {label:9s} max |E − E0| = {np.abs(drift).max():.3g} J = {np.abs(drift).max() / kinetic.max():.3g} "
              f"of the peak kinetic energy {kinetic.max():.4g} J; at {span:g} s {drift[-1]:+.3g} J")


def andrews(adapter: MujocoAdapter, quick: bool) -> None:
    mech, times = case("motored-andrews")
    reference = raw_dynamics(mech, times).frame
    default = adapter.default_settings(mech, times)
    interval = float(times[1] - times[0])
    substeps = round(interval / default["timestep"])
    print(f"motored-andrews 0–{A.T1:g} s (work-precision; error over the whole run; at {A.T1:g} s against the "
          "Test Set's published q):")
    for factor in (1, 2, 4) if quick else (1, 2, 4, 8):
        step = interval / (substeps * factor)
        raw, _, wall = run(adapter, mech, times, timestep=step)
        q = A.test_set_coordinates(raw.frame)[:, -1]
        published = float(np.max(np.abs(q - A.Q1) / np.abs(A.Q1)))
        q_ref = A.test_set_coordinates(reference)[:, -1]
        later = dynamic_errors(mech, reference.iloc[1:], raw.frame.iloc[1:])
        force = max(later[k] for k in mech.reaction_columns() if k in later) * 1e-2
        print(f"  dt {step:.3g} s{' (default)' if factor == 1 else ''}: {summary(mech, reference, raw.frame)} "
              f"(from the second sample on {force:.2g}); "
              f"q(30 ms) vs published {published:.2g} (reference {np.max(np.abs(q_ref - A.Q1) / np.abs(A.Q1)):.2g}) "
              f"relative; {wall:.2f} s wall, rollout {raw.info.wall_time_s:.3f} s, {raw.info.steps} steps")


def main() -> None:
    quick = "--quick" in sys.argv
    adapter = MujocoAdapter()
    print(f"MuJoCo {adapter.version()}")
    cases(adapter)
    integrators(adapter)
    if not quick:
        energy_drift(adapter)
    andrews(adapter, quick)


if __name__ == "__main__":
    main()
