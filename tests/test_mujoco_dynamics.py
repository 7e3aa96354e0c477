"""MuJoCo on torque-driven and free mechanisms, beyond the shared contract
(mechval.testing.contract runs the pendulum, the crank under a torque law, the
free four-bar and the motored slider-crank): a free run has no clock and
no pre-roll, the audit reads each torque law back, a torque law on a
loop-closing pin, inverse mode along the integrated motion, the half-driven
five-bar, and Andrews' squeezer under its motor against the reference and
the Test Set's published solution. Figures: tests/bench/mujoco_dynamics_figures.py."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import andrews as A
import dynamic_mechanisms as dm
from mechval.testing.contract import ANGLE, dynamic_errors
from mechval.records.audit import audit, expected_model, failures, format_audit
from mechval.reference.dynamics import raw_dynamics
from mechval.model.mechanism import TorqueLaw
from mechval.model.scenario import ScenarioError
from mechval.scenarios import parse
from mechval.testing.scenes import fourbar

try:
    import mujoco
except ImportError as exc:
    pytestmark = [pytest.mark.engine, pytest.mark.skip(reason=f"mujoco cannot be imported ({exc})")]
else:
    pytestmark = pytest.mark.engine
    from mechval.engines.mujoco.adapter import MujocoAdapter
    from mechval.engines.mujoco.audit import Reader
    from mechval.engines.mujoco.run import Model

#: Inverse mode evaluates the equations of motion at the reference's own
#: state: only rounding separates them (measured ≤ 9e-13 rad, 6e-15 of each
#: reaction's peak on both mechanisms below).
INVERSE_AGREEMENT = 1e-9


def mechanism(name: str, **changes):
    case = dm.CASES[name]()
    return dataclasses.replace(case.mech, assembly_pose=case.pose, **changes)


def law_at_the_cut_pin():
    """The free four-bar with a torque law at O4, the pin where MuJoCo's
    tree is cut (its tendon runs over the hinges of both paths)."""
    return mechanism("free-fourbar", torque_drives=(TorqueLaw("O4", -20.0, 15.0, 2.0, 0.4, name="rocker"),))


def failing_ratios(mech, times, frame) -> dict[str, float]:
    ratios = dynamic_errors(mech, raw_dynamics(mech, times).frame, frame)
    return {column: ratio for column, ratio in ratios.items() if not ratio <= 1.0}


@pytest.fixture(scope="module")
def engine():
    return MujocoAdapter()


def built(engine, mech, times) -> Model:
    model = Model(mech, times, engine.default_settings(mech, times))
    model.initial_state()
    mujoco.mj_fwdPosition(model.m, model.d)
    return model


def test_a_free_run_has_no_clock_and_no_pre_roll(engine):
    """The free four-bar: no clock joint, no drive equality (only the loop's
    connect), no pre-roll planned or taken, the start state at the first
    instant; the audit finds nothing else and says there is no clock."""
    mech, times = mechanism("free-fourbar"), np.linspace(0.0, 0.5, 51)
    settings = engine.default_settings(mech, times)
    assert settings["preroll_timeconsts"] == 0.0 and engine.planned_steps(times, settings)[1] == 0.0
    model = built(engine, mech, times)
    assert model.preroll == 0 and model.start_motion["t"][0] == times[0]
    assert model.m.njnt == len(mech.joints) - 1 and model.m.neq == 1 and model.m.nu == 0
    table = engine.audit(mech, times, settings)
    assert failures(table).empty, format_audit(failures(table))
    notes = table.set_index(["item", "quantity"])["actual"]
    assert notes[("mujoco", "clock body")] == "none"


def test_a_pre_roll_asked_of_a_free_run_is_refused_with_its_key(engine):
    scenario = parse(fourbar(time={"end": 0.2, "samples": 21}), "short.toml")
    with pytest.raises(ScenarioError, match="settings override: engines.mujoco.preroll_timeconsts: a torque-driven"):
        engine.settings_for(scenario, mechanism("free-fourbar"), {"preroll_timeconsts": 5.0})


@pytest.mark.parametrize("name", ["spinning-crank", "motored-slider-crank", "cut-pin"])
def test_the_audit_reads_each_torque_law_back(engine, name):
    """Each law's joint (the tendon's Jacobian row) matches, its parameters
    are as set; a changed gain in the compiled model makes its applied
    torque differ, and a tendon over other joints its joint."""
    mech = law_at_the_cut_pin() if name == "cut-pin" else mechanism(name)
    times = np.linspace(0.0, 0.2, 21)
    model = built(engine, mech, times)
    table = audit(expected_model(mech), Reader(model).readings())
    assert failures(table).empty, format_audit(failures(table))
    law = mech.torque_drives[0]
    rows = table[table["item"] == f"torque law {law.name}"].set_index("quantity")["verdict"]
    assert rows.to_dict() == {"joint": "match", "torque": "as set", "amplitude": "as set", "frequency": "as set",
                              "phase": "as set"}
    act = model.law_actuators[0]
    model.m.actuator_gainprm[act, 0] = 1.5
    bad = failures(audit(expected_model(mech), Reader(model).readings()))
    assert set(zip(bad["item"], bad["quantity"])) == {(f"torque law {law.name}", quantity) for quantity in
                                                     ("torque", "amplitude", "frequency", "phase")}, format_audit(bad)
    model.m.actuator_gainprm[act, 0] = 1.0
    tendon = model.m.actuator_trnid[act, 0]
    model.m.wrap_prm[model.m.tendon_adr[tendon]] *= 2.0
    bad = failures(audit(expected_model(mech), Reader(model).readings()))
    assert (f"torque law {law.name}", "joint") in set(zip(bad["item"], bad["quantity"])), format_audit(bad)


@pytest.mark.parametrize("name", ["motored-slider-crank", "cut-pin"])
def test_inverse_mode_follows_the_integrated_motion(engine, name):
    """Inverse dynamics along the reference's integrated motion (no time
    integration in MuJoCo) reproduces its reactions and keeps the torque
    law's column: frames and signs of a law on a tree hinge and on the cut
    pin, independent of the step."""
    mech = law_at_the_cut_pin() if name == "cut-pin" else mechanism(name)
    times = np.linspace(0.0, 0.3, 31)
    reference = raw_dynamics(mech, times).frame
    frame = engine.run(mech, times, {**engine.default_settings(mech, times), "mode": "inverse"}).frame
    for column in mech.reaction_columns():
        peak = float(np.abs(reference[column]).max())
        assert float(np.abs(frame[column] - reference[column]).max()) <= INVERSE_AGREEMENT * peak, column
    for body in mech.bodies:
        assert float(np.abs(frame[f"{body.name}.theta"] - reference[f"{body.name}.theta"]).max()) <= INVERSE_AGREEMENT


def test_a_torque_law_at_the_loop_closing_pin(engine):
    """Forward: within the default bounds of the reference (measured worst:
    0.0059 of the bound, O4.Fx, over 0.5 s), its column the law."""
    mech, times = law_at_the_cut_pin(), np.linspace(0.0, 0.5, 51)
    frame = engine.run(mech, times, engine.default_settings(mech, times)).frame
    assert failing_ratios(mech, times, frame) == {}
    np.testing.assert_allclose(frame["rocker.T"], mech.torque_drives[0].value(times), rtol=1e-12, atol=1e-12)


def test_half_driven_five_bar_keeps_its_prescribed_crank(engine):
    """One crank prescribed (its clock and drive equality stay), the other
    free: within the default bounds of the reference (measured worst: 0.031
    of the bound, drive.T at t = 0, the soft drive equality's start), the
    prescribed crank on its law (measured: 4e-9 rad)."""
    mech, times = mechanism("half-driven-five-bar"), np.linspace(0.0, 0.5, 51)
    settings = engine.default_settings(mech, times)
    raw = engine.run(mech, times, settings)
    assert failing_ratios(mech, times, raw.frame) == {}
    model = Model(mech, times, settings)
    assert len(model.clocks) == 1 and model.m.neq == len(model.loop_eqs) + 1
    assert raw.info.facts["drive_error_max"] <= 1e-6


def test_andrews_squeezer_under_its_motor(engine):
    """0–30 ms from the Test Set's consistent initial state at MuJoCo's
    default setting: within the default bounds of the forward-dynamics
    reference (measured worst: 0.043 of the bound, H.Fx at t = 0, where the
    soft loop closures start at MuJoCo's impedance 0.9999 and not yet at
    their equilibrium; every force within 8.1e-5 of its peak from the next
    sample on), and
    the seven coordinates at 30 ms within the default angle bound of the
    published solution (measured: at most 2.2e-5 rad, on Θ; 9.9e-6 relative,
    on γ)."""
    mech, times = mechanism("motored-andrews"), np.linspace(0.0, A.T1, 101)
    frame = engine.run(mech, times, engine.default_settings(mech, times)).frame
    assert failing_ratios(mech, times, frame) == {}
    q = A.test_set_coordinates(frame)[:, -1]
    assert float(np.abs(q - A.Q1).max()) <= ANGLE, np.abs(q - A.Q1)
