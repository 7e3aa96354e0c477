"""The general planar reference (mechval.reference.planar.solver) against what it
must reproduce:

- the four closed-form kinds, on every built-in scenario, to 1e-12;
- itself: power balance, finite differences and loop closure, to 1e-12, on
  mechanisms only it can solve (two drives, prismatic drives, a prismatic
  joint between moving bodies, springs, torques, dampers, gravity);
- Andrews' squeezing mechanism, the published Test Set solution
  (tests/andrews.py cites every number);
- redundant constraints (a parallelogram with three cranks): kinematics
  and drive torque exact, the indeterminate reactions missing with the
  reason;
- refusals that name the key and, for an instant, the time.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

import andrews as A
import planar_mechanisms as pm
from conftest import CLOSED_FORM, builtin_scenario
from mechval.model.drive import DriveLaw
from mechval.reference.closed_forms.fourbar import position as fourbar_position
from mechval.judging.health import joint_gaps, slide_rate
from mechval.reference.linkages import build_mechanism
from mechval.model.kinematics import point_motion
from mechval.model.mechanism import GROUND, BodyPose, BodyTorque, Drive, Joint, SpringDamper
import mechval.reference.planar.positions as positions
from mechval.reference.planar.solver import MechanismError, PlanarSolver, raw_planar
from mechval.reference.adapter import raw_reference
from scales import motion_scales, size
from mechval.testing.twins import twin

#: What "agrees" means for the general reference, as a fraction of each
#: quantity's scale (angles: absolute, rad).
BOUND = 1e-12
MOTION_CLASS = {"x": "length", "y": "length", "theta": "angle", "vx": "vx", "vy": "vy", "omega": "omega",
                "ax": "ax", "ay": "ay", "alpha": "alpha"}


def column_scales(mech, reference, motion: dict[str, float]) -> dict[str, float]:
    """Scale of every raw column: the motion scales (size L, rate Ω: L, 1 rad,
    LΩ, Ω, LΩ², Ω²), and for reactions the peak of their class in the
    reference: forces (Fx, Fy) together, torques (drive T, slide couples M)
    together, slide-drive forces F with the forces."""
    scales = {}
    force_columns = [c for c in reference.columns if c.endswith((".Fx", ".Fy", ".F"))]
    torque_columns = [c for c in reference.columns if c.endswith((".M", ".T"))]
    force = max((float(np.nanmax(np.abs(reference[c]))) for c in force_columns), default=1.0)
    torque = max((float(np.nanmax(np.abs(reference[c]))) for c in torque_columns), default=1.0)
    for column in reference.columns[1:]:
        quantity = column.split(".")[1]
        if quantity in MOTION_CLASS:
            scales[column] = motion[MOTION_CLASS[quantity]]
        else:
            scales[column] = force if column in force_columns else torque
    return scales


def worst(mech, actual, expected, scales) -> tuple[str, float]:
    """The column with the largest scaled error, and that error."""
    errors = {c: float(np.nanmax(np.abs(actual[c].to_numpy() - expected[c].to_numpy()))) / scales[c]
              for c in scales}
    name = max(errors, key=errors.get)
    return name, errors[name]


def own_scales(mech, raw) -> dict[str, float]:
    """Motion scales of a solved run: size L and Ω = max |ω|, √|α|."""
    rate = max(max(float(np.abs(raw[f"{b.name}.omega"]).max()), float(np.sqrt(np.abs(raw[f"{b.name}.alpha"]).max())))
               for b in mech.bodies)
    L = size(mech)
    return {"length": L, "angle": 1.0, "vx": L * rate, "vy": L * rate, "omega": rate,
            "ax": L * rate**2, "ay": L * rate**2, "alpha": rate**2}


# -- the four closed-form kinds ---------------------------------------------------------------

#: Runs too long for the default suite are checked on their first seconds.
DEFAULT_SPAN = {"fourbar-long-run": 2.0}


def perturbed_pose(mech, t0: float, by: float = 0.05) -> dict[str, BodyPose]:
    """The closed form's body angles at t0, each off by `by` rad: the
    solver must close the loop itself."""
    motion = mech.motion(np.array([t0]))
    return {b.name: BodyPose(float(motion[f"{b.name}.theta"].iloc[0]) + by) for b in mech.bodies}


def cross_check(name: str, span: float | None) -> None:
    scenario = builtin_scenario(name)
    mech = build_mechanism(scenario)
    t = scenario.time.t if span is None else scenario.time.t[scenario.time.t <= span]
    solution = raw_planar(mech, t, perturbed_pose(mech, float(t[0])))
    reference = raw_reference(mech, t)
    motion = {**motion_scales(mech, t), "length": size(mech), "angle": 1.0}
    assert list(solution.frame.columns) == list(reference.columns)
    column, error = worst(mech, solution.frame, reference, column_scales(mech, reference, motion))
    assert error <= BOUND, f"{name}: {column} differs from the closed form by {error:.3g} of its scale"
    assert solution.missing == {}
    assert (solution.structure.mobility, solution.structure.redundant) == (1, 0)


@pytest.mark.parametrize("name", CLOSED_FORM)
def test_agrees_with_the_closed_form_on_every_builtin(name):
    cross_check(name, DEFAULT_SPAN.get(name))


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(DEFAULT_SPAN))
def test_agrees_with_the_closed_form_over_the_whole_long_runs(name):
    cross_check(name, None)


def test_the_assembly_pose_picks_the_branch():
    """The seed four-bar's joints close on two branches; a pose near the
    crossed one gives the crossed closed form, not the open one."""
    seed = builtin_scenario("fourbar-seed")
    closed = seed.closed_form
    crossed = dataclasses.replace(seed, closed_form=dataclasses.replace(
        closed, geometry=dataclasses.replace(closed.geometry, branch="crossed")))
    open_mech, crossed_mech = build_mechanism(seed), build_mechanism(crossed)
    assert open_mech.joints == crossed_mech.joints
    t = seed.time.t
    solution = raw_planar(open_mech, t, perturbed_pose(crossed_mech, 0.0))
    reference = raw_reference(crossed_mech, t)
    motion = {**motion_scales(crossed_mech, t), "length": size(crossed_mech), "angle": 1.0}
    column, error = worst(crossed_mech, solution.frame, reference, column_scales(crossed_mech, reference, motion))
    assert error <= BOUND, f"{column}: {error:.3g}"


# -- self-checks on mechanisms only the general reference solves --------------------------------

SELF_CHECKED = {"five-bar": pm.five_bar, "boom": pm.boom, "slider-driven": pm.slider_driven_slider_crank,
                "parallelogram": pm.parallelogram}


def power_terms(mech, raw) -> dict[str, np.ndarray]:
    """Every power in the mechanism, computed from the raw columns alone
    (rigid-body point motion; Norton §11.2's energy method): the drives'
    power, the rate of kinetic + gravitational + elastic energy, the
    dampers' losses and the body torques' power."""
    gx, gy = mech.gravity
    energy = 0.0
    for body in mech.bodies:
        G = point_motion(raw, body.name, body.com)
        w, al = raw[f"{body.name}.omega"].to_numpy(), raw[f"{body.name}.alpha"].to_numpy()
        energy = energy + body.mass * (G["vx"] * G["ax"] + G["vy"] * G["ay"] - gx * G["vx"] - gy * G["vy"]) \
            + body.izz * w * al
    omega = lambda name: 0.0 if name == GROUND else raw[f"{name}.omega"].to_numpy()
    rate = lambda j: omega(j.body_j) - omega(j.body_i) if j.kind == "revolute" else slide_rate(raw, j)
    losses = sum((j.damping * rate(j) ** 2 for j in mech.joints), 0.0)
    torques = 0.0
    for element in mech.forces:
        if isinstance(element, BodyTorque):
            torques = torques + element.torque * omega(element.body)
        else:
            Pa = point_motion(raw, element.body_a, element.point_a)
            Pb = point_motion(raw, element.body_b, element.point_b)
            dx, dy = Pb["x"] - Pa["x"], Pb["y"] - Pa["y"]
            length = np.hypot(dx, dy)
            stretch_rate = (dx * (Pb["vx"] - Pa["vx"]) + dy * (Pb["vy"] - Pa["vy"])) / length
            energy = energy + element.stiffness * (length - element.free_length) * stretch_rate
            losses = losses + element.damping * stretch_rate**2
    drives = sum(raw[d.effort_column(mech.joint(d.joint).kind)].to_numpy() * rate(mech.joint(d.joint))
                 for d in mech.drives)
    return {"drives": drives, "energy": energy, "losses": losses, "torques": torques}


@pytest.mark.parametrize("name", sorted(SELF_CHECKED))
def test_power_balance(name):
    """Σ drive power + body torques' power = d/dt(kinetic + potential) +
    damper losses, at every instant, to 1e-12 of the largest term."""
    mech = SELF_CHECKED[name]()
    raw = raw_planar(mech, np.linspace(0.0, 1.0, 401)).frame
    p = power_terms(mech, raw)
    residual = p["drives"] + p["torques"] - p["energy"] - p["losses"]
    scale = max(float(np.abs(np.broadcast_to(v, residual.shape)).max()) for v in p.values())
    assert np.abs(residual).max() <= BOUND * scale, f"{np.abs(residual).max() / scale:.3g}"


@pytest.mark.parametrize("name", ["boom", "slider-driven"])
def test_power_balance_fails_without_the_prismatic_drive_force(name):
    """The check above can fail: drop the ram's force and it does."""
    mech = SELF_CHECKED[name]()
    raw = raw_planar(mech, np.linspace(0.0, 1.0, 101)).frame
    p = power_terms(mech, raw)
    scale = max(float(np.abs(np.broadcast_to(v, raw["t"].shape)).max()) for v in p.values())
    assert np.abs(p["torques"] - p["energy"] - p["losses"]).max() > 1e-3 * scale


#: Eighth-order central differences of the first derivative (Fornberg 1988).
STENCIL = np.array([1 / 280, -4 / 105, 1 / 5, -4 / 5, 0.0, 4 / 5, -1 / 5, 4 / 105, -1 / 280])


@pytest.mark.parametrize("name", sorted(SELF_CHECKED))
def test_finite_differences(name):
    """θ → ω → α and the frame origins' x → vx → ax (and y) agree with
    eighth-order central differences of the solved positions and
    velocities. Step h·Ω = 0.005 (Ω = max |ω|, √|α|): rounding then costs
    ~eps·|θ|/(h·Ω) ≈ 1e-13 and the truncation, h⁸/630 times the ninth
    derivative, stays below it (at h·Ω = 0.03 it reaches 1e-8 on these
    mechanisms, whose higher derivatives outgrow Ω^k)."""
    mech = SELF_CHECKED[name]()
    coarse = raw_planar(mech, np.linspace(0.0, 1.0, 101)).frame
    scales = own_scales(mech, coarse)
    h = 0.005 / scales["omega"]
    centres = np.array([0.2, 0.45, 0.7, 0.95])
    offsets = np.arange(-4, 5) * h
    raw = raw_planar(mech, (centres[:, None] + offsets[None, :]).ravel()).frame
    for body in mech.bodies:
        for position, rate, acceleration in (("theta", "omega", "alpha"), ("x", "vx", "ax"), ("y", "vy", "ay")):
            for of, derivative in ((position, rate), (rate, acceleration)):
                values = raw[f"{body.name}.{of}"].to_numpy().reshape(len(centres), len(offsets))
                estimate = values @ STENCIL / h
                exact = raw[f"{body.name}.{derivative}"].to_numpy().reshape(len(centres), len(offsets))[:, 4]
                error = np.abs(estimate - exact).max() / scales[MOTION_CLASS[derivative]]
                assert error <= BOUND, f"{body.name}.{derivative} vs d({of})/dt: {error:.3g}"


@pytest.mark.parametrize("name", sorted(SELF_CHECKED))
def test_loop_closure(name):
    """Every joint closes (mechval.judging.health's gap: pin separation, distance
    off a slide's line) to 1e-12 of the mechanism's size."""
    mech = SELF_CHECKED[name]()
    raw = raw_planar(mech, np.linspace(0.0, 1.0, 401)).frame
    assert joint_gaps(mech, raw).max() <= BOUND * size(mech)


def crank_angle(x: np.ndarray) -> np.ndarray:
    """θ2 from the guide of the slider-driven slider-crank, upper branch, at
    slide x: l² = r² + x² − 2·r·x·cosθ2."""
    r, l = pm.SLIDER["crank"], pm.SLIDER["conrod"]
    return np.arccos((r * r + x * x - l * l) / (2 * r * x))


def test_slider_driven_slider_crank_follows_the_law_of_cosines():
    """The crank angle of the slider-driven slider-crank: l² = r² + x² −
    2·r·x·cosθ2 with x = s(t) (upper branch)."""
    mech = pm.slider_driven_slider_crank()
    t = np.linspace(0.0, 1.0, 201)
    raw = raw_planar(mech, t).frame
    x = mech.drive.law.angle(t)
    assert np.abs(raw["crank.theta"] - crank_angle(x)).max() <= BOUND
    assert np.abs(raw["slider.x"] - x).max() <= BOUND * size(mech)


@pytest.mark.parametrize("gap", [1e-4, 3e-5, 1e-5, 1e-6, 1e-7])
def test_a_slide_passing_close_to_dead_centre_stays_on_its_branch(gap):
    """The slide s(t) = 0.3 − gap + 0.2·t − 0.1·t² turns back at t = 1 s
    `gap` short of the outer dead centre r + l = 0.4 m: the crank swings
    down to θ2 = 0.0212 rad at gap 3e-5 (0.0012 rad at 1e-7) and back up,
    the Jacobian's condition peaking at 142 (gap 3e-5) to 2450 (1e-7), far
    from singular. The continuation used to step over the closest approach
    onto the mirror branch (θ2 < 0: the branches are 2·θ2 apart there, so
    Newton from the predictor reached either), then refuse the run at
    t ≈ 0.94 s as "the loop cannot close" (condition there ~40). Now: the
    law of cosines, upper branch, all through (measured within 1.2e-13)."""
    mech = pm.slider_driven_slider_crank(DriveLaw(0.3 - gap, 0.2, -0.2))
    t = np.linspace(0.0, 2.0, 2001)
    solution = raw_planar(mech, t)
    assert np.abs(solution.frame["crank.theta"] - crank_angle(mech.drive.law.angle(t))).max() <= BOUND
    assert solution.facts["condition_max"] < 1e4


def test_the_tilted_slide_passing_close_to_dead_centre_is_solved_densely():
    """The built-in slider-driven slider-crank (guide tilted, size 0.6 m)
    with the law above, gap 3e-5 m, on `mechval analyse`'s 2001 instants:
    the condition peaks at 214 at t = 1 s. Near there the correction's steps
    settle at the residual's noise floor (cond·eps ≈ 1e-14, above the
    rounding floor 1.8e-15) where they wander by a factor of a few; the
    batch used to wait for every instant to be judged settled in the same
    iteration and refused t = 0.963 s as "the loop cannot close" (condition
    there 91.5). The crank follows the law of cosines about the guide."""
    seed = build_mechanism(builtin_scenario("slider-driven-slider-crank"))
    gap = 3e-5
    mech = dataclasses.replace(seed, drive=dataclasses.replace(seed.drive, law=DriveLaw(0.3 - gap, 0.2, -0.2)),
                               assembly_pose={"crank": BodyPose(1.7), "conrod": BodyPose(0.0),
                                              "slider": BodyPose(0.2838)})
    t = np.linspace(0.0, 2.0, 2001)
    solution = raw_planar(mech, t)
    guide = np.arctan2(0.28, 0.96)      # the file's guide axis (0.96, 0.28)
    expected = guide + crank_angle(mech.drive.law.angle(t))
    assert np.abs(solution.frame["crank.theta"] - expected).max() <= BOUND
    assert solution.facts["condition_max"] < 1e3


def test_two_drives_each_hold_their_joint():
    mech = pm.five_bar()
    t = np.linspace(0.0, 1.0, 101)
    raw = raw_planar(mech, t).frame
    assert np.abs(raw["L1.theta"] - mech.drive.law.angle(t)).max() <= BOUND
    assert np.abs(raw["L4.theta"] - mech.extra_drives[0].law.angle(t)).max() <= BOUND
    assert {"drive.T", "drive2.T"} <= set(raw.columns)


# -- Andrews' squeezing mechanism ---------------------------------------------------------------

def lambdas(raw, k: int = 0) -> np.ndarray:
    """(λ1 … λ6) = (F of E3, F of E4, F of E6): the forces by K2 on K3, K4
    and K6 at E (see tests/andrews.py)."""
    return np.array([raw[f"{j}.{c}"].iloc[k] for j in A.LAMBDA_JOINTS for c in ("Fx", "Fy")])


def test_andrews_at_the_published_consistent_initial_state():
    """t = 0, drive β = β0 + ½·β̈0·t² (published β0, β̇0 = 0, β̈0): the six
    other angles and all accelerations agree to 1e-12, the drive torque is
    the motor torque mom = 0.033 N·m and the pin forces at E are the
    published multipliers λ, both to 1e-12."""
    raw = raw_planar(A.andrews_mechanism(), np.array([0.0])).frame
    assert np.abs(A.test_set_coordinates(raw)[:, 0] - A.Q0).max() <= BOUND
    scale = np.abs(A.QDDOT0).max()
    assert np.abs(A.test_set_coordinates(raw, "alpha")[:, 0] - A.QDDOT0).max() <= BOUND * scale
    assert abs(raw["drive.T"].iloc[0] - A.mom) <= BOUND * A.mom
    assert np.abs(lambdas(raw) - A.LAMBDA0).max() <= BOUND * np.abs(A.LAMBDA0).max()


def test_andrews_at_the_published_solution_at_30_ms():
    """t = 0.03 s, drive β(t) with the published β, β̇, β̈ at 0.03 s: angles
    to 1e-12 (rad), velocities to 1e-7, accelerations, torque and λ to 1e-5
    of their peaks (the torque of mom itself); the published data are
    consistent to about 1e-6 there."""
    mech = A.andrews_mechanism(A.local_law(A.T1, A.Q1, A.QDOT1, A.QDDOT1), A.pose_near(A.Q1))
    raw = raw_planar(mech, np.array([A.T1])).frame
    assert np.abs(A.test_set_coordinates(raw)[:, 0] - A.Q1).max() <= BOUND
    assert np.abs(A.test_set_coordinates(raw, "omega")[:, 0] - A.QDOT1).max() <= 1e-7 * np.abs(A.QDOT1).max()
    assert np.abs(A.test_set_coordinates(raw, "alpha")[:, 0] - A.QDDOT1).max() <= 1e-5 * np.abs(A.QDDOT1).max()
    assert abs(raw["drive.T"].iloc[0] - A.mom) <= 1e-5 * A.mom
    assert np.abs(lambdas(raw) - A.LAMBDA1).max() <= 1e-5 * np.abs(A.LAMBDA1).max()


def test_andrews_torque_is_not_the_motor_torque_under_another_law():
    """The torque check has teeth: β̈0 off by 1 % needs another torque."""
    law = A.local_law(0.0, A.Q0, A.QDOT0, 1.01 * A.QDDOT0)
    raw = raw_planar(A.andrews_mechanism(law), np.array([0.0])).frame
    assert abs(raw["drive.T"].iloc[0] - A.mom) > 1e-4 * A.mom


# -- redundant constraints -----------------------------------------------------------------------

def test_redundant_parallelogram():
    """Three parallel cranks: the structure is found (Grübler 0, mobility 1
    by rank, one redundant row); cranks at φ(t) and a translating coupler;
    drive torque (3·m·r²/3 + m_c·r²)·α + g·cosφ·(3·m·r/2 + m_c·r) exactly;
    every pin force missing as statically indeterminate."""
    mech = pm.parallelogram()
    t = np.linspace(0.0, 1.0, 201)
    solution = raw_planar(mech, t)
    raw = solution.frame
    s = solution.structure
    assert (s.grubler, s.mobility, s.redundant) == (0, 1, 1)
    phi, alpha = mech.drive.law.angle(t), mech.drive.law.acceleration(t)
    for k in (1, 2, 3):
        assert np.abs(raw[f"c{k}.theta"] - phi).max() <= BOUND
    assert np.abs(raw["coupler.theta"]).max() <= BOUND
    r, m, mc, g = 0.2, 1.0, 4.0, 9.81
    torque = (3 * m * r * r / 3 + mc * r * r) * alpha + g * np.cos(phi) * (3 * m * r / 2 + mc * r)
    assert np.abs(raw["drive.T"] - torque).max() <= BOUND * np.abs(torque).max()
    pins = {f"{j.name}.{c}" for j in mech.joints for c in ("Fx", "Fy")}
    assert set(solution.missing) == pins
    assert all("not unique" in reason and "redundant" in reason for reason in solution.missing.values())
    assert raw[sorted(pins)].isna().all().all() and not raw["drive.T"].isna().any()


def test_a_joint_row_that_is_not_redundant_keeps_its_reaction():
    """The five-bar has no redundant row: nothing is missing."""
    solution = raw_planar(pm.five_bar(), np.linspace(0.0, 1.0, 11))
    assert solution.missing == {} and solution.structure.redundant == 0


# -- refusals --------------------------------------------------------------------------------------

def refusal(mech, t, pose=None) -> MechanismError:
    with pytest.raises(MechanismError) as caught:
        raw_planar(mech, t, pose)
    return caught.value


def named_time(error: MechanismError) -> float:
    return float(re.search(r"t = ([-0-9.e+]+) s", error.reason).group(1))


def test_refuses_more_drives_than_the_mobility():
    seed = build_mechanism(builtin_scenario("fourbar-seed"))
    mech = dataclasses.replace(seed, extra_drives=(Drive("O4", DriveLaw(0.5), name="drive2"),))
    error = refusal(mech, np.linspace(0.0, 1.0, 11))
    assert error.key == "drive"
    assert "2 drives for a mechanism of mobility 1" in error.reason
    assert "Grübler count 3·3 bodies − 2·4 joints = 1" in error.reason and "has rank 8" in error.reason


def test_refuses_fewer_drives_than_the_mobility():
    mech = dataclasses.replace(pm.five_bar(), extra_drives=())
    error = refusal(mech, np.linspace(0.0, 1.0, 11))
    assert error.key == "drive" and "1 drive for a mechanism of mobility 2" in error.reason
    assert "= 2;" in error.reason and "has rank 10" in error.reason


def test_refuses_an_instant_where_the_loop_cannot_close():
    """The slider pushed past the outer dead centre r + l = 0.4 m, reached at
    t = 0.5 s: refused no later than that, naming the time."""
    mech = pm.slider_driven_slider_crank(DriveLaw(0.3, 0.2, 0.0))
    error = refusal(mech, np.linspace(0.0, 1.0, 101))
    assert error.key == "time" and "cannot close" in error.reason
    assert 0.45 <= named_time(error) <= 0.5


def test_refuses_an_instant_where_the_jacobian_is_singular():
    """The slider driven to the outer dead centre exactly at t = 1 s and
    back: the crank and rod are in line there, the Jacobian singular."""
    mech = pm.slider_driven_slider_crank(DriveLaw(0.3, 0.2, -0.2))
    error = refusal(mech, np.linspace(0.0, 2.0, 201))
    assert error.key == "time" and ("singular" in error.reason or "locks" in error.reason)
    assert 0.9 <= named_time(error) <= 1.0


def test_refuses_a_pose_that_cannot_be_assembled():
    seed = build_mechanism(builtin_scenario("fourbar-seed"))
    short = tuple(dataclasses.replace(j, point_i=(0.05, 0.0)) if j.name == "B" else j for j in seed.joints)
    mech = dataclasses.replace(seed, joints=short)       # rocker 0.05 m: B cannot reach the coupler
    error = refusal(mech, np.linspace(0.0, 1.0, 11))
    assert error.key == "assembly" and "cannot be assembled" in error.reason


@pytest.mark.parametrize("joint, key, reason", [
    (Joint("X", "revolute", "crank", "crank", (0.0, 0.0), (0.1, 0.0)), "joint.X", "joins 'crank' to itself"),
    (Joint("X", "revolute", "crank", "nobody", (0.0, 0.0), (0.1, 0.0)), "joint.X", "unknown body 'nobody'"),
])
def test_refuses_bad_joints(joint, key, reason):
    seed = build_mechanism(builtin_scenario("fourbar-seed"))
    error = refusal(dataclasses.replace(seed, joints=seed.joints + (joint,)), np.array([0.0]))
    assert error.key == key and reason in error.reason


def test_refuses_a_force_on_an_unknown_body():
    seed = build_mechanism(builtin_scenario("fourbar-seed"))
    mech = dataclasses.replace(seed, forces=(SpringDamper("s", "nobody", (0, 0), GROUND, (1, 1), 1.0, 1.0),))
    assert refusal(mech, np.array([0.0])).key == "force.s"


def test_the_fourbar_closure_limit_matches_the_closed_form():
    """A crank that cannot turn fully (ground 0.6, crank 0.25, coupler 0.3,
    rocker 0.5): refused at the instant the diagonal |O4A| reaches
    coupler + rocker, which the closed form's position gives."""
    seed = build_mechanism(builtin_scenario("fourbar-seed"))
    a, b, c, d = 0.25, 0.3, 0.5, 0.6
    joints = tuple(dataclasses.replace(j, point_j=(b, 0.0)) if j.name == "B" else j for j in seed.joints)
    law = DriveLaw(0.0, 1.0, 0.0)
    mech = dataclasses.replace(seed, joints=joints, drive=Drive("O2", law))
    from mechval.reference.closed_forms.fourbar import FourBarGeometry
    g = FourBarGeometry(ground=d, crank=a, coupler=b, rocker=c)
    start = fourbar_position(g, np.array([0.0]))
    pose = {"crank": BodyPose(0.0), "coupler": BodyPose(float(start["theta3"][0])),
            "rocker": BodyPose(float(start["theta4"][0]))}
    limit = np.arccos((a * a + d * d - (b + c) ** 2) / (2 * a * d))   # s = b + c
    error = refusal(mech, np.linspace(0.0, 3.0, 301), pose)
    assert limit - 0.05 <= named_time(error) <= limit


# -- the linear algebra ----------------------------------------------------------------------------

ELIMINATED = {"fourbar-seed": lambda: build_mechanism(builtin_scenario("fourbar-seed")),
              "hand-pump": lambda: build_mechanism(builtin_scenario("hand-pump")),
              "andrews": A.andrews_mechanism, **SELF_CHECKED}


@pytest.mark.parametrize("name", sorted(ELIMINATED))
def test_tree_elimination_solves_like_a_dense_solve(name):
    """Solves through the spanning-tree elimination equal numpy's dense
    solves with the whole Jacobian (least squares where rows are
    redundant), at arbitrary configurations (the elimination is exact
    algebra: it does not need the joints closed)."""
    from mechval.reference.planar.solver import PlanarSolver
    solver = PlanarSolver(ELIMINATED[name]())
    c = solver.c
    rng = np.random.default_rng(7)
    q = rng.normal(scale=0.3, size=(6, c.n)) + np.tile([0.1, 0.1, 0.5], c.n // 3)
    frames = c.frames(q)
    J = c.jacobian(q, frames)
    factor = solver._factor(q, frames, np.zeros(len(q)))
    r = matmul_rows(J, rng.normal(size=(len(q), c.n)))            # consistent even with redundant rows
    f = rng.normal(size=(len(q), c.n))
    x, lam = factor.solve(r), factor.solve_transposed(f)
    scale = lambda a: np.abs(a).max()
    assert np.abs(matmul_rows(J, x) - r).max() <= 1e-12 * scale(r) * factor.condition().max()
    assert np.abs(matmul_rows(J.transpose(0, 2, 1), lam) - f).max() <= 1e-12 * scale(f) * factor.condition().max()


def matmul_rows(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    return (A @ x[..., None])[..., 0]


@pytest.mark.parametrize("size", [1, 2, 3, 4])
def test_small_inverses(size):
    """The stacked inverses, instants on the last axis (k, k, instants)."""
    from mechval.reference.planar.linear import inverse
    rng = np.random.default_rng(size)
    A = rng.normal(size=(200, size, size)) + 2 * np.eye(size)
    inverses = inverse(np.ascontiguousarray(A.transpose(1, 2, 0))).transpose(2, 0, 1)
    residual = np.abs(A @ inverses - np.eye(size)).max(axis=(1, 2))
    assert (residual <= 4 * np.finfo(float).eps * np.linalg.cond(A)).all()


@pytest.mark.parametrize("shape", [(3, 3), (7, 7), (4, 3)])
def test_stacked_products_and_norms(shape):
    """matvec and norm_inf per instant, instants last, against numpy's
    per-matrix results."""
    from mechval.reference.planar.linear import matvec, norm_inf
    rng = np.random.default_rng(sum(shape))
    A, x = rng.normal(size=(50,) + shape), rng.normal(size=(50, shape[1]))
    products = matvec(A.transpose(1, 2, 0), x.T).T
    np.testing.assert_allclose(products, matmul_rows(A, x), rtol=0, atol=1e-14)
    norms = norm_inf(A.transpose(1, 2, 0))
    np.testing.assert_allclose(norms, [np.linalg.norm(a, np.inf) for a in A], rtol=1e-15)


def test_a_run_too_long_to_follow_is_refused_naming_time_end(monkeypatch):
    """The continuation's step limit (planar_positions.MAX_STEPS) refuses a
    run that would take many minutes; lowered here to 50 to be quick. The
    seed four-bar's 509-revolution twin, the longest planar built-in, stays
    within the real limit with room to spare (counted, not timed)."""
    mech = build_mechanism(builtin_scenario("fourbar-seed"))
    monkeypatch.setattr(positions, "MAX_STEPS", 50)
    with pytest.raises(MechanismError) as caught:
        PlanarSolver(mech).solve(np.linspace(0.0, 6.0, 101))
    assert caught.value.key == "time.end" and "in 50 steps, the limit" in caught.value.reason


@pytest.mark.slow
def test_the_longest_planar_built_in_stays_within_the_step_limit(monkeypatch):
    """The 509-revolution twin is followed within two thirds of the limit."""
    monkeypatch.setattr(positions, "MAX_STEPS", positions.MAX_STEPS * 2 // 3)
    scenario = twin("fourbar-long-run")
    assert PlanarSolver(build_mechanism(scenario)).solve(scenario.time.t).facts["continuation_nodes"] > 10_000
