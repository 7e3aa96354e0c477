"""The reference checks itself: power balance, loop closure, finite
differences, closed forms, a static case by hand, mirror symmetry, and an
independently written 9×9 system."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import CLOSED_FORM, builtin_scenario
from mechval.judging.health import power_balance
from mechval.model.kinematics import joint_gaps, point_motion
from mechval.reference.linkages import build_mechanism
from mechval.reference.adapter import raw_reference
from mechval.harness.simulate import simulate
from mechval.reference.newton_euler import assemble, reaction_values
from mechval.scenarios import parse
from mechval.records.signals import SIGNAL_CLASS
from norton import UNKNOWNS, norton_system
from scales import class_peaks, motion_scales, size
from mechval.testing.scenes import fourbar, slider_crank

BOTH_KINDS_VARIANTS = [
    fourbar(),
    fourbar(geometry={"branch": "crossed"}, drive={"phi0": 0.3, "omega0": -3.0, "alpha": 2.0}),
    fourbar(geometry={"ground": 0.2, "crank": 0.4, "coupler": 0.45, "rocker": 0.5},
            effects={"gravity": [1.0, -9.81], "damping": {"O2": 0.5, "A": 0.2, "B": 0.3, "O4": 0.4}}),
    slider_crank(),
    slider_crank(geometry={"offset": 0.05, "branch": "left"}, drive={"alpha": 3.0},
                 mass={"conrod": {"mass": 2.0, "com": 0.1, "izz": 0.05}}),
    slider_crank(geometry={"offset": -0.03}, effects={"damping": {"O2": 0.1, "A": 0.1, "B": 0.2, "guide": 3.0}}),
]
SCENES = [parse(d, f"variant-{k}") for k, d in enumerate(BOTH_KINDS_VARIANTS)] + [builtin_scenario(n) for n in CLOSED_FORM]
IDS = [s.source.name if s.source else s.name for s in SCENES]


def raw_of(scenario, t=None):
    mech = build_mechanism(scenario)
    return mech, raw_reference(mech, scenario.time.t if t is None else t)


@pytest.mark.parametrize("scenario", SCENES, ids=IDS)
def test_power_balance(scenario):
    """T12·ω2 = d/dt(kinetic + potential) + damping losses, to ~1e-12."""
    mech, raw = raw_of(scenario)
    power, rate = power_balance(mech, raw)
    assert np.abs(power - rate).max() <= 1e-12 * (np.abs(power).max() + np.abs(rate).max())


@pytest.mark.parametrize("scenario", SCENES, ids=IDS)
def test_loop_closure(scenario):
    """Both sides of every joint coincide (a slider's point on its guide
    line) to ~1e-12 of the mechanism's size."""
    mech, raw = raw_of(scenario)
    assert joint_gaps(mech, raw).max() <= 1e-12 * size(mech)


@pytest.mark.parametrize("scenario", SCENES, ids=IDS)
def test_finite_differences(scenario):
    """Velocities and accelerations match central differences of positions
    and velocities (h = 1e-5 s: truncation ~h², round-off ~1e-16/h)."""
    mech = build_mechanism(scenario)
    t = np.linspace(0.0, scenario.time.end, 97)
    h = 1e-5
    now, ahead, behind = mech.motion(t), mech.motion(t + h), mech.motion(t - h)
    scale = motion_scales(mech, t)
    for body in mech.bodies:
        for pos, vel, acc in (("theta", "omega", "alpha"), ("x", "vx", "ax"), ("y", "vy", "ay")):
            name = f"{body.name}."
            fd_v = (ahead[name + pos] - behind[name + pos]) / (2 * h)
            fd_a = (ahead[name + vel] - behind[name + vel]) / (2 * h)
            assert np.abs(fd_v - now[name + vel]).max() <= 1e-6 * scale[vel], name + vel
            assert np.abs(fd_a - now[name + acc]).max() <= 1e-6 * scale[acc], name + acc


def test_slider_closed_forms():
    """x4 = r2·cosθ2 + √(r3² − (r2·sinθ2 − e)²), and for e = 0
    ω3 = −r2·ω2·cosθ2 / (r3·cosθ3) (Norton eqs. 4.17, 6.22)."""
    for e in (0.0, 0.04):
        scene = parse(slider_crank(geometry={"offset": e}, drive={"omega0": 7.0, "alpha": 1.5}), "closed-form")
        sig = simulate(scene, "reference")
        r2, r3 = 0.1, 0.4
        th2 = sig["theta2"]
        np.testing.assert_allclose(sig["x4"], r2 * np.cos(th2) + np.sqrt(r3**2 - (r2 * np.sin(th2) - e) ** 2),
                                   rtol=0, atol=1e-15)
        if e == 0.0:
            np.testing.assert_allclose(sig["omega3"], -r2 * sig["omega2"] * np.cos(th2) / (r3 * np.cos(sig["theta3"])),
                                       rtol=1e-13, atol=1e-13)


def test_fourbar_seed_initial_position_by_hand():
    """θ2 = 0: A = (0.25, 0), |AO4| = 0.35; the isosceles triangle A-B-O4
    (0.5, 0.5) puts B at x = 0.425, y = +√(0.5² − 0.175²) (open: above)."""
    sig = simulate(builtin_scenario("fourbar-seed"), "reference")
    by = np.sqrt(0.25 - 0.175**2)
    assert sig["theta3"][0] == pytest.approx(np.arctan2(by, 0.175), abs=1e-15)
    assert sig["theta4"][0] == pytest.approx(np.arctan2(by, -0.175), abs=1e-15)


def test_static_slider_crank_by_hand():
    """At rest with crank and rod horizontal (θ2 = 0), the rod's weight is
    shared equally by A and B, the guide carries the slider plus half the
    rod, and the motor holds both halves on the crank (statics by hand)."""
    g, m2, m3, m4, r2 = 9.81, 1.0, 2.0, 0.5, 0.1
    scene = parse(slider_crank(drive={"phi0": 0.0, "omega0": 0.0, "alpha": 0.0}, time={"end": 1.0, "samples": 3}),
                  "static")
    sig = simulate(scene, "reference")
    expected = {"F12x": 0.0, "F12y": (m2 + m3 / 2) * g, "F32x": 0.0, "F32y": -m3 * g / 2,
                "F43x": 0.0, "F43y": m3 * g / 2, "F14y": (m4 + m3 / 2) * g, "T12": g * r2 * (m2 + m3) / 2}
    for name, value in expected.items():
        np.testing.assert_allclose(sig[name], value, rtol=0, atol=1e-12, err_msg=name)


def test_static_fourbar_moment_balance():
    """At rest the motor torque balances gravity: by virtual work,
    T12 = −Σ m·g·∂yG/∂θ2, with ∂yG/∂θ2 = velocity of G per unit ω2."""
    scene = parse(fourbar(drive={"phi0": 0.7, "omega0": 0.0, "alpha": 0.0}, time={"end": 1.0, "samples": 2}), "s")
    moving = parse(fourbar(drive={"phi0": 0.7, "omega0": 1.0, "alpha": 0.0}, time={"end": 1.0, "samples": 2}), "m")
    sig = simulate(scene, "reference")
    mech = build_mechanism(moving)
    unit_rates = mech.motion(np.array([0.0]))
    # T·δθ2 + Σ m·g·δyG = 0 with g = −9.81 m/s² along y.
    torque = -sum(b.mass * -9.81 * point_motion(unit_rates, b.name, b.com)["vy"][0] for b in mech.bodies)
    assert sig["T12"][0] == pytest.approx(torque, rel=1e-13)


def test_mirror_open_crossed():
    """Mirroring about the ground line maps the open branch at θ2 onto the
    crossed branch at −θ2: angles and y-forces change sign, x-forces stay."""
    open_ = simulate(parse(fourbar(drive={"phi0": 0.2, "omega0": 2.0, "alpha": 0.7},
                                             effects={"gravity": [3.0, -9.81]}), "open"), "reference")
    crossed = simulate(parse(fourbar(geometry={"branch": "crossed"},
                                               drive={"phi0": -0.2, "omega0": -2.0, "alpha": -0.7},
                                               effects={"gravity": [3.0, 9.81]}), "crossed"), "reference")
    peaks = class_peaks(open_, SIGNAL_CLASS)
    for name in open_.frame.columns[1:]:
        sign = 1.0 if name.endswith("x") else -1.0
        np.testing.assert_allclose(crossed[name], sign * open_[name], rtol=0,
                                   atol=1e-11 * peaks[SIGNAL_CLASS[name]], err_msg=name)


def test_mirror_right_left():
    """Mirroring about the y axis maps the right branch at θ2 onto the left
    branch at π − θ2: θ → π − θ, rates and x-forces and T12 change sign."""
    right = simulate(parse(slider_crank(geometry={"offset": 0.03}, drive={"phi0": 0.3, "alpha": 2.0},
                                                  effects={"gravity": [2.0, -9.81]}), "right"), "reference")
    left = simulate(parse(slider_crank(geometry={"offset": 0.03, "branch": "left"},
                                                 drive={"phi0": np.pi - 0.3, "omega0": -10.0, "alpha": -2.0},
                                                 effects={"gravity": [-2.0, -9.81]}), "left"), "reference")
    peaks = class_peaks(right, SIGNAL_CLASS)
    for name in right.frame.columns[1:]:
        if name.startswith("theta"):
            expected = np.pi - right[name]
        elif name.endswith("y") and name.startswith("F"):
            expected = right[name]
        else:
            expected = -right[name]
        np.testing.assert_allclose(left[name], expected, rtol=0,
                                   atol=1e-11 * peaks[SIGNAL_CLASS[name]], err_msg=name)


UNDAMPED_FOURBARS = [(s, i) for s, i in zip(SCENES, IDS) if s.mechanism == "fourbar" and not any(j.damping for j in s.scene.joints)]


@pytest.mark.parametrize("scenario", [s for s, _ in UNDAMPED_FOURBARS], ids=[i for _, i in UNDAMPED_FOURBARS])
def test_matches_norton_9x9(scenario):
    """The reference equals Norton's explicitly written 9×9 system solved
    instant by instant (an independent derivation; eq. 11.9 has no damper
    terms, so undamped scenes only), to ~1e-12."""
    mech, raw = raw_of(scenario, np.linspace(0.0, scenario.time.end, 41))
    m = {b.name: b for b in mech.bodies}
    geometry = scenario.closed_form.geometry
    for k in range(len(raw)):
        kin = {f"{q}{n}": raw[f"{link}.{q}"].iloc[k] for link, n in (("crank", 2), ("coupler", 3), ("rocker", 4))
               for q in ("theta", "omega", "alpha")}
        A, rhs = norton_system(kin, m["crank"].mass, m["coupler"].mass, m["rocker"].mass, m["crank"].izz,
                               m["coupler"].izz, m["rocker"].izz, mech.gravity, geometry.crank,
                               geometry.coupler, geometry.rocker, geometry.ground,
                               (m["crank"].com[0], m["coupler"].com[0], m["rocker"].com[0]))
        x = np.linalg.solve(A, rhs)
        ours = [raw[mech.signal_map[u]].iloc[k] for u in UNKNOWNS]
        np.testing.assert_allclose(ours, x, rtol=0, atol=1e-12 * np.abs(x).max())


@pytest.mark.parametrize("scenario", SCENES, ids=IDS)
def test_null_space_solve_equals_full_solve(scenario):
    """The fast null-space solution equals a plain solve of the assembled
    square system."""
    mech, raw = raw_of(scenario, np.linspace(0.0, scenario.time.end, 23))
    A, b, names = assemble(mech, raw)
    x = np.linalg.solve(A, b[..., None])[..., 0]
    np.testing.assert_allclose(raw[list(names)].to_numpy(), x, rtol=0, atol=1e-12 * np.abs(x).max())


def test_reactions_need_only_the_motion_columns():
    """`reaction_values` takes exactly what `Mechanism.motion_columns()`
    lists (an adapter computing reactions from its own motion has no "t"
    column to give: it raised KeyError 't'); the result is the reference's."""
    mech, raw = raw_of(SCENES[2])
    motion = {name: raw[name].to_numpy() for name in mech.motion_columns()}
    expected = raw[mech.reaction_columns()].to_numpy().T
    np.testing.assert_allclose(reaction_values(mech, motion), expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
