"""Figures: how closely the general planar reference reproduces the closed
forms on every built-in of the four kinds (largest error over all raw columns, as a fraction
of each column's scale, from a pose 0.05 rad off) and the Test Set's
Andrews solution (per quantity, as the tests scale them).

    .venv/bin/python tests/bench/planar_accuracy.py

Prints the figures; the tests (tests/test_planar_solver.py) hold them to
their bounds.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/ helpers

import andrews as A  # noqa: E402
from mechval.reference.linkages import build_mechanism  # noqa: E402
from mechval.reference.planar.solver import raw_planar  # noqa: E402
from mechval.reference.adapter import raw_reference  # noqa: E402
from mechval.scenarios import builtin_names, load  # noqa: E402
from scales import motion_scales, size  # noqa: E402
from test_planar_solver import column_scales, lambdas, perturbed_pose, worst  # noqa: E402


def main() -> None:
    print("general reference against the closed form, largest scaled error (bound 1e-12)")
    for name in builtin_names():
        scenario = load(name)
        if scenario.mechanism == "planar":       # no closed form (the new scenes)
            continue
        mech, t = build_mechanism(scenario), scenario.time.t
        solution = raw_planar(mech, t, perturbed_pose(mech, 0.0))
        reference = raw_reference(mech, t)
        motion = {**motion_scales(mech, t), "length": size(mech), "angle": 1.0}
        column, error = worst(mech, solution.frame, reference, column_scales(mech, reference, motion))
        print(f"  {name:26s} {error:9.2e}  ({column})")
    print("Andrews' squeezer against the Test Set (rforge/bvpsolve pkg/deTestSet)")
    raw = raw_planar(A.andrews_mechanism(), np.array([0.0])).frame
    rows = [("t = 0", raw, A.Q0, A.QDDOT0, A.LAMBDA0, None)]
    law = A.local_law(A.T1, A.Q1, A.QDOT1, A.QDDOT1)
    raw = raw_planar(A.andrews_mechanism(law, A.pose_near(A.Q1)), np.array([A.T1])).frame
    rows.append(("t = 0.03 s", raw, A.Q1, A.QDDOT1, A.LAMBDA1, A.QDOT1))
    for label, raw, q, qddot, lam, qdot in rows:
        figures = {
            "angles (rad)": np.abs(A.test_set_coordinates(raw)[:, 0] - q).max(),
            "accelerations (rel.)": np.abs(A.test_set_coordinates(raw, "alpha")[:, 0] - qddot).max()
            / np.abs(qddot).max(),
            "torque vs mom (rel.)": abs(raw["drive.T"].iloc[0] - A.mom) / A.mom,
            "λ (rel.)": np.abs(lambdas(raw) - lam).max() / np.abs(lam).max(),
        }
        if qdot is not None:
            figures["velocities (rel.)"] = np.abs(A.test_set_coordinates(raw, "omega")[:, 0] - qdot).max() \
                / np.abs(qdot).max()
        print(f"  {label:10s} " + ", ".join(f"{k} {v:.2e}" for k, v in figures.items()))


if __name__ == "__main__":
    main()
