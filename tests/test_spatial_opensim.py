"""OpenSim builds spatial scenes (`mechval.engines.opensim.spatial_run`):
each run at the adapter's default settings against the spatial reference,
per column class with mechval's default tolerances
(`mechval.model.scenario.DEFAULT_TOLERANCE`): positions and quaternion
components absolute, the others max |error| / max |reference| over the
class's columns. Where a scene's reactions are not unique (redundant
constraints) only what the reference reports is compared, and each body's
resultant constraint load (unique) is summed from OpenSim's joint loads."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mechval.adapter import PeakRates, Unrepresentable
from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND, TorqueLaw
from mechval.model.scenario import DEFAULT_TOLERANCE
from mechval.records.signals import SIGNAL_CLASS
from mechval.reference.spatial.mechanism import spatial_mechanism, spatial_solution
from mechval.reference.spatial.rotation import frame_from_axis, quaternion_to_matrix
from mechval.testing import SpatialContract
from mechval.reference.spatial.system import (BodyLoad, JointTorque, SpatialBody, SpatialDrive, SpatialJoint,
                                              SpatialSystem, Spring)
from spatial_benchmarks import Bricard, FlyballGovernor
from spatial_mechanisms import HookesJoint, GRAVITY, RSSR, Bennett, Delta, HeavyTop, SphericalFourBar, TumblingBody, inertia, \
    revolute, unit
from test_spatial_joint_kinds import sliding_body

pytestmark = pytest.mark.engine

osim = pytest.importorskip("opensim")

from mechval.engines.opensim.adapter import OpensimAdapter          # noqa: E402
from mechval.engines.opensim.spatial_run import run_spatial, scene_length      # noqa: E402
from mechval.model.kinematics import spatial_peak_rate      # noqa: E402

CLASSES = {"position": ("x", "y", "z"), "angle": ("qw", "qx", "qy", "qz"),
           "velocity": ("vx", "vy", "vz", "wx", "wy", "wz"), "acceleration": ("ax", "ay", "az", "alphax", "alphay",
                                                                               "alphaz")}


def errors(system: SpatialSystem, t: np.ndarray) -> tuple[dict[str, float], object]:
    """Per class: the adapter's default run's error against the reference
    (absolute for positions and quaternions, else relative to the class
    peak; a class the reference holds at zero, such as a spherical joint's
    moment, relative to the force peak times the scene's size)."""
    adapter = OpensimAdapter()
    mechanism = spatial_mechanism(system)
    ref = spatial_solution(system, t)
    # Ω from the reference on the test's grid, not the harness's dense one
    # (20001 instants: seconds of reference per scene)
    rates = PeakRates(t, ref.frame, spatial_peak_rate(spatial_mechanism(system), ref.frame, t))
    raw = adapter.run(mechanism, t, adapter.default_settings(mechanism, t, rates))
    groups: dict[str, list[str]] = {k: [f"{b.name}.{q}" for b in system.bodies for q in qs] for k, qs in CLASSES.items()}
    for column in system.reaction_columns():
        if column not in ref.missing:
            groups.setdefault(SIGNAL_CLASS[column], []).append(column)
    engine, expected = resultants(system, raw.frame), ref.frame
    if any(c.endswith(".R.Fx") for c in expected):
        for column in engine:
            groups.setdefault(SIGNAL_CLASS[column], []).append(column)
    frame = raw.frame.join(engine)
    size = scene_length(system)
    out, peaks = {}, {}
    for name, columns in groups.items():
        err = np.abs(frame[columns].to_numpy() - expected[columns].to_numpy()).max()
        peaks[name] = np.abs(expected[columns].to_numpy()).max()
        out[name] = err
    for name in out:
        if name not in ("position", "angle"):
            scale = peaks[name] or peaks.get("force", 0.0) * size
            out[name] = out[name] / scale
    return out, raw


def resultants(system: SpatialSystem, frame):
    """Each body's resultant constraint load from OpenSim's joint loads and
    drive efforts (force, moment about the centre of mass, world axes), as
    the reference's B.R columns."""
    import pandas as pd
    n = len(frame)
    pose = {b.name: (quaternion_to_matrix(frame[[f"{b.name}.q{c}" for c in "wxyz"]].to_numpy()),
                     frame[[f"{b.name}.{c}" for c in "xyz"]].to_numpy()) for b in system.bodies}
    world = lambda body, p: (np.broadcast_to(p, (n, 3)) if body == GROUND else   # noqa: E731
                             np.einsum("nij,j->ni", pose[body][0], p) + pose[body][1])
    load = {b.name: [np.zeros((n, 3)), np.zeros((n, 3))] for b in system.bodies}
    efforts = {d.joint: d for d in system.drives}
    for j in system.joints:
        F = frame[[f"{j.name}.F{c}" for c in "xyz"]].to_numpy()
        M = frame[[f"{j.name}.M{c}" for c in "xyz"]].to_numpy()
        drive = efforts.get(j.name)
        if drive is not None:
            zi = world(j.body_i, j.frame_i[:, 2]) - world(j.body_i, np.zeros(3))
            if j.kind == "revolute":
                M = M + frame[[f"{drive.name}.T"]].to_numpy() * zi
            else:
                F = F + frame[[f"{drive.name}.F"]].to_numpy() * zi
        Pj = world(j.body_j, np.asarray(j.point_j, float))
        for body, sign in ((j.body_j, 1.0), (j.body_i, -1.0)):
            if body == GROUND:
                continue
            G = world(body, np.asarray(system.body(body).com, float))
            load[body][0] += sign * F
            load[body][1] += sign * (M + np.cross(Pj - G, F))
    columns = {}
    for body, (F, M) in load.items():
        for k, c in enumerate("xyz"):
            columns[f"{body}.R.F{c}"], columns[f"{body}.R.M{c}"] = F[:, k], M[:, k]
    return pd.DataFrame(columns, index=frame.index)


def check(system: SpatialSystem, t: np.ndarray, bounds: dict[str, float] | None = None):
    found, raw = errors(system, t)
    bounds = {**DEFAULT_TOLERANCE, **(bounds or {})}
    over = {k: f"{v:.3g}" for k, v in found.items() if not v <= bounds[k]}
    assert not over, f"{system.name}: over the default tolerance {over} (all: {found})"
    return found, raw


def with_start(scene) -> SpatialSystem:
    return dataclasses.replace(scene.system, velocities=scene.velocities)


def test_driven_closed_loops_meet_the_reference():
    """A spherical four-bar (three redundant constraints) and an RSSR
    (closed by a point constraint at its ball joint)."""
    check(SphericalFourBar().system, np.linspace(0.0, 2.0, 41))
    check(RSSR().system, np.linspace(0.0, 2.0, 41))


def test_overconstrained_loops_meet_the_reference():
    """Bennett (driven) and Bricard (A04, under gravity): Simbody projects
    onto the redundant constraints and its least-squares multipliers give
    the unique body resultants."""
    check(Bennett().system, np.linspace(0.0, 2.0, 41))
    check(Bricard().system, np.linspace(0.0, 1.0, 51))


def test_delta_robot_with_three_drives_meets_the_reference():
    check(Delta().system, np.linspace(0.0, 1.0, 21))


def test_tumbling_body_flips_as_the_reference():
    """A free body through its intermediate-axis flip: the gyroscopic term
    in full; the Free joint's Euler chart is re-anchored along the way."""
    scene = TumblingBody()
    t = np.linspace(0.0, 2 * scene.quarter, 101)
    _, raw = check(with_start(scene), t)
    assert raw.info.facts["recharts"] >= 1      # the chart did move: the re-anchoring is exercised
    omega = raw.frame[[f"body.w{c}" for c in "xyz"]].to_numpy()
    axis = quaternion_to_matrix(raw.frame[[f"body.q{c}" for c in "wxyz"]].to_numpy())[:, :, 1]
    spin = np.einsum("ni,ni->n", omega, axis)       # about the intermediate axis
    assert spin[0] > 3.9 and spin[-1] < -3.9, "the flip is not in the run"


def test_heavy_top_on_a_spherical_joint_meets_the_reference():
    check(with_start(HeavyTop()), np.linspace(0.0, 0.5, 51))


def test_flyball_governor_springs_meet_the_reference():
    """A05 with springs 400 times softer (k = 2e3 N/m, c = 20 N·s/m) for
    0.5 s: the stiff benchmark's reference costs ~14 s of CPU per 0.05 s
    (the slow test below)."""
    check(with_start(FlyballGovernor(2e3, 20.0)), np.linspace(0.0, 0.5, 26))


@pytest.mark.slow
def test_stiff_flyball_governor_meets_the_reference():
    check(with_start(FlyballGovernor()), np.linspace(0.0, 0.05, 11))


def test_cylindrical_and_planar_joints_meet_the_reference():
    """test_spatial_joint_kinds' sliding bodies, the cylinder's slide damped."""
    for kind, axis, v, w in (("cylindrical", (1.0, 1.0, 1.0), 0.4, 7.0), ("planar", (0.2, -0.3, 1.0), 0.5, -5.0)):
        system, u = sliding_body(kind, axis)
        if kind == "cylindrical":
            system = dataclasses.replace(system, joints=(dataclasses.replace(system.joints[0], damping=2.0),))
        velocity = v * (u if kind == "cylindrical" else unit(np.cross(u, [1.0, 0.0, 0.0])))
        check(dataclasses.replace(system, velocities={"body": (tuple(velocity), tuple(w * u))}),
              np.linspace(0.0, 1.0, 51))


def test_fixed_and_universal_joints_meet_the_reference():
    """A plate welded to a driven crank; Hooke's joint between two driven
    and guided shafts (test_spatial_joint_kinds' scenes)."""
    axis = unit((0.3, 0.1, 1.0))
    crank = SpatialBody("crank", 2.0, (0.1, 0.0, 0.05), inertia(50))
    plate = SpatialBody("plate", 1.0, (0.3, 0.1, -0.1), inertia(51))
    check(SpatialSystem("crank and plate", (crank, plate),
                        (revolute("O", GROUND, "crank", (0.0, 0.0, 0.0), axis),
                         SpatialJoint("W", "fixed", "crank", "plate", (0.25, 0.0, 0.0), (0.25, 0.0, 0.0))),
                        (SpatialDrive("O", DriveLaw(0.2, 3.0, 1.5)),), GRAVITY), np.linspace(0.0, 2.0, 41))
    check(hooke(), np.linspace(0.0, 3.0, 61))


def welded_loop() -> SpatialSystem:
    """The plate welded to the driven crank and held on the crank's axis
    by a cylindrical joint to the ground."""
    axis = unit((0.3, 0.1, 1.0))
    frame = frame_from_axis(axis)
    crank = SpatialBody("crank", 2.0, (0.1, 0.0, 0.05), inertia(50))
    plate = SpatialBody("plate", 1.0, (0.3, 0.1, -0.1), inertia(51))
    on_axis = tuple(0.4 * axis)
    return SpatialSystem("welded loop", (crank, plate),
                         (revolute("O", GROUND, "crank", (0.0, 0.0, 0.0), axis),
                          SpatialJoint("W", "fixed", "crank", "plate", (0.25, 0.0, 0.0), (0.25, 0.0, 0.0)),
                          SpatialJoint("C", "cylindrical", GROUND, "plate", on_axis, on_axis, frame, frame)),
                         (SpatialDrive("O", DriveLaw(0.2, 3.0, 1.5)),), GRAVITY)


def test_a_weld_that_closes_a_loop_meets_the_reference():
    """The weld closes the loop (a WeldConstraint, four redundant rows),
    compared by body resultants."""
    check(welded_loop(), np.linspace(0.0, 2.0, 41))


def hooke() -> SpatialSystem:
    return HookesJoint().system


def torque_crank() -> SpatialSystem:
    """A crank on a tilted axis, its joint written body_i = crank, body_j =
    ground (OpenSim's tree reverses it), turned by a torque law against a
    damper; a bob on a ball joint at its tip, pulled by a spring-damper to
    the ground and pushed by a constant load."""
    axis = unit((0.2, -0.1, 1.0))
    frame = frame_from_axis(axis)
    pin = SpatialJoint("O", "revolute", "crank", GROUND, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), frame, frame,
                       damping=0.05)
    ball = SpatialJoint("S", "spherical", "crank", "bob", (0.3, 0.0, 0.0), (0.3, 0.0, 0.0))
    return SpatialSystem(
        "torque crank", (SpatialBody("crank", 1.0, (0.15, 0.0, 0.02), inertia(70)),
                         SpatialBody("bob", 0.5, (0.3, 0.0, -0.15), inertia(71))),
        (pin, ball), gravity=GRAVITY,
        springs=(Spring("spring", GROUND, (0.2, 0.2, -0.3), "bob", (0.3, 0.0, -0.2), 40.0, 0.15, 0.3),),
        loads=(BodyLoad("push", "bob", (0.5, -0.3, 0.2), (0.0, 0.01, -0.02)),),
        torques=(JointTorque("O", TorqueLaw("O", 0.3, 0.5, 1.5, 0.2), "motor"),),
        velocities={"crank": ((0.0, 0.0, 0.0), tuple(2.0 * axis))})


def driven_slide() -> SpatialSystem:
    """A carriage driven along a tilted slide; a damped pendulum on it,
    turned by a torque law."""
    slide = revolute("P", GROUND, "carriage", (0.0, 0.0, 0.0), (1.0, 0.5, 0.2), kind="prismatic")
    hinge = dataclasses.replace(revolute("H", "carriage", "pendulum", (0.1, 0.0, 0.0), (0.0, 1.0, 0.3)), damping=0.02)
    return SpatialSystem(
        "driven slide", (SpatialBody("carriage", 2.0, (0.05, 0.0, 0.0), inertia(80)),
                         SpatialBody("pendulum", 0.4, (0.1, 0.0, -0.2), inertia(81))),
        (slide, hinge), (SpatialDrive("P", DriveLaw(0.0, 0.3, -0.8), "push"),), GRAVITY,
        torques=(JointTorque("H", TorqueLaw("H", -0.1, 0.2, 2.0), "motor"),))


def test_torque_law_spring_damper_and_load_meet_the_reference():
    """Torque law, joint damper, spring-damper, body load, a reversed tree
    joint and a ball joint under a moving body: forward dynamics."""
    check(torque_crank(), np.linspace(0.0, 1.0, 51))


def test_prismatic_drive_with_a_torque_law_meets_the_reference():
    check(driven_slide(), np.linspace(0.0, 1.0, 51))


def test_a_loop_only_a_slide_closes_is_refused():
    """Two slides from the ground to one body: the second closes a loop no
    constraint of the adapter closes."""
    body = SpatialBody("body", 1.0, (0.0, 0.0, 0.0), inertia(90))
    system = SpatialSystem("two slides", (body,), (
        revolute("A", GROUND, "body", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), kind="prismatic"),
        revolute("B", GROUND, "body", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), kind="cylindrical")),
        (SpatialDrive("A", DriveLaw(0.0, 0.1, 0.0)),))
    with pytest.raises(Unrepresentable) as refused:
        run_spatial(system, np.linspace(0.0, 1.0, 3), {"integrator": "RungeKuttaMerson", "accuracy": 1e-9,
                                                       "constraint_tolerance": 1e-10, "max_step": 0.01})
    assert refused.value.key == "joint.B.kind"


def test_simbody_keeps_the_gyroscopic_term_in_full():
    """The T-handle's flip against Landau's closed form (not the reference):
    ω about the intermediate axis crosses zero a quarter period after the
    start, and the kinetic energy holds. Dropping ω × Iω would leave no
    flip at all; a linearised term drifts the energy and the flip time
    (measured on these 401 samples, steps at most a sample interval:
    Simbody's SemiExplicitEuler2 at accuracy 1e-3 flips 0.043 s late with
    2.2 % energy drift; the default RungeKuttaMerson 2.6e-9 s early, 7e-10
    drift)."""
    scene = TumblingBody()
    system = with_start(scene)
    t = np.linspace(0.0, 2 * scene.quarter, 401)
    rates = PeakRates(t, None, float(np.linalg.norm(scene.omega0)))
    raw = OpensimAdapter().run(spatial_mechanism(system), t,
                               OpensimAdapter().default_settings(spatial_mechanism(system), t, rates))
    R = quaternion_to_matrix(raw.frame[[f"body.q{c}" for c in "wxyz"]].to_numpy())
    omega = np.einsum("nji,nj->ni", R, raw.frame[[f"body.w{c}" for c in "xyz"]].to_numpy())    # body axes
    energy = 0.5 * omega ** 2 @ np.array(scene.principal)
    spin = omega[:, 1]
    k = np.flatnonzero(np.diff(np.sign(spin)))
    assert len(k) == 1, "one flip in half a period"
    k = int(k[0])
    flip = t[k] - spin[k] * (t[k + 1] - t[k]) / (spin[k + 1] - spin[k])
    # the crossing by linear interpolation between samples 8 ms apart: the
    # reference's own, read the same way, is 3e-12 s off the closed form
    assert abs(flip - scene.quarter) <= 1e-6, f"flip at {flip:.9f} s, closed form {scene.quarter:.9f} s"
    assert np.abs(energy / scene.energy - 1).max() <= 1e-8


@pytest.mark.parametrize("build", [lambda: Delta().system, driven_slide, torque_crank, hooke,
                                   lambda: sliding_body("cylindrical", (1.0, 1.0, 1.0))[0],
                                   lambda: sliding_body("planar", (0.2, -0.3, 1.0))[0]],
                         ids=["delta", "driven-slide", "torque-crank", "hooke", "cylindrical", "planar"])
def test_the_built_model_holds_the_scenes_inertia_points_and_axes(build):
    """Read back from OpenSim at the start state: each body's mass, mass
    centre and inertia tensor; each tree joint's frames in the ground
    (`getTransformInGround` of its parent and child frames): origins at
    Pi and Pj, the axis OpenSim turns or slides about along zi and zj."""
    from mechval.engines.opensim.spatial_run import prepare, start_world
    system = build()
    t = np.linspace(0.0, 1.0, 3)
    world = start_world(system, t)
    built, manager = prepare(system, world, 0.0, {"integrator": "RungeKuttaMerson", "accuracy": 1e-9,
                                                  "constraint_tolerance": 1e-10, "max_step": 0.1}, t)
    state = manager.getState()
    built.model.realizePosition(state)
    for body in system.bodies:
        b = built.bodies[body.name]
        I = b.getInertia()
        moments, products = I.getMoments(), I.getProducts()
        tensor = np.array([[moments[0], products[0], products[1]], [products[0], moments[1], products[2]],
                           [products[1], products[2], moments[2]]])
        assert b.getMass() == body.mass
        assert np.allclose([b.getMassCenter()[k] for k in range(3)], body.com, rtol=0, atol=1e-15)
        assert np.allclose(tensor, body.inertia, rtol=1e-14, atol=0)
    # which OpenSim axis each kind turns or slides about, in (parent, child)
    axis_of = {"revolute": (2, 2), "prismatic": (0, 0), "cylindrical": (2, 2), "planar": (2, 2),
               "universal": (0, 1)}
    for joint in system.joints:
        if joint.name not in built.tree:
            continue
        name = built.tree[joint.name]
        mob, osim_joint = built.mobilizers[name], built.joints[name]
        ends = {joint.body_i: (joint.point_i, joint.frame_i), joint.body_j: (joint.point_j, joint.frame_j)}
        for frame, body, column in ((osim_joint.getParentFrame(), mob.parent, axis_of.get(joint.kind, (None,))[0]),
                                    (osim_joint.getChildFrame(), mob.child, axis_of.get(joint.kind, (None, None))[1])):
            X = frame.getTransformInGround(state)
            R = np.array([[X.R().get(i, k) for k in range(3)] for i in range(3)])
            point, scene_frame = ends[body]
            A, origin = (np.eye(3), np.zeros(3)) if body == GROUND else world[body][:2]
            assert np.allclose([X.p()[k] for k in range(3)], A @ np.asarray(point) + origin, rtol=0, atol=1e-12)
            if column is not None:
                assert np.allclose(R[:, column], A @ np.asarray(scene_frame)[:, 2], rtol=0, atol=1e-12)


def test_a_spatial_run_writes_no_files_and_prints_nothing(tmp_path, monkeypatch, capfd):
    """The planar run's guard holds for the spatial one too (a run that
    re-anchors its chart builds and initialises models mid-run)."""
    monkeypatch.chdir(tmp_path)
    scene = TumblingBody()
    raw = run_spatial(with_start(scene), np.linspace(0.0, 2 * scene.quarter, 21),
                      {"integrator": "RungeKuttaMerson", "accuracy": 1e-9, "constraint_tolerance": 1e-10,
                       "max_step": 0.05})
    assert raw.info.facts["recharts"] >= 1
    assert list(tmp_path.iterdir()) == []
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_default_step_without_the_harnesss_peak_rates():
    """Ω from the reference on the dense grid when no peak rates are given:
    at least the rate of Hooke's output where the input angle θ1 = 2t +
    0.35t² passes π/2, ω1/cos β (from tan θ2 = cos β·tan θ1: ω2 = ω1·cos β /
    (cos²θ1 + cos²β·sin²θ1))."""
    t = np.linspace(0.0, 1.0, 11)
    settings = OpensimAdapter().default_settings(spatial_mechanism(hooke()), t)
    quarter = (-2.0 + np.sqrt(4.0 + 1.4 * np.pi / 2)) / 0.7        # θ1 = π/2
    peak = (2.0 + 0.7 * quarter) / np.cos(np.radians(35.0))
    assert settings["max_step"] <= 0.05 / peak
    steps = 0.1 / settings["max_step"]
    assert abs(steps - round(steps)) < 1e-9        # a whole number of steps per sample interval


def reversed_joint(joint: SpatialJoint) -> SpatialJoint:
    """The same joint written from body_j to body_i."""
    return dataclasses.replace(joint, body_i=joint.body_j, body_j=joint.body_i, point_i=joint.point_j,
                               point_j=joint.point_i, frame_i=joint.frame_j, frame_j=joint.frame_i)


def test_reversed_slide_and_universal_joints_meet_the_reference():
    """A tree joint whose parent is its body_j: the driven slide written
    from the carriage to the ground (its slide, so its law, negated), and
    Hooke's cross written from the output to the input (R2 then closes
    the loop)."""
    slide = driven_slide()
    check(dataclasses.replace(slide, joints=(reversed_joint(slide.joints[0]), slide.joints[1]),
                              drives=(dataclasses.replace(slide.drives[0], law=DriveLaw(0.0, -0.3, 0.8)),)),
          np.linspace(0.0, 1.0, 51))
    shafts = hooke()
    check(dataclasses.replace(shafts, joints=(shafts.joints[0], reversed_joint(shafts.joints[1]), shafts.joints[2])),
          np.linspace(0.0, 3.0, 61))


def reversed_hooke() -> SpatialSystem:
    shafts = hooke()
    return dataclasses.replace(shafts, joints=(shafts.joints[0], reversed_joint(shafts.joints[1]), shafts.joints[2]))


def damped_ball() -> SpatialSystem:
    """The torque crank with damping on its ball joint: the scene's damper
    along zi meets no slide there, none is built, and the audit says so."""
    system = torque_crank()
    return dataclasses.replace(system, joints=(system.joints[0], dataclasses.replace(system.joints[1], damping=0.1)))


BUILD_SETTINGS = {"integrator": "RungeKuttaMerson", "accuracy": 1e-9, "constraint_tolerance": 1e-10, "max_step": 0.1}
AUDITED = {"RSSR": lambda: RSSR().system, "delta": lambda: Delta().system, "T-handle": lambda: with_start(TumblingBody()),
           "Hooke reversed": reversed_hooke, "torque crank": torque_crank, "driven slide": driven_slide,
           "cylindrical": lambda: sliding_body("cylindrical", (1.0, 1.0, 1.0))[0], "welded loop": welded_loop,
           "A05": lambda: FlyballGovernor().system, "damped ball": damped_ball}


@pytest.mark.parametrize("scene", list(AUDITED))
def test_model_audit_reads_the_scene_back(scene):
    """Masses, centres of mass, inertia tensors, joint kinds, bodies,
    points and axes (OpenSim's own axis of each joint class in its offset
    frames; closures from their constraints' locations and frames),
    dampers, springs (parsed from their expressions) and gravity read back
    from the built model equal the scene's to 1e-12, through the adapter."""
    from mechval.records.audit import failures
    system = AUDITED[scene]()
    t = np.linspace(0.0, 0.002, 3)          # the start is what is audited; the integrator's settings build nothing
    table = OpensimAdapter().audit(spatial_mechanism(system), t, BUILD_SETTINGS)
    assert failures(table).empty, failures(table).to_string()
    assert (table["verdict"] == "match").sum() >= len(system.bodies) * 10
    if scene == "damped ball":
        assert table.set_index(["item", "quantity"]).loc[("joint S", "damping"), "verdict"] == "note"


def test_model_audit_sees_a_difference():
    """A model built for one scene audited against another whose body has
    its centre of mass moved 1 mm and whose spring is stiffer: those rows,
    and only they, differ."""
    from mechval.engines.opensim.spatial_audit import expected_spatial, read_spatial
    from mechval.engines.opensim.spatial_run import prepare, start_world
    from mechval.records.audit import audit, failures
    system = torque_crank()
    moved = dataclasses.replace(system.bodies[1], com=tuple(np.add(system.bodies[1].com, (0.0, 0.001, 0.0))))
    stiffer = dataclasses.replace(system.springs[0], stiffness=41.0)
    other = dataclasses.replace(system, bodies=(system.bodies[0], moved), springs=(stiffer,))
    t = np.linspace(0.0, 0.1, 3)
    built, _ = prepare(system, start_world(system, t), 0.0, BUILD_SETTINGS, t)
    wrong = failures(audit(expected_spatial(other), read_spatial(built, system)))
    assert list(zip(wrong["item"], wrong["quantity"])) == [("body bob", "com y"), ("spring spring", "stiffness")]


def test_model_audit_catches_an_unturned_slider_frame(monkeypatch):
    """Built with the slide's frames not turned (`X_FROM_Z`: OpenSim slides
    along x, which must be zi), the prismatic joint's axes differ."""
    from mechval.engines.opensim import spatial_model
    from mechval.engines.opensim.spatial_audit import expected_spatial, read_spatial
    from mechval.engines.opensim.spatial_run import prepare, start_world
    from mechval.records.audit import audit, failures
    monkeypatch.setattr(spatial_model, "X_FROM_Z", np.eye(3))
    system, t = driven_slide(), np.linspace(0.0, 0.1, 3)
    built, _ = prepare(system, start_world(system, t), 0.0, BUILD_SETTINGS, t)
    wrong = failures(audit(expected_spatial(system), read_spatial(built, system)))
    assert set(zip(wrong["item"], wrong["quantity"])) == {("joint P", f"axis {s} z{c}") for s in "ij" for c in "xyz"}


class TestSpatialContract(SpatialContract):
    engine = "opensim"
