"""PyBullet on planar files beyond the four kinds (issue 14): the shared
planar contract (testing/planar_contract.py) on the scenes of
testing/planar_scenes.py, at the default tolerances; where the layout hangs
a link below another (a five-bar driven at a pin between moving links, a
Scotch yoke) and which reactions it then derives; what it still cannot
build, refused naming the key.

How PyBullet builds each feature (engines/pybullet/run.py, model.py,
layout.py): every drive is a position-controlled multibody joint,
its effort read from the joint's applied motor torque or force;
spring-dampers and body torques are external loads set before every step
(PyBullet has no spring element between bodies)."""

from __future__ import annotations

import pytest

from mechval.harness.simulate import simulate
from mechval.reference.linkages import build_mechanism
from mechval.testing.planar_contract import PlanarContract
from mechval.testing.planar_scenes import scene

pytestmark = pytest.mark.engine


class TestPlanarContract(PlanarContract):
    engine = "pybullet"


def layout_of(name: str):
    from mechval.engines.pybullet.layout import plan_layout
    layout = plan_layout(build_mechanism(scene(name)), "split")
    links = {root: [(joint.name, parent, child) for joint, parent, child in links]
             for root, links in layout.multibodies.items()}
    return links, [(joint.name, body) for joint, body in layout.derived]


@pytest.mark.parametrize("name, multibodies, derived", [
    # O1 and A both drive (both need a motor): L2 hangs below L1.
    ("pin-driven-five-bar", {"ground": [("O1", "ground", "L1"), ("A", "L1", "L2"), ("O4", "ground", "L4")],
                             "L3": []},
     [("A", "L2"), ("O1", "L1")]),
    # The guide and the slot are both slides: the block hangs below the yoke.
    ("scotch-yoke", {"ground": [("O2", "ground", "crank"), ("guide", "ground", "yoke"), ("slot", "yoke", "block")]},
     [("slot", "block"), ("guide", "yoke")]),
    # Written with the ground second, the pin O2 still hangs the crank from the ground.
    ("ground-second", {"ground": [("O2", "ground", "crank"), ("guide", "ground", "slider")], "conrod": []}, []),
])
def test_the_layout_hangs_a_link_below_another_and_derives_its_reactions(name, multibodies, derived):
    """Drive and prismatic joints are multibody joints (motors; PyBullet's
    slider constraint over-constrains a planar loop). Where two of them
    meet at a moving body, one link hangs below the other; the sensors of
    a joint below a moving link or carrying one are not read but derived
    from the child's balance, children first (the run info says so)."""
    pytest.importorskip("pybullet")
    assert layout_of(name) == (multibodies, derived)
    if derived:
        facts = simulate(scene(name), "pybullet").info.facts["derived_reactions"]
        for joint, body in derived:
            assert f"{joint}: F{' and M' if joint in ('slot', 'guide') else ''} derived from the balance of {body}" \
                in facts


#: Three slides closing one loop (a wedge pushing a follower up its stem):
#: every joint must be a multibody joint, and a tree holds no loop.
WEDGE = """
name = "wedge"
mechanism = "planar"
[ground]
O = [0.0, 0.0]
[[body]]
name = "wedge"
mass = 1.0
com = [0.0, 0.0]
izz = 0.01
points = { P = [0.0, 0.0] }
[[body]]
name = "follower"
mass = 0.5
com = [0.0, 0.0]
izz = 0.01
points = { P = [0.0, 0.0] }
[[joint]]
name = "rail"
type = "prismatic"
between = ["ground.O", "wedge.P"]
axis = [1.0, 0.0]
[[joint]]
name = "stem"
type = "prismatic"
between = ["ground.O", "follower.P"]
axis = [0.0, 1.0]
angle = 0.0
[[joint]]
name = "face"
type = "prismatic"
between = ["wedge.P", "follower.P"]
axis = [-1.0, 0.5]
angle = 0.0
[[drive]]
joint = "rail"
phi0 = 0.1
omega0 = 0.2
[assembly]
wedge = 0.0
follower = { theta = 0.0, x = 0.0, y = 0.05 }
[time]
end = 0.5
samples = 51
"""


def test_a_loop_of_slides_is_refused_naming_the_joint(tmp_path, capsys):
    """What the layout cannot build is bad input for PyBullet: one line
    naming the file, the key of the joint that closes the loop and the
    reason, exit 2, nothing written."""
    pytest.importorskip("pybullet")
    from mechval.harness import cli
    path, csv = tmp_path / "wedge.toml", tmp_path / "out" / "wedge.csv"
    path.write_text(WEDGE)
    assert cli.main(["simulate", str(path), "--engine", "pybullet", "--csv", str(csv)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "wedge.toml: joint.face: pybullet: the prismatic joint 'face' closes a loop" in err
    assert "Traceback" not in err and not csv.exists()


@pytest.mark.engine
def test_linear_rates_of_a_moving_origin_converge_as_dt_squared():
    """A coupler's linear velocity and acceleration are central differences
    of its positions (engines/pybullet/run.py, `assemble`): the mean and
    difference of PyBullet's velocity readings, each mapped through the
    Jacobian at the step's end, were O(dt) off (halving dt halved the
    coupler's ay error) and the power balance of a torque law between two
    moving links failed by 3.85× its bound. Now halving dt quarters the
    error (measured 3.9×) and the balance holds (measured 0.0066 of its
    bound)."""
    import tomllib

    import numpy as np

    from mechval.engines.registry import adapter
    from mechval.harness.plan import prepare
    from mechval.judging.compare import compare, passed
    from mechval.scenarios import parse
    from test_exudyn_moving_pairs import ELBOW_TORQUE

    pybullet = adapter("pybullet")
    data = tomllib.loads(ELBOW_TORQUE)
    data["time"] = {"end": 1.0, "samples": 101}    # its power residual peaks near t = 0.97
    plan = prepare(parse(data, "fourbar-elbow-torque.toml"))
    reference = simulate(plan, "reference")
    records = compare(reference, simulate(plan, pybullet), plan.scenario.tolerance_for("pybullet"),
                      scenario="fourbar-elbow-torque")
    assert passed(records)
    assert "health.power_residual" in set(records["signal"])
    settings = plan.for_engines([pybullet]).settings(pybullet, None)
    t = plan.scenario.time.t
    truth = adapter("reference").run(plan.mechanism, t, {}).frame
    errors = []
    for dt in (settings["timestep"], settings["timestep"] / 2):
        raw = pybullet.run(plan.mechanism, t, {**settings, "timestep": dt}).frame
        errors.append(max(float(np.abs(raw[c] - truth[c]).max()) for c in ("coupler.ax", "coupler.ay")))
    assert 3.0 < errors[0] / errors[1] < 5.0, errors
