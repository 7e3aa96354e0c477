"""The angle a prismatic joint of a planar file holds when the file gives
no `angle` (docs/scenario-format.md#planar-files): θj − θi of the
`[assembly]` pose, or the axis's angle exactly where the pose agrees with
it within AXIS_SNAP — so every shipped file keeps its numbers."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from mechval.harness.simulate import simulate
from mechval.scenarios import parse
from mechval.scenarios.planar import AXIS_SNAP
from conftest import CLOSED_FORM
from mechval.testing.planar_scenes import SCENES
from mechval.testing.twins import twin_document

ROOT = Path(__file__).resolve().parents[1]

#: A slider-crank on a vertical guide (axis [0, 1] along the ground's y)
#: whose slider is drawn aligned with the world (θ = 0), its centre of
#: mass 0.05 m along its own x from the pin.
VERTICAL = """
name = "vertical-slider"
mechanism = "planar"
[ground]
O = [0.0, 0.0]
[[body]]
name = "crank"
mass = 1.0
length = 0.1
[[body]]
name = "conrod"
mass = 2.0
length = 0.4
[[body]]
name = "slider"
mass = 0.5
com = [0.05, 0.0]
izz = 1e-3
points = { pin = [0.0, 0.0] }
[[joint]]
name = "O2"
type = "revolute"
between = ["ground.O", "crank.start"]
[[joint]]
name = "A"
type = "revolute"
between = ["crank.end", "conrod.start"]
[[joint]]
name = "B"
type = "revolute"
between = ["conrod.end", "slider.pin"]
[[joint]]
name = "guide"
type = "prismatic"
between = ["ground.O", "slider.pin"]
axis = [0.0, 2.0]
[[drive]]
joint = "O2"
omega0 = 10.0
[assembly]
crank = 0.0
conrod = 1.82
slider = 0.0
[effects]
gravity = [0.0, -9.81]
[time]
end = 0.5
samples = 51
"""


def guide(scenario):
    return next(j for j in scenario.scene.joints if j.name == "guide")


def test_a_slider_drawn_aligned_with_the_world_stays_so():
    """The file's pose is what the slider holds: θ = 0 (it came out π/2,
    the axis's angle, silently), so its centre of mass is 0.05 m to the
    right of the guide; `angle` still sets any other angle."""
    scenario = parse(tomllib.loads(VERTICAL), "vertical.toml")
    assert guide(scenario).axis == (0.0, 1.0)                 # normalised: u = axis/|axis|
    assert guide(scenario).held_angle == 0.0
    reference = simulate(scenario, "reference")
    np.testing.assert_allclose(reference["slider.theta"], 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(reference["slider.x"], 0.05, rtol=0, atol=1e-12)
    assert np.ptp(reference["slider.y"]) > 0.15                # it does slide: the crank's stroke 0.2 m

    along = parse(tomllib.loads(VERTICAL.replace("axis = [0.0, 2.0]", "axis = [0.0, 2.0]\nangle = 1.5707963267948966")
                                .replace("slider = 0.0", "slider = 1.5")), "along.toml")
    np.testing.assert_allclose(simulate(along, "reference")["slider.x"], 0.0, rtol=0, atol=1e-12)


def test_a_rounded_pose_holds_the_axis_angle_exactly():
    """An assembly angle is approximate: within AXIS_SNAP of the axis's
    angle (hand-pump's 1.57 for π/2) the joint holds the axis's angle;
    beyond it, the pose's."""
    for slider, held in ((math.pi / 2 - 0.9 * AXIS_SNAP, math.pi / 2), (math.pi / 2 + 0.9 * AXIS_SNAP, math.pi / 2),
                         (0.1, 0.1), (-0.2, -0.2)):
        text = VERTICAL.replace("slider = 0.0", f"slider = {slider!r}")
        assert guide(parse(tomllib.loads(text), "v.toml")).held_angle == held, slider


def shipped_planar_files() -> dict[str, dict]:
    """Every shipped planar file and test scene with a prismatic joint."""
    files = {str(path.relative_to(ROOT)): tomllib.loads(path.read_text())
             for folder in ("scenarios", "scenarios/planar", "scenarios/planar-extra")
             for path in sorted((ROOT / folder).glob("*.toml"))}
    files.update({f"testing/planar_scenes.py:{name}": tomllib.loads(text) for name, text in SCENES.items()})
    files.update({f"twin:{name}": twin_document(name) for name in CLOSED_FORM})
    return {name: data for name, data in files.items() if data.get("mechanism") == "planar"
            and any(j.get("type") == "prismatic" for j in data.get("joint", []))}


SHIPPED = shipped_planar_files()


def test_every_shipped_slide_is_checked():
    assert {"twin:hand-pump", "twin:shaper-quick-return",
            "scenarios/slider-driven-slider-crank.toml", "testing/planar_scenes.py:slider-driven"} <= set(SHIPPED)
    assert len(SHIPPED) >= 10


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_files_keep_their_numbers(name):
    """Each shipped file's reference equals, to 1e-13 of each column's
    peak, the one of the same file with the old default written out: every
    slide without `angle` given its axis's angle."""
    data = SHIPPED[name]
    old = copy.deepcopy(data)
    for joint in old["joint"]:
        if joint.get("type") == "prismatic" and "angle" not in joint:
            joint["angle"] = math.atan2(joint["axis"][1], joint["axis"][0])
    new, before = simulate(parse(data, name), "reference"), simulate(parse(old, name), "reference")
    assert list(new.frame.columns) == list(before.frame.columns)
    for column in new.frame.columns:
        peak = max(np.abs(before[column]).max(), 1e-300)
        np.testing.assert_allclose(new[column], before[column], rtol=0, atol=1e-13 * peak, err_msg=column)
