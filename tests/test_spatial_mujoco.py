"""MuJoCo on spatial scenes (issue 26, "Engines"): each scene run by the
adapter at its default settings against the spatial reference at the same
instants, per signal class with mechval's default tolerances
(`DEFAULT_TOLERANCE`): positions and quaternion components absolute,
velocities, accelerations, forces and moments relative to the class's peak
over the columns the reference reports (redundant constraints leave some
reactions missing there: only the others are compared). The model and
its read-out: engines/mujoco/spatial_model.py and spatial.py."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mechval.adapter import PeakRates, Unrepresentable
from mechval.model.kinematics import peak_rate
from mechval.reference.spatial.rotation import quaternion_to_matrix
from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND, TorqueLaw
from mechval.model.scenario import DEFAULT_TOLERANCE
from mechval.reference.spatial.mechanism import spatial_mechanism, spatial_solution
from mechval.reference.spatial.resultants import spatial_resultants
from mechval.reference.spatial.rotation import frame_from_axis
from mechval.testing import SpatialContract
from mechval.reference.spatial.system import (BodyLoad, JointTorque, SpatialBody, SpatialDrive, SpatialJoint,
                                              SpatialSystem, Spring)
from spatial_benchmarks import Bricard, FlyballGovernor
from spatial_mechanisms import HookesJoint, GRAVITY, RSSR, Bennett, Delta, HeavyTop, SphericalFourBar, TumblingBody, inertia, \
    revolute, unit
from test_spatial_joint_kinds import sliding_body
from test_spatial_pybullet import driven_slide
from spatial_audit_checks import assert_the_audit_sees_a_moved_centre_and_a_tilted_axis

try:
    import mujoco  # noqa: F401
except ImportError as exc:
    # Each test skips, saying why (as tests/test_mujoco.py does).
    pytestmark = [pytest.mark.engine, pytest.mark.skip(reason=f"mujoco cannot be imported ({exc})")]
else:
    pytestmark = pytest.mark.engine     # every test here runs MuJoCo
    from mechval.engines.mujoco.adapter import MujocoAdapter
    from mechval.engines.mujoco.spatial_model import spanning_tree

class TestMujocoSpatialContract(SpatialContract):
    """The spatial contract (gravity and reactions in 3-D, a ball joint's
    reaction, a rotor's gyroscopic moment, a free body's momentum)."""

    engine = "mujoco"


CLASSES = {"x": "position", "y": "position", "z": "position", "qw": "angle", "qx": "angle", "qy": "angle",
           "qz": "angle", "vx": "velocity", "vy": "velocity", "vz": "velocity", "wx": "velocity", "wy": "velocity",
           "wz": "velocity", "ax": "acceleration", "ay": "acceleration", "az": "acceleration",
           "alphax": "acceleration", "alphay": "acceleration", "alphaz": "acceleration",
           "Fx": "force", "Fy": "force", "Fz": "force", "F": "force",
           "Mx": "torque", "My": "torque", "Mz": "torque", "T": "torque"}
#: A class whose reference peak is below this (e.g. a ball joint's moment,
#: zero but for rounding) is compared absolutely, against this bound: MuJoCo's
#: value there must be rounding too.
ZERO_PEAK = 1e-9


#: The step rule's grid here (the harness's has 20,001 instants): one
#: reference solve on it gives Ω and, at every `DENSE`-th instant, the
#: reference the run is compared to (a tenth of the cost; on these smooth
#: one-second runs Ω is the same to well under the rule's own rounding).
DENSE = 20


def run(system: SpatialSystem, t: np.ndarray, **overrides):
    """MuJoCo's run at default settings (Ω from `DENSE`× finer instants)
    and the reference at t."""
    mechanism = spatial_mechanism(system)
    adapter = MujocoAdapter()
    fine = np.linspace(t[0], t[-1], DENSE * (len(t) - 1) + 1)
    ref = spatial_solution(system, fine)
    rates = PeakRates(fine, ref.frame, peak_rate(mechanism, ref.frame, fine))
    settings = {**adapter.default_settings(mechanism, t, rates=rates), **overrides}
    ref = dataclasses.replace(ref, frame=ref.frame.iloc[::DENSE].reset_index(drop=True))
    assert np.allclose(ref.frame["t"], t, rtol=0, atol=1e-12)
    raw = adapter.run(mechanism, t, settings)
    if ref.structure.redundant:         # each body's resultant, as the harness adds it
        raw = dataclasses.replace(raw, frame=raw.frame.assign(**spatial_resultants(system, raw.frame)))
    return raw, ref


def errors(raw, ref) -> dict[str, float]:
    """Per class the measure of `DEFAULT_TOLERANCE`: absolute for positions
    and quaternions, else max|err| / max|reference| over the class's columns."""
    columns: dict[str, list[str]] = {}
    for name in ref.frame.columns[1:]:
        if name not in ref.missing:
            columns.setdefault(CLASSES[name.rsplit(".", 1)[1]], []).append(name)
    out = {}
    for cls, names in columns.items():
        assert set(names) <= set(raw.frame.columns), f"MuJoCo left out {sorted(set(names) - set(raw.frame.columns))}"
        err = float(np.abs(raw.frame[names].to_numpy() - ref.frame[names].to_numpy()).max())
        peak = float(np.abs(ref.frame[names].to_numpy()).max())
        out[cls] = err if cls in ("position", "angle") or peak < ZERO_PEAK else err / peak
    return out


def check(system: SpatialSystem, t: np.ndarray, bounds=None, **overrides):
    """Every class within its bound; returns (measures, run, reference)."""
    raw, ref = run(system, t, **overrides)
    assert np.all(np.isfinite(raw.frame.to_numpy())), "MuJoCo's run has NaN"
    measured = errors(raw, ref)
    bounds = {**DEFAULT_TOLERANCE, **(bounds or {})}
    for cls, err in measured.items():
        bound = ZERO_PEAK if cls not in ("position", "angle") and \
            float(np.abs(ref.frame[[c for c in ref.frame.columns[1:] if c not in ref.missing and
                                    CLASSES[c.rsplit(".", 1)[1]] == cls]].to_numpy()).max()) < ZERO_PEAK \
            else bounds[cls]
        assert err <= bound, f"{system.name}: {cls} off by {err:.3g} (bound {bound:g}); all: {measured}"
    assert raw.info.warnings == 0, raw.info
    return measured, raw, ref


ONE_SECOND = np.linspace(0.0, 1.0, 101)


def test_spherical_fourbar_driven_closed_loop():
    """Four revolute axes through one point (three redundant rows: the
    reference reports no joint reaction, only the drive torque)."""
    check(SphericalFourBar().system, ONE_SECOND)


def test_rssr_reactions_through_a_ball_and_a_universal_joint():
    """The loop is cut at the ball (one connect); every reaction is unique."""
    _, raw, ref = check(RSSR().system, ONE_SECOND)
    assert not ref.missing and {"P.Fx", "Q.Mz", "C.My"} <= set(raw.frame.columns)


def test_bennett_overconstrained_loop():
    """Bennett's linkage: the 4R loop MuJoCo closes with a revolute cut
    (two connects, six rows for five), redundant as a whole: its soft,
    regularised rows take the redundancy."""
    check(Bennett().system, ONE_SECOND)


@pytest.mark.slow
def test_bricard_released_under_gravity():
    """A04's first second: Grübler 0, mobility 1, no drive (10 s: the
    reference integrates the second at its tight tolerance)."""
    check(Bricard().system, ONE_SECOND)


def test_delta_robot_three_drives_and_universal_cuts():
    """Three legs, two loops closed at universal joints (a connect and a
    tendon holding the pins square)."""
    check(Delta().system, ONE_SECOND)


def with_velocities(m) -> SpatialSystem:
    return dataclasses.replace(m.system, velocities=m.velocities)


def test_t_handle_flips():
    """The free body through its intermediate-axis flip (the gyroscopic
    term decides it): 2.4 quarter periods, ω2 changes sign."""
    m = TumblingBody()
    t = np.linspace(0.0, 2.4 * m.quarter, 241)
    _, raw, _ = check(with_velocities(m), t)
    A = quaternion_to_matrix(raw.frame[["body.qw", "body.qx", "body.qy", "body.qz"]].to_numpy())
    omega = np.einsum("nji,nj->ni", A, raw.frame[["body.wx", "body.wy", "body.wz"]].to_numpy())   # body axes
    assert omega[0, 1] > 3.9 and omega[-1, 1] < -3.9, "the flip did not happen"


def test_heavy_top_precesses():
    """A quarter of the slow precession of a top on a ball joint; the
    ball's moment is zero in the reference (compared absolutely)."""
    m = HeavyTop()
    check(with_velocities(m), np.linspace(0.0, 0.5 * np.pi / m.precession, 101))


@pytest.mark.parametrize("kind, axis", [("cylindrical", (1.0, 1.0, 1.0)), ("planar", (0.2, -0.3, 1.0))])
def test_sliding_body_joint_kinds(kind, axis):
    """A body sliding and spinning under gravity on a cylindrical (slide +
    hinge) and a planar joint (two slides + hinge)."""
    system, u = sliding_body(kind, axis)
    v0 = 0.4 * u if kind == "cylindrical" else unit(np.cross(u, [1.0, 0.0, 0.0])) * 0.5
    system = dataclasses.replace(system, velocities={"body": (tuple(v0), tuple(7.0 * u))})
    check(system, ONE_SECOND)


def hooke() -> SpatialSystem:
    """Hooke's joint of tests/test_spatial_joint_kinds.py: a universal
    joint in the tree (the loop is cut at the output's bearing)."""
    return HookesJoint().system


def test_universal_joint_in_the_tree():
    check(hooke(), ONE_SECOND)


def crank_plate_slider() -> SpatialSystem:
    """A driven crank with a plate welded to it (fixed joint) and a block
    driven along the crank (a prismatic drive): two drives, no loop."""
    axis = unit((0.3, 0.1, 1.0))
    slide = frame_from_axis((1.0, 0.0, 0.0))
    return SpatialSystem(
        "crank, plate and slider",
        (SpatialBody("crank", 2.0, (0.1, 0.0, 0.05), inertia(50)), SpatialBody("plate", 1.0, (0.3, 0.1, -0.1), inertia(51)),
         SpatialBody("block", 0.5, (0.2, 0.0, 0.0), inertia(52, 1e-4))),
        (revolute("O", GROUND, "crank", (0.0, 0.0, 0.0), axis),
         SpatialJoint("W", "fixed", "crank", "plate", (0.25, 0.0, 0.0), (0.25, 0.0, 0.0)),
         SpatialJoint("S", "prismatic", "crank", "block", (0.2, 0.0, 0.0), (0.2, 0.0, 0.0), slide, slide)),
        (SpatialDrive("O", DriveLaw(0.2, 3.0, 1.5), "crank_drive"), SpatialDrive("S", DriveLaw(0.0, 0.1, -0.2), "push")),
        GRAVITY)


def test_fixed_joint_and_prismatic_drive():
    check(crank_plate_slider(), ONE_SECOND)


def forced_arm() -> SpatialSystem:
    """Torque-driven: an arm on a tilted damped hinge under a sinusoidal
    torque law and a constant body load, a block on a damped slide along
    it pulled by a spring-damper from the ground; gravity askew."""
    axis = unit((0.2, 0.3, 1.0))
    slide = frame_from_axis((1.0, 0.0, 0.0))
    hinge = revolute("O", GROUND, "arm", (0.0, 0.0, 0.0), axis)
    return SpatialSystem(
        "forced arm", (SpatialBody("arm", 1.0, (0.15, 0.0, 0.0), inertia(70, 1e-2)),
                       SpatialBody("block", 0.4, (0.0, 0.0, 0.0), inertia(71, 1e-3), position=(0.25, 0.0, 0.0))),
        (dataclasses.replace(hinge, damping=0.05),
         SpatialJoint("S", "prismatic", "arm", "block", (0.25, 0.0, 0.0), (0.0, 0.0, 0.0), slide, slide, damping=0.8)),
        gravity=(1.0, -2.0, -9.81),
        springs=(Spring("spring", GROUND, (0.0, 0.4, 0.1), "block", (0.0, 0.0, 0.0), 40.0, 0.3, 0.5),),
        loads=(BodyLoad("push", "arm", (0.5, -0.2, 0.1), (0.0, 0.05, -0.1)),),
        torques=(JointTorque("O", TorqueLaw("O", 0.2, 0.5, 1.5, 0.3), "motor"),))


def test_torque_law_spring_damper_and_body_load():
    check(forced_arm(), ONE_SECOND)


def test_a_loop_only_a_slide_closes_is_refused():
    """Two bodies joined to the ground and to each other by prismatic joints
    only: MuJoCo's model closes loops at ball, hinge or universal joints."""
    slide = frame_from_axis((1.0, 0.0, 0.0))
    bodies = tuple(SpatialBody(n, 1.0, (0.0, 0.0, 0.0), inertia(80 + k)) for k, n in enumerate(("a", "b")))
    joints = (SpatialJoint("Sa", "prismatic", GROUND, "a", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), slide, slide),
              SpatialJoint("Sb", "prismatic", GROUND, "b", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), slide, slide),
              SpatialJoint("Sab", "cylindrical", "a", "b", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), slide, slide))
    system = SpatialSystem("slides", bodies, joints, (SpatialDrive("Sa", DriveLaw(0.0, 0.1, 0.0)),))
    with pytest.raises(Unrepresentable) as caught:
        spanning_tree(system)
    assert caught.value.key == "joint.Sab.kind"


def gyroscopic_run(integrator: str, refine: int):
    """The T-handle through its flip with one of MuJoCo's integrators: the
    flip instant (ω2 = 0 in body axes, linear between samples) of MuJoCo
    and of the reference, and the largest relative drift of the energy."""
    m = TumblingBody()
    t = np.linspace(0.0, 2.4 * m.quarter, 241)
    raw, ref = run(with_velocities(m), t, integrator=integrator, refine=refine)

    def body_omega(frame):
        A = quaternion_to_matrix(frame[["body.qw", "body.qx", "body.qy", "body.qz"]].to_numpy())
        return np.einsum("nji,nj->ni", A, frame[["body.wx", "body.wy", "body.wz"]].to_numpy())

    def flip(w):
        k = np.flatnonzero(np.diff(np.sign(w[:, 1])))[0]
        return t[k] - w[k, 1] * (t[k + 1] - t[k]) / (w[k + 1, 1] - w[k, 1])

    w = body_omega(raw.frame)
    energy = 0.5 * (w ** 2 @ np.array(m.principal))
    return flip(w), flip(body_omega(ref.frame)), float(np.abs(energy / energy[0] - 1).max())


@pytest.mark.slow
def test_gyroscopic_term_by_integrator():
    """MuJoCo's RK4 keeps the whole gyroscopic term ω × Iω of the free body
    (its flip instant within 1e-9 s of the reference's, energy within
    1e-11; measured 3.5e-12 s, 1.4e-13 at the default step 0.975 ms).
    Euler and implicitfast keep it too, to first order: their flip is
    late (Euler) or early (implicitfast) by an amount proportional to the
    step (1.20e-3 s and −1.19e-3 s at the default step, a quarter of that
    at a quarter of the step), not dropped (no flip) or frozen. Ratios
    between 3.6 and 4.4 allow for the second-order remainder."""
    flip, expected, drift = gyroscopic_run("RK4", 1)
    assert abs(flip - expected) <= 1e-9 and drift <= 1e-11, (flip - expected, drift)
    for integrator, sign in (("Euler", 1.0), ("implicitfast", -1.0)):
        coarse, expected, _ = gyroscopic_run(integrator, 1)
        fine, _, _ = gyroscopic_run(integrator, 4)
        assert sign * (coarse - expected) > 0 and 3.6 <= (coarse - expected) / (fine - expected) <= 4.4, \
            (integrator, coarse - expected, fine - expected)


FLYBALL_FIRST = np.linspace(0.0, 0.02, 11)      # the fast mode dies out in a few ms


@pytest.mark.slow
def test_flyball_governor_stiff_springs():
    """A05's spring-dampers (k = 8e5 N/m, c = 4e4 N·s/m) have a fast mode
    (the first 2 ms): the step rule's Ω counts the springs' rate √(Σk/m),
    dt 13.6 µs; measured 2.3e-11 of the acceleration peak, 2.1e-12 of the
    force peak over the first 20 ms. (With Ω from the motion alone, dt
    0.333 ms, RK4 lagged that mode: 0.733 and 0.069.)"""
    measured, raw, _ = check(with_velocities(FlyballGovernor()), FLYBALL_FIRST)
    assert raw.info.facts["step"] < 1e-4, raw.info.facts["step"]

def reversed_joint(j: SpatialJoint) -> SpatialJoint:
    """The same joint declared the other way round (body_i ↔ body_j)."""
    return dataclasses.replace(j, body_i=j.body_j, body_j=j.body_i, point_i=j.point_j, point_j=j.point_i,
                               frame_i=j.frame_j, frame_j=j.frame_i)


def test_joints_declared_child_first():
    """Crank, plate and slider with every joint declared from the child
    (the tree's coordinates then run against the scene's: sign −1 on the
    hinge, the slide, both drives and every reaction); the laws are the
    negatives, so the motion is the same."""
    system = crank_plate_slider()
    laws = {"O": DriveLaw(-0.2, -3.0, -1.5), "S": DriveLaw(0.0, -0.1, 0.2)}
    check(dataclasses.replace(system, joints=tuple(reversed_joint(j) for j in system.joints),
                              drives=tuple(dataclasses.replace(d, law=laws[d.joint]) for d in system.drives)),
          ONE_SECOND)


class Sine:
    """φ(t) = sin t: a law whose acceleration is not constant."""

    def angle(self, t):
        return np.sin(t)

    def rate(self, t):
        return np.cos(t)

    def acceleration(self, t):
        return -np.sin(t)


def test_a_drive_of_varying_acceleration_is_refused():
    """The clock follows φ̈ = const only (the planar model's rule too)."""
    from mechval.engines.mujoco.spatial_model import constant_acceleration
    with pytest.raises(Unrepresentable) as caught:
        constant_acceleration(SpatialDrive("O", Sine(), "wave"))
    assert caught.value.key == "drive.wave"
    assert constant_acceleration(SpatialDrive("O", DriveLaw(0.1, 2.0, -0.7))) == -0.7


def test_a_point_mass_is_refused_naming_its_inertia():
    """MuJoCo needs every principal moment of a moving body ≥ 1e-14 kg·m²
    (the spatial reference takes a point mass; the MJCF refuses it before
    MuJoCo's compiler would, naming the body's key)."""
    from mechval.engines.mujoco.spatial_model import Pose, mjcf
    system, _ = sliding_body("spherical", (0.0, 0.0, 1.0))
    system = dataclasses.replace(system, bodies=(dataclasses.replace(system.bodies[0], inertia=np.zeros((3, 3))),))
    settings = {"solref_steps": 10.0, "solref_dampratio": 1.0, "drive_solref_steps": 1.0, "solimp": "0.9999 0.9999 0.001 0.5 2",
                "integrator": "RK4", "clock_mass": 1e12, "tolerance": 0.0, "iterations": 3}
    with pytest.raises(Unrepresentable) as caught:
        mjcf(system, spanning_tree(system), {"body": Pose(np.zeros(3), np.eye(3))}, settings, 1e-3)
    assert caught.value.key == "body.body.inertia"


#: Planar built-ins MuJoCo's spatial model refuses, with the key it names:
#: point-mass sliders (no inertia to give MuJoCo) and loops whose every
#: joint is damped or driven (no equality closes a damped joint).
PLANAR_REFUSED = {"fourbar-damped": "joint.O4.kind", "fourbar-reversing": "joint.O4.kind",
                  "slider-crank-damped": "joint.guide.kind", "slider-crank": "body.slider.inertia",
                  "slider-crank-10m": "body.slider.inertia", "slider-crank-150": "body.slider.inertia",
                  "slider-crank-offset": "body.slider.inertia", "slider-crank-toggle": "body.slider.inertia"}


def same_rotation(raw, ref) -> None:
    """q and −q are one rotation: the convention qw ≥ 0 jumps at half a
    turn, where the engine and the reference may sit a rounding apart on
    either side (fourbar-change-point's crank at t = 0.5 s: MuJoCo
    4.3e-9 rad past π, the reference 1.5e-16 short of it). Flip the run's
    quaternion to the reference's sign before comparing."""
    for body in [c[:-3] for c in ref.frame.columns if c.endswith(".qw")]:
        cols = [f"{body}.q{c}" for c in "wxyz"]
        q, q_ref = raw.frame[cols].to_numpy(), ref.frame[cols].to_numpy()
        raw.frame[cols] = q * np.where(np.sum(q * q_ref, axis=1, keepdims=True) < 0, -1.0, 1.0)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["andrews-squeezer", "five-bar-two-drives", "fourbar-change-point", "fourbar-crossed",
                                  "fourbar-mass-ratio", "fourbar-millimetre", "fourbar-seed", "hand-pump",
                                  "jansen-leg", "shaper-quick-return", "slider-driven-slider-crank",
                                  "stephenson-six-bar", "watt-six-bar", *PLANAR_REFUSED])
def test_planar_builtin_as_a_spatial_twin(name):
    """Each prescribed planar built-in built in three dimensions
    (`spatial_from_planar`: three redundant rows per loop) over its first
    second: within the default tolerances (measured worst 0.041 of a bound,
    jansen-leg's positions), or refused naming the key."""
    from mechval.reference.linkages import build_mechanism
    from mechval.scenarios.loader import load
    from test_spatial_planar import raw_planar, spatial_twin
    scenario = load(name)
    mech = build_mechanism(scenario)
    t = np.linspace(0.0, min(float(scenario.time.t[-1]), 1.0), 101)
    system = spatial_twin(mech, raw_planar(mech, t[:2]).frame)
    if name in PLANAR_REFUSED:
        with pytest.raises(Unrepresentable) as caught:
            run(system, t)
        assert caught.value.key == PLANAR_REFUSED[name]
        return
    raw, ref = run(system, t)
    same_rotation(raw, ref)
    measured = errors(raw, ref)
    for cls, err in measured.items():
        assert err <= DEFAULT_TOLERANCE[cls], (cls, err, measured)


AUDITED = {"RSSR": lambda: RSSR().system, "delta": lambda: Delta().system, "Bennett": lambda: Bennett().system,
           "T-handle": lambda: with_velocities(TumblingBody()), "Hooke": hooke,
           "A05": lambda: FlyballGovernor().system, "forced arm": forced_arm, "crank, plate, slider": crank_plate_slider,
           "reversed": lambda: reversed_rssr(), "cylindrical": lambda: sliding_body("cylindrical", (0.3, -0.2, 1.0))[0],
           "planar": lambda: sliding_body("planar", (0.2, -0.3, 1.0))[0], "driven slide": driven_slide}


def reversed_rssr() -> SpatialSystem:
    """The RSSR with every joint declared child first (the tree's parent is
    body_j): the audit carries the points and axes to the other side."""
    system = RSSR().system
    return dataclasses.replace(system, joints=tuple(reversed_joint(j) for j in system.joints))


def audit_settings(system: SpatialSystem, t: np.ndarray) -> dict:
    """The defaults at Ω = 10 rad/s (1 ms steps) and no pre-roll: what is
    audited is the model's start, built the same at any step; the scene's
    own Ω would cost a reference solve on 20,001 instants per scene (the
    CLI's audit of the built-ins takes the defaults as they are)."""
    mechanism = spatial_mechanism(system)
    return {**MujocoAdapter().default_settings(mechanism, t, rates=PeakRates(t, None, 10.0)), "preroll_timeconsts": 0.0}


@pytest.mark.parametrize("scene", list(AUDITED))
def test_model_audit_reads_the_scene_back(scene):
    """Masses, centres of mass, inertia tensors (principal moments and
    axes rotated back), joint kinds, points and axes on both bodies,
    damping, springs and gravity read back from the compiled MjModel equal
    the scene's to 1e-12, through the adapter; a weld's child side is the
    only "as set"."""
    from mechval.records.audit import failures
    system = AUDITED[scene]()
    t = np.linspace(0.4, 0.402, 3)          # the start is what is audited: bodies turned from their file pose
    adapter = MujocoAdapter()
    table = adapter.audit(spatial_mechanism(system), t, audit_settings(system, t))
    assert failures(table).empty, failures(table).to_string()
    assert (table["verdict"] == "match").sum() >= len(system.bodies) * 10
    fixed = {j.name for j in system.joints if j.kind == "fixed"}
    assert set(table.loc[table["verdict"] == "as set", "item"]) == {f"joint {name}" for name in fixed}


def test_model_audit_sees_a_difference():
    """A model built for one scene audited against another whose body has
    its centre of mass moved 1 mm, and one whose bearing is tilted: those
    rows, and only they, differ."""
    from mechval.engines.mujoco.spatial_audit import built, read_spatial
    system = RSSR().system
    t = np.linspace(0.4, 0.402, 3)
    assert_the_audit_sees_a_moved_centre_and_a_tilted_axis(system, read_spatial(built(system, t, audit_settings(system, t))))


def test_model_audit_names_an_element_the_scene_lacks():
    """The forced arm's model read as if its scene had no torque law: the
    actuator is an element nothing in the scene accounts for, one row that
    differs."""
    from mechval.engines.mujoco.spatial_audit import Reader, built, expected_spatial
    from mechval.records.audit import audit, failures
    system = forced_arm()
    t = np.linspace(0.0, 0.002, 3)
    reader = Reader(built(system, t, audit_settings(system, t)))
    reader.system = dataclasses.replace(system, torques=())
    wrong = failures(audit(expected_spatial(reader.system), reader.readings()))
    assert list(zip(wrong["item"], wrong["quantity"], wrong["actual"])) == [("scene", "other elements",
                                                                             "actuator 'torque0'")]
