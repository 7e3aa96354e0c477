"""A spatial scene through the harness: its mechanism, its reference run,
health and signal classes, and the refusals of adapters that do not build
it (`mechval.reference.spatial.mechanism`, `mechval.judging.spatial_health`)."""

import dataclasses

import numpy as np
import pytest

from mechval.harness.simulate import simulate
from mechval.judging.compare import compare
from mechval.model.scenario import ScenarioError
from mechval.records.signals import SIGNAL_CLASS
from mechval.reference.adapter import ReferenceAdapter
from mechval.reference.linkages import build_mechanism
from mechval.testing import spatial_scenes as ss

ROUNDING = 1e-12


def test_a_spatial_scenario_becomes_a_spatial_mechanism():
    scenario = ss.scenario("rotor", ss.SpinningRotor().system(), 0.2, 21)
    mech = build_mechanism(scenario)
    assert mech.kind == "spatial" and mech.spatial is scenario.scene and not mech.forward_dynamics
    assert list(mech.signal_map) == mech.spatial.motion_columns() + mech.spatial.reaction_columns()


def test_every_spatial_signal_has_a_tolerance_class():
    system = ss.SpinningRotor().system()
    classes = {name: SIGNAL_CLASS[name] for name in system.motion_columns() + system.reaction_columns()}
    assert classes["rotor.qw"] == "angle" and classes["rotor.wz"] == "velocity"
    assert classes["rotor.alphax"] == "acceleration" and classes["bearing.Mz"] == "torque"
    assert classes["bearing.Fz"] == "force" and classes["spin.T"] == "torque" and classes["rotor.z"] == "position"


@pytest.mark.parametrize("case", ["rotor", "brick"])
def test_the_reference_run_is_healthy(case):
    """The reference's own run: its joints closed, its drive followed, a
    free body's energy kept, to rounding (or the integration's 1e-12)."""
    system = ss.SpinningRotor().system() if case == "rotor" else ss.FreeBrick().system()
    signals = simulate(ss.scenario(case, system, 0.5), "reference")
    health = signals.health
    assert health["nonfinite"].max() == 0
    assert health["constraint_drift"].max() <= ROUNDING
    if case == "rotor":
        assert health["drive_error"].max() <= ROUNDING and "energy_drift" not in health
    else:
        assert health["energy_drift"].max() <= 1e-10 and "drive_error" not in health


def test_a_wrong_column_is_found_by_the_comparison():
    """The comparison judges spatial columns by their class: a moment 2 %
    off fails the torque class, and nothing else does."""
    scenario = ss.scenario("rotor", ss.SpinningRotor().system(), 0.2, 21)
    reference = simulate(scenario, "reference")
    frame = reference.frame.copy()
    frame["bearing.Mx"] *= 1.02
    records = compare(reference, dataclasses.replace(reference, frame=frame, source="off"), scenario.tolerance,
                      scenario.name)
    failed = set(records.loc[records["verdict"] == "fail", "signal"])
    assert failed == {"bearing.Mx"}


class RevoluteOnly(ReferenceAdapter):
    name = "revolute-only"
    spatial_joints = frozenset({"revolute"})


class Planar(ReferenceAdapter):
    name = "planar-only"
    features = ReferenceAdapter.features - {"spatial"}


def test_an_adapter_without_spatial_scenes_is_refused_up_front():
    scenario = ss.scenario("hanging", ss.hanging(), 0.1, 11)
    with pytest.raises(ScenarioError) as refused:
        simulate(scenario, Planar())
    assert refused.value.key == "mechanism" and "does not build spatial" in refused.value.reason


def test_a_joint_kind_the_adapter_does_not_build_is_refused_naming_the_joint():
    scenario = ss.scenario("hanging", ss.hanging(), 0.1, 11)
    with pytest.raises(ScenarioError) as refused:
        simulate(scenario, RevoluteOnly())
    assert refused.value.key == "joint.pivot.kind" and "spherical" in refused.value.reason
    assert np.isfinite(simulate(ss.scenario("rotor", ss.SpinningRotor().system(), 0.1, 11), RevoluteOnly())
                       ["bearing.Mx"]).all()



def test_a_scene_an_engine_declares_it_cannot_build_is_a_row_that_says_so_not_a_failed_run():
    """`mechval run`'s path for a declared refusal (`Plan.refusal`,
    `Task.refused`): the task is never run, its one record is "missing"
    with the reason, the run passes, and the page's cell says "not built"."""
    from mechval.harness.plan import prepare
    from mechval.harness.runner import outcome_records, run_alongside
    from mechval.judging.compare import passed
    from mechval.records.outcome import Task
    from mechval.reports.build import _cell

    scenario = ss.scenario("hanging", ss.hanging(), 0.1, 11)
    refusal = prepare(scenario).refusal(Planar())
    assert refusal.startswith("mechanism: planar-only: its adapter does not build spatial")
    assert prepare(scenario).refusal(ReferenceAdapter()) == ""

    class NeverRuns:
        def run(self, call, items, done):
            assert not items, "a refused task was run"
            return []

    seen = []
    outcomes, _ = run_alongside([Task(scenario, "planar-only", refused=refusal)], (), NeverRuns(), seen.append)
    assert [o.error for o in outcomes] == [refusal] and [o.error for o in seen] == [refusal]
    records = outcome_records(outcomes[0], None)
    assert list(records["verdict"]) == ["missing"] and refusal in records["reason"].iloc[0]
    assert passed(records) and _cell(records)["text"] == "not built"


def test_a_bodys_resultant_from_its_reactions_is_its_newton_euler_load():
    """`spatial_resultants` from the delta robot's reactions and drive
    efforts: each body's net constraint force is m·(a_G − g), its moment
    about the centre of mass I·α + ω × I·ω (nothing else acts), to rounding."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    from spatial_mechanisms import Delta
    from mechval.reference.spatial.columns import body_state
    from mechval.reference.spatial.forces import world_inertia
    from mechval.reference.spatial.resultants import spatial_resultants
    from mechval.reference.spatial.solver import solve_spatial

    m = Delta()
    frame = solve_spatial(m.system, np.linspace(0.0, 1.0, 21)).frame
    found = spatial_resultants(m.system, frame)
    pose, w, dw = body_state(m.system, frame)
    inertia = world_inertia(m.system, pose)
    for k, body in enumerate(m.system.bodies):
        force = np.stack([found[f"{body.name}.R.F{c}"] for c in "xyz"], axis=1)
        moment = np.stack([found[f"{body.name}.R.M{c}"] for c in "xyz"], axis=1)
        om = w[:, k, 3:]
        spin = np.einsum("nij,nj->ni", inertia[:, k], om)
        expected = body.mass * (dw[:, k, :3] - np.asarray(m.system.gravity))
        assert np.abs(force - expected).max() <= ROUNDING * np.abs(expected).max() * 10
        expected = np.einsum("nij,nj->ni", inertia[:, k], dw[:, k, 3:]) + np.cross(om, spin)
        # the resultant sums joint moments and drive torques up to 0.71 N·m
        # into ~3e-5 N·m: its rounding scales with those terms (a floor of
        # 1e-3 N·m put the bound at 1e-15, below them: the numpy solver
        # missed it at 101 instants by 1.05e-15, the compiled one at 21 by 1.26e-15)
        terms = frame[[c for c in frame.columns if c.endswith((".Mx", ".My", ".Mz", ".T"))]].abs().to_numpy().max()
        assert np.abs(moment - expected).max() <= ROUNDING * max(np.abs(expected).max(), terms)


def test_with_redundant_constraints_the_run_reports_each_bodys_resultant():
    """Bricard's linkage (one redundant row): its signals include every
    body's resultant, finite, while the reactions the redundant row makes
    indeterminate are missing with their reason."""
    from mechval.scenarios import load

    scenario = load("spatial/bricard")
    mech = build_mechanism(scenario)
    wanted = [f"{b.name}.R.{q}" for b in mech.spatial.bodies for q in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")]
    assert set(wanted) <= set(mech.signal_map)
    short = dataclasses.replace(scenario, time=dataclasses.replace(scenario.time, end=0.1, samples=11))
    signals = simulate(short, "reference")
    assert np.isfinite(signals.frame[wanted].to_numpy()).all()
    assert signals.missing and all("not unique" in reason for reason in signals.missing.values())


def test_an_attitude_is_compared_up_to_the_quaternions_sign():
    """q and −q are one attitude: an engine whose quaternion has the other
    sign (past half a turn, where qw ≥ 0 jumps) is not off by 2, while a
    quaternion truly off still fails."""
    scenario = ss.scenario("rotor", ss.SpinningRotor().system(), 0.2, 21)
    reference = simulate(scenario, "reference")
    columns = [f"rotor.q{c}" for c in "wxyz"]
    flipped = reference.frame.copy()
    flipped.loc[5:, columns] *= -1.0
    records = compare(reference, dataclasses.replace(reference, frame=flipped, source="x"), scenario.tolerance)
    assert (records.set_index("signal").loc[columns, "max_error"] == 0).all()
    off = reference.frame.copy()
    off["rotor.qx"] += 2e-3
    records = compare(reference, dataclasses.replace(reference, frame=off, source="x"), scenario.tolerance)
    assert set(records.loc[records["verdict"] == "fail", "signal"]) == {"rotor.qx"}


def test_moments_zero_in_theory_are_judged_against_forces_times_size():
    """A spatial reference states its size: a rotor spun about a principal
    axis under gravity has bearing moments zero in theory (their values
    rounding) and forces m·g; an engine's moment of 1e-6 N·m is judged
    against m·g times that size, not against the rounding."""
    from mechval.reference.spatial.rotation import frame_from_axis
    from mechval.reference.spatial.system import SpatialBody, SpatialDrive, SpatialJoint, SpatialSystem
    from mechval.model.drive import DriveLaw

    frame = frame_from_axis((0.0, 0.0, 1.0))
    rotor = SpatialBody("rotor", 2.0, (0.0, 0.0, 0.0), np.diag([0.01, 0.02, 0.03]))
    bearing = SpatialJoint("bearing", "revolute", "ground", "rotor", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), frame, frame)
    system = SpatialSystem("principal-rotor", (rotor,), (bearing,), (SpatialDrive("bearing", DriveLaw(0, 10, 0), "spin"),),
                           gravity=(0.0, -9.81, 0.0))
    scenario = ss.scenario("principal-rotor", system, 0.2, 21)
    reference = simulate(scenario, "reference")
    assert np.abs(reference.frame[["bearing.Mx", "bearing.My", "bearing.Mz", "spin.T"]].to_numpy()).max() < 1e-12
    engine = reference.frame.copy()
    engine["bearing.Mx"] += 1e-6
    judged = lambda ref: compare(ref, dataclasses.replace(reference, frame=engine, source="x"), scenario.tolerance)
    row = judged(reference).set_index("signal").loc["bearing.Mx"]
    assert row["verdict"] == "pass" and row["bound"] >= 1e-2 * 2.0 * 9.81 * reference.info.facts["length_scale"]
    planar_rule = dataclasses.replace(reference, info=dataclasses.replace(reference.info, facts={}))
    assert judged(planar_rule).set_index("signal").loc["bearing.Mx", "verdict"] == "fail"


@pytest.mark.engine
def test_a_spatial_scene_has_a_baseline_an_engine_run_checks_against(tmp_path, capsys):
    """`mechval baseline save` and `check` on a spatial built-in: the
    stored run checks out unchanged."""
    from mechval.harness.cli import main
    from mechval.testing import engine_or_skip

    engine_or_skip("mujoco")
    args = ["spatial/spherical-fourbar", "--engine", "mujoco", "--dir", str(tmp_path)]
    assert main(["baseline", "save", *args]) == 0
    assert main(["baseline", "check", *args]) == 0
    assert "baseline check: ok" in capsys.readouterr().out


def test_the_page_draws_a_bodys_attitude_as_yaw_pitch_and_roll():
    """Display only: a body turning about z at 10 rad/s reads yaw = 10·t,
    unwrapped past ±π, pitch and roll zero; the angles get no bound and
    are no signal the comparison judges."""
    from mechval.model.drive import DriveLaw
    from mechval.reference.spatial.rotation import frame_from_axis
    from mechval.reference.spatial.system import SpatialBody, SpatialDrive, SpatialJoint, SpatialSystem
    from mechval.reports.spatial_plots import with_attitude_angles

    frame = frame_from_axis((0.0, 0.0, 1.0))
    system = SpatialSystem("turning", (SpatialBody("rotor", 1.0, (0.0, 0.0, 0.0), np.diag([0.01, 0.02, 0.03])),),
                           (SpatialJoint("bearing", "revolute", "ground", "rotor", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                                         frame, frame),), (SpatialDrive("bearing", DriveLaw(0, 10, 0), "spin"),))
    reference = simulate(ss.scenario("turning", system, 1.0, 101), "reference")
    angles = with_attitude_angles(reference.frame)
    assert list(angles.columns[list(angles.columns).index("rotor.qz") + 1:][:3]) == ["rotor.yaw", "rotor.pitch",
                                                                                      "rotor.roll"]
    np.testing.assert_allclose(angles["rotor.yaw"], 10.0 * reference.t, rtol=0, atol=1e-12)
    assert np.abs(angles[["rotor.pitch", "rotor.roll"]].to_numpy()).max() <= 1e-12
    assert "rotor.yaw" not in reference.frame and "rotor.yaw" not in build_mechanism(
        ss.scenario("turning", system, 1.0, 101)).signal_map


def test_mechval_list_names_the_spatial_built_ins(capsys):
    from mechval.harness.cli import main
    from mechval.scenarios.loader import spatial_builtin_names

    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in spatial_builtin_names():
        assert f"  {name} " in out
    assert any(line.startswith("  spatial/t-handle") and "[extra]" in line for line in out.splitlines())


@pytest.mark.parametrize("case", ["Bricard (free, redundant)", "Bennett (prescribed, redundant)"])
def test_the_motion_alone_is_the_full_solutions_motion(case):
    """What the step rule reads (`Mechanism.motion`, no reactions: their
    uniqueness check where rows are redundant cost most of a dense grid's
    solve) is the full reference's motion columns, the same numbers."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    from spatial_benchmarks import Bricard
    from spatial_mechanisms import Bennett
    from mechval.reference.spatial.mechanism import spatial_mechanism, spatial_solution
    system = Bricard().system if case.startswith("Bricard") else Bennett().system
    t = np.linspace(0.0, 0.2, 41)
    full = spatial_solution(system, t).frame
    motion = spatial_mechanism(system).motion(t)
    assert list(motion.columns) == ["t", *system.motion_columns()]
    assert np.abs(motion.to_numpy() - full[motion.columns].to_numpy()).max() <= ROUNDING


@pytest.mark.parametrize("name", ["spatial/t-handle", "spatial/heavy-top"])
def test_a_free_spatial_scenes_step_rule_reads_a_looser_integration_to_the_same_rate(name):
    """The step rule's motion of a torque-driven or free spatial scene is
    integrated at RATE_RTOL, as a planar one's (`planned_motion`): its peak
    rate Ω agrees with the reference's own integration to 1e-6, and so the
    default step with it."""
    from mechval.engines.base import RATE_RTOL, dense_grid, default_step, planned_motion
    from mechval.model.kinematics import peak_rate
    from mechval.reference.spatial.mechanism import spatial_solution
    from mechval.scenarios.loader import load
    scenario = load(name)
    mech = build_mechanism(scenario)
    t = dense_grid(scenario.time.t)
    loose = peak_rate(mech, planned_motion(mech).motion(t), t)
    exact = peak_rate(mech, spatial_solution(mech.spatial, t, reactions=False).frame, t)
    assert RATE_RTOL > 1e-9 and abs(loose - exact) <= 1e-6 * exact
    assert default_step(mech, scenario.time.t, rate=loose) == default_step(mech, scenario.time.t, rate=exact)
