"""A planar mechanism as a spatial system, for checking one reference
against the other: every body in the plane z = 0, revolute axes along z,
prismatic axes in the plane.

Bodies: frame origin (x, y, 0) and rotation Rz(θ) at the planar assembly
pose; centre of mass (cx, cy, 0); inertia diag(izz/2, izz/2, izz) (a
lamina's: the out-of-plane moments do not enter planar motion, and with no
products of inertia no out-of-plane moment is needed). Joints: revolute
with both joint frames the body axes, so the spatial drive angle is
θj − θi as the planar drive's; prismatic with z along the planar axis u
and x out of the plane on body_i, body_j's frame the same turned by the
held angle, so the slide zi·(Pj − Pi) is the planar u·(Pj − Pi). Loads
keep their planar meaning: gravity, constant body torques about z,
spring-dampers, joint dampers, torque laws.
"""

from __future__ import annotations

import numpy as np

from mechval.model.mechanism import BodyTorque, Mechanism, SpringDamper
from mechval.reference.spatial.system import (BodyLoad, JointTorque, SpatialBody, SpatialDrive, SpatialJoint,
                                              SpatialSystem, Spring)


def rot_z(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _xyz(p) -> tuple[float, float, float]:
    return (float(p[0]), float(p[1]), 0.0)


def spatial_from_planar(mech: Mechanism, poses: dict[str, tuple[float, float, float]]) -> SpatialSystem:
    """`mech` in three dimensions; `poses` per body (x, y, θ) of its frame
    near the assembly (the planar reference's solution at t0 will do)."""
    bodies = tuple(
        SpatialBody(b.name, b.mass, _xyz(b.com), np.diag([b.izz / 2, b.izz / 2, b.izz]),
                    position=_xyz(poses[b.name][:2]), rotation=rot_z(poses[b.name][2]))
        for b in mech.bodies)
    joints = []
    for j in mech.joints:
        if j.kind == "revolute":
            joints.append(SpatialJoint(j.name, "revolute", j.body_i, j.body_j, _xyz(j.point_i), _xyz(j.point_j),
                                       damping=j.damping))
            continue
        u = np.array([j.axis[0], j.axis[1], 0.0]) / np.hypot(*j.axis)
        frame_i = np.column_stack([[0.0, 0.0, 1.0], np.cross(u, [0.0, 0.0, 1.0]), u])
        joints.append(SpatialJoint(j.name, "prismatic", j.body_i, j.body_j, _xyz(j.point_i), _xyz(j.point_j),
                                   frame_i=frame_i, frame_j=rot_z(j.held_angle).T @ frame_i, damping=j.damping))
    drives = tuple(SpatialDrive(d.joint, d.law, d.name) for d in mech.drives)
    springs = tuple(Spring(e.name, e.body_a, _xyz(e.point_a), e.body_b, _xyz(e.point_b), e.stiffness,
                           e.free_length, e.damping) for e in mech.forces if isinstance(e, SpringDamper))
    loads = tuple(BodyLoad(e.name, e.body, torque=(0.0, 0.0, e.torque)) for e in mech.forces
                  if isinstance(e, BodyTorque))
    torques = tuple(JointTorque(law.joint, law, law.name) for law in mech.torque_drives)
    return SpatialSystem(mech.name, bodies, tuple(joints), drives, _xyz(mech.gravity), springs, loads, torques)
