"""The crank-slotted lever and the inverted slider-crank check themselves:
power balance, loop closure (incl. the slide), finite differences, the
textbook closed forms, mirror branches, bad input, and the quick-return
time ratio."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import builtin_scenario
from mechval.reference.analysis import analyse
from mechval.reference.closed_forms.loop import measured_stroke_ratio
from mechval.reference.linkages import build_mechanism
from mechval.model.kinematics import joint_gap
from mechval.model.mechanism import GROUND
from mechval.reference.adapter import raw_reference
from mechval.harness.simulate import simulate
from mechval.model.scenario import ScenarioError
from mechval.scenarios import parse
from mechval.records.signals import SIGNAL_CLASS, signal_names, with_slide_columns
from scales import class_peaks, motion_scales
from mechval.testing.scenes import merge
from mechval.judging.health import power_balance


def slotted_lever(**overrides) -> dict:
    data = {
        "name": "test-slotted-lever", "mechanism": "slotted_lever",
        "geometry": {"ground": 0.3, "crank": 0.1, "lever": 0.5},
        "mass": {"crank": 2.0, "block": {"mass": 0.5, "izz": 1e-4}, "lever": 4.0},
        "drive": {"phi0": 0.0, "omega0": 6.0, "alpha": 0.0},
        "effects": {"gravity": [9.81, 0.0]},
        "time": {"end": 3.0, "samples": 601},
    }
    return merge(data, overrides)


def inverted_slider(**overrides) -> dict:
    data = {
        "name": "test-inverted-slider", "mechanism": "inverted_slider",
        "geometry": {"ground": 0.3, "crank": 0.1, "rod": 0.5, "offset": 0.05, "branch": "left"},
        "mass": {"crank": 1.0, "rod": 1.5, "rocker": {"mass": 0.8, "izz": 2e-3}},
        "drive": {"phi0": 0.3, "omega0": 5.0, "alpha": 1.0},
        "effects": {"gravity": [0.0, -9.81]},
        "time": {"end": 2.0, "samples": 401},
    }
    return merge(data, overrides)


WHITWORTH = {"ground": 0.1, "crank": 0.25, "lever": 0.5}
VARIANTS = {
    "shaper": slotted_lever(),
    "whitworth-damped": slotted_lever(
        geometry=WHITWORTH, drive={"phi0": 0.4, "omega0": -4.0, "alpha": 3.0},
        effects={"gravity": [2.0, -9.81], "damping": {"O2": 0.1, "A": 0.05, "slot": 2.0, "O4": 0.2}}),
    "lever-mass-tables": slotted_lever(
        mass={"crank": {"mass": 2.0, "com": 0.03, "izz": 3e-3}, "lever": {"mass": 4.0, "com": 0.3, "izz": 0.1}},
        drive={"phi0": 1.0, "omega0": 3.0, "alpha": -2.5}),
    "pump-left": inverted_slider(),
    "pump-right-damped": inverted_slider(
        geometry={"branch": "right"},
        effects={"damping": {"O2": 0.1, "A": 0.05, "sleeve": 2.0, "O4": 0.2}}),
    "pump-rotating-rod": inverted_slider(
        geometry={"ground": 0.1, "crank": 0.3, "rod": 0.6},
        mass={"rod": {"mass": 1.5, "com": 0.2, "izz": 0.04}}, effects={"gravity": [3.0, -9.81]}),
    "pump-no-offset": inverted_slider(geometry={"offset": 0.0}),
}
SCENES = {name: parse(data, f"{name}.toml") for name, data in VARIANTS.items()}
SCENES.update({name: builtin_scenario(name) for name in ("shaper-quick-return", "hand-pump")})


def slides(mech, t):
    """Body motion plus the slide columns (J.s, J.v, J.a) at instants t."""
    motion = mech.motion(t)
    return with_slide_columns(mech, motion, {})[0]


@pytest.mark.parametrize("name", SCENES)
def test_power_balance(name):
    """T12·ω2 = d/dt(kinetic + potential) + damping losses, to ~1e-12."""
    scenario = SCENES[name]
    mech = build_mechanism(scenario)
    power, rate = power_balance(mech, raw_reference(mech, scenario.time.t))
    assert np.abs(power - rate).max() <= 1e-12 * (np.abs(power).max() + np.abs(rate).max())


@pytest.mark.parametrize("name", SCENES)
def test_loop_closure(name):
    """Pins coincide, the slide point lies on the slide line and the slide
    does not turn relative to its guide, all to ~1e-12."""
    scenario = SCENES[name]
    mech = build_mechanism(scenario)
    motion = mech.motion(scenario.time.t)
    theta = lambda body: 0.0 if body == GROUND else motion[f"{body}.theta"].to_numpy()
    for joint in mech.joints:
        assert joint_gap(motion, joint).max() <= 1e-12, joint.name
        if joint.kind == "prismatic":
            turn = theta(joint.body_j) - theta(joint.body_i)
            assert np.ptp(turn) <= 1e-12, joint.name


@pytest.mark.parametrize("name", SCENES)
def test_finite_differences(name):
    """Rates of every body frame and of the slide match central differences
    (h = 1e-5 s: truncation ~h², round-off ~1e-16/h)."""
    scenario = SCENES[name]
    mech = build_mechanism(scenario)
    t = np.linspace(0.0, scenario.time.end, 97)
    h = 1e-5
    now, ahead, behind = slides(mech, t), slides(mech, t + h), slides(mech, t - h)
    slide = next(j.name for j in mech.joints if j.kind == "prismatic")
    scale = motion_scales(mech, t)
    triples = [(f"{b.name}.{p}", f"{b.name}.{v}", f"{b.name}.{a}") for b in mech.bodies
               for p, v, a in (("theta", "omega", "alpha"), ("x", "vx", "ax"), ("y", "vy", "ay"))]
    for pos, vel, acc in triples + [(f"{slide}.s", f"{slide}.v", f"{slide}.a")]:
        fd_v = (ahead[pos] - behind[pos]) / (2 * h)
        fd_a = (ahead[vel] - behind[vel]) / (2 * h)
        assert np.abs(fd_v - now[vel]).max() <= 1e-6 * scale[vel.split(".")[1]], vel
        assert np.abs(fd_a - now[acc]).max() <= 1e-6 * scale[acc.split(".")[1]], acc


def wrapped(angle):
    return np.angle(np.exp(1j * angle))


def test_slotted_lever_closed_forms():
    """θ4 = atan2(r2·sinθ2, r2·cosθ2 − r1) (mod 2π), r4 = |A − O4|,
    ṙ4 = r2·ω2·sin(θ4 − θ2), ω4 = r2·ω2·cos(θ2 − θ4)/r4, and θ3 = θ4."""
    for name, (r1, r2) in (("shaper", (0.3, 0.1)), ("whitworth-damped", (0.1, 0.25))):
        sig = simulate(SCENES[name], "reference")
        th2, w2, th4 = sig["theta2"], sig["omega2"], sig["theta4"]
        r4 = np.sqrt(r1**2 + r2**2 - 2 * r1 * r2 * np.cos(th2))
        np.testing.assert_allclose(wrapped(th4 - np.arctan2(r2 * np.sin(th2), r2 * np.cos(th2) - r1)), 0,
                                   atol=1e-14)
        np.testing.assert_allclose(sig["s34"], r4, rtol=0, atol=1e-15)
        np.testing.assert_allclose(sig["v34"], r2 * w2 * np.sin(th4 - th2), rtol=0, atol=1e-14)
        np.testing.assert_allclose(sig["omega4"], r2 * w2 * np.cos(th2 - th4) / r4, rtol=0, atol=1e-13)
        np.testing.assert_array_equal(sig["theta3"], th4)


def test_slotted_lever_by_hand():
    """θ2 = 0: A = (0.1, 0) on the ground line, the lever points back at
    O2 (θ4 = π), r4 = 0.2 m and ω4 = −0.1·6/0.2 = −3 rad/s. The block's
    centre of mass is its pin, so the slot's couple alone turns it:
    M43 = izz_block·α4."""
    sig = simulate(SCENES["shaper"], "reference")
    assert sig["theta4"][0] == pytest.approx(np.pi, abs=1e-15)
    assert sig["s34"][0] == pytest.approx(0.2, abs=1e-15)
    assert sig["omega4"][0] == pytest.approx(-3.0, abs=1e-14)
    np.testing.assert_allclose(sig["M43"], 1e-4 * sig["alpha4"], rtol=0, atol=1e-15)


@pytest.mark.parametrize("branch, sigma", [("left", 1.0), ("right", -1.0)])
def test_inverted_slider_half_angle(branch, sigma):
    """θ3 and b against the half-angle solution (the form of Norton eq. 4.20):
    projecting the loop on the rod's normal j·e^{jθ3} eliminates b and leaves
    P·sinθ3 + Q·cosθ3 + R = 0 with P = −(a·cosθ2 − d), Q = a·sinθ2, R = σ·c,
    so tan(θ3/2) = (−P ± √(P² + Q² − R²)) / (R − Q); the root with
    b = (A − O4)·e^{jθ3} > 0 is the assembly. Also θ4 = θ3 − σ·90°."""
    a, d, c = 0.1, 0.3, 0.05
    sig = simulate(parse(inverted_slider(geometry={"branch": branch}), "half-angle"), "reference")
    th2 = sig["theta2"]
    rx, ry = a * np.cos(th2) - d, a * np.sin(th2)
    P, Q, R = -rx, ry, sigma * c
    root = np.sqrt(P * P + Q * Q - R * R)
    candidates = [2 * np.arctan((-P + s * root) / (R - Q)) for s in (1.0, -1.0)]
    b_of = lambda th3: rx * np.cos(th3) + ry * np.sin(th3)
    th3 = np.where(b_of(candidates[0]) > 0, candidates[0], candidates[1])
    np.testing.assert_allclose(wrapped(sig["theta3"] - th3), 0, atol=1e-13)
    np.testing.assert_allclose(sig["s34"], b_of(th3), rtol=0, atol=1e-14)
    np.testing.assert_allclose(sig["s34"], np.sqrt(rx**2 + ry**2 - c**2), rtol=0, atol=1e-15)
    np.testing.assert_allclose(sig["theta4"], sig["theta3"] - sigma * np.pi / 2, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(sig["omega4"], sig["omega3"])


def mirrored(signals):
    """Expected signals of the mechanism mirrored about the ground line:
    angles, rates, y-forces, the normal force, the couple and T12 change
    sign; x-forces and the slide's position and rates stay."""
    stay = {"s34", "v34", "a34"}
    return {name: (1.0 if name in stay or (name.startswith("F") and name.endswith("x")) else -1.0)
            * signals[name] for name in signals.frame.columns[1:]}


@pytest.mark.parametrize("make, first, second", [
    (inverted_slider, {"branch": "left"}, {"branch": "right"}),
    (slotted_lever, {}, {}),
    (slotted_lever, WHITWORTH, WHITWORTH),
], ids=["inverted-left-right", "slotted-lever", "whitworth"])
def test_mirror_branches(make, first, second):
    """Mirroring about the ground line maps the mechanism at θ2 (the
    inverted slider on its left branch) onto the one at −θ2 (on its right
    branch) with mirrored gravity; angles agree modulo 2π."""
    drive, gravity = {"phi0": 0.3, "omega0": 5.0, "alpha": 1.0}, [2.0, -9.81]
    one = simulate(parse(make(geometry=first, drive=drive, effects={"gravity": gravity}), "one"), "reference")
    two = simulate(parse(make(geometry=second, drive={k: -v for k, v in drive.items()},
                                        effects={"gravity": [gravity[0], -gravity[1]]}), "two"), "reference")
    peaks = class_peaks(one, SIGNAL_CLASS)
    for name, expected in mirrored(one).items():
        error = wrapped(two[name] - expected) if name.startswith("theta") else two[name] - expected
        bound = 2 * np.pi if name.startswith("theta") else peaks[SIGNAL_CLASS[name]]
        assert np.abs(error).max() <= 1e-11 * bound, name


def test_whitworth_lever_turns_continuously():
    """Crank longer than ground (Whitworth) is accepted: θ4 is continuous
    and turns as many times as the crank."""
    scene = parse(slotted_lever(geometry=WHITWORTH, drive={"omega0": 6.0}), "whitworth")
    sig = simulate(scene, "reference")
    assert np.abs(np.diff(sig["theta4"])).max() < 0.1
    turns = lambda angle: (angle[-1] - angle[0]) / (2 * np.pi)
    assert turns(sig["theta4"]) == pytest.approx(turns(sig["theta2"]), abs=0.1)
    assert analyse(scene).quick_return is None


def test_quick_return_ratio():
    """Forward over return stroke time: the closed form (π + 2·asin(r2/r1)) /
    (π − 2·asin(r2/r1)) equals the ratio measured from the reference's
    lever motion, and `analyse` reports both. At the scenario's 5 ms
    samples each stroke end (a zero crossing of ω4, linearly interpolated)
    is off by up to ~dt²/8 times the ratio of ω4's third to first
    derivative there, ~1e-5 s of 0.4–0.6 s strokes: hence rel = 5e-4
    (`analyse` samples every 1.5 ms)."""
    scene = SCENES["shaper-quick-return"]
    closed = (np.pi + 2 * np.arcsin(0.1 / 0.3)) / (np.pi - 2 * np.arcsin(0.1 / 0.3))
    sig = simulate(scene, "reference")
    assert measured_stroke_ratio(sig.t, sig["omega4"], sig["omega2"]) == pytest.approx(closed, rel=5e-4)
    report = analyse(scene)
    assert report.quick_return == pytest.approx(closed, rel=1e-14)
    assert report.quick_return_measured == pytest.approx(closed, rel=1e-4)


def test_quick_return_ratio_with_offset():
    """The offset moves the stroke ends to d·cosθ2 = a ∓ c: the closed form
    (2π − β)/β, β = acos((a − c)/d) + acos((a + c)/d), matches the measured
    rod motion at a constant crank speed."""
    a, d, c = 0.1, 0.3, 0.05
    scene = parse(inverted_slider(drive={"phi0": 0.0, "omega0": 6.0, "alpha": 0.0},
                                  time={"end": 4.0, "samples": 4001}), "offset")
    beta = np.arccos((a - c) / d) + np.arccos((a + c) / d)
    report = analyse(scene)
    assert report.quick_return == pytest.approx((2 * np.pi - beta) / beta, rel=1e-14)
    assert report.quick_return_measured == pytest.approx((2 * np.pi - beta) / beta, rel=1e-4)


@pytest.mark.parametrize("name", ["shaper-quick-return", "hand-pump"])
def test_canonical_columns(name):
    scene = builtin_scenario(name)
    assert tuple(simulate(scene, "reference").frame.columns) == signal_names(scene.mechanism)


BAD = [
    (slotted_lever(geometry={"crank": 0.3}), "geometry.crank", "crank equals ground"),
    (slotted_lever(geometry={"lever": 0.35}), "geometry.lever", "the block leaves the lever at t = "),
    (slotted_lever(geometry={"lever": None}), "geometry.lever", "missing value"),
    (slotted_lever(geometry={"lever": -0.5}), "geometry.lever", "must be positive"),
    (slotted_lever(geometry={"branch": "open"}), "geometry.branch", "unknown key"),
    (slotted_lever(mass={"block": {"mass": 0.5, "com": 0.01}}), "mass.block.com", "unknown key"),
    (slotted_lever(mass={"lever": 0.0}), "mass.lever", "must be positive"),
    (slotted_lever(effects={"damping": {"guide": 1.0}}), "effects.damping.guide", "unknown key"),
    (inverted_slider(geometry={"offset": -0.05}), "geometry.offset", "must not be negative"),
    (inverted_slider(geometry={"offset": 0.25}), "geometry", "the loop cannot close at t = "),
    (inverted_slider(geometry={"ground": 0.1, "crank": 0.12}), "geometry", "the crank pin reaches the sleeve"),
    (inverted_slider(geometry={"rod": 0.3}), "geometry.rod", "the rod leaves the sleeve at t = "),
    (inverted_slider(geometry={"branch": "open"}), "geometry.branch", "must be one of"),
    (inverted_slider(mass={"rod": None}), "mass.rod", "missing value"),
    (inverted_slider(mass={"rocker": {"mass": 0.8, "com": 0.02}}), "mass.rocker.com", "unknown key"),
]


@pytest.mark.parametrize("data, key, reason", BAD, ids=[f"{b[1]}:{b[2]}" for b in BAD])
def test_bad_input_refused(data, key, reason):
    with pytest.raises(ScenarioError) as info:
        parse(data, "bad.toml")
    assert (info.value.source, info.value.key) == ("bad.toml", key)
    assert reason in info.value.reason


def test_closure_checked_between_samples():
    """The block reaches the lever's end (θ2 = π) only between the samples
    t = 0 and t = 2 s: still refused."""
    data = slotted_lever(geometry={"lever": 0.39}, drive={"phi0": -1.0, "omega0": 1.6},
                         time={"end": 4.0, "samples": 3})
    with pytest.raises(ScenarioError, match="the block leaves the lever"):
        parse(data, "between.toml")
