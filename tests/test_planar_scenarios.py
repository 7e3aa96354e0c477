"""Planar files (`mechanism = "planar"`): the four kinds' built-ins expand
into the scene a planar file states and, written as planar files, agree
with their closed forms to 1e-12; their canonical
signals, health and analysis; mechanisms only planar files describe (two
drives, springs, a redundant parallelogram) through the whole harness;
every refusal names the file, the key and the reason."""

from __future__ import annotations

import copy
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from conftest import CLOSED_FORM, builtin_scenario
from mechval.adapter import mechanism_features
from mechval.reference.analysis import analyse, format_analysis
from mechval.harness.simulate import simulate
from mechval.reference.linkages import build_mechanism, without_closed_form
from mechval.model.kinematics import point_motion
from mechval.reference.planar.solver import raw_planar
from mechval.reference.adapter import raw_reference
from mechval.model.scenario import ScenarioError
from mechval.scenarios import load, parse
from mechval.records.signals import SIGNAL_CLASS
from scales import motion_scales, size
from test_planar_solver import BOUND, column_scales, worst
from mechval.testing.twins import twin_document, twin_text

ROOT = Path(__file__).resolve().parents[1]
#: Runs too long for the default suite are checked on their first seconds.
DEFAULT_END = {"fourbar-long-run": 2.0}


def twin(name: str, end: float | None = None):
    """Built-in `name` written as a planar file (testing/twins.py) and loaded
    back, its run cut at `end` if given."""
    data = twin_document(name)
    if end is not None:
        data["time"] = {"end": end, "samples": int(round(end / builtin_scenario(name).time.end
                                                         * (builtin_scenario(name).time.samples - 1))) + 1}
    return parse(data, f"{name}-planar.toml")


def agrees_with_its_closed_form(name: str, end: float | None) -> None:
    planar = twin(name, end)
    closed = build_mechanism(builtin_scenario(name))
    t = planar.time.t
    assert np.array_equal(t, builtin_scenario(name).time.t[:len(t)])
    solution = raw_planar(build_mechanism(planar), t)
    reference = raw_reference(closed, t)
    assert list(solution.frame.columns) == list(reference.columns)
    motion = {**motion_scales(closed, t), "length": size(closed), "angle": 1.0}
    column, error = worst(closed, solution.frame, reference, column_scales(closed, reference, motion))
    assert error <= BOUND, f"{name}: {column} differs from the closed form by {error:.3g} of its scale"


@pytest.mark.parametrize("name", CLOSED_FORM + ["fourbar-falling", "slider-crank-motor"])
def test_a_kind_expands_into_the_scene_its_planar_file_states(name):
    """Every closed-form built-in (torque-driven and free ones too) is one
    scene: written as a planar file and loaded back, it has the same bodies,
    frames, joints, drives, torque laws, initial values, forces and gravity,
    and no closed form."""
    scenario, planar = builtin_scenario(name), twin(name)
    assert scenario.closed_form is not None and planar.closed_form is None
    for part in ("bodies", "joints", "drives", "torques", "initial", "forces", "gravity"):
        assert getattr(planar.scene, part) == getattr(scenario.scene, part), part
    assert (planar.time, planar.tolerance) == (scenario.time, scenario.tolerance)


def test_the_general_reference_of_a_kind_needs_no_file():
    """`without_closed_form`: the same scenario for the general reference."""
    scenario = builtin_scenario("hand-pump")
    general = without_closed_form(scenario)
    assert general.closed_form is None and general.scene.joints == scenario.scene.joints
    t = scenario.time.t[:41]
    solved = raw_planar(build_mechanism(general), t).frame
    closed = raw_reference(build_mechanism(scenario), t)
    scale = np.abs(closed["rod.theta"]).max()
    assert np.abs(solved["rod.theta"] - closed["rod.theta"]).max() <= BOUND * scale


@pytest.mark.parametrize("name", CLOSED_FORM)
def test_planar_twin_agrees_with_the_closed_form(name):
    agrees_with_its_closed_form(name, DEFAULT_END.get(name))


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(DEFAULT_END))
def test_planar_twin_agrees_over_the_whole_long_runs(name):
    agrees_with_its_closed_form(name, None)


def test_mechval_export_prints_a_loadable_planar_file(tmp_path, capsys):
    from mechval.harness.cli import main
    assert main(["export", "slider-crank"]) == 0
    path = tmp_path / "slider-crank-planar.toml"
    path.write_text(capsys.readouterr().out, encoding="utf-8")
    scenario = load(str(path))
    assert scenario.name == "slider-crank-planar" and scenario.closed_form is None
    assert scenario.scene.joints == builtin_scenario("slider-crank").scene.joints


def test_canonical_signals_of_a_planar_file():
    """Per body θ, ω, α and its centre of mass's x, y, vx, vy, ax, ay; per
    joint Fx, Fy (N, M for the slide); the drive's torque named after its
    joint — each equal to the closed form's motion and reactions."""
    scenario = twin("hand-pump")
    signals = simulate(scenario, "reference")
    closed = build_mechanism(builtin_scenario("hand-pump"))
    reference = raw_reference(closed, scenario.time.t)
    names = list(signals.frame.columns)
    assert names[:10] == ["t", "crank.theta", "crank.omega", "crank.alpha", "crank.x", "crank.y",
                          "crank.vx", "crank.vy", "crank.ax", "crank.ay"]
    assert names[-11:] == ["O2.Fx", "O2.Fy", "A.Fx", "A.Fy", "sleeve.Fx", "sleeve.Fy", "sleeve.N", "sleeve.M",
                           "O4.Fx", "O4.Fy", "O2.T"]
    assert [SIGNAL_CLASS[n] for n in ("rod.theta", "rod.vx", "rod.alpha", "sleeve.N", "sleeve.M", "O2.T")] == \
        ["angle", "velocity", "acceleration", "force", "torque", "torque"]
    G = point_motion(reference, "rod", closed.body("rod").com)
    L, rate = size(closed), float(np.abs(reference["rod.omega"]).max())
    assert np.abs(signals["rod.x"] - G["x"]).max() <= BOUND * L
    assert np.abs(signals["rod.ay"] - G["ay"]).max() <= BOUND * L * rate**2 * 10
    assert np.abs(signals["O2.T"] - reference["drive.T"]).max() <= BOUND * np.abs(reference["drive.T"]).max()
    assert signals.missing == {}
    health = signals.health
    assert health["gap"].max() <= BOUND * L and health["drive_error"].max() <= BOUND
    assert health["power_residual"].max() <= 1e-10


# -- what only planar files describe ------------------------------------------------------------------

FIVE_BAR = {
    "name": "five-bar", "mechanism": "planar",
    "description": "Two cranks driven independently, a spring and a torque",
    "ground": {"O1": [0.0, 0.0], "O4": [0.3, 0.0], "C": [0.15, 0.5]},
    "body": [{"name": "L1", "mass": 1.0, "length": 0.15}, {"name": "L2", "mass": 1.5, "length": 0.3},
             {"name": "L3", "mass": 1.5, "length": 0.3, "points": {"mid": [0.15, 0.0]}},
             {"name": "L4", "mass": 1.0, "length": 0.15}],
    "joint": [{"name": "O1", "type": "revolute", "between": ["ground.O1", "L1.start"]},
              {"name": "A", "type": "revolute", "between": ["L1.end", "L2.start"], "damping": 0.05},
              {"name": "P", "type": "revolute", "between": ["L2.end", "L3.end"], "damping": 0.05},
              {"name": "B", "type": "revolute", "between": ["L4.end", "L3.start"]},
              {"name": "O4", "type": "revolute", "between": ["ground.O4", "L4.start"]}],
    "drive": [{"joint": "O1", "phi0": 0.5, "omega0": 2.0}, {"joint": "O4", "phi0": 2.0, "omega0": 1.5, "alpha": 1.0}],
    "force": [{"type": "spring", "between": ["L3.mid", "ground.C"], "stiffness": 200.0, "free_length": 0.3,
               "damping": 2.0},
              {"type": "torque", "body": "L3", "torque": 0.4}],
    "assembly": {"L1": 0.5, "L2": -0.8, "L3": -1.2, "L4": 2.0},
    "effects": {"gravity": [0.0, -9.81]},
    "time": {"end": 1.0, "samples": 201},
}

PARALLELOGRAM = {
    "name": "parallelogram", "mechanism": "planar", "description": "Three parallel cranks on one coupler",
    "ground": {"O1": [0.0, 0.0], "O2": [0.4, 0.0], "O3": [0.8, 0.0]},
    "body": [{"name": "c1", "mass": 1.0, "length": 0.2}, {"name": "c2", "mass": 1.0, "length": 0.2},
             {"name": "c3", "mass": 1.0, "length": 0.2},
             {"name": "coupler", "mass": 4.0, "length": 0.8, "points": {"mid": [0.4, 0.0]}}],
    "joint": [{"name": "O1", "type": "revolute", "between": ["ground.O1", "c1.start"]},
              {"name": "O2", "type": "revolute", "between": ["ground.O2", "c2.start"]},
              {"name": "O3", "type": "revolute", "between": ["ground.O3", "c3.start"]},
              {"name": "A1", "type": "revolute", "between": ["c1.end", "coupler.start"]},
              {"name": "A2", "type": "revolute", "between": ["c2.end", "coupler.mid"]},
              {"name": "A3", "type": "revolute", "between": ["c3.end", "coupler.end"]}],
    "drive": [{"joint": "O1", "phi0": 0.3, "omega0": 2.0, "alpha": 1.0}],
    "assembly": {"c1": 0.3, "c2": 0.3, "c3": 0.3, "coupler": 0.0},
    "effects": {"gravity": [0.0, -9.81]},
    "time": {"end": 1.0, "samples": 101},
}


def test_two_drives_a_spring_and_a_torque_through_the_harness():
    """The five-bar's reference: both drives held, both torques reported,
    and the power balance (all drives, spring, damper, torque) closes."""
    scenario = parse(copy.deepcopy(FIVE_BAR), "five-bar.toml")
    signals = simulate(scenario, "reference")
    t = scenario.time.t
    assert np.abs(signals["L1.theta"] - (0.5 + 2.0 * t)).max() <= BOUND
    assert np.abs(signals["L4.theta"] - (2.0 + 1.5 * t + 0.5 * t * t)).max() <= BOUND
    assert {"O1.T", "O4.T"} <= set(signals.frame.columns)
    assert signals.health["power_residual"].max() <= 1e-10
    assert signals.health["drive_error"].max() <= BOUND


def test_redundant_parallelogram_through_the_harness():
    scenario = parse(copy.deepcopy(PARALLELOGRAM), "parallelogram.toml")
    signals = simulate(scenario, "reference")
    pins = {f"{j}.{c}" for j in ("O1", "O2", "O3", "A1", "A2", "A3") for c in ("Fx", "Fy")}
    assert set(signals.missing) == pins
    assert all("statically indeterminate" in reason for reason in signals.missing.values())
    assert not np.isnan(signals["O1.T"]).any()
    assert signals.info.facts["redundant_constraints"] == 1
    text = format_analysis(analyse(scenario))
    assert "mobility            1 from the Jacobian's rank; Grübler count 3·4 − 2·6 = 0" in text
    assert "redundant           1 constraint (Jacobian rank 12)" in text


def slider_driven_near_dead_centre(gap: float, end: float = 1.0):
    """The built-in slider-driven slider-crank with its slide passing `gap`
    m from the inner dead centre s = conrod − crank = 0.2 m at t = 0.5 s:
    s(t) = 0.35 − a·t/2 + a·t²/2, a = (0.15 − gap)/0.125, s(0.5) = 0.2 + gap."""
    data = tomllib.loads((ROOT / "scenarios" / "slider-driven-slider-crank.toml").read_text(encoding="utf-8"))
    a = (0.35 - 0.2 - gap) / 0.125
    data["drive"] = [dict(data["drive"][0], phi0=0.35, omega0=-0.5 * a, alpha=a)]
    data["time"] = {"end": end, "samples": 201}
    return parse(data, "near-dead-centre.toml")


def test_analyse_finds_the_near_singular_instant():
    """1e-4 m from the dead centre the Jacobian's condition peaks at t =
    0.5 s, over 10× its median (crank and conrod nearly collinear); 1e-2 m
    away it stays within 2× and nothing is reported; a run that stops at
    the near-singular instant reports it too."""
    near = analyse(slider_driven_near_dead_centre(1e-4))
    assert [t for t, _ in near.near_singular] == [0.5] and near.condition_t == 0.5
    assert near.near_singular[0][1] > 10 * near.condition_median
    text = format_analysis(near)
    assert "near-singular       1 instant (condition peaks above 10× the median)" in text
    assert "t =    0.50000 s  condition" in text
    far = analyse(slider_driven_near_dead_centre(1e-2))
    assert far.near_singular == () and far.condition_max < 2 * far.condition_median
    assert [t for t, _ in analyse(slider_driven_near_dead_centre(1e-4, end=0.5)).near_singular] == [0.5]


def test_analyse_refuses_an_instant_its_denser_grid_cannot_solve(monkeypatch):
    """`analyse` solves at ≥ 2001 instants, more than the file's samples: an
    instant refused there is one line naming the file, the key and the
    time (it was a traceback)."""
    import mechval.reference.planar.analysis as planar_analysis
    from mechval.reference.planar.constraints import MechanismError

    def refuses(mech, t):
        raise MechanismError("time", "the loop cannot close at t = 0.4955 s")
    monkeypatch.setattr(planar_analysis, "raw_planar", refuses)
    with pytest.raises(ScenarioError) as caught:
        analyse(parse(copy.deepcopy(FIVE_BAR), "five-bar.toml"))
    assert str(caught.value) == "five-bar.toml: time: the loop cannot close at t = 0.4955 s"


# -- refusals -----------------------------------------------------------------------------------------

def mutate(base: dict, path: tuple, value) -> dict:
    data = copy.deepcopy(base)
    target = data
    for key in path[:-1]:
        target = target[key]
    if value is DELETE:
        del target[path[-1]]
    else:
        target[path[-1]] = value
    return data


DELETE = object()
REFUSALS = [
    (("joint", 1, "between"), ["L1.end", "L9.start"], "joint.A.between", "unknown body 'L9'"),
    (("joint", 1, "between"), ["L1.end", "L2.middle"], "joint.A.between", "'L2' has no point 'middle'"),
    (("joint", 1, "between"), ["L2.end", "L2.start"], "joint.A.between", "joins 'L2' to itself"),
    (("joint", 1, "type"), "hinge", "joint.A.type", "must be one of 'revolute', 'prismatic'"),
    (("body",), FIVE_BAR["body"] + [{"name": "L5", "mass": 1.0, "length": 0.1}], "body.L5",
     "not connected to the ground"),
    (("body", 1, "name"), "L1", "body[1].name", "a second body named 'L1'"),
    (("body", 1, "name"), "L.2", "body[1].name", "not a usable name"),
    (("body", 2, "points"), {"start": [0.1, 0.0]}, "body.L3.points.start", "given by `length`"),
    (("body", 0, "length"), DELETE, "body.L1.com", "give `length` for a uniform bar, or `com` and `izz`"),
    (("drive",), [{"joint": "O1", "omega0": 2.0}], "drive",
     "1 drive for a mechanism of mobility 2 (Grübler count 3·4 bodies − 2·5 joints = 2; "
     "the Jacobian of the 10 joint equations in 12 coordinates has rank 10"),
    (("drive", 1, "joint"), "O1", "drive[1].joint", "a second drive on joint 'O1'"),
    (("drive", 1, "joint"), "Q", "drive[1].joint", "unknown joint 'Q'"),
    (("assembly", "L3"), DELETE, "assembly.L3", "every body needs an approximate angle"),
    (("assembly", "L3"), {"theta": -1.2, "x": 0.1}, "assembly.L3.x", "give both x and y"),
    (("force", 1, "body"), "L7", "force[1].body", "unknown body 'L7'"),
    (("effects", "damping"), {"A": 0.1}, "effects.damping", "unknown key"),
    (("ground", "O4"), [3.0, 0.0], "assembly", "the pose cannot be assembled"),
]


@pytest.mark.parametrize("path, value, key, reason", REFUSALS, ids=[r[2] + ":" + r[3][:24] for r in REFUSALS])
def test_refusals_name_the_file_the_key_and_the_reason(path, value, key, reason):
    with pytest.raises(ScenarioError) as caught:
        parse(mutate(FIVE_BAR, path, value), "five-bar.toml")
    error = caught.value
    assert (error.source, error.key) == ("five-bar.toml", key), str(error)
    assert reason in error.reason, str(error)


def test_refuses_the_instant_the_loop_cannot_close():
    """O4 moved to (0.6, 0): the cranks' pins A and B drift more than the
    two links' 0.6 m apart. Refused naming the time, just before the
    instant where |AB| reaches 0.6 m (found here by bisection)."""
    def gap(t):
        a = 0.15 * np.array([np.cos(0.5 + 2 * t), np.sin(0.5 + 2 * t)])
        angle = 2.0 + 1.5 * t + 0.5 * t * t
        b = np.array([0.6 + 0.15 * np.cos(angle), 0.15 * np.sin(angle)])
        return np.linalg.norm(b - a) - 0.6
    lo, hi = 0.0, 1.0
    assert gap(lo) < 0 < gap(hi)
    for _ in range(60):
        lo, hi = (lo, (lo + hi) / 2) if gap((lo + hi) / 2) > 0 else ((lo + hi) / 2, hi)
    with pytest.raises(ScenarioError) as caught:
        parse(mutate(FIVE_BAR, ("ground", "O4"), [0.6, 0.0]), "five-bar.toml")
    error = caught.value
    assert error.key == "time" and "the loop cannot close" in error.reason
    named = float(error.reason.split("t = ")[1].split(" s")[0])
    assert lo - 0.01 <= named <= lo, (named, lo)


def test_the_command_line_refuses_a_planar_file_in_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    text = twin_text("fourbar-seed").replace('"crank.A"', '"crank.tip"')
    bad.write_text(text, encoding="utf-8")
    result = subprocess.run([sys.executable, "-m", "mechval.harness.cli", "simulate", str(bad), "--engine",
                             "reference", "--csv", str(tmp_path / "out.csv")], capture_output=True, text=True)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "bad.toml: joint.A.between: 'crank' has no point 'tip'" in lines[0]
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("engine_name", ["mujoco", "pybullet", "exudyn"])
def test_engines_are_refused_what_their_adapters_do_not_build(engine_name):
    """Until an adapter builds several drives, prismatic drives, springs and
    body torques, a scene that asks for them is refused for that engine,
    naming the key, rather than simulated without them."""
    from conftest import engine_or_skip
    engine = engine_or_skip(engine_name)
    if {"several drives", "spring-dampers"} <= engine.features:
        pytest.skip(f"{engine_name} builds several drives and spring-dampers (its tests compare them)")
    if "several drives" not in engine.features:
        scenario = parse(copy.deepcopy(FIVE_BAR), "five-bar.toml")
        with pytest.raises(ScenarioError, match=rf"five-bar.toml: drive: {engine_name}: its adapter does not "
                                                "build several drives yet"):
            simulate(scenario, engine)
    if "spring-dampers" not in engine.features:
        data = twin_document("fourbar-seed")
        data["force"] = [{"type": "spring", "between": ["coupler.B", "ground.O2"], "stiffness": 10.0,
                          "free_length": 0.5}]
        with pytest.raises(ScenarioError, match=rf"seed.toml: force.force1: {engine_name}: its adapter does not "
                                                "build spring-dampers yet"):
            simulate(parse(data, "seed.toml"), engine)


@pytest.mark.parametrize("name", ["planar-extra/parallelogram-double-fourbar", "five-bar-two-drives", "watt-six-bar",
                                  "jansen-leg", "fourbar-seed"])
def test_redundant_constraints_are_a_feature_an_engine_must_declare(name):
    """Only the parallelogram (three equal parallel cranks) has a redundant
    joint equation; an engine that cannot run one is refused it by name
    (tests/test_exudyn_planar.py), as for every other feature."""
    features = mechanism_features(build_mechanism(builtin_scenario(name)))
    assert ("redundant constraints" in features) == name.endswith("parallelogram-double-fourbar")


@pytest.mark.parametrize("name", ["watt-six-bar", "stephenson-six-bar", "jansen-leg", "slider-driven-slider-crank",
                                  "andrews-squeezer", "andrews-squeezer-motor"])
def test_the_report_draws_the_mechanism_to_scale(name):
    """The report's drawing (reports/plots.py) of a planar built-in: at each
    drawn instant every body is there, each body's points keep the
    distances its file gives (to scale, equal axes), ternary links are
    closed polygons, both ends of every revolute joint are drawn at one
    place (the loops are closed in the picture) and every spring is drawn
    between its two points."""
    from mechval.reports.plots import mechanism_figure
    scenario = builtin_scenario(name)
    mech = build_mechanism(scenario)
    figure = mechanism_figure(mech, scenario.time.t)
    assert (figure["layout"]["yaxis"]["scaleanchor"], figure["layout"]["yaxis"]["scaleratio"]) == ("x", 1)
    scale = size(mech)
    instants = sorted({trace["legendgroup"] for trace in figure["data"] if "legendgroup" in trace})
    assert len(instants) == 4
    for instant in instants:
        drawn = {trace["text"][0]: np.column_stack([trace["x"], trace["y"]])
                 for trace in figure["data"] if trace.get("legendgroup") == instant}
        assert set(drawn) == {b.name for b in mech.bodies} | {f.name for f in mech.forces if hasattr(f, "stiffness")}
        where = {}                                 # (joint, side) → drawn point
        for body in mech.bodies:
            joints = [j for j in mech.joints if body.name in (j.body_i, j.body_j)]
            local = [np.array(j.point_j if j.body_j == body.name else j.point_i) for j in joints]
            points = drawn[body.name]
            closed = len({tuple(p) for p in points[:len(local)]}) >= 3
            assert len(points) == len(local) + closed and (not closed or np.array_equal(points[0], points[-1]))
            for a in range(len(local)):
                for b in range(a):
                    assert abs(np.linalg.norm(points[a] - points[b]) - np.linalg.norm(local[a] - local[b])) \
                        <= 1e-9 * scale, (instant, body.name)
            for j, point in zip(joints, points):
                where[j.name, "j" if j.body_j == body.name else "i"] = point
        for j in mech.joints:
            if j.kind == "revolute":
                ends = [where.get((j.name, side), np.array(j.point_i if side == "i" else j.point_j)) for side in "ij"]
                assert np.linalg.norm(ends[0] - ends[1]) <= 1e-9 * scale, (instant, j.name)
        for spring in (f for f in mech.forces if hasattr(f, "stiffness")):
            a, b = drawn[spring.name]
            for end, body, point in ((a, spring.body_a, spring.point_a), (b, spring.body_b, spring.point_b)):
                joint = next((j for j in mech.joints if (j.body_i, j.point_i) == (body, point)
                              or (j.body_j, j.point_j) == (body, point)), None)
                if joint is not None:            # a spring end at a joint's point is drawn there
                    side = "i" if (joint.body_i, joint.point_i) == (body, point) else "j"
                    assert np.linalg.norm(end - where.get((joint.name, side), np.array(point))) <= 1e-9 * scale


def planar_examples() -> list:
    """The ```toml planar blocks of the docs: complete planar files."""
    import re
    fence = re.compile(r"^```toml planar\n(.*?)^```", re.S | re.M)
    return [text for page in sorted((ROOT / "docs").glob("*.md"))
            for text in fence.findall(page.read_text(encoding="utf-8"))]


def test_the_docs_planar_example_loads_and_balances_its_power():
    examples = planar_examples()
    assert examples, "docs/scenario-format.md shows a planar file"
    for text in examples:
        scenario = parse(tomllib.loads(text), "docs example")
        signals = simulate(scenario, "reference")
        assert signals.health["power_residual"].max() <= 1e-10
        assert signals.health["gap"].max() <= 1e-12
