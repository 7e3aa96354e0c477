"""The planar kinematics kernel (`mechval.model.kinematics`) against motions
written independently with complex numbers: a lever that turns and whose
pivot moves, and a block sliding along the lever's axis (s(t) a cubic),
optionally off the guide line by a known offset h."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from mechval.model.kinematics import (joint_gap, joint_gaps, point_motion, point_position, rotate, rotate_scalar,
                                slide_motion, slide_rate, turn)
from mechval.model.mechanism import GROUND, Joint

T = np.linspace(0.0, 2.0, 201)
#: Lever: pivot O(t) = (0.2 + 0.1t², −0.1 + 0.3t), angle θ = 0.3 + 2t + 0.7t².
THETA = 0.3 + 2 * T + 0.7 * T**2, 2 + 1.4 * T, 1.4 + 0 * T
ORIGIN = 0.2 + 0.1 * T**2 + 1j * (-0.1 + 0.3 * T), 0.2 * T + 0.3j, 0.2 + 0j * T
#: Block: travel s(t) along the axis (unit, lever frame) through P_i.
S = 0.1 + 0.5 * T - 0.2 * T**3, 0.5 - 0.6 * T**2, -1.2 * T
AXIS, P_I, P_J, TURN = (0.6, 0.8), (0.05, 0.02), (0.03, -0.01), 0.4
SLOT = Joint("slot", "prismatic", "lever", "block", P_I, P_J, AXIS)


def c(v) -> complex:
    return v[0] + 1j * v[1]


def rigid(origin, theta, q):
    """Position, velocity, acceleration of O + e^{iθ}·q(t) (complex)."""
    (z, dz, ddz), (th, w, al), (q0, q1, q2) = origin, theta, q
    e = np.exp(1j * th)
    return z + e * q0, dz + 1j * w * e * q0 + e * q1, ddz + (1j * al - w * w) * e * q0 + 2j * w * e * q1 + e * q2


def motion(offset: float = 0.0) -> dict[str, np.ndarray]:
    """Raw motion columns of the lever and the block; the block's point is
    `offset` off the guide line (along ẑ × axis)."""
    u, n = c(AXIS), 1j * c(AXIS)
    pj = rigid(ORIGIN, THETA, (c(P_I) + S[0] * u + offset * n, S[1] * u, S[2] * u))
    block_theta = (THETA[0] + TURN, THETA[1], THETA[2])
    e = np.exp(1j * block_theta[0])
    w, al = block_theta[1], block_theta[2]
    # The block's frame origin: P_j − e^{iθ_j}·p_j and its rates.
    origin = (pj[0] - e * c(P_J), pj[1] - 1j * w * e * c(P_J), pj[2] - (1j * al - w * w) * e * c(P_J))
    columns = {"t": T}
    for body, (z, dz, ddz), (th, w, al) in (("lever", ORIGIN, THETA), ("block", origin, block_theta)):
        columns.update({f"{body}.x": z.real, f"{body}.y": z.imag, f"{body}.theta": th,
                        f"{body}.vx": dz.real, f"{body}.vy": dz.imag, f"{body}.omega": w,
                        f"{body}.ax": ddz.real, f"{body}.ay": ddz.imag, f"{body}.alpha": al})
    return columns


def test_rotate_is_multiplication_by_e_to_the_i_theta():
    v = (0.3, -1.7)
    x, y = rotate(THETA[0], v)
    np.testing.assert_allclose(x + 1j * y, np.exp(1j * THETA[0]) * c(v), rtol=0, atol=1e-15)
    assert rotate_scalar(0.5 * math.pi, (1.0, 0.0)) == pytest.approx((0.0, 1.0), abs=1e-16)


def test_turn_is_the_same_arithmetic_on_floats_and_arrays():
    """The per-step scalar path (floats) and the array path agree to the
    bit given the same cosine and sine."""
    cos, sin, v = np.cos(THETA[0]), np.sin(THETA[0]), (0.3, -1.7)
    arrays = turn(cos, sin, v)
    floats = np.array([turn(float(ci), float(si), v) for ci, si in zip(cos, sin)]).T
    np.testing.assert_array_equal(np.array(arrays), floats)


def test_point_motion_is_the_rigid_body_motion_of_the_point():
    raw = motion()
    expected = rigid(ORIGIN, THETA, (c(P_I), 0, 0))        # the lever's point P_i
    got = point_motion(raw, "lever", P_I)
    for (x, y), z in ((("x", "y"), expected[0]), (("vx", "vy"), expected[1]), (("ax", "ay"), expected[2])):
        np.testing.assert_allclose(got[x] + 1j * got[y], z, rtol=0, atol=1e-14)
    position = point_position(raw, "lever", P_I)
    np.testing.assert_array_equal(position["x"], got["x"])
    np.testing.assert_array_equal(position["y"], got["y"])


def test_a_ground_point_is_at_rest():
    got = point_motion(motion(), GROUND, (0.4, -0.2))
    assert (got["x"] == 0.4).all() and (got["y"] == -0.2).all()
    assert all((got[q] == 0.0).all() for q in ("vx", "vy", "ax", "ay"))


def test_slide_motion_is_the_travel_along_the_axis():
    raw = motion()
    slide = slide_motion(raw, SLOT)
    for name, exact in zip("sva", S):
        np.testing.assert_allclose(slide[name], exact, rtol=0, atol=1e-13, err_msg=name)
    np.testing.assert_allclose(slide_rate(raw, SLOT), S[1], rtol=0, atol=1e-13)
    assert joint_gap(raw, SLOT).max() <= 1e-15


def test_an_offset_from_the_guide_line_is_the_gap():
    """Off the line by h: the gap is h, the travel is unchanged, and the
    damper's rate (v_Pj − v_Pi)·u is ṡ − ω_i·h (the lever's turning moves
    the offset point along u)."""
    h = 4e-3
    raw = motion(offset=h)
    np.testing.assert_allclose(joint_gap(raw, SLOT), h, rtol=1e-12)
    np.testing.assert_allclose(slide_motion(raw, SLOT)["s"], S[0], rtol=0, atol=1e-13)
    np.testing.assert_allclose(slide_rate(raw, SLOT), S[1] - THETA[1] * h, rtol=0, atol=1e-13)


def test_revolute_gap_is_the_distance_of_the_pins():
    raw = motion()
    pin = Joint("pin", "revolute", "lever", "block", P_I, P_J)
    lever_pin = rigid(ORIGIN, THETA, (c(P_I), 0, 0))[0]
    block_pin = rigid(ORIGIN, THETA, (c(P_I) + S[0] * c(AXIS), S[1] * c(AXIS), S[2] * c(AXIS)))[0]
    np.testing.assert_allclose(joint_gap(raw, pin), np.abs(block_pin - lever_pin), rtol=1e-12)
    both = SimpleNamespace(joints=(pin, SLOT))              # all joint_gaps reads of a mechanism
    np.testing.assert_array_equal(joint_gaps(both, raw), np.maximum(joint_gap(raw, pin), joint_gap(raw, SLOT)))
