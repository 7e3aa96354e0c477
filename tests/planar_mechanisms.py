"""Mechanisms for the general reference's tests that the four closed-form
kinds cannot express: two drives, a prismatic drive (on the ground and
between two moving bodies), spring-dampers, body torques, and a redundant
parallelogram (the slider-driven slider-crank is in
`mechval.testing.mechanisms`, which the contract suite uses). Each comes
with an approximate assembly pose worked out here by hand (rounded), never
by the solver under test."""

from __future__ import annotations

import numpy as np

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND, Body, BodyPose, BodyTorque, Drive, Joint, Mechanism, SpringDamper
# The slider-driven slider-crank is one of the contract suite's mechanisms.
from mechval.testing.mechanisms import SLIDER, bar, slider_driven_slider_crank  # noqa: F401


def _no_closed_form(t):
    raise NotImplementedError("no closed form: solve with mechval.reference.planar.solver")


def circle_apex(a: np.ndarray, b: np.ndarray, ra: float, rb: float) -> np.ndarray:
    """The intersection of circles (a, ra) and (b, rb) left of a→b."""
    d = np.linalg.norm(b - a)
    along = (ra * ra - rb * rb + d * d) / (2 * d)
    h = np.sqrt(ra * ra - along * along)
    e = (b - a) / d
    return a + along * e + h * np.array([-e[1], e[0]])


def five_bar() -> Mechanism:
    """Two cranks driven independently (O1: φ1 = 0.5 + 2t; O4: φ4 = 2 +
    1.5t + 0.5t²), two coupler links meeting at P; gravity, dampers at A and
    P, a spring-damper from L2's middle to the ground, a torque on L3."""
    o1, o4, crank, link = np.array([0.0, 0.0]), np.array([0.3, 0.0]), 0.15, 0.3
    bodies = (bar("L1", 1.0, crank), bar("L2", 1.5, link), bar("L3", 1.5, link), bar("L4", 1.0, crank))
    joints = (
        Joint("O1", "revolute", GROUND, "L1", tuple(o1), (0.0, 0.0)),
        Joint("A", "revolute", "L1", "L2", (crank, 0.0), (0.0, 0.0), damping=0.05),
        Joint("P", "revolute", "L2", "L3", (link, 0.0), (link, 0.0), damping=0.05),
        Joint("B", "revolute", "L4", "L3", (crank, 0.0), (0.0, 0.0)),
        Joint("O4", "revolute", GROUND, "L4", tuple(o4), (0.0, 0.0)),
    )
    th1, th4 = 0.5, 2.0
    a = o1 + crank * np.array([np.cos(th1), np.sin(th1)])
    b = o4 + crank * np.array([np.cos(th4), np.sin(th4)])
    p = circle_apex(b, a, link, link)        # P above the segment
    angle = lambda v: float(np.arctan2(v[1], v[0]))
    pose = {"L1": th1, "L2": angle(p - a), "L3": angle(p - b), "L4": th4}
    return Mechanism(
        name="five-bar", kind="planar", bodies=bodies, joints=joints,
        drive=Drive("O1", DriveLaw(0.5, 2.0, 0.0)), gravity=(0.0, -9.81), motion=_no_closed_form, signal_map={},
        extra_drives=(Drive("O4", DriveLaw(2.0, 1.5, 1.0), name="drive2"),),
        forces=(SpringDamper("spring", "L2", (link / 2, 0.0), GROUND, (0.15, 0.5), 200.0, 0.3, 2.0),
                BodyTorque("motor3", "L3", 0.4)),
        assembly_pose={k: BodyPose(round(v, 1)) for k, v in pose.items()},
    )


def boom() -> Mechanism:
    """A boom pivoted at O, lifted by a hydraulic cylinder: the barrel is
    pivoted at the ground point C, the rod slides in it (a prismatic joint
    between two moving bodies, damped) and is pinned to the boom at R. The
    ram drive prescribes the cylinder length |CR| = s(t) = 0.55 + 0.2t −
    0.1t². Gravity, a spring-damper from the boom tip to the ground, a
    torque on the barrel."""
    c, r_on_boom = np.array([0.2, -0.3]), 0.6
    bodies = (bar("boom", 20.0, 1.0), Body("barrel", 5.0, (0.2, 0.0), 0.1), Body("rod", 3.0, (-0.2, 0.0), 0.05))
    joints = (
        Joint("O", "revolute", GROUND, "boom", (0.0, 0.0), (0.0, 0.0), damping=0.3),
        Joint("C", "revolute", GROUND, "barrel", tuple(c), (0.0, 0.0)),
        Joint("R", "revolute", "boom", "rod", (r_on_boom, 0.0), (0.0, 0.0)),
        Joint("cylinder", "prismatic", "barrel", "rod", (0.0, 0.0), (0.0, 0.0), axis=(1.0, 0.0), damping=50.0),
    )
    law = DriveLaw(0.55, 0.2, -0.2)
    # Boom angle with |C − R| = 0.55, R = 0.6·(cos θ, sin θ): by the law of
    # cosines in triangle O, C, R (θ above the ray O→C).
    oc = float(np.linalg.norm(c))
    gamma = np.arccos((r_on_boom**2 + oc**2 - 0.55**2) / (2 * r_on_boom * oc))
    th_boom = float(np.arctan2(c[1], c[0]) + gamma)
    rod_end = r_on_boom * np.array([np.cos(th_boom), np.sin(th_boom)])
    th_cyl = float(np.arctan2(*(rod_end - c)[::-1]))
    pose = {"boom": th_boom, "barrel": th_cyl, "rod": th_cyl}
    return Mechanism(
        name="boom", kind="planar", bodies=bodies, joints=joints, drive=Drive("cylinder", law, name="ram"),
        gravity=(0.0, -9.81), motion=_no_closed_form, signal_map={},
        forces=(SpringDamper("tie", "boom", (1.0, 0.0), GROUND, (1.2, 1.0), 300.0, 0.5, 5.0),
                BodyTorque("twist", "barrel", 0.5)),
        assembly_pose={k: BodyPose(round(v, 1)) for k, v in pose.items()},
    )


def parallelogram(law: DriveLaw = DriveLaw(0.3, 2.0, 1.0)) -> Mechanism:
    """Three equal parallel cranks (O1, O2, O3 on the ground, 0.4 m apart)
    carrying one coupler: Grübler 3·4 − 2·6 = 0, yet it moves (mobility 1)
    because one of its 12 joint equations is redundant. Closed form: every
    crank at φ(t), the coupler translating at angle 0. φ must stay off 0
    and π: there the coupler lies on the ground line and may also turn (the
    parallelogram's change point, a singular position)."""
    crank = 0.2
    bodies = (bar("c1", 1.0, crank), bar("c2", 1.0, crank), bar("c3", 1.0, crank), bar("coupler", 4.0, 0.8))
    joints = tuple(Joint(f"O{k}", "revolute", GROUND, f"c{k}", (0.4 * (k - 1), 0.0), (0.0, 0.0)) for k in (1, 2, 3)) + \
        tuple(Joint(f"A{k}", "revolute", f"c{k}", "coupler", (crank, 0.0), (0.4 * (k - 1), 0.0)) for k in (1, 2, 3))
    return Mechanism(
        name="parallelogram", kind="planar", bodies=bodies, joints=joints, drive=Drive("O1", law),
        gravity=(0.0, -9.81), motion=_no_closed_form, signal_map={},
        assembly_pose={"c1": BodyPose(0.3), "c2": BodyPose(0.3), "c3": BodyPose(0.3), "coupler": BodyPose(0.0)},
    )
