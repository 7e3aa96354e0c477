"""Planar files that use what the four closed-form kinds cannot, for the
engines' planar tests (testing/planar_contract.py and the per-engine
tests/test_<engine>_planar.py): two drives, a prismatic drive (also with
the slider's centre of mass off its joint point), a spring-damper between
two moving links, body torques, a two-loop six-bar, a five-bar driven at a
pin between two moving links, a Scotch yoke (a slide on a slide), a joint
that lists the ground second.

Each scene is short (≤ 1 s, ≤ 161 samples) and its lengths are derived
here, not taken from a source; assembly poses are worked out by hand
(circle intersections, rounded) and the general reference closes the loops
itself (a file whose loop cannot close over the run is refused on load).
Figures per engine: `.venv/bin/python tests/bench/planar_figures.py`
prints each engine's worst signals on each.
"""

from __future__ import annotations

import tomllib

from mechval.scenarios import parse
from .twins import twin_text

#: fourbar-seed's links (Norton's crank-rocker of the published 9x9 study,
#: docs/scenario-format.md), the base of the four-bar and six-bar scenes;
#: dampers at O2 and B, a rocker point C for the six-bar's second loop.
FOURBAR = """
mechanism = "planar"
[ground]
O2 = [0.0, 0.0]
O4 = [0.6, 0.0]
[[body]]
name = "crank"
mass = 12.5
length = 0.25
[[body]]
name = "coupler"
mass = 25.0
length = 0.5
points = { mid = [0.25, 0.0] }
[[body]]
name = "rocker"
mass = 25.0
length = 0.5
points = { mid = [0.25, 0.0], C = [0.3, 0.15] }
[[joint]]
name = "O2"
type = "revolute"
between = ["ground.O2", "crank.start"]
damping = 0.5
[[joint]]
name = "A"
type = "revolute"
between = ["coupler.start", "crank.end"]
[[joint]]
name = "B"
type = "revolute"
between = ["rocker.end", "coupler.end"]
damping = 0.3
[[joint]]
name = "O4"
type = "revolute"
between = ["ground.O4", "rocker.start"]
[[drive]]
joint = "O2"
phi0 = 0.0
omega0 = 3.0
alpha = 1.0
[effects]
gravity = [0.0, -9.81]
[time]
end = 1.0
samples = 101
"""
FOURBAR_POSE = "[assembly]\ncrank = 0.0\ncoupler = 1.21\nrocker = 1.93\n"

#: A spring-damper between two moving links (coupler middle to rocker middle).
FOURBAR_SPRING = 'name = "fourbar-spring"\n' + FOURBAR + FOURBAR_POSE + """
[[force]]
name = "tie"
type = "spring"
between = ["coupler.mid", "rocker.mid"]
stiffness = 2000.0
free_length = 0.1
damping = 50.0
"""

#: Constant torques on two moving links.
FOURBAR_TORQUE = 'name = "fourbar-torque"\n' + FOURBAR + FOURBAR_POSE + """
[[force]]
name = "twist"
type = "torque"
body = "coupler"
torque = 15.0
[[force]]
name = "brake"
type = "torque"
body = "rocker"
torque = -40.0
"""

#: A Watt II six-bar (two four-bars in series): loop 1 is the four-bar above;
#: the rocker is a ternary link whose point C = [0.3, 0.15] drives loop 2,
#: the coupler CD (0.55 m) and the output rocker O6D (0.4 m) about
#: O6 = (1.0, 0.45). Over a whole crank turn |O6C| stays in 0.596 … 0.869 m,
#: inside (0.15, 0.95) = (|l5 − l6|, l5 + l6), so loop 2 closes at every
#: crank angle, away from its toggles.
SIX_BAR = 'name = "watt-six-bar"\n' + FOURBAR.replace("O4 = [0.6, 0.0]", "O4 = [0.6, 0.0]\nO6 = [1.0, 0.45]") + """
[[body]]
name = "link5"
mass = 8.0
length = 0.55
[[body]]
name = "link6"
mass = 6.0
length = 0.4
[[joint]]
name = "C"
type = "revolute"
between = ["rocker.C", "link5.start"]
damping = 0.2
[[joint]]
name = "D"
type = "revolute"
between = ["link5.end", "link6.end"]
[[joint]]
name = "O6"
type = "revolute"
between = ["ground.O6", "link6.start"]
[assembly]
crank = 0.0
coupler = 1.21
rocker = 1.93
link5 = 0.96
link6 = 2.53
"""

#: Two cranks on the ground driven independently (tests/planar_mechanisms.py's
#: `five_bar` without its force elements): φ1 = 0.5 + 2t at O1, φ4 = 2 +
#: 1.5t + 0.5t² at O4, couplers meeting at P; gravity, dampers at A and P.
FIVE_BAR = """
name = "two-drive-five-bar"
mechanism = "planar"
[ground]
O1 = [0.0, 0.0]
O4 = [0.3, 0.0]
[[body]]
name = "L1"
mass = 1.0
length = 0.15
[[body]]
name = "L2"
mass = 1.5
length = 0.3
[[body]]
name = "L3"
mass = 1.5
length = 0.3
[[body]]
name = "L4"
mass = 1.0
length = 0.15
[[joint]]
name = "O1"
type = "revolute"
between = ["ground.O1", "L1.start"]
[[joint]]
name = "A"
type = "revolute"
between = ["L1.end", "L2.start"]
damping = 0.05
[[joint]]
name = "P"
type = "revolute"
between = ["L2.end", "L3.end"]
damping = 0.05
[[joint]]
name = "B"
type = "revolute"
between = ["L4.end", "L3.start"]
[[joint]]
name = "O4"
type = "revolute"
between = ["ground.O4", "L4.start"]
[[drive]]
joint = "O1"
phi0 = 0.5
omega0 = 2.0
[[drive]]
joint = "O4"
phi0 = 2.0
omega0 = 1.5
alpha = 1.0
[assembly]
L1 = 0.5
L2 = -0.8
L3 = -1.2
L4 = 2.0
[effects]
gravity = [0.0, -9.81]
[time]
end = 1.0
samples = 101
"""

#: The seed textbook's slider-driven slider-crank (docs/scenario-format.md,
#: "Planar files"): the slide is prescribed, s = 0.35 − 0.12t − 0.05t²
#: inside the dead centres 0.2 and 0.4 m (crank 0.1 m, conrod 0.3 m); a
#: return spring from the slider to the wall, a damped guide, and a torque
#: on the slider block (which the guide's couple M carries). Unlike the
#: docs' example the guide is tilted and the slide accelerates: on a level
#: guide at constant rate the reference's slider.vy and slider.ax are
#: rounding noise (~1e-17), and the comparison's bound, relative to a
#: signal's own peak, would then be ~1e-19 (a limit of the comparison rule,
#: not of an engine).
SLIDER_DRIVEN = """
name = "slider-driven-slider-crank"
mechanism = "planar"
[ground]
O = [0.0, 0.0]
wall = [0.6, 0.0]
[[body]]
name = "crank"
mass = 1.0
length = 0.1
[[body]]
name = "conrod"
mass = 2.0
length = 0.3
[[body]]
name = "slider"
mass = 3.0
com = [0.0, 0.0]
izz = 1e-3
points = { pin = [0.0, 0.0] }
[[joint]]
name = "O2"
type = "revolute"
between = ["ground.O", "crank.start"]
[[joint]]
name = "A"
type = "revolute"
between = ["conrod.start", "crank.end"]
[[joint]]
name = "B"
type = "revolute"
between = ["slider.pin", "conrod.end"]
[[joint]]
name = "guide"
type = "prismatic"
between = ["ground.O", "slider.pin"]
axis = [0.96, 0.28]
damping = 4.0
[[drive]]
joint = "guide"
phi0 = 0.35
omega0 = -0.12
alpha = -0.1
[[force]]
name = "return"
type = "spring"
between = ["slider.pin", "ground.wall"]
stiffness = 50.0
free_length = 0.2
[[force]]
name = "block"
type = "torque"
body = "slider"
torque = 2.0
[assembly]
crank = 0.9
conrod = 0.05
slider = 0.2838
[effects]
gravity = [0.0, -9.81]
[time]
end = 0.8
samples = 161
"""



def _edited(text: str, *edits: tuple[str, str]) -> str:
    """`text` with each (old, new) replaced; each old must be there."""
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    return text


#: The slider-driven slider-crank with the slider's centre of mass off the
#: joint point, an axis not of unit length (the same direction, twice as
#: long) and the slider's frame held level (`angle = 0`) instead of along
#: the tilted guide: the guide's couple M then carries the moment of the
#: drive force F, taken at the joint point, about the centre of mass
#: (PyBullet's sensor left it out: 42× the bound on M before the fix).
SLIDER_DRIVEN_OFFSET = _edited(
    SLIDER_DRIVEN, ('name = "slider-driven-slider-crank"', 'name = "slider-driven-offset-com"'),
    ("com = [0.0, 0.0]", "com = [0.03, -0.02]"), ("axis = [0.96, 0.28]", "axis = [1.92, 0.56]\nangle = 0.0"),
    ("slider = 0.2838", "slider = 0.0"))

#: FIVE_BAR driven at O1 and at the pin A between its two moving links L1
#: and L2 instead of at O4: A's law is a quadratic fitted to the relative
#: angle θL2 − θL1 of FIVE_BAR's reference over its first second (−1.316 −
#: 5.8·t + 3.3·t², rounded), so the loop follows nearly FIVE_BAR's motion;
#: the run stops at 0.6 s, as the loop locks just after 0.647 s with this
#: law (the reference refuses a longer one).
FIVE_BAR_PIN_DRIVEN = _edited(
    FIVE_BAR, ('name = "two-drive-five-bar"', 'name = "pin-driven-five-bar"'),
    ('joint = "O4"\nphi0 = 2.0\nomega0 = 1.5\nalpha = 1.0', 'joint = "A"\nphi0 = -1.316\nomega0 = -5.8\nalpha = 6.6'),
    ("end = 1.0\nsamples = 101", "end = 0.6\nsamples = 61"))

#: A Scotch yoke: the crank's pin A carries a block that slides in the
#: yoke's slot (along the yoke's y axis), and the yoke slides on a damped
#: horizontal guide, so the yoke's x is 0.1·cos φ. The yoke's centre of mass
#: is off its guide point; the block's frame is held along the slot.
#: Assembly by hand: block at 90°, yoke level; nothing locks (the slot is
#: always across the guide).
SCOTCH_YOKE = """
name = "scotch-yoke-damped"
mechanism = "planar"
[ground]
O = [0.0, 0.0]
[[body]]
name = "crank"
mass = 1.0
length = 0.1
[[body]]
name = "block"
mass = 0.2
com = [0.0, 0.0]
izz = 1e-4
points = { pin = [0.0, 0.0] }
[[body]]
name = "yoke"
mass = 2.0
com = [0.15, 0.02]
izz = 0.02
points = { slot = [0.0, 0.0] }
[[joint]]
name = "O2"
type = "revolute"
between = ["ground.O", "crank.start"]
[[joint]]
name = "A"
type = "revolute"
between = ["crank.end", "block.pin"]
[[joint]]
name = "guide"
type = "prismatic"
between = ["ground.O", "yoke.slot"]
axis = [1.0, 0.0]
damping = 5.0
[[joint]]
name = "slot"
type = "prismatic"
between = ["yoke.slot", "block.pin"]
axis = [0.0, 1.0]
[[drive]]
joint = "O2"
phi0 = 0.3
omega0 = 6.0
alpha = 2.0
[assembly]
crank = 0.3
block = 1.5708
yoke = 0.0
[effects]
gravity = [0.0, -9.81]
[time]
end = 1.0
samples = 101
"""

#: The planar twin of the built-in slider-crank with its ground pin written
#: the other way round, `between = ["crank.start", "ground.O2"]`, and its
#: drive reversed to keep the motion (θground − θcrank = −10·t): O2's
#: reaction is then the force by the crank on the ground and O2.T the
#: torque on the ground, minus the twin's (Newton's third law). 0.5 s.
TWIN = twin_text("slider-crank")
GROUND_SECOND = _edited(
    TWIN, ('name = "slider-crank-planar"', 'name = "slider-crank-ground-second"'),
    ('between = ["ground.O2", "crank.O2"]', 'between = ["crank.O2", "ground.O2"]'),
    ("omega0 = 10.0", "omega0 = -10.0"), ("end = 2.0\nsamples = 401", "end = 0.5\nsamples = 101"))

SCENES = {"five-bar": FIVE_BAR, "slider-driven": SLIDER_DRIVEN, "spring": FOURBAR_SPRING,
          "torque": FOURBAR_TORQUE, "six-bar": SIX_BAR, "slider-driven-offset-com": SLIDER_DRIVEN_OFFSET,
          "pin-driven-five-bar": FIVE_BAR_PIN_DRIVEN, "scotch-yoke": SCOTCH_YOKE, "ground-second": GROUND_SECOND}


def scene(name: str):
    """The scenario of SCENES[name], as loaded from a file `name`.toml."""
    return parse(tomllib.loads(SCENES[name]), f"{name}.toml")
