"""Pinocchio on spatial scenes (engines/pinocchio/spatial_*.py) against the
spatial reference, per column class with mechval's default tolerances
(`DEFAULT_TOLERANCE`): positions 1e-4 m and quaternion components 1e-3
absolute; velocities (with ω), accelerations (with α), forces and
moments/torques relative to the class's peak, 1e-2. Each run uses the
adapter's default settings (`PinocchioAdapter.default_settings`, Ω from
the reference motion and the spring-dampers). Columns the reference
reports missing (reactions redundant constraints leave indeterminate)
are not compared. Also: the integrator's order on a free body's
gyroscopic motion, the step rule's spring-damper rate, λ's sign (the
Newton–Euler residual), and a scene the adapter refuses."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mechval.adapter import PeakRates, Unrepresentable
from mechval.model.drive import DriveLaw
from mechval.model.kinematics import dense_grid, spatial_peak_rate
from mechval.model.mechanism import GROUND, TorqueLaw
from mechval.model.scenario import DEFAULT_TOLERANCE
from mechval.reference.spatial.columns import body_state
from mechval.reference.spatial.dynamics import energy
from mechval.reference.spatial.mechanism import spatial_mechanism, spatial_solution
from mechval.testing import SpatialContract
from mechval.reference.spatial.rotation import frame_from_axis, quaternion_to_matrix
from mechval.reference.spatial.system import (BodyLoad, JointTorque, SpatialBody, SpatialDrive, SpatialJoint,
                                              SpatialSystem)
from spatial_benchmarks import Bricard, FlyballGovernor
from spatial_mechanisms import (HookesJoint, GRAVITY, Bennett, Delta, HeavyTop, RSSR, SphericalFourBar, TumblingBody, inertia,
                                revolute, unit)
from test_spatial_joint_kinds import sliding_body
from spatial_exudyn_cases import torque_pendulum, welded_crank

try:
    import pinocchio  # noqa: F401
except ImportError as exc:
    pytestmark = [pytest.mark.engine, pytest.mark.skip(reason=f"pinocchio cannot be imported ({exc})")]
else:
    pytestmark = pytest.mark.engine
    from mechval.engines.pinocchio.adapter import PinocchioAdapter
    from mechval.engines.pinocchio.spatial_run import run_spatial

#: Column classes: (suffixes, tolerance, absolute).
CLASSES = {
    "position": (("x", "y", "z"), DEFAULT_TOLERANCE["position"], True),
    "quaternion": (("qw", "qx", "qy", "qz"), DEFAULT_TOLERANCE["angle"], True),
    "velocity": (("vx", "vy", "vz", "wx", "wy", "wz"), DEFAULT_TOLERANCE["velocity"], False),
    "acceleration": (("ax", "ay", "az", "alphax", "alphay", "alphaz"), DEFAULT_TOLERANCE["acceleration"], False),
    "force": (("Fx", "Fy", "Fz", "F"), DEFAULT_TOLERANCE["force"], False),
    "torque": (("Mx", "My", "Mz", "T"), DEFAULT_TOLERANCE["torque"], False),
}


def with_velocities(system: SpatialSystem, velocities: dict) -> SpatialSystem:
    return dataclasses.replace(system, velocities=velocities)


#: The step rule's grid here: a tenth of the harness's (`STEP_RULE_GRID`),
#: which costs a second of forward-dynamics reference per scene.
RATE_GRID = 2001


def run_both(system: SpatialSystem, t: np.ndarray, settings: dict | None = None):
    """(reference solution, Pinocchio run, settings) at the adapter's defaults."""
    mechanism = spatial_mechanism(system)
    adapter = PinocchioAdapter()
    dense = dense_grid(t, RATE_GRID)
    motion = mechanism.motion(dense)
    rates = PeakRates(dense, motion, spatial_peak_rate(mechanism, motion, dense))
    settings = {**adapter.default_settings(mechanism, t, rates), **(settings or {})}
    return spatial_solution(system, t), adapter.run(mechanism, t, settings), settings


def ratios(system: SpatialSystem, reference, run) -> dict[str, float]:
    """Per class: max error over its columns / its bound (relative classes:
    tolerance × the class's reference peak). A class whose reference is
    zero throughout (a spherical joint's moment) is left out: see the tests."""
    out = {}
    columns = [c for c in system.motion_columns() + system.reaction_columns() if c not in reference.missing]
    for name, (suffixes, tolerance, absolute) in CLASSES.items():
        chosen = [c for c in columns if c.rsplit(".", 1)[1] in suffixes]
        if not chosen:
            continue
        expected, got = reference.frame[chosen].to_numpy(), run.frame[chosen].to_numpy()
        peak = np.abs(expected).max()
        if not absolute and peak == 0.0:
            continue
        out[name] = float(np.abs(got - expected).max() / (tolerance if absolute else tolerance * peak))
    return out


def assert_within(system, t, settings=None) -> dict[str, float]:
    reference, run, _ = run_both(system, t, settings)
    found = ratios(system, reference, run)
    assert found and max(found.values()) <= 1.0, f"{system.name}: error / bound per class {found}"
    # λ's sign and the subtree sums: the drive efforts come back, the rest is 0
    # (measured ≤ 1e-13, 3e-10 on the delta: its carriers' 1e-9 inertia)
    efforts = np.abs(run.frame.filter(like=".T").to_numpy()).max(initial=1.0)
    assert run.info.facts["newton_euler_residual_max"] <= 1e-6 * efforts
    return found


# -- scenes with a closed form or a benchmark (tests/spatial_*.py) -------------------------------------------


def test_rssr_driven_closed_loop():
    """A loop cut at its ball joint (one CONTACT_3D), a universal joint in the tree."""
    assert_within(RSSR().system, np.linspace(0.0, 2.0, 101))


def test_spherical_fourbar_redundant_constraints():
    """Cut at a revolute (two CONTACT_3D: six rows for five, and three more
    redundant in a spherical 4R): the proximal solver picks λ; the drive
    torque and the motion are unique and compared."""
    assert_within(SphericalFourBar().system, np.linspace(0.0, 2.0, 101))


def test_bennett_overconstrained():
    assert_within(Bennett().system, np.linspace(0.0, 2.0, 101))


def body_resultants(system: SpatialSystem, frame) -> dict[str, np.ndarray]:
    """Each body's resultant constraint load, force and moment about its
    centre of mass (the reference's B.R.* columns: joints and drives, not
    the applied effects), summed from a run's reactions and drive efforts."""
    def pose(body):
        if body == GROUND:
            return np.zeros((len(frame), 3)), np.broadcast_to(np.eye(3), (len(frame), 3, 3))
        q = frame[[f"{body}.q{c}" for c in "wxyz"]].to_numpy()
        return frame[[f"{body}.{c}" for c in "xyz"]].to_numpy(), quaternion_to_matrix(q)

    total = {b.name: np.zeros((len(frame), 6)) for b in system.bodies}
    centre = {b.name: pose(b.name)[0] + pose(b.name)[1] @ np.asarray(b.com) for b in system.bodies}
    efforts = {d.joint: frame[[c for c in system.reaction_columns() if c.startswith(f"{d.name}.")][0]].to_numpy()
               for d in system.drives}

    def add(body, force, moment, at):
        if body != GROUND:
            total[body] += np.concatenate([force, moment + np.cross(at - centre[body], force)], axis=1)

    for j in system.joints:
        origin, R = pose(j.body_j)
        Pj = origin + R @ np.asarray(j.point_j, dtype=float)
        F = frame[[f"{j.name}.F{c}" for c in "xyz"]].to_numpy()
        M = frame[[f"{j.name}.M{c}" for c in "xyz"]].to_numpy()
        if j.name in efforts:
            z = pose(j.body_i)[1] @ j.frame_i[:, 2]
            effort = efforts[j.name][:, None] * z
            F, M = (F, M + effort) if j.kind == "revolute" else (F + effort, M)
        add(j.body_j, F, M, Pj)
        add(j.body_i, -F, -M, Pj)
    return total


@pytest.mark.parametrize("scene", [SphericalFourBar, Bennett, Bricard])
def test_redundant_loops_give_each_bodys_unique_resultant(scene):
    """The proximal solver's λ is one of many, but every body's resultant
    of its joints' loads is unique: the reference's B.R columns (measured
    1 s: force 2e-12, 2e-12, 4e-8 and moment 2e-10, 8e-9, 2e-7 of their
    peaks on the spherical four-bar, Bennett and Bricard)."""
    system = scene().system
    reference, run, _ = run_both(system, np.linspace(0.0, 1.0, 51))
    got = body_resultants(system, run.frame)
    for part, columns in (("force", ("R.Fx", "R.Fy", "R.Fz")), ("torque", ("R.Mx", "R.My", "R.Mz"))):
        chosen = [f"{b.name}.{c}" for b in system.bodies for c in columns]
        expected = reference.frame[chosen].to_numpy()
        pick = slice(0, 3) if part == "force" else slice(3, 6)
        mine = np.concatenate([got[b.name][:, pick] for b in system.bodies], axis=1)
        ratio = np.abs(mine - expected).max() / (DEFAULT_TOLERANCE[part] * np.abs(expected).max())
        assert ratio <= 1.0, f"{part} resultants: {ratio:.3g} of the bound"


def test_bricard_a04_under_gravity():
    """A04: Grübler 0, mobility 1, released at rest; 2 s of its 10."""
    assert_within(Bricard().system, np.linspace(0.0, 2.0, 101))


@pytest.mark.slow
def test_bricard_a04_ten_seconds_keeps_its_energy():
    """A04's whole 10 s and its measure, the mechanical energy: |E − E0|
    over the kinetic energy's peak, held to the velocity tolerance as
    mechval's health check of a conservative scene (`energy_drift`);
    measured 2.3e-7 J of E0 = −29.43 J, 5.1e-8 of the kinetic peak 4.55 J
    (the reference: 3.4e-12 J), every class within 8.4e-4 of its bound
    (about 20 s of CPU)."""
    system = Bricard().system
    reference, run, _ = run_both(system, np.linspace(0.0, 10.0, 1001))
    found = ratios(system, reference, run)
    assert max(found.values()) <= 1.0, found
    pose, w, _ = body_state(system, run.frame)
    total = energy(system, pose, w)
    kinetic = energy(dataclasses.replace(system, gravity=(0.0, 0.0, 0.0)), pose, w)
    drift = np.abs(total - total[0]).max() / kinetic.max()
    assert drift <= DEFAULT_TOLERANCE["velocity"], f"energy drift {drift:.3g} of the kinetic energy's peak"


def test_delta_robot_three_drives():
    """Two loops closed at universal joints, each the joint itself on a
    near-massless carrier welded to the platform (CONTACT_6D)."""
    assert_within(Delta().system, np.linspace(0.0, 1.0, 51))


def test_t_handle_flips_about_its_intermediate_axis():
    """A free body (free flyer): the flip at twice the quarter period."""
    m = TumblingBody()
    assert_within(with_velocities(m.system, m.velocities), np.linspace(0.0, 2.4 * m.quarter, 121))


def test_heavy_top_on_a_spherical_joint():
    """Spin 200 rad/s: Ω sets dt ≈ 1e-4 s. The ball joint's moment is zero
    in theory; here rounding."""
    m = HeavyTop()
    system = with_velocities(m.system, m.velocities)
    reference, run, _ = run_both(system, np.linspace(0.0, 0.3, 31))
    found = ratios(system, reference, run)
    assert max(found.values()) <= 1.0, found
    moment = np.abs(run.frame[[f"tip.M{c}" for c in "xyz"]].to_numpy()).max()
    assert moment <= 1e-9 * m.mass * 9.81 * m.arm


@pytest.mark.parametrize("kind, axis, speed, spin", [("cylindrical", (1.0, 1.0, 1.0), 0.4, 7.0),
                                                     ("planar", (0.2, -0.3, 1.0), 0.5, -5.0)])
def test_cylindrical_and_planar_joints(kind, axis, speed, spin):
    """The composite PZ + RZ and the native planar joint: a body sliding
    and spinning under gravity; the joint supplies the gyroscopic moment."""
    system, u = sliding_body(kind, axis)
    v0 = speed * (u if kind == "cylindrical" else unit(np.cross(u, [1.0, 0.0, 0.0])))
    assert_within(with_velocities(system, {"body": (tuple(v0), tuple(spin * u))}), np.linspace(0.0, 1.0, 51))


def hooke() -> SpatialSystem:
    return HookesJoint().system


def test_universal_joint_closing_a_loop():
    """Hooke's joint: the loop cut at a revolute, the universal in the tree."""
    assert_within(hooke(), np.linspace(0.0, 2.0, 101))


def test_fixed_joint_as_a_rigid_frame():
    """A plate welded to a driven crank: no Pinocchio joint; its reaction
    from the plate's own Newton–Euler."""
    axis = unit((0.3, 0.1, 1.0))
    system = SpatialSystem(
        "crank and plate", (SpatialBody("crank", 2.0, (0.1, 0.0, 0.05), inertia(50)),
                            SpatialBody("plate", 1.0, (0.3, 0.1, -0.1), inertia(51))),
        (revolute("O", GROUND, "crank", (0.0, 0.0, 0.0), axis),
         SpatialJoint("W", "fixed", "crank", "plate", (0.25, 0.0, 0.0), (0.25, 0.0, 0.0))),
        (SpatialDrive("O", DriveLaw(0.2, 3.0, 1.5)),), GRAVITY)
    assert_within(system, np.linspace(0.0, 1.0, 51))


def rsup() -> SpatialSystem:
    """A spatial slider-crank: crank about z (driven), a ball at its pin, a
    rod to a universal joint on a slider guided along x at height h; the
    slider's prismatic joint written last."""
    a, length, h, theta = 0.1, 0.35, 0.12, 0.4
    P = np.array([a * np.cos(theta), a * np.sin(theta), 0.0])
    Q = np.array([a * np.cos(theta) + np.sqrt(length**2 - h**2 - (a * np.sin(theta))**2), 0.0, h])
    pin_slider = np.array([0.0, 1.0, 0.0])
    pin_rod = unit(np.cross(pin_slider, Q - P))
    return SpatialSystem(
        "RSUP", (SpatialBody("crank", 0.4, tuple(P / 2), inertia(70)),
                 SpatialBody("rod", 0.3, tuple((P + Q) / 2), inertia(71)),
                 SpatialBody("slider", 0.5, tuple(Q), inertia(72))),
        (revolute("O", GROUND, "crank", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0)),
         SpatialJoint("S", "spherical", "crank", "rod", tuple(P), tuple(P)),
         SpatialJoint("U", "universal", "rod", "slider", tuple(Q), tuple(Q), frame_from_axis(pin_rod),
                      frame_from_axis(pin_slider)),
         revolute("G", GROUND, "slider", Q, (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), kind="prismatic")),
        (SpatialDrive("O", DriveLaw(0.0, 2.0, 0.5)),), GRAVITY)


def test_a_loop_closed_at_a_prismatic_joint_by_a_carrier(monkeypatch):
    """With the ball ranked a tree joint, the loop's cut falls on the
    slider's prismatic joint (written last): a carrier on a PZ from the
    ground, welded to the slider."""
    from mechval.engines.pinocchio import spatial_model
    monkeypatch.setitem(spatial_model.TREE_RANK, "spherical", 1)
    _, cuts = spatial_model.topology(rsup())
    assert [j.name for j in cuts] == ["G"]
    assert_within(rsup(), np.linspace(0.0, 1.0, 51))


@pytest.mark.parametrize("reversed_", [False, True])
def test_a_revolute_whose_axes_point_apart(reversed_):
    """zj = −zi (the scene allows it): a driven crank whose frame_j is
    built on the opposite axis, written ground → crank or crank → ground
    (the tree then runs against the joint)."""
    axis = unit((0.3, 0.1, 1.0))
    frame_i, frame_j = frame_from_axis(axis, (1.0, 0.0, 0.0)), frame_from_axis(-axis, (1.0, 0.0, 0.0))
    ends = (("crank", GROUND), (frame_j, frame_i)) if reversed_ else ((GROUND, "crank"), (frame_i, frame_j))
    joint = SpatialJoint("O", "revolute", *ends[0], (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), *ends[1])
    system = SpatialSystem("crank", (SpatialBody("crank", 2.0, (0.1, 0.0, 0.05), inertia(50)),), (joint,),
                           (SpatialDrive("O", DriveLaw(0.2, 3.0, 1.5)),), GRAVITY)
    assert_within(system, np.linspace(0.0, 1.0, 51))


def test_a_loop_cut_at_a_revolute_whose_axes_point_apart():
    """The spherical four-bar with D's frame_j on the opposite axis: the
    cut's second points sit on either side to meet."""
    m = SphericalFourBar()
    joints = tuple(dataclasses.replace(j, frame_j=frame_from_axis(-m.w)) if j.name == "D" else j
                   for j in m.system.joints)
    assert_within(dataclasses.replace(m.system, joints=joints), np.linspace(0.0, 1.0, 51))


def test_prismatic_drive_and_damper():
    """A body on a prismatic joint: driven; then free, damped, falling."""
    system, u = sliding_body("prismatic", (0.3, -0.2, 1.0))
    driven = dataclasses.replace(system, drives=(SpatialDrive("J", DriveLaw(0.0, 0.5, -1.0)),))
    assert_within(driven, np.linspace(0.0, 1.0, 51))
    damped = dataclasses.replace(system, joints=(dataclasses.replace(system.joints[0], damping=2.0),),
                                 velocities={"body": (tuple(0.3 * u), (0.0, 0.0, 0.0))})
    assert_within(damped, np.linspace(0.0, 1.0, 51))


def test_torque_law_in_the_tree_and_damper_at_the_cut_of_hookes_joint():
    """Hooke's joint undriven: a torque law at R1 (a tree joint), a damper
    at R2 (the loop's cut), from rest."""
    system = hooke()
    joints = tuple(dataclasses.replace(j, damping=0.05) if j.name == "R2" else j for j in system.joints)
    free = dataclasses.replace(system, joints=joints, drives=(),
                               torques=(JointTorque("R1", TorqueLaw("R1", 0.2, 0.1, 2.0), "motor"),))
    assert_within(free, np.linspace(0.0, 1.0, 51))


def test_torque_law_damper_and_load_on_the_fourbar():
    """The spherical four-bar without its drive: a torque law at the cut
    revolute D (a pair of body torques), a damper at B (tree), a body
    load on the coupler; integrated from rest."""
    m = SphericalFourBar()
    joints = tuple(dataclasses.replace(j, damping=0.02) if j.name == "B" else j for j in m.system.joints)
    system = dataclasses.replace(m.system, joints=joints, drives=(),
                                 torques=(JointTorque("D", TorqueLaw("D", 0.1, 0.05, 1.0), "motor"),),
                                 loads=(BodyLoad("push", "coupler", (0.5, 0.0, 0.2), (0.0, 0.01, 0.0)),))
    assert_within(system, np.linspace(0.0, 1.0, 51))


@pytest.mark.slow          # ~15 s of CPU: the stiff reference and RK4 at the springs' step
def test_flyball_governor_a05_springs():
    """A05's stiff spring-dampers (k 8e5 N/m, c 4e4 N·s/m), 20 ms: the step
    comes from the springs (`force_rate`: √(k/m) = 516 rad/s), not the
    motion's Ω = 31 rad/s, at whose step RK4 diverges (measured: the
    state is not finite after 6 ms at dt = 5e-4 s)."""
    m = FlyballGovernor()
    system = with_velocities(m.system, m.velocities)
    t = np.linspace(0.0, 0.02, 21)
    _, _, settings = run_both(system, t[:2])
    assert settings["timestep"] < 5e-5
    assert_within(system, t)
    with pytest.raises(FloatingPointError):
        run_spatial(system, t, {**settings, "timestep": 5e-4})


# -- the integrator and the refusals -------------------------------------------------------------------------


def test_rkmk4_keeps_fourth_order_on_the_free_body():
    """The T-handle through its flip at 2 and 4 × the default step: the
    angular velocity's error falls as dt⁴ (measured ratio ≈ 16; a
    Lie-group update that dropped dexp⁻¹ or the gyroscopic term ω × Jω
    would fall as dt² at best)."""
    m = TumblingBody()
    system = with_velocities(m.system, m.velocities)
    t = np.linspace(0.0, 2.4 * m.quarter, 25)
    reference, run, settings = run_both(system, t)
    errors = []
    for factor in (2.0, 4.0):
        coarse = run_spatial(system, t, {**settings, "timestep": factor * settings["timestep"]})
        columns = [f"body.w{c}" for c in "xyz"]
        errors.append(np.abs(coarse.frame[columns].to_numpy() - reference.frame[columns].to_numpy()).max())
    assert errors[1] / errors[0] >= 12.0, f"error ratio at double the step: {errors[1] / errors[0]:.3g}"


def test_finding_massless_welded_joint_is_present():
    """The probe measures the finding on the installed version (a release
    that fixes it fails this test: update the finding and the carriers);
    1e-12 kg on the joint gives the exact value, so the exact value is right."""
    from mechval.engines.pinocchio import findings
    measured = findings.probe_massless_welded_joint()
    assert measured.present and measured.figure == np.inf, measured.describe()
    read, exact = findings.welded_pendulum(carrier_mass=1e-12)
    assert read == pytest.approx(exact, rel=1e-9)


def test_the_spatial_model_holds_no_effect_the_scene_lacks():
    """No friction, damping, armature or rotor inertia in the built model
    (every joint kind and a carrier: the delta and the RSSR)."""
    from mechval.engines.pinocchio.spatial_model import build_spatial_model
    for system in (Delta().system, RSSR().system):
        model = build_spatial_model(system).model
        for name in ("friction", "damping", "armature", "rotorInertia"):
            assert not np.any(np.asarray(getattr(model, name))), f"{system.name}: model.{name}"


def test_a_drive_that_closes_a_loop_of_drives_is_refused():
    """Every pin of the spherical four-bar driven: one of them must close
    the loop, and a driven joint must be a tree coordinate here."""
    m = SphericalFourBar()
    drives = tuple(SpatialDrive(j.name, DriveLaw(0.0, 1.0, 0.0), f"drive{j.name}") for j in m.system.joints)
    system = SpatialSystem("all driven", m.system.bodies, m.system.joints, drives, GRAVITY)
    settings = {"timestep": 0.01, "proximal_accuracy": 1e-12, "proximal_mu": 1e-8, "proximal_max_iterations": 50,
                "baumgarte_steps": 300.0}
    with pytest.raises(Unrepresentable) as refused:
        run_spatial(system, np.linspace(0.0, 0.1, 3), settings)
    assert refused.value.key == "drive.driveD"


def flipped_crank() -> SpatialSystem:
    """A driven crank written crank → ground with zj against zi (the
    adapter turns the child's frame)."""
    axis = unit((0.3, 0.1, 1.0))
    joint = SpatialJoint("O", "revolute", "crank", GROUND, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                         frame_from_axis(-axis, (1.0, 0.0, 0.0)), frame_from_axis(axis, (1.0, 0.0, 0.0)))
    return SpatialSystem("crank", (SpatialBody("crank", 2.0, (0.1, 0.0, 0.05), inertia(50)),), (joint,),
                         (SpatialDrive("O", DriveLaw(0.2, 3.0, 1.5)),), GRAVITY)


def fourbar_cut_flipped() -> SpatialSystem:
    """The spherical four-bar with its cut D's zj against zi."""
    m = SphericalFourBar()
    joints = tuple(dataclasses.replace(j, frame_j=frame_from_axis(-m.w)) if j.name == "D" else j
                   for j in m.system.joints)
    return dataclasses.replace(m.system, joints=joints)


AUDITED = {"RSSR": lambda: RSSR().system, "delta": lambda: Delta().system,
           "T-handle": lambda: with_velocities(TumblingBody().system, TumblingBody().velocities),
           "Hooke": hooke, "A05": lambda: FlyballGovernor().system,
           "cylindrical": lambda: sliding_body("cylindrical", (0.3, -0.2, 1.0))[0],
           "fixed": welded_crank, "torque law, spring, load, damper": torque_pendulum,
           "flipped revolute": flipped_crank, "flipped cut": fourbar_cut_flipped, "carrier": rsup}


@pytest.mark.parametrize("scene", list(AUDITED))
def test_model_audit_reads_the_scene_back(scene, monkeypatch):
    """Masses, centres of mass, inertia tensors (each body's frame's),
    joint kinds, bodies, points and axes (tree joints, point and weld
    constraints, a carrier's joint, flipped frames turned back) and gravity
    read back from the built model equal the scene's to 1e-12 (dampers
    and springs "as set": the adapter applies them), through the adapter."""
    from mechval.engines.pinocchio import spatial_model
    from mechval.records.audit import failures
    if scene == "carrier":      # the loop's cut on the prismatic joint (as test_a_loop_closed_at_a_prismatic...)
        monkeypatch.setitem(spatial_model.TREE_RANK, "spherical", 1)
    system = AUDITED[scene]()
    t = np.linspace(0.0, 0.002, 3)         # the model takes no settings
    table = PinocchioAdapter().audit(spatial_mechanism(system), t, {})
    assert failures(table).empty, failures(table).to_string()
    assert (table["verdict"] == "match").sum() >= len(system.bodies) * 10
    if scene == "carrier":
        assert "JointModelPZ" in table.set_index(["item", "quantity"]).loc[("joint G", "kind"), "note"]


def test_model_audit_sees_a_difference():
    """A model built for one scene audited against another whose body has
    its centre of mass moved 1 mm: that row, and only it, differs; and a
    joint's inertia that is not its frames' sum is listed."""
    from mechval.engines.pinocchio.spatial_audit import expected_spatial, read_spatial
    from mechval.engines.pinocchio.spatial_model import build_spatial_model
    from mechval.records.audit import audit, failures
    system = RSSR().system
    moved = dataclasses.replace(system.bodies[1], com=tuple(np.add(system.bodies[1].com, (0.0, 0.001, 0.0))))
    other = dataclasses.replace(system, bodies=(system.bodies[0], moved, system.bodies[2]))
    sm = build_spatial_model(system)
    wrong = failures(audit(expected_spatial(other), read_spatial(sm, system)))
    assert list(zip(wrong["item"], wrong["quantity"])) == [("body coupler", "com y")]
    index = sm.joint_of["coupler"]
    held = sm.model.inertias[index]
    sm.model.inertias[index] = pinocchio.Inertia(held.mass * 1.001, held.lever, held.inertia)
    wrong = failures(audit(expected_spatial(system), read_spatial(sm, system)))
    assert list(zip(wrong["item"], wrong["quantity"])) == [(f"pinocchio joint {index}", "inertia")]


def test_model_audit_catches_an_unturned_universal_frame(monkeypatch):
    """Built with the child's frame not turned (`UNIVERSAL_TURN`: its pin
    zj must be Pinocchio's axis2, x), Hooke's cross differs on body_j."""
    from mechval.engines.pinocchio import spatial_model
    from mechval.engines.pinocchio.spatial_audit import expected_spatial, read_spatial
    from mechval.records.audit import audit, failures
    monkeypatch.setattr(spatial_model, "UNIVERSAL_TURN", np.eye(3))
    system = hooke()
    wrong = failures(audit(expected_spatial(system), read_spatial(spatial_model.build_spatial_model(system), system)))
    assert set(wrong["quantity"]) and set(wrong["quantity"]) <= {f"axis j z{c}" for c in "xyz"}


class TestSpatialContract(SpatialContract):
    engine = "pinocchio"
