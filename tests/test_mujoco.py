"""MuJoCo adapter: the built model holds only the scene's effects, inverse
dynamics reproduces the reference (frames, signs, inertias), signs of gravity
and torque, the high-accuracy setting, users' scenes, and a prismatic joint
between two moving bodies."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from mechval.testing.contract import AdapterContract
from conftest import BUILTIN, builtin_reference, builtin_scenario, engine_or_skip
from mechval.judging.compare import compare, passed
from mechval.testing import assert_within_tolerance, discrepancy_table
from mechval.model.drive import DriveLaw
from mechval.reference.linkages import build_mechanism
from mechval.model.mechanism import GROUND, Body, Drive, Joint, Mechanism
from mechval.reference.newton_euler import reactions
from mechval.scenarios import parse
from scales import motion_scales
from mechval.testing.scenes import fourbar, slider_crank

from mechval.harness.simulate import simulate

try:
    import mujoco
except ImportError as exc:
    # Each test skips, saying why (a module-level importorskip would report
    # the module skipped even where -m "not engine" deselects all of it).
    pytestmark = [pytest.mark.engine, pytest.mark.skip(reason=f"mujoco cannot be imported ({exc})")]
else:
    pytestmark = pytest.mark.engine     # every test here runs MuJoCo
    from mechval.engines.mujoco.adapter import MujocoAdapter
    from mechval.engines.mujoco.run import Model

FORCE_CLASSES = ("force", "torque")
#: Inverse mode evaluates the same equations as the reference at the same
#: state: only rounding separates them (measured ~1e-14).
INVERSE_AGREEMENT = 1e-9
#: Goals of the issue: default setting on fourbar-seed, high-accuracy setting.
DEFAULT_GOAL, HIGH_ACCURACY_GOAL = 1e-3, 1e-5

#: Users' scenes: 150 rad/s cranks, offsets, both branches, damping at every
#: pin (incl. the loop-closing one) and at the guide, tilted gravity.
USER_SCENES = {
    "fast-fourbar": fourbar(
        geometry={"ground": 0.30, "crank": 0.08, "coupler": 0.28, "rocker": 0.22, "branch": "crossed"},
        mass={"crank": {"mass": 0.6, "com": 0.03, "izz": 6.0e-4}, "coupler": 1.2, "rocker": 0.9},
        drive={"phi0": 0.4, "omega0": 150.0, "alpha": -20.0},
        effects={"gravity": [2.0, -9.81], "damping": {"O2": 0.02, "A": 0.01, "B": 0.015, "O4": 0.03}},
        time={"end": 0.2, "samples": 201}),
    "fast-slider": slider_crank(
        geometry={"crank": 0.05, "conrod": 0.17, "offset": 0.02, "branch": "left"},
        mass={"crank": 0.3, "conrod": {"mass": 0.5, "com": 0.07, "izz": 1.5e-3}, "slider": 0.4},
        drive={"phi0": -0.5, "omega0": 150.0, "alpha": 30.0},
        effects={"damping": {"O2": 0.01, "A": 0.004, "B": 0.006, "guide": 1.5}},
        time={"end": 0.2, "samples": 201}),
}


@pytest.fixture(scope="module")
def engine():
    return engine_or_skip("mujoco")


def worst_relative(records: pd.DataFrame, classes=FORCE_CLASSES) -> float:
    return float(records[records["class"].isin(classes)]["relative_error"].max())


def built_model(engine, scenario) -> tuple[Model, dict]:
    mech = build_mechanism(scenario)
    settings = engine.settings_for(scenario, mech)
    return Model(mech, scenario.time.t, settings), settings


@pytest.mark.parametrize("name", ["fourbar-seed", "slider-crank-damped"])
def test_model_has_only_the_scenes_effects(engine, name):
    scenario = builtin_scenario(name)
    model, settings = built_model(engine, scenario)
    m, mech = model.m, model.mech
    off = m.opt.disableflags
    assert m.ngeom == 0 and off & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert off & mujoco.mjtDisableBit.mjDSBL_AUTORESET
    assert off & mujoco.mjtDisableBit.mjDSBL_REFSAFE               # solref as written
    assert m.opt.enableflags == 0                              # no sleep, energy, override, ...
    np.testing.assert_array_equal(m.opt.gravity, [*mech.gravity, 0.0])
    assert bool(off & mujoco.mjtDisableBit.mjDSBL_GRAVITY) == (not mech.has_gravity)
    assert m.opt.density == 0 and m.opt.viscosity == 0 and not m.opt.wind.any()
    dt = settings["timestep"] / settings["refine"]
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4 and m.opt.timestep == dt
    assert m.opt.tolerance == 0 and m.opt.iterations == settings["iterations"]
    for field in ("dof_damping", "dof_armature", "dof_frictionloss", "jnt_stiffness", "jnt_limited"):
        assert not getattr(m, field).any(), field
    # Dampers: one tendon per damped joint, with exactly the scene's value.
    assert m.ntendon == len(mech.damped_joints)
    np.testing.assert_array_equal(m.tendon_damping, [j.damping for j in mech.damped_joints])
    assert not m.tendon_stiffness.any() and not m.tendon_frictionloss.any()
    # The only actuator is the clock's constant force (no gain, no ctrl effect).
    assert m.nu == 1 and m.actuator_trnid[0, 0] == m.joint("mechval_clock").id
    assert not m.actuator_gainprm.any()
    np.testing.assert_array_equal(m.actuator_biasprm[0, :3], [settings["clock_mass"] * mech.drive.law.alpha, 0, 0])
    # Mass properties as given (izz; the in-plane axes do not act).
    for body in mech.bodies:
        b = m.body(model.names.body[body.name])
        assert b.mass[0] == body.mass and b.inertia[2] == (body.izz or body.mass)
        np.testing.assert_array_equal(b.ipos[:2], body.com)
    # Soft constraints as recorded.
    loop, drive = m.eq(model.loop_eq), m.eq(model.drive_eq)
    np.testing.assert_allclose(loop.solref, [settings["solref_steps"] * dt, settings["solref_dampratio"]], rtol=1e-15)
    np.testing.assert_allclose(drive.solref, [settings["drive_solref_steps"] * dt, settings["solref_dampratio"]],
                               rtol=1e-15)
    for eq in (loop, drive):
        np.testing.assert_array_equal(eq.solimp, [float(v) for v in settings["solimp"].split()])


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if "hard" in builtin_scenario(n).tags
                                  else n for n in BUILTIN])
def test_inverse_mode_reproduces_the_reference(engine, name):
    scenario = builtin_scenario(name)
    result = simulate(scenario, engine, {"mode": "inverse"})
    records = compare(builtin_reference(name), result, scenario.tolerance, scenario=name, setting="inverse")
    assert worst_relative(records) <= INVERSE_AGREEMENT, "\n" + discrepancy_table(records)


def static_scene(gravity, kind=fourbar):
    """At rest, crank along +x, for 0.05 s."""
    return parse(kind(drive={"phi0": 0.0, "omega0": 0.0, "alpha": 0.0}, effects={"gravity": gravity},
                      time={"end": 0.05, "samples": 6}), "static")


def test_gravity_signs(engine):
    down, up = (simulate(static_scene(g), engine) for g in ([0.0, -9.81], [0.0, 9.81]))
    # The crank's and coupler's weight turn the horizontal crank clockwise:
    # the motor holds it with a positive (counter-clockwise) torque, the
    # ground pushes the crank up; reversed gravity reverses both.
    assert (down["T12"] > 0).all() and (down["F12y"] > 0).all()
    np.testing.assert_allclose(up["T12"], -down["T12"], rtol=1e-6)
    slider = simulate(static_scene([0.0, -9.81], slider_crank), engine)
    assert (slider["F14y"] > 0).all()                # the guide carries the slider's weight


def test_torque_sign(engine):
    # No gravity, from rest, accelerating counter-clockwise: T12 > 0 and
    # equal to the reference's (inertia only).
    scenario = parse(fourbar(drive={"phi0": 0.0, "omega0": 0.0, "alpha": 5.0}, effects={},
                             time={"end": 0.1, "samples": 11}), "spin-up")
    result = simulate(scenario, engine)
    assert (result["T12"] > 0).all()
    np.testing.assert_allclose(result["T12"], simulate(scenario, "reference")["T12"], rtol=1e-4)


@pytest.mark.parametrize("setting", ["default", "high-accuracy"])
def test_accuracy_on_fourbar_seed(engine, setting):
    scenario = builtin_scenario("fourbar-seed")
    result = simulate(scenario, engine, MujocoAdapter.variants[setting])
    records = compare(builtin_reference("fourbar-seed"), result, scenario.tolerance, scenario="fourbar-seed",
                      setting=setting)
    goal = DEFAULT_GOAL if setting == "default" else HIGH_ACCURACY_GOAL
    assert passed(records) and worst_relative(records) <= goal, "\n" + discrepancy_table(records)


@pytest.mark.parametrize("name", list(USER_SCENES))
def test_users_scene_meets_default_tolerances(engine, name):
    scenario = parse(USER_SCENES[name], name)
    result = simulate(scenario, engine)
    records = compare(simulate(scenario, "reference"), result, scenario.tolerance, scenario=name)
    assert_within_tolerance(records)
    assert result.info.facts["closure_gap_max"] < 1e-6


def test_scenario_table_overrides_settings(engine):
    scenario = parse(slider_crank(time={"end": 0.2, "samples": 41},
                                  engines={"mujoco": {"timestep": 5e-4, "mode": "inverse"}}), "override")
    result = simulate(scenario, engine)
    assert result.settings["timestep"] == 5e-4 and result.settings["mode"] == "inverse"


# -- a prismatic joint between two moving bodies --------------------------------

def inverted_slider_crank(damping: float, o4_on_ground: bool = False) -> Mechanism:
    """A block pinned to the crank at A slides along a rocker pivoted at O4
    (whitworth quick-return). Kinematics from r = A − O4 = (a·cosθ2 − d,
    a·sinθ2): θ4 = arg r, ω4 = (r × v)/|r|², α4 = (r × acc)/|r|² − 2ω4(r·v)/|r|².
    `o4_on_ground` orders O4 as (rocker, ground): its reaction is then the
    force on the ground, and the pin MuJoCo cuts has body_j = ground."""
    a, d, law = 0.1, 0.3, DriveLaw(0.3, 8.0, 2.0)

    def motion(t: np.ndarray) -> pd.DataFrame:
        t = np.asarray(t, dtype=float)
        th2, w2, al2 = law.angle(t), law.rate(t), law.acceleration(t)
        c2, s2 = np.cos(th2), np.sin(th2)
        ax_, ay_ = a * c2, a * s2
        vx, vy = -a * w2 * s2, a * w2 * c2
        accx, accy = -a * al2 * s2 - a * w2**2 * c2, a * al2 * c2 - a * w2**2 * s2
        rx, ry = ax_ - d, ay_
        r2 = rx * rx + ry * ry
        th4 = np.pi + np.arctan2(-ry, -rx)          # rx < 0 throughout: continuous
        w4 = (rx * vy - ry * vx) / r2
        al4 = (rx * accy - ry * accx) / r2 - 2 * w4 * (rx * vx + ry * vy) / r2
        zero = np.zeros_like(t)
        frames = {"crank": (zero, zero, th2, zero, zero, w2, zero, zero, al2),
                  "block": (ax_, ay_, th4, vx, vy, w4, accx, accy, al4),
                  "rocker": (zero + d, zero, th4, zero, zero, w4, zero, zero, al4)}
        columns = {"t": t}
        for body, values in frames.items():
            columns.update({f"{body}.{q}": v for q, v in
                            zip(("x", "y", "theta", "vx", "vy", "omega", "ax", "ay", "alpha"), values)})
        return pd.DataFrame(columns)

    bodies = (Body("crank", 1.0, (a / 2, 0.0), 1.0 * a * a / 12), Body("block", 0.4, (0.0, 0.0), 2e-4),
              Body("rocker", 2.0, (0.25, 0.0), 2.0 * 0.5**2 / 12))
    joints = (Joint("O2", "revolute", GROUND, "crank", (0.0, 0.0), (0.0, 0.0), damping=damping),
              Joint("A", "revolute", "block", "crank", (0.0, 0.0), (a, 0.0), damping=damping),
              Joint("guide", "prismatic", "rocker", "block", (0.0, 0.0), (0.0, 0.0), (1.0, 0.0), damping=damping),
              Joint("O4", "revolute", "rocker", GROUND, (0.0, 0.0), (d, 0.0), damping=damping) if o4_on_ground
              else Joint("O4", "revolute", GROUND, "rocker", (d, 0.0), (0.0, 0.0), damping=damping))
    return Mechanism("inverted-slider-crank", "inverted_slider_crank", bodies, joints, Drive("O2", law),
                     (0.0, -9.81), motion, {})


@pytest.mark.parametrize("o4_on_ground", [False, True])
@pytest.mark.parametrize("mode, goal", [("inverse", INVERSE_AGREEMENT), ("forward", 1e-4)])
def test_prismatic_joint_between_moving_bodies(engine, mode, goal, o4_on_ground):
    mech = inverted_slider_crank(damping=0.05, o4_on_ground=o4_on_ground)
    times = np.linspace(0.0, 1.0, 101)
    raw = engine.run(mech, times, {**engine.default_settings(mech, times), "mode": mode})
    motion = mech.motion(times)
    expected = pd.concat([motion, reactions(mech, motion)], axis=1)
    scales = motion_scales(mech, times)
    for column in mech.reaction_columns() + [c for c in mech.motion_columns() if c.endswith((".ax", ".alpha"))]:
        # A fixed frame origin's acceleration is identically 0: judge it
        # against the mechanism's acceleration scale L·Ω² (m/s²), not its
        # own zero peak.
        scale = np.abs(expected[column]).max() or scales[column.split(".")[1]]
        error = np.abs(raw.frame[column] - expected[column]).max() / scale
        assert error <= goal, f"{column}: {error:.3g} relative"
    assert raw.info.facts["closure_gap_max"] < 1e-6


def forward_states(model: Model, count: int) -> np.ndarray:
    """`count` states along a short forward rollout of `model`."""
    from mujoco import rollout
    states = rollout.rollout(model.m, model.d, model.initial_state()[None, :], nstep=model.nstep)[0][0]
    return states[:: max(1, len(states) // count)][:count]


@pytest.mark.parametrize("name", ["fourbar-damped", "hand-pump"])
def test_read_out_is_the_native_data(engine, name, monkeypatch):
    """The read-out's one-piece copy holds each mjData field bit for bit
    (across its blocks: 2 samples per block here), and the cut force and
    drive torque it reads from efc_force and qfrc_constraint are the
    equalities' efc_force rows bit for bit."""
    from mechval.engines.mujoco import snapshot as mujoco_snapshot
    from mechval.engines.mujoco.run import FULL, RECORDED
    from mechval.engines.mujoco.snapshot import Snapshot
    monkeypatch.setattr(mujoco_snapshot, "CHUNK", 2)
    model, _ = built_model(engine, builtin_scenario(name))
    m, d = model.m, model.d
    states = forward_states(model, 5)
    snapshot = Snapshot(d, RECORDED, len(states))
    expected = {field: [] for field in RECORDED}
    efc = []
    for k, state in enumerate(states):
        mujoco.mj_setState(m, d, state, FULL)
        mujoco.mj_forward(m, d)
        mujoco.mj_rnePostConstraint(m, d)
        snapshot.take(k)
        for field in RECORDED:
            expected[field].append(getattr(d, field).copy())
        rows = lambda eq: np.flatnonzero((d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & (d.efc_id == eq))
        efc.append(np.concatenate([d.efc_force[rows(model.loop_eq)][:2], d.efc_force[rows(model.drive_eq)][:1]]))
    fields, efc = snapshot.fields(), np.array(efc)
    for field in RECORDED:
        np.testing.assert_array_equal(fields[field], np.array(expected[field]), err_msg=field)
    np.testing.assert_array_equal(model.loop_rows(), rows(model.loop_eq))
    np.testing.assert_array_equal(model.drive_efforts(fields)[:, 0], model.drive.sign * efc[:, 2])


def test_snapshot_refuses_fields_outside_the_data_buffer(engine):
    from mechval.engines.mujoco.snapshot import Snapshot
    model, _ = built_model(engine, builtin_scenario("slider-crank"))
    mujoco.mj_forward(model.m, model.d)
    with pytest.raises(ValueError, match="one mjData buffer"):
        Snapshot(model.d, ("qacc", "efc_force"), 3)          # efc_* live in the arena
    with pytest.raises(ValueError, match="one mjData buffer"):
        Snapshot(model.d, ("qacc", "body_awake"), 3)         # not float


def test_a_blow_up_is_reported_not_logged_to_the_working_directory(engine, tmp_path, monkeypatch):
    """Euler with the drive's solref at 1·dt is unstable (docs/engines.md): its
    warnings land in the run's info, not in ./MUJOCO_LOG.TXT or stdout."""
    monkeypatch.chdir(tmp_path)
    scenario = builtin_scenario("slider-crank")
    mech = build_mechanism(scenario)
    settings = {**engine.settings_for(scenario, mech), "integrator": "Euler"}
    raw = engine.run(mech, scenario.time.t, settings)
    assert raw.info.warnings > 0 and "mjWARN_BADQACC" in raw.info.facts["warning_kinds"]
    assert not list(tmp_path.iterdir())
    assert mujoco.get_mju_user_warning() is None                      # MuJoCo's default restored


def test_overlapping_runs_share_the_warning_silencer(engine):
    """Threads running at once (a Dask worker with several threads) install
    the handler once and restore MuJoCo's default only when the last
    leaves, whatever the order."""
    from mechval.engines.mujoco.run import warnings_silenced
    first, second = warnings_silenced, warnings_silenced
    first.__enter__()
    second.__enter__()
    first.__exit__(None, None, None)
    assert mujoco.get_mju_user_warning() is not None
    second.__exit__(None, None, None)
    assert mujoco.get_mju_user_warning() is None


def test_a_single_instant_without_pre_roll(engine):
    """One sample and no pre-roll: no step at all, the read-out of the
    reference state itself."""
    scenario = builtin_scenario("fourbar-seed")
    mech = build_mechanism(scenario)
    settings = {**engine.default_settings(mech, scenario.time.t), "preroll_timeconsts": 0.0}
    raw = engine.run(mech, scenario.time.t[:1], settings)
    assert raw.info.steps == 0 and len(raw.frame) == 1
    assert np.all(np.isfinite(raw.frame.to_numpy()))


# -- what reaches MuJoCo's compiler ----------------------------------------------

def test_build_warnings_not_logged_to_the_working_directory(engine, tmp_path, monkeypatch):
    """A rocker whose centre of mass is 1e49 m out makes MuJoCo warn while
    compiling (near-singular inertia); the warning must not land in
    ./MUJOCO_LOG.TXT (or stdout)."""
    import dataclasses
    monkeypatch.chdir(tmp_path)
    scenario = builtin_scenario("fourbar-seed")
    mech = build_mechanism(scenario)
    far = tuple(dataclasses.replace(b, com=(1e49, 0.0)) if b.name == "rocker" else b for b in mech.bodies)
    Model(dataclasses.replace(mech, bodies=far), scenario.time.t, engine.settings_for(scenario, mech))
    assert not list(tmp_path.iterdir())
    assert mujoco.get_mju_user_warning() is None                      # MuJoCo's default restored


def renamed(mech: Mechanism, new) -> Mechanism:
    """`mech` with every body, joint and the mechanism itself renamed by
    `new(old_name)` (the motion's columns likewise)."""
    import dataclasses
    body = lambda name: name if name == GROUND else new(name)
    bodies = tuple(dataclasses.replace(b, name=body(b.name)) for b in mech.bodies)
    joints = tuple(dataclasses.replace(j, name=new(j.name), body_i=body(j.body_i), body_j=body(j.body_j))
                   for j in mech.joints)
    column = lambda c: c if c == "t" else ".".join([body(c.split(".")[0]), c.split(".")[1]])
    return dataclasses.replace(mech, name=new(mech.name), bodies=bodies, joints=joints,
                               drive=dataclasses.replace(mech.drive, joint=new(mech.drive.joint)),
                               motion=lambda t: mech.motion(t).rename(columns=column))


@pytest.mark.parametrize("name", ["fourbar-damped", "shaper-quick-return"])
def test_names_never_reach_the_model(engine, name):
    """Names with a quote, markup, a NUL or a newline (the scenario's, the
    bodies', the joints') change nothing, bit for bit: MuJoCo's elements
    carry generated names, and none of the names is in the MJCF."""
    hostile = lambda old: f'{old}" active="false <x/> &amp; \x00 \n'
    scenario = builtin_scenario(name)
    mech = build_mechanism(scenario)
    times = scenario.time.t[:41]
    settings = engine.settings_for(scenario, mech)
    plain = engine.run(mech, times, settings).frame
    odd_mech = renamed(mech, hostile)
    odd = engine.run(odd_mech, times, settings).frame
    back = {hostile(b): b for b in [x.name for x in mech.bodies] + [j.name for j in mech.joints]}
    odd.columns = [".".join([back.get(c.split(".")[0], c.split(".")[0]), *c.split(".")[1:]]) for c in odd.columns]
    pd.testing.assert_frame_equal(odd, plain, check_exact=True)
    xml = Model(odd_mech, times, settings).xml
    assert '"' + " active" not in xml and "\x00" not in xml and "<x/>" not in xml


def scene_with_block(block, scale: float = 1.0):
    """shaper-quick-return for one crank turn with the given block mass
    entry, every length and mass times `scale`."""
    return parse({"name": "block", "mechanism": "slotted_lever",
                  "geometry": {"ground": 0.30 * scale, "crank": 0.10 * scale, "lever": 0.50 * scale},
                  "mass": {"crank": 2.0 * scale, "block": block, "lever": 4.0 * scale},
                  "drive": {"phi0": 0.0, "omega0": 6.0, "alpha": 0.0}, "effects": {"gravity": [9.81, 0.0]},
                  "time": {"end": 1.2, "samples": 241}}, "block.toml")


def test_point_mass_turning_with_its_lever_borrows_inertia(engine):
    """The point-mass block (izz = 0) gets MIN_IZZ, taken from the lever it
    turns with (their total, which the motion depends on, is kept); a
    slider that never turns keeps its stand-in mass·(1 m)²."""
    from mechval.engines.mujoco.model import MIN_IZZ, inertia_shift, planar_inertias
    mech = build_mechanism(scene_with_block(0.5))
    izz = planar_inertias(mech)
    lever = mech.body("lever").izz
    assert izz["block"] == MIN_IZZ and izz["lever"] == lever - MIN_IZZ and izz["crank"] == mech.body("crank").izz
    assert izz["block"] + izz["lever"] == pytest.approx(lever, rel=1e-15)
    # The shift is what MuJoCo holds minus the scene's izz, rounding of the
    # lever's subtraction included (ulp(lever izz) ≈ 1e-17).
    assert inertia_shift(mech) == {"block": MIN_IZZ, "lever": pytest.approx(-MIN_IZZ, abs=1e-16)}
    slider = build_mechanism(builtin_scenario("slider-crank"))
    assert planar_inertias(slider)["slider"] == slider.body("slider").mass and not inertia_shift(slider)


@pytest.mark.parametrize("scale", [1.0, 1e-3])
def test_point_mass_block_inverse_mode_reproduces_the_reference(engine, scale):
    """Inverse dynamics of the point-mass block matches the reference to
    rounding, the slide's couple M43 included: the inertia the block
    borrows from the lever is taken out of it again. (Left in, it is
    MIN_IZZ·α4: 1e-7 of the torques on a millimetre-and-gram lever.)"""
    scenario = scene_with_block(0.5 * scale, scale)
    result = simulate(scenario, engine, {"mode": "inverse"})
    records = compare(simulate(scenario, "reference"), result, scenario.tolerance, setting="inverse")
    assert worst_relative(records) <= INVERSE_AGREEMENT, "\n" + discrepancy_table(records)


def test_masses_mujoco_cannot_hold_are_refused_with_the_key(engine, monkeypatch):
    """A mass below MuJoCo's floor (1e-15 kg), or a turning point mass with
    no body to borrow inertia from, is refused naming the scene's key (the
    compiler's error was a traceback)."""
    import dataclasses

    from mechval.engines.base import Unrepresentable
    from mechval.harness import plan as harness_plan
    from mechval.model.scenario import ScenarioError
    scenario = builtin_scenario("slider-crank")
    mech = build_mechanism(scenario)
    light = dataclasses.replace(mech, bodies=tuple(dataclasses.replace(b, mass=1e-300) if b.name == "crank" else b
                                                   for b in mech.bodies))
    monkeypatch.setattr(harness_plan, "build_mechanism", lambda s: light)
    with pytest.raises(ScenarioError, match="mass.crank: mujoco: MuJoCo refuses a moving body lighter") as refused:
        simulate(scenario, engine)
    assert refused.value.source == str(scenario.source)
    block = build_mechanism(scene_with_block(0.5))
    bare = dataclasses.replace(block, bodies=tuple(dataclasses.replace(b, izz=0.0) if b.name == "lever" else b
                                                   for b in block.bodies))
    with pytest.raises(Unrepresentable, match=r"mass.block: MuJoCo needs izz .* turning with it \(lever\)"):
        engine.run(bare, scenario.time.t, engine.default_settings(bare, scenario.time.t))


class TestContract(AdapterContract):
    engine = "mujoco"
