"""Figures: PyBullet on torque-driven and free mechanisms (issue 15), at
its default setting, against the forward-dynamics reference
(`mechval.reference.dynamics`, DOP853 at its RTOL).

    .venv/bin/python tests/bench/pybullet_dynamics_figures.py [--no-energy] [--no-andrews] [CASE ...]

1. Every case of tests/dynamic_mechanisms.py CASES (101 samples over the
   span the reference's tests use): the default step, wall time, the
   largest closure gap, and the worst ratios error / default bound of
   `mechval.testing.contract.dynamic_errors` (angles 1e-3 rad and positions
   1e-4 m absolute, reactions and efforts 1e-2 of the reference column's
   peak; ≤ 1 passes). A reaction the reference leaves indeterminate
   (the redundant parallelogram's pins) has no peak and is not compared.
2. The free, undamped seed four-bar falling from rest for 10 s: energy
   drift max |E(t) − E(0)| (kinetic + potential, `mechval.judging.energy`) in J
   and relative to the peak kinetic energy, for PyBullet and the reference.
3. Andrews' squeezer under its motor, 0–0.03 s: the work-precision line
   (the worst body-angle error over the whole run against wall time, for
   four steps around the default) and the error of the Test Set's seven
   coordinates at 0.03 s against the published solution (tests/andrews.py).

Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import andrews as A  # noqa: E402
import dynamic_mechanisms as dm  # noqa: E402
from mechval.testing.contract import DYNAMIC, dynamic_errors  # noqa: E402
from mechval.reference.dynamics import raw_dynamics  # noqa: E402
from mechval.judging.energy import kinetic_energy, potential_energy  # noqa: E402
from mechval.engines.registry import adapter  # noqa: E402

#: The span (s) of each case, as mechval.testing.contract and tests/test_dynamics.py run them.
SPANS = {**DYNAMIC, "free-five-bar": 1.0, "half-driven-five-bar": 1.0, "free-parallelogram": 2.0,
         "motored-andrews": A.T1}
SAMPLES = 101
ENERGY_SPAN = 10.0


def case_mechanism(name: str):
    case = dm.CASES[name]()
    return dataclasses.replace(case.mech, assembly_pose=case.pose)


def timed_run(engine, mech, times, settings):
    started = time.perf_counter()
    raw = engine.run(mech, times, settings)
    return raw, time.perf_counter() - started


def with_step(settings: dict, times: np.ndarray, factor: float) -> dict:
    """The settings with the step times `factor`, rounded to divide the sample interval."""
    interval = float(times[1] - times[0])
    return {**settings, "timestep": interval / max(1, round(interval / (settings["timestep"] * factor)))}


def cases(engine, names) -> None:
    print(f"1. Default setting vs the forward-dynamics reference ({SAMPLES} samples)")
    print(f"{'case':22s} {'span s':>6s} {'dt s':>9s} {'wall s':>7s} {'gap m':>8s}  worst ratios error/bound")
    for name in names:
        mech = case_mechanism(name)
        times = np.linspace(0.0, SPANS[name], SAMPLES)
        settings = engine.default_settings(mech, times)
        raw, wall = timed_run(engine, mech, times, settings)
        ratios = dynamic_errors(mech, raw_dynamics(mech, times).frame, raw.frame)
        worst = sorted(ratios.items(), key=lambda item: -item[1])[:4]
        gap = raw.info.facts["closure_gap_max"]
        print(f"{name:22s} {SPANS[name]:6.3g} {settings['timestep']:9.3g} {wall:7.2f} {gap:8.1e}  "
              + ", ".join(f"{column} {ratio:.3g}" for column, ratio in worst))


def energy_drift(engine) -> None:
    mech = case_mechanism("free-fourbar")
    times = np.linspace(0.0, ENERGY_SPAN, 1001)
    settings = engine.default_settings(mech, times)
    raw, wall = timed_run(engine, mech, times, settings)
    print(f"\n2. Free undamped seed four-bar, {ENERGY_SPAN:g} s from rest: energy drift max |E(t) - E(0)|")
    for source, frame in (("pybullet", raw.frame), ("reference", raw_dynamics(mech, times).frame)):
        energy = kinetic_energy(mech, frame) + potential_energy(mech, frame)
        drift = float(np.max(np.abs(energy - energy[0])))
        peak = float(np.max(kinetic_energy(mech, frame)))
        print(f"   {source:9s} {drift:.3e} J = {drift / peak:.2e} of the peak kinetic energy {peak:.4g} J"
              + (f" (dt {settings['timestep']:.3g} s, {wall:.2f} s wall)" if source == "pybullet" else ""))


def andrews(engine) -> None:
    mech = case_mechanism("motored-andrews")
    times = np.linspace(0.0, A.T1, SAMPLES)
    reference = raw_dynamics(mech, times).frame
    default = engine.default_settings(mech, times)
    print(f"\n3. Andrews' squeezer under its motor, 0-{A.T1} s (default dt {default['timestep']:.3g} s)")
    print(f"{'dt s':>9s} {'wall s':>7s} {'worst angle error rad':>22s} {'worst E-pin force rel':>22s} "
          f"{'Test Set q(0.03) worst rel':>27s}")
    for factor in (4.0, 2.0, 1.0, 0.5):
        settings = with_step(default, times, factor)
        raw, wall = timed_run(engine, mech, times, settings)
        frame = raw.frame
        angle = max(float(np.max(np.abs(frame[f"{b}.theta"] - reference[f"{b}.theta"]))) for b in A.BODIES)
        force = max(float(np.max(np.abs(frame[c] - reference[c])) / np.max(np.abs(reference[c])))
                    for j in A.LAMBDA_JOINTS for c in (f"{j}.Fx", f"{j}.Fy"))
        q = A.test_set_coordinates(frame)[:, -1]
        published = float(np.max(np.abs(q - A.Q1) / np.abs(A.Q1)))
        print(f"{settings['timestep']:9.3g} {wall:7.2f} {angle:22.3e} {force:22.3e} {published:27.3e}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", default=list(dm.CASES))
    parser.add_argument("--no-energy", action="store_true")
    parser.add_argument("--no-andrews", action="store_true")
    args = parser.parse_args()
    engine = adapter("pybullet")
    cases(engine, args.cases)
    if not args.no_energy:
        energy_drift(engine)
    if not args.no_andrews:
        andrews(engine)


if __name__ == "__main__":
    main()
