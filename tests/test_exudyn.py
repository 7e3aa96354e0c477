"""Exudyn adapter: the built model holds only the scene's effects, each
setting that spoils forces while the kinematics look perfect shows its
effect (or is proven in effect), signs, the index-3 variant, a user-style
150 rad/s damped scene and the documented high-accuracy setting; torque
laws and free motion beyond the contract (a half-driven five-bar, Andrews'
squeezer under its motor, the audit of torque laws and free joints)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

import andrews as A
import dynamic_mechanisms as dm
from mechval.testing.contract import ANGLE, AdapterContract, dynamic_errors
from conftest import builtin_reference, builtin_scenario, engine_or_skip
from mechval.records.audit import audit, expected_model, failures
from mechval.judging.compare import compare
from mechval.testing import assert_within_tolerance, discrepancy_table
from mechval.model.drive import DriveLaw
from mechval.reference.dynamics import raw_dynamics
from mechval.reference.linkages import build_mechanism
from mechval.adapter import Unrepresentable
from mechval.model.mechanism import GROUND, MOTION_QUANTITIES, Body, Drive, InitialValue, Joint, Mechanism
from mechval.reference.adapter import raw_reference
from mechval.scenarios import parse
from mechval.testing.scenes import fourbar, slider_crank

from mechval.harness.simulate import simulate

try:
    import exudyn
except ImportError as exc:
    # Each test skips, saying why (a module-level importorskip would report
    # the module skipped even where -m "not engine" deselects all of it).
    pytestmark = [pytest.mark.engine, pytest.mark.skip(reason=f"exudyn cannot be imported ({exc})")]
else:
    pytestmark = pytest.mark.engine     # every test here runs Exudyn
    from mechval.engines.exudyn.audit import Reader
    from mechval.engines.exudyn.model import build_model, simulation_settings, solve, torque_law_load_names
    from mechval.engines.exudyn.run import prepare

#: fourbar-seed at the default setting: every signal within this fraction
#: of its peak (measured 1.7e-5 at the derived step 7.7e-4 s).
SEED_DEFAULT_ERROR = 2e-5
#: The documented high-accuracy setting (timestep 1e-4 s) on fourbar-seed:
#: every relative error and every angle error (rad) below this (measured
#: 2.9e-7 relative, 5.3e-8 rad).
HIGH_ACCURACY = {"timestep": 1e-4}
HIGH_ACCURACY_ERROR = 1e-6


@pytest.fixture(scope="module")
def adapter():
    return engine_or_skip("exudyn")


def errors(adapter, scenario, overrides=None, reference=None):
    """Discrepancy records of the Exudyn adapter on the scenario."""
    reference = reference or simulate(scenario, "reference")
    return compare(reference, simulate(scenario, adapter, overrides), scenario.tolerance_for("exudyn"),
                   scenario=scenario.name)


def max_relative(records, classes=("force", "torque")) -> float:
    return float(records[records["class"].isin(classes)]["relative_error"].max())


def short_seed(**overrides):
    """fourbar-seed's mechanism over its first second (cheap trap tests)."""
    return parse(fourbar(time={"end": 1.0, "samples": 101}, **overrides), "test")


def item_types(mbs) -> list[str]:
    return [mbs.GetObject(i)["objectType"] for i in range(mbs.systemData.NumberOfObjects())]


def built(scenario):
    return build_model(build_mechanism(scenario), 0.0)


# --- only the scene's effects ------------------------------------------------

def test_model_holds_only_the_scene_effects():
    bare = built(parse(slider_crank(effects=None), "test")).mbs
    assert bare.systemData.NumberOfLoads() == 0
    assert sorted(item_types(bare)) == sorted(
        ["Ground"] + ["RigidBody2D"] * 3 + ["JointRevolute2D"] * 3 + ["JointPrismatic2D", "ConnectorCoordinate"])

    scene = parse(slider_crank(effects={"gravity": [1.0, -9.81],
                                        "damping": {"O2": 0.1, "A": 0.0, "B": 0.2, "guide": 3.0}}), "test")
    full = built(scene).mbs
    loads = [full.GetLoad(i) for i in range(full.systemData.NumberOfLoads())]
    assert [load["loadType"] for load in loads] == ["MassProportional"] * 3
    assert all(list(load["loadVector"]) == [1.0, -9.81, 0.0] for load in loads)
    dampers = [full.GetObject(i) for i in range(full.systemData.NumberOfObjects())
               if full.GetObject(i)["objectType"] == "ConnectorCoordinateSpringDamper"]
    assert sorted(d["damping"] for d in dampers) == [0.1, 0.2, 3.0]
    assert all(d["stiffness"] == 0.0 for d in dampers)
    assert len(item_types(full)) == len(item_types(bare)) + 3


def test_no_files_and_no_console_output(adapter, tmp_path, monkeypatch, capfd):
    monkeypatch.chdir(tmp_path)
    simulate(short_seed(), adapter)
    assert list(tmp_path.iterdir()) == []
    out, err = capfd.readouterr()
    assert out == "" and err == ""


# --- the traps --------------------------------------------------------------

def test_trap_exudyn_initial_accelerations_ignore_the_drive(adapter):
    """Exudyn's own initial-acceleration solve ignores φ''; with undamped
    trapezoidal index-2 the wrong start never decays (measured 16 %)."""
    scene = short_seed()
    reference = simulate(scene, "reference")
    assert max_relative(errors(adapter, scene, reference=reference)) < 1e-5
    assert max_relative(errors(adapter, scene, {"compute_initial_accelerations": True}, reference)) > 1e-2


def test_trap_modified_newton_with_default_tolerances(adapter):
    """Modified Newton at Exudyn's default tolerances caps force accuracy
    (measured 3.8e-5 at dt 1e-4, where full Newton at the scaled tolerance
    gives 8e-9)."""
    scene = short_seed()
    reference = simulate(scene, "reference")
    exudyn_defaults = {"timestep": 1e-4, "full_newton": False,
                       "newton_relative_tolerance": 1e-8, "newton_absolute_tolerance": 1e-10}
    assert max_relative(errors(adapter, scene, {"timestep": 1e-4}, reference)) < 1e-7
    assert max_relative(errors(adapter, scene, exudyn_defaults, reference)) > 1e-5


def test_trap_fixed_absolute_newton_tolerance_aborts_at_round_off(adapter):
    """When the relative goal is out of reach, a fixed absolute tolerance of
    1e-14 N never converges (the residual is a force at round-off), while
    the tolerance scaled by the force estimate ends Newton there."""
    scene = short_seed(mass={"crank": 12.5e3, "coupler": 25.0e3, "rocker": 25.0e3})
    unreachable = {"newton_relative_tolerance": 1e-16}
    with pytest.raises(exudyn.SolverError):
        simulate(scene, adapter, {**unreachable, "newton_absolute_tolerance": 1e-14})
    records = errors(adapter, scene, unreachable)
    assert_within_tolerance(records)


def test_trap_spectral_radius_one_makes_index3_forces_zig_zag(adapter):
    """ρ∞ = 1 (no numerical damping) leaves the index-3 multipliers
    oscillating step to step; the adapter refuses it."""
    mechanism = build_mechanism(builtin_scenario("fourbar-seed"))
    settings = adapter.default_settings(mechanism, builtin_scenario("fourbar-seed").time.t)
    turns = {}
    for rho in (0.9, 1.0):
        model = build_model(mechanism, 0.0)
        solve(model, simulation_settings({**settings, "spectral_radius": rho}, 0.5, 1e-3), "index3")
        torque = model.mbs.GetSensorStoredData(model.drive_sensor)[-101:, 1]
        turns[rho] = int(np.sum(np.diff(np.sign(np.diff(torque))) != 0))
    assert turns == {0.9: 0, 1.0: 99}
    with pytest.raises(ValueError, match="spectral_radius"):
        simulate(short_seed(), adapter, {"solver": "index3", "spectral_radius": 1.0})


def test_fixed_steps_recorded_every_step(adapter):
    """adaptive_step off and sensor write period 0: one stored row per fixed
    step (Exudyn's default period, 0.01 s, would keep one row in 13 here)."""
    scene = short_seed()
    mechanism = build_mechanism(scene)
    settings = adapter.default_settings(mechanism, scene.time.t)
    simulation = simulation_settings(settings, 1.0, settings["timestep"])
    assert not simulation.timeIntegration.adaptiveStep
    assert simulation.solution.sensors.writePeriod == 0.0
    model = build_model(mechanism, 0.0)
    solve(model, simulation, "index2")
    t = model.mbs.GetSensorStoredData(model.drive_sensor)[:, 0]
    assert np.allclose(np.diff(t), settings["timestep"], rtol=1e-9)
    assert len(t) == round(1.0 / settings["timestep"]) + 1


# --- signs, variants, user scenes, accuracy --------------------------------

@pytest.mark.parametrize("gravity", [[0.0, -9.81], [0.0, 9.81]])
def test_gravity_and_torque_signs(adapter, gravity):
    """A crank turned slowly against gravity: T12 is the holding torque, so
    it follows the reference's sign and flips with gravity."""
    scene = parse(fourbar(drive={"omega0": 0.2, "alpha": 0.0}, effects={"gravity": gravity},
                          time={"end": 2.0, "samples": 201}), "test")
    reference = simulate(scene, "reference")
    result = simulate(scene, adapter)
    for signal in ("T12", "F12y"):
        big = np.abs(reference[signal]) > 0.1 * np.abs(reference[signal]).max()
        assert np.all(np.sign(result[signal][big]) == np.sign(reference[signal][big])), signal
    # Holding the linkage up, the ground pushes the crank against gravity.
    assert np.sign(np.mean(result["F12y"])) == -np.sign(gravity[1])
    assert max_relative(compare(reference, result, scene.tolerance_for("exudyn"))) < 1e-4


def test_index3_variant(adapter):
    """Generalised-α index-3: exact closure, and the pre-roll puts its force
    start-up transient (3e-4 relative, ~100 steps at ρ = 0.9) before t = 0,
    so no sample is dropped."""
    scene = builtin_scenario("fourbar-seed")
    result = simulate(scene, adapter, {"solver": "index3"})
    records = compare(builtin_reference("fourbar-seed"), result, scene.tolerance_for("exudyn"))
    assert_within_tolerance(records)
    assert max_relative(records) < 2e-4
    assert result.info.facts["closure_gap_max"] < 1e-12
    assert not result.missing
    reference = builtin_reference("fourbar-seed")
    early = reference.t <= 0.1
    worst = max(np.abs(result[s][early] - reference[s][early]).max() / np.abs(reference[s]).max()
                for s in ("F12x", "F12y", "F32x", "F32y", "F43x", "F43y", "F14x", "F14y", "T12"))
    assert worst < 1e-5


@pytest.mark.parametrize("data", [
    slider_crank(geometry={"offset": 0.03, "branch": "left"}, drive={"omega0": 150.0, "alpha": 20.0},
                 effects={"damping": {"O2": 0.02, "A": 0.01, "B": 0.01, "guide": 5.0}},
                 time={"end": 0.2, "samples": 431}),
    fourbar(drive={"omega0": 150.0, "alpha": 0.0},
            effects={"damping": {"O2": 0.5, "A": 0.2, "B": 0.3, "O4": 0.4}},
            time={"end": 0.2, "samples": 431}),
], ids=["slider-crank", "fourbar"])
def test_user_scene_150_rad_per_s_damped(adapter, data):
    """A crank at 150 rad/s sampled every 4°, damping at every pin: default
    settings meet the default tolerances."""
    scene = parse(data, "test")
    records = errors(adapter, scene)
    assert_within_tolerance(records)


def test_fourbar_seed_default_accuracy(adapter):
    records = errors(adapter, builtin_scenario("fourbar-seed"), reference=builtin_reference("fourbar-seed"))
    relative = records[~records["class"].isin(["angle"])]["relative_error"]
    assert relative.max() < SEED_DEFAULT_ERROR, discrepancy_table(records)


def test_high_accuracy_setting(adapter):
    records = errors(adapter, builtin_scenario("fourbar-seed"), HIGH_ACCURACY, builtin_reference("fourbar-seed"))
    assert records["relative_error"].max() < HIGH_ACCURACY_ERROR, discrepancy_table(records)
    angles = records[records["class"] == "angle"]["max_error"]
    assert angles.max() < HIGH_ACCURACY_ERROR, discrepancy_table(records)


# --- a prismatic joint between two moving bodies ---------------------------

def inverted_slider_crank(damping: float) -> Mechanism:
    """Inverted slider-crank (Norton §4.6 inversion #3, built here only as a
    `Mechanism`): crank O2→A, a block pinned at A slides along the rocker,
    which pivots at O4 = (d, 0). The rocker angle is that of A − O4, so
    θ4 = π + atan2(−r_y, −r_x) (r_x < 0 throughout since a < d),
    ω4 = (r × v)/|r|², α4 = (r × a)/|r|² − 2 (r·v)(r × v)/|r|⁴."""
    a, d = 0.1, 0.3
    law = DriveLaw(phi0=0.3, omega0=5.0, alpha=2.0)

    def motion(t):
        t = np.asarray(t, dtype=float)
        th2, w2, al2 = law.angle(t), law.rate(t), law.acceleration(t)
        c, s, zero = np.cos(th2), np.sin(th2), np.zeros_like(t)
        ax_, ay_ = a * c, a * s
        vx, vy = -a * w2 * s, a * w2 * c
        accx, accy = -a * al2 * s - a * w2**2 * c, a * al2 * c - a * w2**2 * s
        rx, ry = ax_ - d, ay_
        r2 = rx * rx + ry * ry
        th4 = np.pi + np.arctan2(-ry, -rx)
        cross_v = rx * vy - ry * vx
        w4 = cross_v / r2
        al4 = (rx * accy - ry * accx) / r2 - 2 * (rx * vx + ry * vy) * cross_v / r2**2
        frames = {"crank": (zero, zero, th2, zero, zero, w2, zero, zero, al2),
                  "block": (ax_, ay_, th4, vx, vy, w4, accx, accy, al4),
                  "rocker": (zero + d, zero, th4, zero, zero, w4, zero, zero, al4)}
        return pd.DataFrame({"t": t} | {f"{body}.{q}": v for body, values in frames.items()
                                        for q, v in zip(MOTION_QUANTITIES, values)})

    return Mechanism(
        name="inverted-slider-crank", kind="inverted_slider_crank",
        bodies=(Body("crank", 1.0, (0.05, 0.0), 1e-3), Body("block", 0.5, (0.0, 0.0), 1e-4),
                Body("rocker", 2.0, (0.2, 0.0), 0.03)),
        joints=(Joint("O2", "revolute", GROUND, "crank", (0.0, 0.0), (0.0, 0.0)),
                Joint("A", "revolute", "block", "crank", (0.0, 0.0), (a, 0.0), damping=0.2 * damping),
                Joint("slide", "prismatic", "rocker", "block", (0.0, 0.0), (0.0, 0.0), damping=damping),
                Joint("O4", "revolute", GROUND, "rocker", (d, 0.0), (0.0, 0.0))),
        drive=Drive("O2", law), gravity=(0.0, -9.81), motion=motion, signal_map={})


@pytest.mark.parametrize("damping", [0.0, 3.0])
def test_prismatic_joint_between_moving_bodies(adapter, damping):
    """The adapter builds any single-loop planar mechanism: here the guide
    turns with the rocker (and is damped along itself)."""
    mechanism = inverted_slider_crank(damping)
    times = np.linspace(0.0, 1.0, 201)
    result = adapter.run(mechanism, times, adapter.default_settings(mechanism, times))
    reference = raw_reference(mechanism, times)
    for column in mechanism.reaction_columns():
        # slide.M (derived from the block's balance) against the peak of its
        # class, as `compare` does (T12 and M43 are torques): undamped, its
        # own peak is 2.5e-3 N·m, and its error 2.7e-6 N·m.
        peak = np.abs(reference[["drive.T", "slide.M"] if column == "slide.M" else column]).to_numpy().max()
        error = np.abs(result.frame[column] - reference[column]).max() / peak
        assert error < 1e-4, column
    for column in mechanism.motion_columns():
        error = np.abs(result.frame[column] - reference[column]).max()
        quantity = column.split(".")[1]
        if quantity in ("x", "y", "theta"):
            assert error < 1e-5, column       # m, rad (index-2 drift: 1.8e-6)
        else:                                 # relative to the largest of its kind (some are 0)
            peak = max(np.abs(reference[f"{b.name}.{quantity}"]).max() for b in mechanism.bodies)
            assert error < 1e-4 * peak, column


class TestContract(AdapterContract):
    engine = "exudyn"


# --- torque-driven and free motion (beyond mechval.testing.contract) -----------------

def dynamic_case(name: str, end: float, samples: int = 101):
    """A case of tests/dynamic_mechanisms.py with its assembly pose, and its
    output instants from 0 to `end`."""
    case = dm.CASES[name]()
    return dataclasses.replace(case.mech, assembly_pose=case.pose), np.linspace(0.0, end, samples)


def test_a_half_driven_five_bar_keeps_its_drive_and_integrates_the_rest(adapter):
    """Its first crank stays prescribed (one coordinate constraint, tracked
    to rounding), the second is free: every column within the default
    bounds of the forward-dynamics reference (measured ≤ 0.011 of them)."""
    mech, times = dynamic_case("half-driven-five-bar", 1.0)
    raw = adapter.run(mech, times, adapter.default_settings(mech, times))
    ratios = dynamic_errors(mech, raw_dynamics(mech, times).frame, raw.frame)
    assert {column: ratio for column, ratio in ratios.items() if not ratio <= 1.0} == {}
    assert raw.info.facts["drive_error_max"] < 1e-12


@pytest.fixture(scope="module")
def andrews_run(adapter):
    mech, times = dynamic_case("motored-andrews", A.T1)
    return mech, times, adapter.run(mech, times, adapter.default_settings(mech, times)).frame


def test_andrews_squeezer_under_its_motor_follows_the_reference(andrews_run):
    """Andrews' squeezer, 0 ≤ t ≤ 0.03 s from the Test Set's initial state:
    every column within the default bounds of the forward-dynamics
    reference (measured ≤ 0.016 of them, K1.theta)."""
    mech, times, frame = andrews_run
    ratios = dynamic_errors(mech, raw_dynamics(mech, times).frame, frame)
    assert {column: ratio for column, ratio in ratios.items() if not ratio <= 1.0} == {}


def test_andrews_squeezer_under_its_motor_meets_the_published_solution(andrews_run):
    """The seven coordinates at t = 0.03 s against the Test Set's published
    solution (tests/andrews.py, PSIDE at 1e-14), within the default angle
    tolerance (rad; measured 1.6e-5 on β, the crank that turns 15.9 rad)."""
    _, _, frame = andrews_run
    q = A.test_set_coordinates(frame.iloc[[-1]])[:, 0]
    assert float(np.max(np.abs(q - A.Q1))) <= ANGLE


def test_a_torque_law_is_two_opposite_loads_and_a_free_joint_no_constraint():
    """The model of the motored slider-crank: no coordinate constraint (the
    crank is free), the motor two LoadTorqueVectors on the crank (+T) and
    nothing on the ground, evaluated at the solver's time."""
    mech, times = dynamic_case("motored-slider-crank", 1.0)
    mbs = build_model(mech, 0.0).mbs
    assert "ConnectorCoordinate" not in item_types(mbs)
    loads = [mbs.GetLoad(i) for i in range(mbs.systemData.NumberOfLoads())]
    motor = [load for load in loads if load["name"] in torque_law_load_names(mech.torque_drives[0]).values()]
    assert [load["loadType"] for load in motor] == ["TorqueVector"]     # O2 joins the crank to the ground
    law = mech.torque_drives[0]
    function = motor[0]["loadVectorUserFunction"]["function"]
    assert [function(mbs, t, 0)[2] for t in times] == pytest.approx(law.value(times), rel=1e-15, abs=1e-15)


def test_the_audit_reads_back_the_torque_law_and_the_free_joint(adapter):
    """The model of one mechanism read as another: a changed amplitude is
    the one torque-law row that differs, and the half-driven five-bar's
    drive, read as the free five-bar, is the prescribed motion of a joint
    that should have none (and a motor, a constraint, the scene does not
    ask for)."""
    mech, times = dynamic_case("motored-slider-crank", 1.0)
    settings = adapter.default_settings(mech, times)
    model, simulation, t0 = prepare(mech, times, settings)
    readings = Reader(mech, model, t0, times, settings, simulation).readings()
    assert failures(audit(expected_model(mech), readings)).empty
    louder = dataclasses.replace(mech.torque_drives[0], amplitude=0.6)
    table = audit(expected_model(dataclasses.replace(mech, torque_drives=(louder,))), readings)
    assert failures(table)[["item", "quantity"]].values.tolist() == [["torque law motor", "amplitude"]]

    half, times = dynamic_case("half-driven-five-bar", 1.0)
    half_settings = adapter.default_settings(half, times)
    model, simulation, t0 = prepare(half, times, half_settings)
    free = dynamic_case("free-five-bar", 1.0)[0]
    different = failures(audit(expected_model(free), Reader(free, model, t0, times, half_settings, simulation).readings()))
    assert different[["item", "quantity"]].values.tolist() == [["joint O1", "prescribed motion"],
                                                                ["scene", "motors other than the drive"],
                                                                ["scene", "other constraints"]]
    assert "ConnectorCoordinate" in different["actual"].iloc[0]


def test_without_its_own_initial_solve_the_first_reactions_are_missing(adapter):
    """A run with no pre-roll and Exudyn's initial-acceleration solve off:
    Exudyn reports zero reactions at the first instant, so they are missing
    with the reason (the torque law's column is known there); a pre-roll is
    refused, as there is no motion before the first instant."""
    mech, times = dynamic_case("spinning-crank", 0.2, 21)
    settings = adapter.default_settings(mech, times)
    assert settings["compute_initial_accelerations"] and settings["pre_roll_steps"] == 0
    raw = adapter.run(mech, times, {**settings, "compute_initial_accelerations": False})
    assert np.isnan(raw.frame["O.Fx"][0]) and np.isfinite(raw.frame["O.Fx"][1:]).all()
    assert "zero reactions" in raw.missing["O.Fx"] and "drive.T" not in raw.missing
    with pytest.raises(ValueError, match="pre_roll_steps must be 0"):
        adapter.run(mech, times, {**settings, "pre_roll_steps": 1})


def test_a_torque_law_is_applied_at_the_step_s_own_time(adapter):
    """The crank under its torque law against the closed form: halving the
    step quarters the error (measured 2.93e-5 → 7.32e-6 rad, ratio 4.0), as
    the second-order solver gives when the load is evaluated at the time of
    the step it acts in; a torque lagging by a step would be first order
    (ratio 2)."""
    mech, times = dynamic_case("spinning-crank", 1.0)
    settings = adapter.default_settings(mech, times)
    theta, _ = dm.spinning_exact(times)
    error = [float(np.max(np.abs(adapter.run(mech, times, {**settings, "timestep": dt}).frame["crank.theta"] - theta)))
             for dt in (1e-3, 5e-4)]
    assert error[0] / error[1] > 3.8


def test_initial_values_the_reference_refuses_are_refused_with_its_key(adapter):
    """Too many initial values for the four-bar's one degree of freedom: the
    adapter says what the forward-dynamics reference says, naming the key,
    before any Exudyn model exists."""
    mech, times = dynamic_case("free-fourbar", 0.1, 11)
    bad = dataclasses.replace(mech, initial_values=(InitialValue("A", 0.3), InitialValue("O2", 0.3)))
    with pytest.raises(Unrepresentable) as refused:
        adapter.default_settings(bad, times)
    assert refused.value.key == "initial" and "too many initial values" in refused.value.reason


@pytest.mark.parametrize("solver", ["index2", "index3"])
def test_a_free_run_takes_the_steps_it_declares(adapter, solver):
    """Run size (`planned_steps`, checked before any run): a torque-driven
    run has no pre-roll, with either solver (index-3's transient pre-roll is
    for prescribed motion), and takes exactly the declared steps."""
    mech, times = dynamic_case("spinning-crank", 0.2, 21)
    settings = {**adapter.default_settings(mech, times), "solver": solver}
    per_interval, pre_roll = adapter.planned_steps(times, settings)
    raw = adapter.run(mech, times, settings)
    assert pre_roll == 0 and raw.info.facts["pre_roll_start"] == times[0]
    assert raw.info.steps == per_interval * (len(times) - 1)
