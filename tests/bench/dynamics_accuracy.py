"""Figures: how closely the forward-dynamics reference (mechval.dynamics)
meets its checks, as tests/test_dynamics.py scales them: the closed forms
(pendulum, crank under a torque law), and per test mechanism the energy
balance residual, the constraint drift and the change when the tolerance
is tightened 100×.

    .venv/bin/python tests/bench/dynamics_accuracy.py

Prints the figures; the tests hold them to their bounds (ACCURACY = 100·rtol
= 1e-8, the drift to 1e-12).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

import dynamic_mechanisms as dm  # noqa: E402
from mechval.dynamics import RTOL  # noqa: E402
from mechval.health import joint_gaps  # noqa: E402
from mechval.planar_positions import mechanism_size as size  # noqa: E402
from test_dynamics import SPANS, energy_residual, motion_scales, solved  # noqa: E402


def main() -> None:
    print(f"closed forms at rtol {RTOL:g} (bound {100 * RTOL:g})")
    case, solution = solved("pendulum")
    raw = solution.frame
    theta, omega = dm.pendulum_exact(raw["t"].to_numpy())
    print(f"  pendulum, {SPANS['pendulum']:g} s: θ {np.abs(raw['bar.theta'] - theta).max():.2e} rad, "
          f"ω {np.abs(raw['bar.omega'] - omega).max() / np.abs(omega).max():.2e} of max |ω|")
    case, solution = solved("spinning-crank")
    raw = solution.frame
    theta, omega = dm.spinning_exact(raw["t"].to_numpy())
    print(f"  crank under T0 + A·sin, {SPANS['spinning-crank']:g} s: θ "
          f"{np.abs(raw['crank.theta'] - theta).max() / np.abs(theta).max():.2e} of max |θ|, "
          f"ω {np.abs(raw['crank.omega'] - omega).max() / np.abs(omega).max():.2e} of max |ω|")
    print("per mechanism: energy residual, constraint drift (of the size), change at rtol/100 (scaled)")
    for name in dm.CASES:
        case, solution = solved(name)
        raw = solution.frame
        tight = solved(name, RTOL / 100)[1].frame
        scales = motion_scales(case, raw)
        change = max(float(np.abs(raw[f"{b.name}.{q}"] - tight[f"{b.name}.{q}"]).max()) / s
                     for b in case.mech.bodies for q, s in scales.items())
        print(f"  {name:22s} {SPANS[name]:5g} s  energy {energy_residual(case.mech, raw, SPANS[name]):9.2e}  "
              f"drift {joint_gaps(case.mech, raw).max() / size(case.mech):9.2e}  rtol/100 {change:9.2e}  "
              f"({solution.facts['steps']} steps, {solution.facts['evaluations']} evaluations)")


if __name__ == "__main__":
    main()
