"""Run health (mechval.judging.health) on torque-driven and free motion, and the
comparison's error growth (mechval.judging.compare.error_growth):

- the reference's own health on the forward-dynamics cases of
  tests/dynamic_mechanisms.py: energy drift, energy balance, constraint
  drift and power residual at the reference's accuracy;
- each measure catches what it is for: an energy that grows, a pin that
  opens, a slider that turns on its guide;
- the work's quadrature (cumulative Simpson) is fourth order, its
  estimate honest, and a run sampled too coarsely is not judged on it;
- error growth tells a bias from an error that grows.

Bounds: ACCURACY (100·rtol) and DRIFT (1e-12) as tests/test_dynamics.py
states them; PRESCRIBED (1e-12) for the power residual, a balance of
quantities computed at one instant, as tests/test_reference.py holds it.
"""

from __future__ import annotations


import numpy as np
import pandas as pd
import pytest

import dynamic_mechanisms as dm
from mechval.judging.compare import COLUMNS, GROWTH_COLUMNS, HEALTH_BOUNDS, QUADRATURE_SHARE, compare, error_growth
from mechval.reference.dynamics import raw_dynamics
from mechval.judging.energy import conservative, work, work_error
from mechval.judging.health import health
from mechval.reference.planar.positions import mechanism_size
from mechval.model.scenario import Tolerance
from mechval.records.signals import Signals
from test_dynamics import ACCURACY, DRIFT, PRESCRIBED, solved

CONSERVATIVE = [name for name in sorted(dm.CASES) if conservative(dm.CASES[name]().mech)]


def health_of(name: str) -> tuple[dm.Case, pd.DataFrame, pd.DataFrame]:
    case, solution = solved(name)
    return case, solution.frame, health(case.mech, solution.frame, solution.missing)


def test_the_conservative_cases_are_the_undamped_free_ones():
    assert CONSERVATIVE == ["free-fourbar", "free-parallelogram", "pendulum"]


@pytest.mark.parametrize("name", CONSERVATIVE)
def test_the_reference_conserves_energy(name):
    """Energy drift |E − E(t0)| / S within ACCURACY (free four-bar: 4e-13,
    pendulum 6.1e-13, parallelogram 1.1e-12 measured); no balance row."""
    _, _, measures = health_of(name)
    assert measures["energy_drift"].max() <= ACCURACY
    assert "energy_balance" not in measures


@pytest.mark.parametrize("name", sorted(dm.CASES))
def test_the_reference_keeps_its_constraints_and_its_power_balance(name):
    """Constraint drift (gaps over L, prismatic angle errors) ≤ DRIFT and the
    power residual ≤ PRESCRIBED on every case (measured ≤ 7e-16 and 1.3e-14)."""
    _, _, measures = health_of(name)
    assert measures["constraint_drift"].max() <= DRIFT
    assert measures["power_residual"].max() <= PRESCRIBED
    assert ("drive_error" in measures) == bool(dm.CASES[name]().mech.drives)


def test_the_reference_balances_the_work_of_a_motor_dampers_a_spring_and_a_body_torque():
    """The motored slider-crank (every kind of applied power) sampled every
    0.125 ms: E − E(t0) − W within ACCURACY (measured 4e-13; Simpson's
    error, fourth order, is 3e-11 at 0.5 ms, 2e-12 at 0.25 ms)."""
    case = dm.motored_slider_crank()
    t = np.linspace(0.0, 0.5, 4001)
    solution = raw_dynamics(case.mech, t, case.initial, case.pose)
    measures = health(case.mech, solution.frame, solution.missing)
    assert measures["energy_balance"].max() <= ACCURACY
    assert "energy_drift" not in measures


# -- each measure catches what it is for --------------------------------------------------------

def test_energy_drift_sees_an_energy_that_grows():
    """Speeds 1 % high by the end (×(1 + 0.01·t/T)): the kinetic energy up to
    2 % of its peak, so the drift is ≥ 1e-2 and the row fails against the
    velocity tolerance 1e-2; the growth exponent says it grows."""
    case, raw, _ = health_of("free-fourbar")
    t = raw["t"].to_numpy()
    fast = raw.copy()
    for column in raw.columns:
        if column.endswith((".vx", ".vy", ".omega")):
            fast[column] = raw[column] * (1 + 0.01 * t / t[-1])
    drift = health(case.mech, fast)["energy_drift"]
    assert drift.max() >= 1e-2
    reference = Signals(pd.DataFrame({"t": t}), "reference")
    row = compare(reference, Signals(pd.DataFrame({"t": t}), "x", health=health(case.mech, fast)),
                  Tolerance()).set_index("signal").loc["health.energy_drift"]
    assert row["verdict"] == "fail" and row["growth_exponent"] > 1


def test_constraint_drift_sees_an_open_pin_and_a_turned_slider():
    """The conrod moved 1e-6·L off its pins: drift 1e-6 (its gaps over L);
    the slider turned 2e-6 rad on its guide: drift 2e-6 (the angle error),
    where the gap alone sees nothing."""
    case, raw, _ = health_of("motored-slider-crank")
    size = mechanism_size(case.mech)
    moved = raw.assign(**{"conrod.x": raw["conrod.x"] + 1e-6 * size})
    assert health(case.mech, moved)["constraint_drift"].max() == pytest.approx(1e-6, rel=1e-6)
    turned = raw.assign(**{"slider.theta": raw["slider.theta"] + 2e-6})
    measures = health(case.mech, turned)
    assert measures["constraint_drift"].max() == pytest.approx(2e-6, rel=1e-6)
    assert measures["gap"].max() <= DRIFT * size


# -- the work's quadrature ----------------------------------------------------------------------

def test_the_work_is_integrated_to_fourth_order_and_its_error_estimated():
    """∫ cos(3t)·e^(t/3) dt: the error falls ×16 per halving of the sample
    interval (measured ×15.4 … ×16.0), and the Richardson estimate is within
    a factor 3 of the error (measured 0.8 … 1.1 here; 0.3 … 1.2 on the
    dynamic cases against the reference's residual)."""
    exact = lambda t: np.real((np.exp((1 / 3 + 3j) * t) - 1) / (1 / 3 + 3j))   # noqa: E731
    errors = []
    for n in (41, 81, 161):
        t = np.linspace(0.0, 3.0, n)
        power = np.cos(3 * t) * np.exp(t / 3)
        error = np.abs(work(t, power) - exact(t)).max()
        assert error / 3 <= work_error(t, power).max() <= 3 * error
        errors.append(error)
    assert all(14 <= coarse / fine <= 18 for coarse, fine in zip(errors, errors[1:]))


def test_a_balance_the_samples_cannot_integrate_is_not_judged():
    """The motored slider-crank with 21 samples over 1 s: the work's
    quadrature error estimate exceeds QUADRATURE_SHARE of the bound, so
    the row is 'missing' with the estimate, whatever the residual."""
    case = dm.motored_slider_crank()
    t = np.linspace(0.0, 1.0, 21)
    solution = raw_dynamics(case.mech, t, case.initial, case.pose)
    measures = health(case.mech, solution.frame)
    assert measures["energy_quadrature"].max() > QUADRATURE_SHARE * Tolerance()[HEALTH_BOUNDS["energy_balance"]]
    empty = pd.DataFrame({"t": t})
    row = compare(Signals(empty, "reference"), Signals(empty, "x", health=measures),
                  Tolerance()).set_index("signal").loc["health.energy_balance"]
    assert row["verdict"] == "missing" and "too coarse to integrate" in row["reason"]


# -- error growth -------------------------------------------------------------------------------

T = np.linspace(0.0, 4.0, 401)


@pytest.mark.parametrize("error, exponent", [
    (1e-3 * (1 + 0.5 * np.sin(9 * T)), 0.0),            # a bias that oscillates
    (1e-3 * T * np.abs(np.cos(5 * T)), 1.0),            # a phase error: grows with t under the motion
    (1e-4 * T**2, 2.0),
])
def test_growth_exponent_tells_a_bias_from_an_error_that_grows(error, exponent):
    growth = error_growth(T, error)
    assert abs(growth["growth_exponent"] - exponent) <= 0.15, growth
    assert growth["error_first_quarter"] == np.abs(error[T <= 1.0]).max()
    assert growth["error_last_quarter"] == np.abs(error[T >= 3.0]).max()


def test_error_growth_of_no_error_is_undefined():
    growth = error_growth(T, np.zeros_like(T))
    assert np.isnan(growth["growth_exponent"]) and growth["error_first_quarter"] == 0.0


def test_the_growth_columns_extend_the_records_and_leave_the_others_in_place():
    """Downstream files read the first sixteen columns by name and place."""
    assert COLUMNS[:16] == ["scenario", "engine", "setting", "signal", "class", "max_error", "t_max", "rms_error",
                            "peak", "relative_error", "tolerance", "bound", "ratio", "verdict", "missing", "reason"]
    assert COLUMNS[16:] == GROWTH_COLUMNS


def test_a_record_carries_its_error_growth():
    reference = Signals(pd.DataFrame({"t": T, "crank.theta": np.sin(T)}), "reference")
    engine = Signals(pd.DataFrame({"t": T, "crank.theta": np.sin(T) + 1e-5 * T}), "x")
    row = compare(reference, engine, Tolerance()).set_index("signal").loc["crank.theta"]
    assert row["error_last_quarter"] == pytest.approx(4e-5) and row["growth_exponent"] == pytest.approx(1.0)
    assert row["error_first_quarter"] == pytest.approx(1e-5)
