"""PyBullet on spatial scenes (engines/pybullet/spatial*.py) against the
spatial reference, per column class with mechval's default tolerances:
positions 1e-4 m and quaternion components 1e-3 absolute; velocities
(with ω), accelerations (with α), forces, moments and torques relative
(max |error| over the class's columns / max |reference| over them), 1e-2.
Only what the reference reports is compared (redundant constraints leave
some reactions missing there). Each test states its worst ratio to the
bound as measured on PyBullet 3.2.7 (`ratios`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND, TorqueLaw
from mechval.model.scenario import DEFAULT_TOLERANCE
from mechval.reference.spatial.mechanism import spatial_mechanism, spatial_solution
from mechval.reference.spatial.rotation import frame_from_axis
from mechval.testing import SpatialContract
from mechval.reference.spatial.system import BodyLoad, JointTorque, SpatialBody, SpatialDrive, SpatialJoint, SpatialSystem, Spring
from spatial_benchmarks import Bricard, FlyballGovernor
from spatial_mechanisms import HookesJoint, GRAVITY, Bennett, Delta, HeavyTop, RSSR, SphericalFourBar, TumblingBody, inertia, revolute, unit
from test_spatial_joint_kinds import sliding_body
from spatial_audit_checks import assert_the_audit_sees_a_moved_centre_and_a_tilted_axis

pytestmark = pytest.mark.engine

CLASSES = {"position": ("x", "y", "z"), "quaternion": ("qw", "qx", "qy", "qz"),
           "velocity": ("vx", "vy", "vz", "wx", "wy", "wz"),
           "acceleration": ("ax", "ay", "az", "alphax", "alphay", "alphaz"),
           "force": ("Fx", "Fy", "Fz", "F"), "torque": ("Mx", "My", "Mz", "T")}
BOUNDS = {"position": DEFAULT_TOLERANCE["position"], "quaternion": DEFAULT_TOLERANCE["angle"],
          "velocity": DEFAULT_TOLERANCE["velocity"], "acceleration": DEFAULT_TOLERANCE["acceleration"],
          "force": DEFAULT_TOLERANCE["force"], "torque": DEFAULT_TOLERANCE["torque"]}


@pytest.fixture(scope="module")
def adapter():
    pytest.importorskip("pybullet")
    from mechval.engines.pybullet.adapter import PybulletAdapter
    return PybulletAdapter()


def run(adapter, system: SpatialSystem, t: np.ndarray, **overrides):
    mechanism = spatial_mechanism(system)
    settings = {**adapter.default_settings(mechanism, t), **overrides}
    return adapter.run(mechanism, t, settings)


def ratios(adapter, system: SpatialSystem, t: np.ndarray, facts: dict | None = None, **overrides) -> dict[str, float]:
    """Per class: the engine's error over the bound (relative classes over
    the class's reference peak); a relative class whose reference peak is 0
    (a spherical joint's moment, all its columns) is left out; the run's
    facts are copied into `facts` when given."""
    raw = run(adapter, system, t, **overrides)
    if facts is not None:
        facts.update(raw.info.facts)
    ref = spatial_solution(system, t)
    errors: dict[str, list[float]] = {}
    for column in system.motion_columns() + system.reaction_columns():
        if column in ref.missing:
            continue
        quantity = column.rsplit(".", 1)[1]
        kind = next(k for k, names in CLASSES.items() if quantity in names)
        error = float(np.abs(raw.frame[column].to_numpy() - ref.frame[column].to_numpy()).max())
        peak = float(np.abs(ref.frame[column].to_numpy()).max())
        e, r = errors.setdefault(kind, [0.0, 0.0])
        errors[kind] = [max(e, error), max(r, peak)]
    out = {}
    for kind, (error, peak) in errors.items():
        if kind in ("position", "quaternion"):
            out[kind] = error / BOUNDS[kind]
        elif peak > 0:
            out[kind] = error / peak / BOUNDS[kind]
    return out


def assert_within(r: dict[str, float], limit: float = 1.0) -> None:
    worst = max(r, key=r.get)
    assert r[worst] <= limit, f"{worst} at {r[worst]:.3g}× its bound ({r})"


def test_lcp_solvers_blow_up_on_a_spatial_loop(adapter, monkeypatch):
    """Why spatial scenes use the sequential-impulse solver: with the
    Dantzig LCP planar scenes use, the RSSR's loop (a point-to-point
    constraint inside one multibody) blows up within 0.2 s (ω ~1e9 rad/s
    measured on 3.2.7, against 2.5 rad/s)."""
    from mechval.engines.pybullet import spatial_build
    monkeypatch.setattr(spatial_build, "SOLVER", spatial_build.p.CONSTRAINT_SOLVER_LCP_DANTZIG)
    system = RSSR().system
    raw = adapter.run(spatial_mechanism(system), np.linspace(0.0, 0.2, 21),
                      {"timestep": 1e-3, "preroll_steps": 10, "layout": "split"})
    omega = raw.frame[[c for c in raw.frame.columns if c.endswith((".wx", ".wy", ".wz"))]].to_numpy()
    assert not (np.abs(omega).max() < 1e3), "the Dantzig solver keeps the loop now: reconsider SOLVER"


def test_rssr_driven_closed_loop(adapter):
    """Loop closed at the ball P (one point-to-point constraint); worst
    0.0027 (the universal joint's moment)."""
    assert_within(ratios(adapter, RSSR().system, np.linspace(0.0, 1.0, 51)))


def test_spherical_fourbar_redundant_loop(adapter):
    """Four revolute axes through one point, three redundant constraints;
    closed at D by two point-to-point constraints; worst 0.0019 (A's moment)."""
    assert_within(ratios(adapter, SphericalFourBar().system, np.linspace(0.0, 1.0, 51)))


def test_bennett_overconstrained(adapter):
    """Grübler −2, mobility 1; worst 0.10 (link3's α: one blip at 0.86 s)."""
    assert_within(ratios(adapter, Bennett().system, np.linspace(0.0, 1.0, 51)))


@pytest.mark.xfail(strict=True, reason="the universal joint's moments (peak 5.6e-3 N·m: light shafts) are off by "
                   "2.9e-4 N·m, 5.25× the torque bound at the step rule, 2.62× at half its step: first order in "
                   "dt (PyBullet's velocity-dependent terms at the step's start, as pybullet.explicit-gyroscopic); "
                   "the motion within 6e-4 of its bounds")
def test_universal_joint_in_a_loop(adapter):
    """Hooke's joint between a driven shaft and a held one: the universal
    joint is two revolute joints through a massless cross; the loop closes
    at the output's bearing (a revolute user-constraint pair)."""
    system = HookesJoint().system
    assert_within(ratios(adapter, system, np.linspace(0.0, 1.0, 51)))


@pytest.mark.parametrize("kind, axis", [("cylindrical", (1.0, 1.0, 1.0)), ("planar", (0.2, -0.3, 1.0))])
def test_composite_kinds_through_massless_links(adapter, kind, axis):
    """A cylindrical joint (prismatic + revolute) and a planar one (two
    prismatic + revolute) through massless links PyBullet accepts: a free
    body under gravity to 1e-7 of the bounds (the massless links add nothing)."""
    system, u = sliding_body(kind, axis)
    v0 = 0.4 * u if kind == "cylindrical" else unit(np.cross(u, [1.0, 0.0, 0.0])) * 0.5
    system = dataclasses.replace(system, velocities={"body": (tuple(v0), tuple(7.0 * u))})
    assert_within(ratios(adapter, system, np.linspace(0.0, 1.0, 51)), 1e-5)


def welded_crank() -> SpatialSystem:
    """A crank with a plate welded on (fixed joint), a torque law at its
    hinge and a spring from the plate to the ground."""
    axis = unit((0.3, 0.1, 1.0))
    crank = SpatialBody("crank", 2.0, (0.1, 0.0, 0.05), inertia(50))
    plate = SpatialBody("plate", 1.0, (0.3, 0.1, -0.1), inertia(51))
    return SpatialSystem(
        "welded crank", (crank, plate),
        (revolute("O", GROUND, "crank", (0.0, 0.0, 0.0), axis),
         SpatialJoint("W", "fixed", "crank", "plate", (0.25, 0.0, 0.0), (0.25, 0.0, 0.0))),
        gravity=GRAVITY,
        springs=(Spring("spring", GROUND, (0.4, 0.3, 0.2), "plate", (0.3, 0.1, -0.1), 50.0, 0.2, 0.5),),
        torques=(JointTorque("O", TorqueLaw("O", 0.5, 0.3, 1.0, 0.0, "motor"), "motor"),))


def test_fixed_joint_and_spring_and_torque_law(adapter):
    """The welded crank: its torque law and spring are external loads set
    every step; worst 0.0022 (a moment)."""
    assert_within(ratios(adapter, welded_crank(), np.linspace(0.0, 1.0, 51)))


def damped_pendulum() -> SpatialSystem:
    """A free pendulum on a damped revolute joint (turned axis) with a
    constant body load."""
    axis = unit((0.2, 1.0, 0.1))
    bob = SpatialBody("bob", 1.5, (0.3, 0.0, -0.2), inertia(70))
    return SpatialSystem(
        "damped pendulum", (bob,),
        (dataclasses.replace(revolute("O", GROUND, "bob", (0.0, 0.0, 0.0), axis), damping=0.05),),
        gravity=GRAVITY, loads=(BodyLoad("push", "bob", (0.5, 0.0, 0.2), (0.0, 0.1, 0.0)),),
        velocities={"bob": ((0.0, 0.0, 0.0), tuple(2.0 * axis))})


def test_damped_pendulum_with_a_body_load(adapter):
    """The damped pendulum: the damper and the load as external loads;
    worst 0.005 (α)."""
    assert_within(ratios(adapter, damped_pendulum(), np.linspace(0.0, 1.0, 51)))


def driven_slide() -> SpatialSystem:
    """A slider driven along a guide that a revolute drive turns (the
    slide's points 0.15 m apart along it)."""
    guide = SpatialBody("guide", 1.0, (0.2, 0.0, 0.0), inertia(80))
    slider = SpatialBody("slider", 0.5, (0.25, 0.02, 0.01), inertia(81))
    frame = frame_from_axis((1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    return SpatialSystem(
        "driven slide", (guide, slider),
        (revolute("O", GROUND, "guide", (0.0, 0.0, 0.0), unit((0.1, 0.2, 1.0))),
         SpatialJoint("S", "prismatic", "guide", "slider", (0.1, 0.0, 0.0), (0.25, 0.0, 0.0), frame, frame)),
        (SpatialDrive("O", DriveLaw(0.0, 1.5, 0.5), "turn"), SpatialDrive("S", DriveLaw(0.0, 0.2, -0.1), "push")),
        GRAVITY)


def test_prismatic_drive_on_a_turning_guide(adapter):
    """The driven slide: the slide's force (D.F) and the guide's reactions
    on a moving parent; worst 8.2e-4 (a force)."""
    assert_within(ratios(adapter, driven_slide(), np.linspace(0.0, 1.0, 51)))


def reversed_elbow() -> SpatialSystem:
    """A driven two-link arm whose elbow names the outer link body_i."""
    upper = SpatialBody("upper", 1.0, (0.15, 0.0, 0.0), inertia(90))
    fore = SpatialBody("fore", 0.6, (0.4, 0.05, 0.0), inertia(91))
    elbow = revolute("elbow", "fore", "upper", (0.3, 0.0, 0.0), unit((0.0, 0.3, 1.0)), (1.0, 0.0, 0.0))
    return SpatialSystem(
        "reversed elbow", (upper, fore),
        (revolute("shoulder", GROUND, "upper", (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)), elbow),
        (SpatialDrive("shoulder", DriveLaw(0.0, 1.0, 0.5), "d1"), SpatialDrive("elbow", DriveLaw(0.0, -2.0, 1.0), "d2")),
        GRAVITY)


def test_joint_declared_against_the_tree(adapter):
    """The reversed elbow: the tree hangs the outer link as the elbow's
    child, so the elbow's coordinate, drive torque and reaction change sign
    (`spatial_reactions`); worst 4.4e-4 (a moment)."""
    assert_within(ratios(adapter, reversed_elbow(), np.linspace(0.0, 1.0, 51)))


def test_heavy_top_spherical_joint(adapter):
    """A spherical multibody joint under gravity, spinning at 200 rad/s;
    0.3 s (about 900 steps at the step rule)."""
    top = HeavyTop()
    system = dataclasses.replace(top.system, velocities=top.velocities)
    assert_within(ratios(adapter, system, np.linspace(0.0, 0.3, 31)))


def test_tumbling_body_flips(adapter):
    """The intermediate-axis flip happens (ω and α within their bounds) ..."""
    body = TumblingBody()
    system = dataclasses.replace(body.system, velocities=body.velocities)
    r = ratios(adapter, system, np.linspace(0.0, 2.4 * body.quarter, 121))
    assert r["velocity"] <= 1.0 and r["acceleration"] <= 1.0, r


@pytest.mark.xfail(strict=True, reason="PyBullet 3.2.7 integrates the gyroscopic term explicitly: the free "
                   "body's attitude is first-order in dt (finding pybullet.explicit-gyroscopic); at the step "
                   "rule (0.002 rad per step) its quaternion misses 1e-3 by 3.5× through the flip, 1.8× at "
                   "half the step")
def test_tumbling_body_attitude(adapter):
    body = TumblingBody()
    system = dataclasses.replace(body.system, velocities=body.velocities)
    assert_within(ratios(adapter, system, np.linspace(0.0, 2.4 * body.quarter, 121)))


def test_delta_robot_three_drives(adapter):
    """Each delta loop passes through driven revolute and universal joints
    only, which no PyBullet user constraint closes: the loops close inside
    rods 1 and 2, each built as two welded halves (`spatial_split`);
    worst 5.8e-4 (a universal joint's moment)."""
    facts: dict = {}
    assert_within(ratios(adapter, Delta().system, np.linspace(0.0, 1.0, 51), facts))
    assert facts["split_bodies"] == "rod1, rod2"


@pytest.mark.slow
def test_bricard_free_overconstrained_loop(adapter):
    """A04, released under gravity, its first second (about 8 s of CPU):
    worst 0.86 (bar3's position; it grows as the bars fall, so the
    benchmark's 10 s is not claimed here)."""
    assert_within(ratios(adapter, Bricard().system, np.linspace(0.0, 1.0, 51)))


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="A05's stiff spring-dampers (k 8e5 N/m, c 4e4 N·s/m) are external loads "
                   "PyBullet takes explicitly (it has no spring element): c·dt/m = 0.83 for the 3 kg slider at the "
                   "step rule's 6.25e-5 s, near explicit damping's limit; over 10 ms the slider's acceleration "
                   "misses its bound 38×, the pins' forces 3.6×")
def test_flyball_governor_stiff_springs(adapter):
    governor = FlyballGovernor()
    system = dataclasses.replace(governor.system, velocities=governor.velocities)
    assert_within(ratios(adapter, system, np.linspace(0.0, 0.01, 21)))


#: Measured on PyBullet 3.2.7: the free body's energy gain after 2 s at a
#: 1e-3 s step (1.92e-3 at 5e-4 s: first order). A release that changes it
#: has changed the integrator: update pybullet.explicit-gyroscopic.
ENERGY_GAIN = 3.85e-3


def test_explicit_gyroscopic_finding_still_present(adapter):
    from mechval.engines.pybullet import findings
    m = findings.probe_explicit_gyroscopic()
    assert m.present and m.figure == pytest.approx(ENERGY_GAIN, rel=0.02), m.describe()
    # First order: half the step, half the gain.
    assert findings.tumbling_energy_gain(5e-4) == pytest.approx(ENERGY_GAIN / 2, rel=0.02)


#: Measured on PyBullet 3.2.7 at the default step (3.1e-4 s): its
#: semi-implicit Euler step is first order, and free flight shows it.
FREE_FLIGHT = ("the centre of mass is 5.0e-4 m off its parabola after 1 s (bound 1e-4 m), 2.5e-4 at half the "
               "step, 1.25e-4 at a quarter: first order in the step")


class TestSpatialContract(SpatialContract):
    engine = "pybullet"

    @pytest.mark.xfail(strict=True, reason=FREE_FLIGHT)
    def test_a_free_body_keeps_its_momentum(self, adapter):
        super().test_a_free_body_keeps_its_momentum(adapter)


AUDITED = {"RSSR": lambda: RSSR().system, "delta": lambda: Delta().system, "Bennett": lambda: Bennett().system,
           "Bricard": lambda: Bricard().system, "A05": lambda: FlyballGovernor().system,
           "T-handle": lambda: dataclasses.replace(TumblingBody().system, velocities=TumblingBody().velocities),
           "Hooke": lambda: HookesJoint().system, "welded crank": welded_crank, "damped pendulum": damped_pendulum,
           "driven slide": driven_slide, "reversed elbow": reversed_elbow,
           "cylindrical": lambda: sliding_body("cylindrical", (0.3, -0.2, 1.0))[0],
           "planar": lambda: sliding_body("planar", (0.2, -0.3, 1.0))[0]}
#: The start audited: 0.4 s in, so the driven bodies have turned from their
#: file pose (a conversion that forgot a body's rotation shows there).
AUDIT_TIMES = np.linspace(0.4, 0.402, 3)


def audit_settings(adapter, system: SpatialSystem) -> dict:
    """The defaults at Ω = 10 rad/s: the model's start is built the same at
    any step; the scene's own Ω would cost a reference solve on 20,001
    instants (the CLI's audit of the built-ins takes the defaults as they are)."""
    from mechval.adapter import PeakRates
    return adapter.default_settings(spatial_mechanism(system), AUDIT_TIMES, rates=PeakRates(AUDIT_TIMES, None, 10.0))


@pytest.mark.parametrize("scene", list(AUDITED))
def test_model_audit_reads_the_scene_back(adapter, scene):
    """Masses, centres of mass, inertia tensors (a split body's halves
    summed), joint kinds, points and axes on both bodies (PyBullet's axis in
    the link's inertial frame, turned to world), loop constraints' pivots
    and gravity read back from the built multibodies equal the scene's to
    1e-12, through the adapter; "as set" only what the stepping loop
    applies (damping, springs) and a weld's child frame."""
    from mechval.records.audit import failures
    system = AUDITED[scene]()
    mechanism = spatial_mechanism(system)
    table = adapter.audit(mechanism, AUDIT_TIMES, audit_settings(adapter, system))
    assert failures(table).empty, failures(table).to_string()
    assert (table["verdict"] == "match").sum() >= len(system.bodies) * 10
    as_set = table[table["verdict"] == "as set"]
    stepped = as_set["quantity"].eq("damping") | as_set["item"].str.startswith("spring ")
    welds = as_set["item"].isin([f"joint {j.name}" for j in system.joints if j.kind == "fixed"])
    assert (stepped | welds).all(), as_set.to_string()


def test_model_audit_sees_a_difference(adapter):
    """A model built for one scene audited against another whose body has
    its centre of mass moved 1 mm, and one whose output bearing is tilted
    1 mrad: those rows, and only they, differ."""
    from mechval.engines.pybullet.model import p
    from mechval.engines.pybullet.spatial import start_model
    from mechval.engines.pybullet.spatial_audit import read_spatial
    system = RSSR().system
    start = start_model(system, AUDIT_TIMES, audit_settings(adapter, system))
    try:
        readings = read_spatial(system, start)
    finally:
        p.disconnect(start.model.client)
    assert_the_audit_sees_a_moved_centre_and_a_tilted_axis(system, readings)


def test_model_audit_names_an_element_the_scene_lacks(adapter):
    """A user constraint added to the RSSR's built model after the build:
    an element nothing in the scene accounts for, one row that differs."""
    from mechval.engines.pybullet.model import p
    from mechval.engines.pybullet.spatial import start_model
    from mechval.engines.pybullet.spatial_audit import expected_spatial, read_spatial
    from mechval.records.audit import audit, failures
    system = RSSR().system
    start = start_model(system, AUDIT_TIMES, audit_settings(adapter, system))
    try:
        (ui, li), (uj, lj) = start.model.handles["input"], start.model.handles["output"]
        cid = p.createConstraint(ui, li, uj, lj, p.JOINT_POINT2POINT, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0),
                                 (0.0, 0.0, 0.0), physicsClientId=start.model.client)
        readings = read_spatial(system, start)
    finally:
        p.disconnect(start.model.client)
    wrong = failures(audit(expected_spatial(system), readings))
    assert list(zip(wrong["item"], wrong["quantity"], wrong["actual"])) == [("scene", "other elements",
                                                                             f"constraint {cid}")]
