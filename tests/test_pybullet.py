"""PyBullet adapter: every PyBullet default that adds an effect is off (read
back from the built model, or shown by re-arming it on the same model), the
leaf layout beats the naive tree, signs, a user-style 150 rad/s scene, the
documented high-accuracy setting, and torque-driven and free runs beyond
the contract's (audit rows, a half-driven five-bar, torque laws at a leaf
and at a loop-closing joint, Andrews' squeezer under its motor)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import andrews as A
import dynamic_mechanisms as dm
from mechval.testing.contract import MOVING_SLIDE, AdapterContract, dynamic_errors
from conftest import engine_or_skip
from mechval.adapter import Unrepresentable
from mechval.records.audit import failures, format_audit, torque_law_item
from mechval.reference.dynamics import raw_dynamics
from mechval.model.mechanism import InitialValue, TorqueLaw
from mechval.reference.planar.solver import default_pose
from mechval.judging.compare import compare
from mechval.testing import assert_within_tolerance
from mechval.reference.linkages import build_mechanism
from mechval.scenarios import parse
from mechval.records.signals import canonical_signals
from mechval.testing.scenes import fourbar, slider_crank
from test_linkages_more import VARIANTS as SLIDE_VARIANTS

from mechval.harness.simulate import simulate

try:
    import pybullet as p
except ImportError as exc:
    # Each test skips, saying why (a module-level importorskip would report
    # the module skipped even where -m "not engine" deselects all of it).
    pytestmark = [pytest.mark.engine, pytest.mark.skip(reason=f"pybullet cannot be imported ({exc})")]
else:
    pytestmark = pytest.mark.engine     # every test here runs PyBullet
    from mechval.engines.pybullet.run import run_model
    from mechval.engines.pybullet.model import NO_CAP, build

#: Forces and torque of the short seed at the default setting (measured
#: 3.9e-5); a re-armed default must make them clearly worse than this.
SEED_DEFAULT_ERROR = 1e-4
#: The documented high-accuracy setting (fourbar-seed, timestep 1e-5 s):
#: every force and T12 within HIGH_ACCURACY_ERROR of its peak (measured
#: ≤ 1.9e-6, 38 s wall for the 6 s run) except F14, the rocker sensor, which
#: converges only as O(dt): its centripetal term uses the mid-step speed
#: ω(t − dt/2) (substituting that speed into m·r·ω² leaves an O(dt²)
#: residual). Measured F14x 1.9e-5 at 1e-5 s. A smaller step does not get
#: there: at 4e-6 s (78 s wall) every force is worse, 1.1e-5–1.8e-5 and
#: F14x 2.5e-5 — an error floor that rises as dt shrinks (impulse/dt).
HIGH_ACCURACY = {"timestep": 1e-5}
HIGH_ACCURACY_ERROR = 1e-5
F14_AT_HIGH_ACCURACY = 1.9e-5


@pytest.fixture(scope="module")
def adapter():
    return engine_or_skip("pybullet")


def short_seed(**overrides):
    """fourbar-seed's mechanism over its first second (cheap effect tests)."""
    return parse(fourbar(time={"end": 1.0, "samples": 101}, **overrides), "test")


def records(adapter, scenario, overrides=None, prepare=None):
    """Discrepancy records against the reference; `prepare(model)` may
    re-arm a PyBullet default on the built model before stepping."""
    mechanism = build_mechanism(scenario)
    settings = adapter.settings_for(scenario, mechanism, overrides)
    raw = run_model(mechanism, scenario.time.t, settings, prepare)
    result = canonical_signals(mechanism, raw.frame, "pybullet", missing=raw.missing, info=raw.info)
    return compare(simulate(scenario, "reference"), result, scenario.tolerance, scenario=scenario.name)


def force_error(recs) -> float:
    return float(recs[recs["class"].isin(["force", "torque"])]["relative_error"].max())


@pytest.fixture(scope="module")
def seed_error(adapter):
    error = force_error(records(adapter, short_seed()))
    assert error < SEED_DEFAULT_ERROR
    return error


@pytest.fixture
def coasting():
    """The short seed's model with its loop constraints removed and no
    gravity: each link must keep its speed exactly unless a default acts."""
    scenario = short_seed(effects=None)
    mechanism = build_mechanism(scenario)
    model = build(mechanism, 1e-3, "split", 0.0)
    for constraint in model.constraints.values():
        p.removeConstraint(constraint.cid, physicsClientId=model.client)
    yield model
    p.disconnect(model.client)


def step(model, n=20):
    for _ in range(n):
        p.stepSimulation(physicsClientId=model.client)


def test_default_velocity_motors_are_released(coasting):
    rocker = coasting.bodies["rocker"]
    p.resetJointState(rocker.uid, rocker.link, 0.3, 2.0, physicsClientId=coasting.client)
    step(coasting)
    assert p.getJointState(rocker.uid, rocker.link, physicsClientId=coasting.client)[1] == pytest.approx(2.0, abs=1e-12)


def test_no_linear_or_angular_damping(coasting):
    coupler = coasting.bodies["coupler"]
    p.resetBaseVelocity(coupler.uid, (0.5, -0.2, 0.0), (0.0, 0.0, 3.0), physicsClientId=coasting.client)
    step(coasting)
    linear, angular = p.getBaseVelocity(coupler.uid, physicsClientId=coasting.client)
    np.testing.assert_allclose(linear, (0.5, -0.2, 0.0), atol=1e-12)
    np.testing.assert_allclose(angular, (0.0, 0.0, 3.0), atol=1e-12)


def test_no_joint_speed_clamp(coasting):
    # PyBullet clamps joint speeds at 100 rad/s by default.
    rocker = coasting.bodies["rocker"]
    p.resetJointState(rocker.uid, rocker.link, 0.0, 150.0, physicsClientId=coasting.client)
    step(coasting)
    speed = p.getJointState(rocker.uid, rocker.link, physicsClientId=coasting.client)[1]
    assert speed == pytest.approx(150.0, abs=1e-9)


def test_shapeless_links_get_their_inertia_and_no_contacts(coasting):
    mechanism = build_mechanism(short_seed())
    for name, handle in coasting.bodies.items():
        body = mechanism.body(name)
        info = p.getDynamicsInfo(handle.uid, handle.link, physicsClientId=coasting.client)
        assert info[0] == pytest.approx(body.mass)
        assert info[2] == pytest.approx((body.izz,) * 3)
        assert p.getCollisionShapeData(handle.uid, handle.link, physicsClientId=coasting.client) == ()


def test_point_to_point_cap_lifted(adapter, seed_error):
    scenario = short_seed()
    model = build(build_mechanism(scenario), 1e-3, "split", 0.0)
    try:
        caps = [p.getConstraintInfo(c.cid, physicsClientId=model.client)[10] for c in model.constraints.values()]
    finally:
        p.disconnect(model.client)
    assert caps and all(cap == NO_CAP for cap in caps)

    def cap(model):
        for c in model.constraints.values():
            p.changeConstraint(c.cid, maxForce=50.0, physicsClientId=model.client)
    assert force_error(records(adapter, scenario, prepare=cap)) > 100 * seed_error


def test_no_sub_steps_and_fixed_step(adapter, seed_error):
    scenario = short_seed()
    model = build(build_mechanism(scenario), 1e-3, "split", 0.0)
    try:
        params = p.getPhysicsEngineParameters(physicsClientId=model.client)
    finally:
        p.disconnect(model.client)
    assert params["numSubSteps"] == 0 and params["fixedTimeStep"] == 1e-3
    # Sub-steps corrupt the reported torque and constraint forces.
    rearm = lambda m: p.setPhysicsEngineParameter(numSubSteps=4, physicsClientId=m.client)  # noqa: E731
    assert force_error(records(adapter, scenario, prepare=rearm)) > 100 * seed_error


def test_solver_does_not_stop_early(adapter, seed_error):
    # Dantzig ignores the residual threshold; PGS (its fallback) honours it:
    # under PGS our threshold 0 keeps the error near the Dantzig figure,
    # PyBullet's default 1e-7 makes it ~1000× worse (measured 5.9e-2).
    def pgs(threshold=None):
        extra = {} if threshold is None else {"solverResidualThreshold": threshold}
        return lambda m: p.setPhysicsEngineParameter(constraintSolverType=p.CONSTRAINT_SOLVER_LCP_SI,
                                                     physicsClientId=m.client, **extra)
    ours = force_error(records(adapter, short_seed(), prepare=pgs()))
    default = force_error(records(adapter, short_seed(), prepare=pgs(1e-7)))
    assert ours < 2 * seed_error
    assert default > 100 * ours


def test_dantzig_is_at_least_as_exact_as_pgs(adapter, seed_error):
    rearm = lambda m: p.setPhysicsEngineParameter(constraintSolverType=p.CONSTRAINT_SOLVER_LCP_SI,  # noqa: E731
                                                  physicsClientId=m.client)
    assert seed_error <= force_error(records(adapter, short_seed(), prepare=rearm))


def test_no_cfm_and_full_error_reduction(adapter, seed_error):
    # Measured: erp 0.2 → 1.4e-3, globalCFM 1e-4 → 0.8 on the short seed.
    for rearm in ({"erp": 0.2}, {"globalCFM": 1e-4}):
        prepare = lambda m, kw=rearm: p.setPhysicsEngineParameter(physicsClientId=m.client, **kw)  # noqa: E731
        assert force_error(records(adapter, short_seed(), prepare=prepare)) > 10 * seed_error, rearm


def test_client_disconnected_even_on_error(adapter):
    scenario = short_seed()
    mechanism = build_mechanism(scenario)
    clients = []

    def fail(model):
        clients.append(model.client)
        raise RuntimeError("boom")
    with pytest.raises(RuntimeError, match="boom"):
        run_model(mechanism, scenario.time.t, adapter.settings_for(scenario, mechanism), fail)
    assert not p.isConnected(physicsClientId=clients[0])


def test_naive_tree_layout_breaks_the_crank_sensor(adapter, seed_error):
    """In one spanning tree the crank carries the coupler, and PyBullet's
    sensor at O2 is then off by tens of percent (measured 54 % on F12x)."""
    naive = records(adapter, short_seed(), {"layout": "tree"})
    f12 = naive[naive["signal"].isin(["F12x", "F12y"])]["relative_error"].max()
    assert f12 > 0.1 > 1000 * seed_error


def test_gravity_and_torque_signs(adapter):
    """A slider-crank held still at 1 rad under gravity −y, then +y: the
    static T12 and pin forces equal the reference's (signs included) and
    flip with gravity."""
    held = dict(drive={"phi0": 1.0, "omega0": 0.0, "alpha": 0.0}, time={"end": 0.1, "samples": 11})
    results = {}
    for g in (-9.81, 9.81):
        scenario = parse(slider_crank(effects={"gravity": [0.0, g]}, **held), "test")
        result, reference = simulate(scenario, adapter), simulate(scenario, "reference")
        for name in ("T12", "F12y", "F32y", "F43y", "F14y"):
            np.testing.assert_allclose(result[name], reference[name], rtol=1e-6, atol=1e-9, err_msg=name)
        results[g] = result
    down, up = results[-9.81], results[9.81]
    # Holding the crank against gravity at θ2 = 1 rad: the motor pushes the
    # crank counter-clockwise (T12 > 0) and the ground pin carries weight.
    assert down["T12"][0] > 0.1 and down["F12y"][0] > 0.0
    for name in ("T12", "F12y", "F32y", "F14y"):
        np.testing.assert_allclose(down[name], -up[name], rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("scene", [
    slider_crank(geometry={"offset": 0.03, "branch": "left"},
                 drive={"phi0": 0.5, "omega0": 150.0, "alpha": -20.0},
                 effects={"gravity": [1.0, -9.81], "damping": {"O2": 0.01, "A": 0.005, "B": 0.004, "guide": 1.5}},
                 time={"end": 0.3, "samples": 301}),
    fourbar(geometry={"ground": 0.5, "crank": 0.15, "coupler": 0.55, "rocker": 0.4, "branch": "crossed"},
            drive={"phi0": 0.3, "omega0": 150.0, "alpha": 10.0},
            effects={"gravity": [0.0, -9.81], "damping": {"O2": 0.1, "A": 0.05, "B": 0.08, "O4": 0.06}},
            time={"end": 0.2, "samples": 201}),
], ids=["slider-150", "fourbar-150"])
def test_user_scene_at_150_rad_s_meets_default_tolerances(adapter, scene):
    scenario = parse(scene, "test")
    recs = records(adapter, scenario)
    assert_within_tolerance(recs)


@pytest.mark.parametrize("name", ["whitworth-damped", "lever-mass-tables", "pump-left", "pump-right-damped",
                                  "pump-rotating-rod", "pump-no-offset"])
def test_user_slide_scene_meets_default_tolerances(adapter, name):
    """Slotted levers and inverted slider-cranks with an offset, a rod
    centre of mass away from A, dampers: PyBullet's slide sensor misreads a
    slide whose parent turns (engine finding), so the adapter derives F43
    and M43 from the sliding body's balance. Read from the sensor they were
    1.5–11× the default bound (pump-rotating-rod: N43 9.4×, M43 11×);
    derived, every signal meets the default tolerances."""
    recs = records(adapter, parse(SLIDE_VARIANTS[name], f"{name}.toml"))
    assert_within_tolerance(recs)


def test_slide_reaction_is_declared_derived(adapter):
    """The run info says which reactions are derived; with no pre-roll the
    first sample has no step before it, so the derived reaction is missing
    there, with the reason, and nowhere else."""
    scenario = parse(SLIDE_VARIANTS["pump-left"], "pump-left.toml")
    result = simulate(scenario, adapter, {"preroll_steps": 0})
    assert "sleeve: F and M derived from the balance of rod" in result.info.facts["derived_reactions"]
    for name in ("F43x", "F43y", "N43", "M43"):
        assert "preroll_steps = 0" in result.missing[name], name
        assert np.isnan(result[name][0]) and np.isfinite(result[name][1:]).all(), name
    assert "derived_reactions" not in simulate(short_seed(), adapter).info.facts


def late_seed():
    """fourbar-seed over 0.3 s from t = 5 s, where its forces peak (a cheap
    stand-in for the 6 s run: same state, same peaks)."""
    return parse(fourbar(drive={"phi0": 17.5, "omega0": 6.0, "alpha": 1.0}, time={"end": 0.3, "samples": 31}),
                 "test")


def high_accuracy_errors(adapter, scenario):
    recs = records(adapter, scenario, HIGH_ACCURACY)
    recs = recs[recs["class"].isin(["force", "torque"])].set_index("signal")["relative_error"]
    return recs.drop(["F14x", "F14y"]), recs[["F14x", "F14y"]]


@pytest.fixture(scope="module")
def late_seed_high_accuracy(adapter):
    return high_accuracy_errors(adapter, late_seed())


def test_high_accuracy_setting_short(late_seed_high_accuracy):
    others, _ = late_seed_high_accuracy
    assert others.max() <= HIGH_ACCURACY_ERROR, others


@pytest.mark.xfail(strict=True, reason=f"F14 (rocker sensor) converges as O(dt) into a rising floor: "
                                       f"{F14_AT_HIGH_ACCURACY:g} at 1e-5 s")
def test_high_accuracy_setting_short_f14(late_seed_high_accuracy):
    _, f14 = late_seed_high_accuracy
    assert f14.max() <= HIGH_ACCURACY_ERROR, f14


@pytest.mark.slow
def test_high_accuracy_setting_fourbar_seed(adapter):
    from conftest import builtin_scenario
    others, f14 = high_accuracy_errors(adapter, builtin_scenario("fourbar-seed"))
    assert others.max() <= HIGH_ACCURACY_ERROR, others
    assert f14.max() == pytest.approx(F14_AT_HIGH_ACCURACY, rel=0.2), f14


def test_scenario_table_overrides_settings(adapter):
    scenario = short_seed(engines={"pybullet": {"timestep": 5e-4, "layout": "tree"}})
    mechanism = build_mechanism(scenario)
    defaults = adapter.default_settings(mechanism, scenario.time.t)
    assert adapter.settings_for(scenario, mechanism) == {**defaults, "timestep": 5e-4, "layout": "tree"}


# -- torque-driven and free motion (what the contract's dynamic tests do not cover) --------------

#: The half-driven five-bar's start-up transient at its first sample (t0),
#: relative to each reaction's peak: the first step's loop forces, which
#: do not shrink with the step (docs/engines.md). Measured after the
#: start's rate correction (pybullet.run.steady_start): drive.T 7.6e-2,
#: A.Fx and O1.Fx 4.0e-2 at both the default step and a quarter of it
#: (before it: drive.T 0.24). Every later sample meets the default bounds.
HALF_DRIVEN_START_TRANSIENT = 0.1
#: Andrews' squeezer at the default step: the Test Set's seven coordinates
#: at 0.03 s against the published solution, worst relative error (measured
#: 1.35e-5 at 1.74e-6 s, falling as dt²: 5.4e-5 at twice the step; the
#: reference reaches 1e-9 there, tests/test_dynamics.py).
#: PyBullet's semi-implicit Euler at 1.7e-6 s: the error is its own.
ANDREWS_PUBLISHED = 1e-4


def dynamic_case(name: str, end: float, samples: int = 101):
    case = dm.CASES[name]()
    return dataclasses.replace(case.mech, assembly_pose=case.pose), np.linspace(0.0, end, samples)


def dynamic_run(adapter, mech, times, **overrides):
    return adapter.run(mech, times, {**adapter.default_settings(mech, times), **overrides})


def out_of_bounds(ratios: dict) -> dict:
    return {column: ratio for column, ratio in ratios.items() if not ratio <= 1.0}


@pytest.mark.parametrize("name", ["spinning-crank", "motored-slider-crank", "free-fourbar", "half-driven-five-bar"])
def test_a_free_model_holds_its_torque_laws_and_no_motor_on_a_free_joint(adapter, name):
    """The audit of a torque-driven or free model: every torque law's joint
    and numbers as the stepping loop applies them, and no motor on a
    joint no drive prescribes (free joints only released motors)."""
    mech, times = dynamic_case(name, 0.5)
    table = adapter.audit(mech, times, adapter.default_settings(mech, times))
    assert failures(table).empty, "\n" + format_audit(failures(table))
    laws = table[table["item"].isin([torque_law_item(law) for law in mech.torque_drives])]
    assert len(laws) == 5 * len(mech.torque_drives) and set(laws["verdict"]) <= {"as set"}
    motors = table[table["quantity"] == "motors other than the drive"]
    assert motors["actual"].item() == "none" and "no motor on the joints no drive prescribes" in motors["note"].item()


def test_the_audit_shows_a_motor_left_on_a_free_joint(adapter, monkeypatch):
    """A position motor on the half-driven five-bar's free crank (O4), as
    the build would leave it if it treated every ground joint as driven:
    the audit's motors row names it."""
    from mechval.engines.pybullet import audit as pybullet_audit
    build = pybullet_audit.build

    def motored(mechanism, *args):
        model = build(mechanism, *args)
        crank = model.tree_joints["O4"].handle
        p.setJointMotorControl2(crank.uid, crank.link, p.POSITION_CONTROL, targetPosition=2.0, force=10.0,
                                physicsClientId=model.client)
        return model
    monkeypatch.setattr(pybullet_audit, "build", motored)
    mech, times = dynamic_case("half-driven-five-bar", 0.5)
    table = adapter.audit(mech, times, adapter.default_settings(mech, times))
    assert set(zip(failures(table)["item"], failures(table)["quantity"])) == {("scene", "motors other than the drive")}


def test_half_driven_five_bar_keeps_its_drive_and_frees_the_other_crank(adapter):
    """One crank prescribed (φ1 = 0.5 + 2t), the other free: the drive
    lands on its law, and every signal follows the forward-dynamics
    reference within the default bounds from the second sample on; the
    first sample carries the start-up transient (HALF_DRIVEN_START_TRANSIENT)."""
    mech, times = dynamic_case("half-driven-five-bar", 1.0)
    raw = dynamic_run(adapter, mech, times)
    reference = raw_dynamics(mech, times).frame
    assert raw.info.facts["drive_error_max"] <= 1e-9
    assert out_of_bounds(dynamic_errors(mech, reference.iloc[1:], raw.frame.iloc[1:])) == {}
    start = {c: abs(raw.frame[c][0] - reference[c][0]) / np.abs(reference[c]).max() for c in mech.reaction_columns()}
    assert max(start.values()) <= HALF_DRIVEN_START_TRANSIENT, start


def test_torque_laws_at_a_loop_closing_joint_and_a_leaf(adapter):
    """The free seed four-bar under two torque laws, at O2 (a leaf of the
    ground: TORQUE_CONTROL, read back from its sensor) and at A (a
    point-to-point constraint closing the loop: equal and opposite
    external torques): within the default bounds of the reference, each
    column the law it applies."""
    mech, times = dynamic_case("free-fourbar", 0.5, 51)
    laws = (TorqueLaw("A", 20.0, 10.0, 2.0, 0.3, name="tA"), TorqueLaw("O2", -15.0, name="tO2"))
    mech = dataclasses.replace(mech, torque_drives=laws)
    raw = dynamic_run(adapter, mech, times)
    assert "tO2 at O2: TORQUE_CONTROL" in raw.info.facts["torque_laws"]
    assert "tA at A: equal and opposite external torques" in raw.info.facts["torque_laws"]
    for law in laws:
        np.testing.assert_allclose(raw.frame[f"{law.name}.T"], law.value(times), rtol=1e-12, atol=1e-12)
    assert out_of_bounds(dynamic_errors(mech, raw_dynamics(mech, times).frame, raw.frame)) == {}


def test_a_torque_law_counts_in_a_derived_slide_reaction(adapter):
    """The contract's slotted lever with its drive removed, spun from 6 rad/s
    by a torque law at the pin A (on the crank, and its reaction on the
    block, the slide's body_j): the slide's derived F and M count it
    (left out, M43 was 100× its bound, measured), within the default
    bounds from the second sample on; the first is missing with its reason
    (no step before it)."""
    mech = build_mechanism(parse(MOVING_SLIDE, "moving-slide.toml"))
    pose = default_pose(mech, 0.0)
    mech = dataclasses.replace(mech, drive=None, assembly_pose=pose,
                               torque_drives=(TorqueLaw("A", 0.5, 0.2, 2.0, 0.0, name="tA"),),
                               initial_values=(InitialValue("O2", float(pose["crank"].theta), 6.0),))
    times = np.linspace(0.0, 0.5, 51)
    raw = dynamic_run(adapter, mech, times)
    assert {"slot.Fx", "slot.Fy", "slot.M"} <= set(raw.missing)
    assert raw.frame[["slot.Fx", "slot.Fy", "slot.M"]].iloc[1:].notna().all().all()
    reference = raw_dynamics(mech, times).frame
    assert out_of_bounds(dynamic_errors(mech, reference.iloc[1:], raw.frame.iloc[1:])) == {}


def test_andrews_under_its_motor(adapter):
    """Andrews' squeezer under its motor torque and spring, 0–0.03 s from
    the Test Set's consistent initial state: within the default bounds of
    the forward-dynamics reference, and the seven coordinates at 0.03 s
    against the published solution (tests/andrews.py) within
    ANDREWS_PUBLISHED."""
    mech, times = dynamic_case("motored-andrews", A.T1)
    raw = dynamic_run(adapter, mech, times)
    assert out_of_bounds(dynamic_errors(mech, raw_dynamics(mech, times).frame, raw.frame)) == {}
    q = A.test_set_coordinates(raw.frame)[:, -1]
    assert float(np.max(np.abs(q - A.Q1) / np.abs(A.Q1))) <= ANDREWS_PUBLISHED
    np.testing.assert_allclose(raw.frame["drive.T"], A.mom, rtol=1e-12)


def test_a_free_run_refuses_a_pre_roll_and_a_loop_inside_one_tree(adapter):
    """There is no prescribed motion to pre-roll along: a pre-roll setting
    on a free run is refused, naming the setting; the default is none.
    Layout "tree" closes a loop inside one multibody, which PyBullet lets
    fly apart without a drive's motor (measured: the free four-bar's loop
    opened by 1 m within 0.2 s): refused for a free closed loop, kept for
    a free open chain."""
    mech, times = dynamic_case("pendulum", 0.1, 11)
    assert adapter.default_settings(mech, times)["preroll_steps"] == 0
    with pytest.raises(Unrepresentable) as info:
        dynamic_run(adapter, mech, times, preroll_steps=5)
    assert info.value.key == "engines.pybullet.preroll_steps"
    assert dynamic_run(adapter, mech, times, layout="tree").frame["bar.theta"].notna().all()
    loop, times = dynamic_case("free-fourbar", 0.1, 11)
    with pytest.raises(Unrepresentable) as info:
        dynamic_run(adapter, loop, times, layout="tree")
    assert info.value.key == "engines.pybullet.layout"


class TestContract(AdapterContract):
    engine = "pybullet"
