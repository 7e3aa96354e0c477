"""The spatial scenes' contract, one more class for an engine's tests to
subclass (docs/adapters.md, "Testing an adapter"):

    from mechval.testing import SpatialContract

    class TestSpatialContract(SpatialContract):
        engine = "mujoco"

Its expected values come from physics (`mechval.testing.spatial_scenes`):
gravity and reactions in 3-D (a weight at rest under a gravity turned off
every axis), a spherical joint's reaction (a conical pendulum, upright and
turned), a spinning rotor's gyroscopic moment, a free body's momentum. An
adapter that builds no spatial scene (no "spatial" in its `features`) is
checked to refuse one up front, naming the file and key, and the rest skip.
Bounds are the default tolerances (docs/scenario-format.md): angles and
positions absolute, the other classes relative to the expected peak.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pytest

from mechval.harness.simulate import simulate
from mechval.model.scenario import DEFAULT_TOLERANCE, ScenarioError
from mechval.reference.spatial.rotation import quaternion_to_matrix

from . import spatial_scenes as ss
from .comparison import engine_or_skip


def relative(actual: np.ndarray, expected: np.ndarray, floor: float) -> float:
    """max |actual − expected| over max(max |expected|, floor)."""
    return float(np.abs(actual - expected).max() / max(np.abs(expected).max(), floor))


def vectors(signals, name: str, quantities: str) -> np.ndarray:
    return np.stack([signals[f"{name}.{q}"] for q in quantities.split()], axis=1)


class SpatialContract:
    """What an adapter promises of spatial scenes (docs/adapters.md)."""

    engine: ClassVar[str]

    @pytest.fixture
    def adapter(self):
        return engine_or_skip(self.engine)

    def run(self, adapter, name: str, system, end: float = 1.0):
        if "spatial" not in adapter.features:
            pytest.skip(f"{adapter.name} declares no spatial scenes (no 'spatial' in its features)")
        return simulate(ss.scenario(name, system, end), adapter)

    def test_a_spatial_scene_is_built_or_refused_up_front(self, adapter):
        scene = ss.scenario("hanging", ss.hanging(), 0.1, 11)
        if "spatial" in adapter.features:
            assert adapter.spatial_joints, f"{adapter.name} declares spatial scenes but no joint kinds"
            return
        with pytest.raises(ScenarioError) as refused:
            simulate(scene, adapter)
        assert refused.value.key == "mechanism" and adapter.name in refused.value.reason

    def test_a_weight_at_rest_hangs_from_its_pivot_under_oblique_gravity(self, adapter):
        """Statics: the pivot's force on the body (its second body) is −m·g,
        and nothing moves (a spherical joint's moment is zero by its kind:
        no signal)."""
        system = ss.hanging()
        signals = self.run(adapter, "hanging", system, 0.5)
        weight = system.body("weight").mass * np.asarray(system.gravity)
        force = vectors(signals, "pivot", "Fx Fy Fz")
        assert relative(force, np.broadcast_to(-weight, force.shape), 0.0) <= DEFAULT_TOLERANCE["force"]
        assert np.abs(vectors(signals, "weight", "x y z")).max() <= DEFAULT_TOLERANCE["position"]

    @pytest.mark.parametrize("turned", [False, True], ids=["upright", "turned"])
    def test_a_conical_pendulum_circles_steadily_on_its_spherical_joint(self, adapter, turned):
        """Ω² = g/(L·cos β) keeps the tilt: the attitude is the turn Ω·t
        about the vertical, ω is Ω along it, and the pivot's force on the
        body is m·(a_G − g) (centripetal a_G)."""
        case = ss.ConicalPendulum(turn=ss.OBLIQUE) if turned else ss.ConicalPendulum()
        signals = self.run(adapter, "conical-pendulum", case.system())
        t = signals.t
        w = vectors(signals, "bob", "wx wy wz")
        expected_w = np.broadcast_to(case.rate * case.vertical, w.shape)
        assert relative(w, expected_w, 0.0) <= DEFAULT_TOLERANCE["velocity"]
        # the attitude through where it turns a vector: the centre of mass's arm
        com = np.asarray(case.system().body("bob").com)
        q = vectors(signals, "bob", "qw qx qy qz")
        arm = rotate(q, com)
        assert np.abs(arm - np.einsum("nij,j->ni", case.attitude(t), com)).max() <= DEFAULT_TOLERANCE["position"]
        force = vectors(signals, "pivot", "Fx Fy Fz")
        assert relative(force, case.pivot_force(t), 0.0) <= DEFAULT_TOLERANCE["force"]

    def test_a_spinning_rotor_needs_its_gyroscopic_moment(self, adapter):
        """At constant ω = Ω·u the bearing's moment is ω × (I(t)·ω), the
        force and the drive torque zero (scaled by the moment's peak)."""
        case = ss.SpinningRotor()
        signals = self.run(adapter, "spinning-rotor", case.system(), 0.5)
        expected = case.moment(signals.t)
        moment = vectors(signals, "bearing", "Mx My Mz")
        assert relative(moment, expected, 0.0) <= DEFAULT_TOLERANCE["torque"]
        peak = np.abs(expected).max()
        assert np.abs(signals["spin.T"]).max() <= DEFAULT_TOLERANCE["torque"] * peak
        gyration = np.sqrt(np.linalg.eigvalsh(ss.TILTED_INERTIA).max() / case.mass)     # the rotor's size (m)
        force = vectors(signals, "bearing", "Fx Fy Fz")
        assert np.abs(force).max() <= DEFAULT_TOLERANCE["force"] * peak / gyration

    def test_a_free_body_keeps_its_momentum(self, adapter):
        """Free flight: the centre of mass on its parabola, m·v_G = m·v_G0 +
        m·g·t, and I(t)·ω(t) about the centre of mass constant."""
        case = ss.FreeBrick()
        signals = self.run(adapter, "free-brick", case.system())
        t = signals.t
        q = vectors(signals, "brick", "qw qx qy qz")
        origin, w = vectors(signals, "brick", "x y z"), vectors(signals, "brick", "wx wy wz")
        arm = rotate(q, np.asarray(case.com))
        assert np.abs(origin + arm - case.com_position(t)).max() <= DEFAULT_TOLERANCE["position"]
        v_G = vectors(signals, "brick", "vx vy vz") + np.cross(w, arm)
        assert relative(v_G, case.com_velocity(t), 0.0) <= DEFAULT_TOLERANCE["velocity"]
        R = quaternion_to_matrix(q)
        H = np.einsum("nij,jk,nlk,nl->ni", R, ss.TILTED_INERTIA, R, w)
        assert relative(H, np.broadcast_to(H[0], H.shape), 0.0) <= DEFAULT_TOLERANCE["velocity"]


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("nij,j->ni", quaternion_to_matrix(q), v)
