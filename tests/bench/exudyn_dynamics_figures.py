"""Figures: Exudyn on torque-driven and free mechanisms (issue 15).

1. At the default setting, on every case of tests/dynamic_mechanisms.py
   (CASES): the worst ratio of an error to its default bound against the
   forward-dynamics reference (`mechval.testing.contract.dynamic_errors`), the
   worst angle error (rad) and relative reaction error, the step and the
   wall time of the Exudyn run (default_settings, which integrates the
   reference for the step rule, not counted). A case Exudyn cannot run is
   printed with its error.
2. Energy drift of the seed four-bar falling freely (undamped) for 10 s:
   E(t) − E(0) over the peak kinetic energy (its largest size, and its
   mean over the last second), at the default step and at a coarse one,
   for the default solver (trapezoidal index-2, no numerical dissipation)
   and generalized-α index-3 at spectral radius 0.9 (the default) and 0.6.
3. Work-precision on Andrews' squeezer under its motor, 0–0.03 s: the
   error over the whole run (worst angle error, worst relative reaction
   error) against the wall time, for a few steps and both solvers.

    .venv/bin/python tests/bench/exudyn_dynamics_figures.py [--fall 10] [--skip-andrews]

Prints the figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

import andrews as A
import dynamic_mechanisms as dm
from mechval.testing.contract import ANGLE, FORCE, dynamic_errors
from mechval.reference.dynamics import RTOL, raw_dynamics
from mechval.judging.energy import kinetic_energy, potential_energy
from mechval.engines.registry import adapter

#: How long each case runs (s): the contract's, the five-bars 1 s, Andrews' 0.03 s.
ENDS = {"pendulum": 2.0, "spinning-crank": 1.0, "free-fourbar": 2.0, "motored-slider-crank": 1.0,
        "free-five-bar": 1.0, "half-driven-five-bar": 1.0, "free-parallelogram": 2.0, "motored-andrews": A.T1}
#: A step about 12 times the default on the falling four-bar, where the
#: numerical dissipation of generalized-α shows (divides the 0.01 s interval).
COARSE_FALL_STEP = 0.005
#: The redundant parallelogram stops at the default Newton goal (its residual
#: stalls at round-off ~1e-11, above the relative 1e-12); run it again with this.
RETRY = {"free-parallelogram": {"newton_relative_tolerance": 1e-10}}
#: Andrews' steps (s; each divides the sample interval 3e-4 s).
ANDREWS_STEPS = (3e-5, 1e-5, 5e-6, 2.5e-6)


def case_mechanism(name: str, end: float, samples: int = 101):
    case = dm.CASES[name]()
    return dataclasses.replace(case.mech, assembly_pose=case.pose), np.linspace(0.0, end, samples)


def timed_run(engine, mech, times, settings):
    start = time.perf_counter()
    raw = engine.run(mech, times, settings)
    return raw, time.perf_counter() - start


def worst(mech, reference, frame) -> tuple[float, float]:
    """(worst angle error in rad, worst reaction error relative to its peak)."""
    ratios = dynamic_errors(mech, reference, frame)
    angles = [ratios[c] * ANGLE for c in ratios if c.endswith(".theta")]
    forces = [ratios[c] * FORCE for c in mech.reaction_columns() if c in ratios]
    return max(angles), max(forces, default=0.0)


def accuracy(engine) -> None:
    print("1. default setting against the forward-dynamics reference (ratio: error / default bound)")
    for name, end in ENDS.items():
        mech, times = case_mechanism(name, end)
        settings = engine.default_settings(mech, times)
        try:
            raw, wall = timed_run(engine, mech, times, settings)
        except Exception as exc:   # a case Exudyn cannot run: say what happens
            print(f"  {name:21s} cannot run: {type(exc).__name__}: {str(exc).splitlines()[0][:160]}")
            if name not in RETRY:
                continue
            settings = {**settings, **RETRY[name]}
            raw, wall = timed_run(engine, mech, times, settings)
            name = f"  … with {RETRY[name]}"
        reference = raw_dynamics(mech, times).frame
        ratios = dynamic_errors(mech, reference, raw.frame)
        column = max(ratios, key=ratios.get)
        angle, force = worst(mech, reference, raw.frame)
        print(f"  {name:21s} worst ratio {ratios[column]:.2g} ({column}); angle {angle:.2g} rad, "
              f"reaction {force:.2g} of peak; dt {settings['timestep']:.3g} s, {raw.info.steps} steps, "
              f"{wall:.2f} s")


def energy_drift(engine, fall: float) -> None:
    mech, times = case_mechanism("free-fourbar", fall, int(round(fall * 100)) + 1)
    defaults = engine.default_settings(mech, times)
    reference = raw_dynamics(mech, times).frame
    kinetic = kinetic_energy(mech, reference).max()
    print(f"2. energy, seed four-bar falling freely for {fall:g} s: (E − E0) / peak kinetic energy "
          f"{kinetic:.4g} J; max |·|, and its mean over the last second (a secular loss is negative)")
    solvers = {"index2 (default)": {}, "index3, spectral radius 0.9 (default)": {"solver": "index3"},
               "index3, spectral radius 0.6": {"solver": "index3", "spectral_radius": 0.6}}
    runs = [(f"reference (DOP853, rtol {RTOL:g})", reference, float("nan"))]
    for dt in (defaults["timestep"], COARSE_FALL_STEP):
        for label, overrides in solvers.items():
            raw, wall = timed_run(engine, mech, times, {**defaults, **overrides, "timestep": dt})
            runs.append((f"{label}, dt {dt:.3g} s", raw.frame, wall))
    last_second = times > times[-1] - 1.0
    for label, frame, wall in runs:
        energy = kinetic_energy(mech, frame) + potential_energy(mech, frame)
        change = (energy - energy[0]) / kinetic
        angle, force = worst(mech, reference, frame)
        print(f"  {label:50s} max {np.abs(change).max():.2g}, last second {change[last_second].mean():+.2g}; "
              f"angle error {angle:.2g} rad, reaction {force:.2g} of peak; {wall:.2f} s")


def work_precision(engine) -> None:
    mech, times = case_mechanism("motored-andrews", A.T1)
    defaults = engine.default_settings(mech, times)
    reference = raw_dynamics(mech, times).frame
    print(f"3. work-precision, Andrews' squeezer under its motor, 0–0.03 s (default dt {defaults['timestep']:.3g} s): "
          "error over the whole run")
    for solver in ("index2", "index3"):
        for dt in ANDREWS_STEPS:
            raw, wall = timed_run(engine, mech, times, {**defaults, "solver": solver, "timestep": dt})
            angle, force = worst(mech, reference, raw.frame)
            q = A.test_set_coordinates(raw.frame.iloc[[-1]])[:, 0]
            print(f"  {solver} dt {dt:.2g} s: angle {angle:.2g} rad, reaction {force:.2g} of peak, "
                  f"published q at 0.03 s {np.max(np.abs(q - A.Q1)):.2g} rad; {wall:.2f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fall", type=float, default=10.0, help="seconds the four-bar falls")
    parser.add_argument("--skip-andrews", action="store_true", help="leave out the work-precision line")
    args = parser.parse_args()
    engine = adapter("exudyn")
    accuracy(engine)
    energy_drift(engine, args.fall)
    if not args.skip_andrews:
        work_precision(engine)


if __name__ == "__main__":
    main()
