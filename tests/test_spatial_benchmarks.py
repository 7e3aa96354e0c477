"""The spatial reference on problems of the IFToMM / A Coruña multibody
benchmark library (issue 26, "Checks against published or closed-form
results"; the systems and their sources in tests/spatial_benchmarks.py).

A04, Bricard's mechanism: the benchmark's stated facts are the mobility
(Grübler 0, actually 1) and, with no dissipation, the mechanical energy,
which its measure requires to hold over the 10 s run. Its published
reference solution (the time history of a point, a data file on the
library's site) is not in our sources, so no trajectory is compared here."""

from __future__ import annotations

import numpy as np
import pytest

from mechval.reference.spatial.columns import body_state
from mechval.reference.spatial.dynamics import SpatialDynamics, energy
from spatial_benchmarks import Bricard

#: As for the other integrated spatial systems (tests/test_spatial_closed_forms.py):
#: energy within 1e-10 of its size, every constraint row (the redundant one
#: included) within 1e-10 scaled, at the dynamics' default tolerances.
ENERGY_TOL = 1e-10
CLOSURE_TOL = 1e-10


def run_bricard(duration: float):
    m = Bricard()
    dynamics = SpatialDynamics(m.system)
    t = np.linspace(0.0, duration, int(round(100 * duration)) + 1)
    sol = dynamics.solve(t)
    return m, sol


def closing_joint_gap(m: Bricard, frame) -> tuple[float, float]:
    """Independently of the solver's rows: how far bar5's end is from the
    ground pin P5 (m), and the sine of the angle between its pin axis and
    the ground's, the joint that closes the loop (bar5's frame is the
    world frame at the assembly, so P5 is also its point in body axes)."""
    A5 = body_state(m.system, frame)[0].A[:, 4]
    origin = frame[["bar5.x", "bar5.y", "bar5.z"]].to_numpy()
    P5, axis = m.points[5] * m.length, m.axes[5]
    gap = np.linalg.norm(origin + A5 @ P5 - P5, axis=1).max()
    turn = np.linalg.norm(np.cross(A5 @ axis, axis), axis=1).max()
    return float(gap), float(turn)


def check_bricard(duration: float) -> None:
    m, sol = run_bricard(duration)
    facts = sol.facts
    assert (facts["mobility"], facts["redundant_constraints"], sol.structure.grubler) == (1, 1, 0)
    pose, w, _ = body_state(m.system, sol.frame)
    E = energy(m.system, pose, w)
    # released at rest: all the energy is the bars' height, −m·g·Σy = 3·m·g
    assert abs(E[0] + 3 * m.mass * 9.81 * m.length) <= 1e-12 * abs(E[0])
    change = np.abs(E - E[0]).max()
    assert change <= ENERGY_TOL * abs(E[0]), f"energy changed by {change:.3g} J of {E[0]:.4g} J"
    kinetic = E - 9.81 * m.mass * pose.G[..., 1].sum(axis=1)
    assert kinetic.max() > 0.1 * abs(E[0]), "the mechanism should move (it is not at equilibrium)"
    assert facts["constraint_drift_max"] <= CLOSURE_TOL and facts["velocity_drift_max"] <= CLOSURE_TOL, facts
    gap, turn = closing_joint_gap(m, sol.frame)
    assert gap <= CLOSURE_TOL * m.length and turn <= CLOSURE_TOL, (gap, turn)


def test_bricard_first_second_conserves_energy_and_closes():
    """The benchmark's first second (the default run's share)."""
    check_bricard(1.0)


@pytest.mark.slow
def test_bricard_benchmark_ten_seconds():
    """The benchmark's full 10 s: two swings out and back to the start."""
    check_bricard(10.0)
