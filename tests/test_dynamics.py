"""The forward-dynamics reference (mechval.reference.dynamics) against what it must
reproduce:

- closed forms: a pendulum released from rest (elliptic functions), a
  crank spun by a constant-plus-sinusoid torque;
- Andrews' squeezing mechanism under its motor torque, the published Test
  Set solution at t = 0.03 s (tests/andrews.py cites every number);
- itself: the energy balance, the constraints at every output, the result
  unchanged when the tolerance is tightened to scipy's finest (TIGHTEST;
  tests/test_dynamics_accuracy.py holds every signal against it, per class,
  as the comparison does), and the prescribed-motion
  reference (mechval.reference.planar.solver) driven along the integrated motion
  needing exactly the applied torque, with the same reactions;
- refusals that name the key.

Bounds (STYLE.md §4): the integrator keeps each step's error within
rtol = 1e-13 (relative, `mechval.reference.dynamics.RTOL`); over a run the errors of
its steps add up. On the closed forms below the global error is ≤ 9·rtol
(the pendulum after 2 s, five swings: 8.4e-13 rad), so `ACCURACY` =
100·rtol bounds the global error of a run of a few seconds with a decade
of margin, and every derived quantity (energy, the tightened run's
difference) is held to it, scaled as each test says.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline

import andrews as A
import dynamic_mechanisms as dm
from mechval.adapter import Unrepresentable, mechanism_features
from mechval.reference.dynamics import RTOL, ForwardDynamics, raw_dynamics
from mechval.judging.energy import applied_power, kinetic_energy, potential_energy
from mechval.judging.health import joint_gaps
from mechval.reference.linkages import build_mechanism
from mechval.model.mechanism import GROUND, Body, BodyPose, Drive, InitialValue, Joint, TorqueLaw
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.planar.solver import raw_planar
from mechval.reference.adapter import ReferenceAdapter
from mechval.scenarios import load
from mechval.reference.planar.positions import mechanism_size as size  # L: joint, centre-of-mass and force points
from test_dynamics_accuracy import TIGHTEST

ACCURACY = 100 * RTOL
#: Constraint drift at every output, as a fraction of the mechanism's size (issue 15).
DRIFT = 1e-12
#: Andrews' published coordinates must agree to this, relative per coordinate (issue 15).
ANDREWS = 1e-9
#: The published velocities of the dependent coordinates agree with the
#: published positions only to ~2e-8 (the prescribed reference at the
#: published β, β̇: tests/test_planar_solver.py holds them to 1e-7).
ANDREWS_DEPENDENT_RATES = 1e-7
#: A prescribed solve along the integrated motion: both sides are linear
#: solves at the same positions, so they agree to rounding (as
#: tests/test_planar_solver.py's BOUND), relative to each class's peak.
PRESCRIBED = 1e-12
#: Seconds each case runs (Andrews: the Test Set's interval).
SPANS = {"pendulum": 2.0, "spinning-crank": 2.0, "free-fourbar": 2.0, "motored-slider-crank": 1.0,
         "free-five-bar": 1.0, "half-driven-five-bar": 1.0, "free-parallelogram": 2.0, "motored-andrews": A.T1}
#: Quadrature panels over each run (see gauss_instants).
PANELS = 50


def run(name: str, t: np.ndarray, rtol: float = RTOL):
    case = dm.CASES[name]()
    return case, raw_dynamics(case.mech, t, case.initial, case.pose, rtol=rtol)


def gauss_instants(span: float, panels: int = PANELS, nodes: int = 8):
    """Panel edges and Gauss–Legendre nodes on [0, span], all sorted: the
    instants, which of them are edges, and the quadrature weights."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    edges = np.linspace(0.0, span, panels + 1)
    h = np.diff(edges)
    inner = edges[:-1, None] + (x[None, :] + 1) / 2 * h[:, None]
    t = np.sort(np.concatenate([edges, inner.ravel()]))
    return t, np.isin(t, edges), w[None, :] * h[:, None] / 2


@functools.lru_cache(maxsize=None)
def solved(name: str, rtol: float = RTOL):
    """A case run over its span at the Gauss instants (shared by the tests)."""
    return run(name, gauss_instants(SPANS[name])[0], rtol)


def motion_scales(case, raw) -> dict[str, float]:
    """Angle: max(1 rad, max |θ|) (a crank's angle grows: the integrator's
    error is relative to it); rate Ω = max |ω|; lengths L, LΩ."""
    bodies = [b.name for b in case.mech.bodies]
    angle = max(1.0, max(float(np.abs(raw[f"{b}.theta"]).max()) for b in bodies))
    omega = max(float(np.abs(raw[f"{b}.omega"]).max()) for b in bodies)
    L = size(case.mech)
    return {"theta": angle, "omega": omega, "x": L, "y": L, "vx": L * omega, "vy": L * omega}


# -- closed forms -------------------------------------------------------------------------------

def test_pendulum_released_from_rest_follows_the_elliptic_solution():
    case, solution = solved("pendulum")
    theta, omega = dm.pendulum_exact(solution.frame["t"].to_numpy())
    raw = solution.frame
    assert np.abs(raw["bar.theta"] - theta).max() <= ACCURACY
    assert np.abs(raw["bar.omega"] - omega).max() <= ACCURACY * np.abs(omega).max()


def test_crank_under_a_torque_law_follows_the_closed_form():
    case, solution = solved("spinning-crank")
    t = solution.frame["t"].to_numpy()
    theta, omega = dm.spinning_exact(t)
    raw = solution.frame
    assert np.abs(raw["crank.theta"] - theta).max() <= ACCURACY * np.abs(theta).max()
    assert np.abs(raw["crank.omega"] - omega).max() <= ACCURACY * np.abs(omega).max()
    assert np.array_equal(raw["drive.T"], case.mech.torque_drives[0].value(t))


#: Radau's tolerance here: of order 5, at the default RTOL it needs about
#: 38,000 evaluations for this 2 s run (DOP853: 1,600), beyond the limit.
RADAU_RTOL = 1e-10


@pytest.mark.slow
def test_radau_follows_the_pendulum_too():
    """The other integrator offered (implicit, for stiff scenes): the same
    closed form within 100·RADAU_RTOL (measured 6e-11 rad; ~6 s, 963 steps)."""
    case = dm.pendulum()
    t = np.linspace(0.0, SPANS["pendulum"], 201)
    solution = raw_dynamics(case.mech, t, rtol=RADAU_RTOL, method="Radau")
    assert np.abs(solution.frame["bar.theta"] - dm.pendulum_exact(t)[0]).max() <= 100 * RADAU_RTOL
    assert solution.facts["integrator"] == "scipy.integrate.Radau"


def test_the_output_states_the_integrator_and_its_tolerance():
    facts = solved("pendulum")[1].facts
    assert facts["integrator"] == "scipy.integrate.DOP853"
    assert facts["rtol"] == RTOL and len(facts["atol"]) == 2
    assert facts["steps"] > 0 and facts["evaluations"] > facts["steps"]


# -- Andrews' squeezer --------------------------------------------------------------------------

def test_andrews_under_its_motor_torque_reaches_the_published_state_at_30_ms():
    """From the Test Set's consistent initial state (q0, q̇0 = 0) under mom
    and the spring, to t = 0.03 s: the seven coordinates within 1e-9
    relative (measured: β 7.3e-11, Θ 9.1e-11, γ 2.7e-10, Φ 3.6e-11, δ
    1.1e-12, Ω 3.6e-11, ε 3.1e-13)."""
    case, solution = solved("motored-andrews")
    raw = solution.frame
    assert raw["t"].iloc[-1] == A.T1
    assert np.abs(A.test_set_coordinates(raw)[:, 0] - A.Q0).max() <= 1e-15 * np.abs(A.Q0).max()
    q = A.test_set_coordinates(raw)[:, -1]
    errors = np.abs(q - A.Q1) / np.abs(A.Q1)
    assert errors.max() <= ANDREWS, errors
    rates = np.abs(A.test_set_coordinates(raw, "omega")[:, -1] - A.QDOT1) / np.abs(A.QDOT1)
    assert rates[:2].max() <= ANDREWS, rates           # β̇ (integrated) and Θ̇
    assert rates.max() <= ANDREWS_DEPENDENT_RATES, rates
    assert raw["drive.T"].iloc[-1] == A.mom


# -- self-checks --------------------------------------------------------------------------------

def energy_residual(mech, raw, span: float) -> float:
    """max |E(t) − E(0) − W(t)| over the panel edges of `raw` (a run at
    gauss_instants(span)), relative to the largest of the kinetic energy,
    the potential energy's change and the work W of the applied torques and
    dampers (mechval.judging.energy, from the raw columns alone)."""
    _, edges, weights = gauss_instants(span)
    kinetic, potential = kinetic_energy(mech, raw), potential_energy(mech, raw)
    power = applied_power(mech, raw)
    work = np.concatenate([[0.0], np.cumsum((power[~edges].reshape(weights.shape) * weights).sum(axis=1))])
    energy = (kinetic + potential)[edges]
    scale = max(np.abs(kinetic).max(), np.abs(potential - potential[0]).max(), np.abs(work).max())
    return float(np.abs(energy - energy[0] - work).max() / scale)


@pytest.mark.parametrize("name", sorted(dm.CASES))
def test_energy_balance(name):
    """E(t) − E(0) = ∫ applied power dt at every panel edge, the integral by
    8-point Gauss–Legendre on 50 panels (its error, ~(h·Ω)¹⁶/16!, is below
    rounding for these smooth powers), within ACCURACY (energy_residual)."""
    case, solution = solved(name)
    residual = energy_residual(case.mech, solution.frame, SPANS[name])
    assert residual <= ACCURACY, f"{residual:.3g}"


def test_energy_balance_fails_without_the_damper_losses():
    """The check above can fail: leave the slider's damper out of the power."""
    case, solution = solved("motored-slider-crank")
    undamped = dataclasses.replace(case.mech, joints=tuple(dataclasses.replace(j, damping=0.0)
                                                           if j.name == "guide" else j for j in case.mech.joints))
    assert energy_residual(undamped, solution.frame, SPANS["motored-slider-crank"]) > 1e-3


@pytest.mark.parametrize("name", sorted(dm.CASES))
def test_constraint_drift(name):
    """Every joint closes at every output (mechval.judging.health's gap) to 1e-12
    of the mechanism's size, and the run's own measure says so."""
    case, solution = solved(name)
    assert joint_gaps(case.mech, solution.frame).max() <= DRIFT * size(case.mech)
    assert solution.facts["constraint_drift_max"] <= DRIFT


@pytest.mark.parametrize("name", ["free-fourbar", "motored-andrews",
                                  pytest.param("motored-slider-crank", marks=pytest.mark.slow),
                                  pytest.param("free-five-bar", marks=pytest.mark.slow)])
def test_tightening_the_tolerance_changes_nothing(name):
    """Every motion column at RTOL against scipy's finest tolerance
    (TIGHTEST) within ACCURACY of its scale (motion_scales)."""
    case, solution = solved(name)
    tight = solved(name, TIGHTEST)[1].frame
    scales = motion_scales(case, solution.frame)
    for body in case.mech.bodies:
        for quantity, scale in scales.items():
            column = f"{body.name}.{quantity}"
            error = np.abs(solution.frame[column] - tight[column]).max() / scale
            assert error <= ACCURACY, f"{column}: {error:.3g}"


class TableLaw:
    """A drive law through given (φ, φ̇, φ̈) at given instants, exact there
    (cubic Hermite in between: only the prescribed solver's continuation
    nodes, its predictors, fall between)."""

    def __init__(self, t, angle, rate, acceleration):
        self._angle, self._rate = CubicHermiteSpline(t, angle, rate), CubicHermiteSpline(t, rate, acceleration)

    def angle(self, t):
        return self._angle(t)

    def rate(self, t):
        return self._rate(t)

    def acceleration(self, t):
        return self._rate.derivative()(t)


def test_a_prescribed_solve_along_the_motion_needs_exactly_the_applied_torque():
    """Drive the motored slider-crank's crank along its integrated motion
    θ2(t) with the prescribed-motion reference (no torque law): the drive
    torque it needs is the motor's T(t), its motion and reactions are the
    forward dynamics' (PRESCRIBED of each class's peak)."""
    case, solution = solved("motored-slider-crank")
    raw = solution.frame
    t = raw["t"].to_numpy()
    law = TableLaw(t, raw["crank.theta"].to_numpy(), raw["crank.omega"].to_numpy(), raw["crank.alpha"].to_numpy())
    prescribed = dataclasses.replace(case.mech, drive=Drive("O2", law, name="motor"), torque_drives=())
    expected = raw_planar(prescribed, t, case.pose).frame
    force = max(float(np.abs(raw[c]).max()) for c in raw.columns if c.endswith((".Fx", ".Fy")))
    torque = max(float(np.abs(raw[c]).max()) for c in raw.columns if c.endswith((".T", ".M")))
    scales = motion_scales(case, raw)
    for column in raw.columns[1:]:
        quantity = column.split(".")[1]
        scale = force if quantity in ("Fx", "Fy") else torque if quantity in ("T", "M") else \
            scales.get(quantity, scales["omega"] ** 2 * size(case.mech) if quantity in ("ax", "ay") else
                       scales["omega"] ** 2)
        error = np.abs(raw[column] - expected[column]).max() / scale
        assert error <= PRESCRIBED, f"{column}: {error:.3g}"


# -- refusals -----------------------------------------------------------------------------------

def run_case(case, t):
    return raw_dynamics(case.mech, t, case.initial, case.pose)


def refusal(case, initial=None, mech=None) -> MechanismError:
    with pytest.raises(MechanismError) as caught:
        ForwardDynamics(mech or case.mech, case.initial if initial is None else initial, case.pose)
    return caught.value


def test_refuses_too_few_initial_values():
    case = dm.free_five_bar()
    error = refusal(case, case.initial[:1])
    assert error.key == "initial" and "too few initial values: 1 given for 2 degrees of freedom" in error.reason


def test_refuses_too_many_initial_values():
    case = dm.free_fourbar()
    error = refusal(case, (*case.initial, InitialValue("O4", 1.5)))
    assert error.key == "initial" and "too many initial values: 2 given for 1 degree of freedom" in error.reason


def test_refuses_values_that_leave_a_degree_of_freedom_open():
    """A four-bar and a separate pendulum (two degrees of freedom), values
    given at two joints of the four-bar: they count two but fix one."""
    case = dm.free_fourbar()
    mech = dataclasses.replace(case.mech, bodies=(*case.mech.bodies, Body("bob", 1.0, (0.2, 0.0), 0.01)),
                               joints=(*case.mech.joints, Joint("P", "revolute", GROUND, "bob", (2.0, 0.0), (0.0, 0.0))))
    pose = {**case.pose, "bob": BodyPose(-1.0)}
    with pytest.raises(MechanismError) as caught:
        ForwardDynamics(mech, (*case.initial, InitialValue("A", 0.5)), pose)
    assert caught.value.key == "initial" and "do not fix the configuration" in caught.value.reason


def test_refuses_a_value_the_loop_cannot_reach():
    """The seed rocker along +x from O4 puts B 1.1 m from O2, beyond crank +
    coupler = 0.75 m."""
    case = dm.free_fourbar()
    error = refusal(case, (InitialValue("O4", 0.0),))
    assert error.key == "initial" and "inconsistent initial state" in error.reason


def test_refuses_a_run_whose_coordinate_reaches_its_toggle():
    """The seed four-bar falling from rest with the rocker's angle as its
    coordinate: the rocker reaches its extreme within 0.36 s, where its
    angle cannot parametrise the motion."""
    case = dm.free_fourbar()
    start = ForwardDynamics(case.mech, case.initial, case.pose).start
    rocker = dm.case(case.mech, (InitialValue("O4", float(start.q[8])),), case.pose)
    with pytest.raises(MechanismError) as caught:
        run_case(rocker, np.linspace(0.0, 1.0, 11))
    assert caught.value.key == "time" and "cannot parametrise the motion" in caught.value.reason


def test_refuses_a_value_at_which_the_coordinate_cannot_move_the_mechanism():
    """The seed rocker at its extreme angle ψ (crank and coupler in line:
    |O2B| = 0.75 m, so 0.36 + 0.25 + 0.6·cos ψ = 0.75²): the rocker's angle
    cannot parametrise the motion there."""
    case = dm.free_fourbar()
    psi = float(np.arccos((0.75**2 - 0.61) / 0.6))
    error = refusal(case, (InitialValue("O4", psi),))
    assert error.key == "initial" and "inconsistent initial state" in error.reason


@pytest.mark.parametrize("initial, key, reason", [
    ((InitialValue("Q", 0.0),), "initial.Q", "unknown joint"),
    ((InitialValue("O2", 0.0), InitialValue("O2", 0.1)), "initial.O2", "two initial values"),
    ((InitialValue("O2", float("nan")),), "initial.O2", "must be finite"),
])
def test_refuses_bad_initial_values(initial, key, reason):
    error = refusal(dm.free_fourbar(), initial)
    assert error.key == key and reason in error.reason


def test_refuses_an_initial_value_at_a_prescribed_joint():
    case = dm.free_fourbar()
    mech = dataclasses.replace(case.mech, drive=Drive("O2", TableLaw([0, 1], [0, 1], [1, 1], [0, 0])))
    error = refusal(case, mech=mech)
    assert error.key == "initial.O2" and "prescribed by a drive" in error.reason


@pytest.mark.parametrize("law, reason", [
    (TorqueLaw("nowhere", 1.0), "unknown joint"),
    (TorqueLaw("guide", 1.0), "is prismatic"),
    (TorqueLaw("O2", float("inf")), "must be finite"),
])
def test_refuses_bad_torque_laws(law, reason):
    case = dm.motored_slider_crank()
    error = refusal(case, mech=dataclasses.replace(case.mech, torque_drives=(law,)))
    assert error.key == f"torque.{law.name}" and reason in error.reason


# -- as the reference adapter -------------------------------------------------------------------

def test_the_reference_adapter_integrates_torque_driven_and_free_mechanisms():
    """ReferenceAdapter runs a mechanism without a prescribed drive (or with
    torque laws) by forward dynamics from its own initial values, and its
    RunInfo states the integrator and tolerance."""
    t = np.linspace(0.0, 0.5, 11)
    for case in (dm.spinning_crank(), dm.half_driven_five_bar()):
        run_ = ReferenceAdapter().run(case.mech, t, {})
        direct = raw_dynamics(case.mech, t)
        assert run_.frame.equals(direct.frame)
        assert run_.info.facts["rtol"] == RTOL and run_.info.facts["integrator"].endswith("DOP853")


def test_the_reference_adapter_refuses_a_bad_initial_state_as_unrepresentable():
    case = dm.free_fourbar()
    mech = dataclasses.replace(case.mech, initial_values=())
    with pytest.raises(Unrepresentable) as caught:
        ReferenceAdapter().run(mech, np.linspace(0.0, 1.0, 5), {})
    assert caught.value.key == "initial" and "too few initial values" in caught.value.reason


def test_torque_laws_and_free_motion_are_features_engines_must_declare():
    """Engines that do not list them are refused before they run
    (mechval.adapter.mechanism_features)."""
    assert mechanism_features(dm.free_fourbar().mech) == {"free motion": "initial"}
    assert mechanism_features(dm.spinning_crank().mech) == {"torque laws": "torque.drive", "free motion": "initial"}
    assert mechanism_features(dm.half_driven_five_bar().mech)["free motion"] == "initial"
    assert mechanism_features(build_mechanism(load("fourbar-seed"))) == {}


def test_redundant_reactions_are_missing_with_the_reason_as_in_the_prescribed_reference():
    """The free parallelogram: its kinematics and energy are checked above;
    the reactions its redundant constraint leaves indeterminate are NaN
    with the reason, the same columns the prescribed reference leaves out."""
    case, solution = solved("free-parallelogram")
    prescribed = raw_planar(dataclasses.replace(case.mech, drive=Drive("O1", TableLaw([0, 1], [-0.5, -0.4],
                                                                                     [0.1, 0.1], [0, 0]))),
                            np.array([0.0, 0.5]), case.pose)
    assert sorted(solution.missing) == sorted(prescribed.missing)
    for column, reason in solution.missing.items():
        assert solution.frame[column].isna().all() and "not unique" in reason
    assert not solution.frame.drop(columns=list(solution.missing)).isna().any().any()
