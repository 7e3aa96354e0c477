"""PyBullet findings and their probes (`mechval.records.findings`).

Each probe builds a tiny multibody in its own DIRECT client with the
adapter's solver settings (`model.configure_solver`: exact Dantzig
LCP, joint feedback in world axes), takes a few steps and compares a joint
sensor's read-out after the last step with the exact value for the state
that step started from (the state the engine computed its forces at; the
forces read after a step belong to its start, docs/engines.md), from the
model's Lagrange equations in closed form. Exact for the engine's own
state, the comparison does not depend on integration error: a correct
sensor agrees to round-off (the tests show it on the same models with the
bug's trigger removed, and check the closed-form accelerations against the
engine's own velocity change over the step).

Probed on PyBullet 3.2.7 and not reproduced, so not findings here: the
sensor's torque at 2× the motor torque under TORQUE_CONTROL (bullet3 issue
2966, fixed by pull request 4583) and the passive pendulum's wrong
centripetal force (issue 4451, fixed by pull request 4462); both read the
exact value on 3.2.7.
"""

from __future__ import annotations

import importlib.metadata
import math
from dataclasses import dataclass

import numpy as np
from mechval.records.findings import Finding, Measurement

from mechval.engines.base import native_output_silenced
from mechval.engines.pybullet.model import configure_solver, p   # p: pybullet, imported quietly there

ENGINE = "pybullet"

SLIDE_SENSOR = Finding(
    key="pybullet.slide-sensor-turning-parent",
    engine=ENGINE,
    title="Joint sensor on a link whose parent turns: slide force and couple misread",
    wrong=("The force/torque sensor of a joint whose parent link turns adds a Coriolis-like error in "
           "(parent's ω)·(joint rate) that does not shrink with the step. On a slide (the block on a "
           "slotted lever, the rod in a pivoted sleeve) the normal force and the couple read wrong: "
           "N43/F43/M43 errors of 1.5–11× the default bound on users' slide scenes. mechval derives "
           "these reactions from the sliding body's balance instead (engines/pybullet/slide.py)."),
    how=("A lever turning freely about a fixed pivot (1 kg, izz 0.05 kg·m², centre of mass at the pivot) "
         "carries a 0.5 kg block (izz 1e-4 kg·m²) on a free slide, no gravity, from ω = 2 rad/s, "
         "s = 0.2 m, ṡ = 0.5 m/s; 10 steps of 1e-4 s. Exact normal force on the block "
         "N = m·(2·ṡ·ω + s·α), α = −2·m·s·ṡ·ω / (izz_lever + izz_block + m·s²)."),
    figure="|N read − N exact| / |N exact|",
    present_above=1e-3,
    since="3.2.7 (earliest measured)",
    workaround="derive the slide's reaction from the body balance (mechval does)",
)

NON_LEAF_SENSOR = Finding(
    key="pybullet.non-leaf-sensor",
    engine=ENGINE,
    title="Joint sensor of a joint whose child carries further moving links",
    wrong=("The force/torque sensor of a joint whose child link carries further moving links misreads "
           "the joint force, even when the joint's parent is at rest; the error grows with the joint "
           "speeds (40–80 % on F12/F32 of a four-bar built as one tree). mechval builds every joint "
           "whose reaction it reads as a leaf (layout \"split\") and derives the reaction of a joint that "
           "must carry another link (a drive beside a drive, a slide on a slide) from its child's balance."),
    how=("A free two-link chain on a fixed pivot (2 kg and 1 kg, centres of mass 0.15 m and 0.2 m "
         "from their joints, second joint 0.3 m out, izz 0.02 and 0.01 kg·m²), no gravity, from "
         "joint angles 0.3 and 0.7 rad turning at 5 and 5 rad/s; 10 steps of 1e-4 s. Exact force on "
         "the first link at the pivot m1·a_G1 + m2·a_G2, accelerations from the chain's Lagrange "
         "equations."),
    figure="|F read − F exact| / |F exact|",
    present_above=1e-3,
    since="3.2.7 (earliest measured)",
    workaround="make every joint whose reaction is read a leaf; derive the others (mechval does)",
)

FINDINGS = (SLIDE_SENSOR, NON_LEAF_SENSOR)


@dataclass(frozen=True)
class ProbeReading:
    """A probe's read-out and exact value, and the closed-form
    accelerations beside the engine's own (its velocity change over the
    step / dt), which show that the exact value is right."""

    read: np.ndarray
    exact: np.ndarray
    alpha_closed_form: np.ndarray
    alpha_engine: np.ndarray

    @property
    def relative_error(self) -> float:
        return float(np.linalg.norm(self.read - self.exact) / np.linalg.norm(self.exact))


def _chain(client: int, masses, izz, offsets, coms, types, axes) -> int:
    """A fixed-base serial chain in the x–y plane with no effect added
    (no damping, no velocity motors, no speed clamp) and sensors on."""
    n = len(masses)
    uid = p.createMultiBody(
        baseMass=0.0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
        linkMasses=list(masses), linkCollisionShapeIndices=[-1] * n, linkVisualShapeIndices=[-1] * n,
        linkPositions=[(x, 0.0, 0.0) for x in offsets], linkOrientations=[(0.0, 0.0, 0.0, 1.0)] * n,
        linkInertialFramePositions=[(x, 0.0, 0.0) for x in coms],
        linkInertialFrameOrientations=[(0.0, 0.0, 0.0, 1.0)] * n, linkParentIndices=list(range(n)),
        linkJointTypes=list(types), linkJointAxis=list(axes), physicsClientId=client)
    p.changeDynamics(uid, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=client)
    p.changeDynamics(uid, -1, maxJointVelocity=1e9, physicsClientId=client)
    for k in range(n):
        p.changeDynamics(uid, k, localInertiaDiagonal=[izz[k]] * 3, jointDamping=0.0, physicsClientId=client)
        p.setJointMotorControl2(uid, k, p.VELOCITY_CONTROL, force=0.0, physicsClientId=client)
        p.enableJointForceTorqueSensor(uid, k, True, physicsClientId=client)
    return uid


def _step_and_read(client: int, uid: int, n_joints: int, steps: int):
    """Joint (position, velocity) pairs before the last step, after it, and
    the sensors' readings after it (parent on child, world axes)."""
    for _ in range(steps):
        before = [p.getJointState(uid, k, physicsClientId=client)[:2] for k in range(n_joints)]
        p.stepSimulation(physicsClientId=client)
    states = [p.getJointState(uid, k, physicsClientId=client) for k in range(n_joints)]
    return before, [s[:2] for s in states], [s[2] for s in states]


def _client(dt: float, gravity_y: float) -> int:
    client = p.connect(p.DIRECT)
    with native_output_silenced():      # "switched solver" notices from C
        configure_solver(client, dt, (0.0, gravity_y))
    return client


def rotating_slide(omega: float = 2.0, slide_rate: float = 0.5, gravity: float = 0.0, steps: int = 10,
                   dt: float = 1e-4) -> ProbeReading:
    """The slide probe (SLIDE_SENSOR.how); `gravity` (m/s², along −y) for
    the tests' control case. Read and exact: (N, M) on the block; alphas:
    the lever's."""
    m_lever, izz_lever, m, izz, s0 = 1.0, 0.05, 0.5, 1e-4, 0.2
    client = _client(dt, -gravity)
    try:
        uid = _chain(client, (m_lever, m), (izz_lever, izz), (0.0, 0.0), (0.0, 0.0),
                     (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC), ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0)))
        p.resetJointState(uid, 0, 0.0, omega, physicsClientId=client)
        p.resetJointState(uid, 1, s0, slide_rate, physicsClientId=client)
        before, after, sensors = _step_and_read(client, uid, 2, steps)
    finally:
        p.disconnect(client)
    (theta, w), (s, v) = before
    # Lagrange: T = ½·J·θ̇² + ½·m·ṡ², J = izz_lever + izz + m·s²; V = m·g·s·sinθ.
    inertia = izz_lever + izz + m * s * s
    alpha = -(2 * m * s * v * w + m * gravity * s * math.cos(theta)) / inertia
    normal = m * (2 * v * w + s * alpha + gravity * math.cos(theta))
    force = sensors[1]
    n_read = -math.sin(theta) * force[0] + math.cos(theta) * force[1]
    return ProbeReading(np.array([n_read, force[5]]), np.array([normal, izz * alpha]),
                        np.array([alpha]), np.array([(after[0][1] - w) / dt]))


def two_link_chain(omega1: float = 5.0, omega2: float = 5.0, gravity: float = 0.0, steps: int = 10,
                   dt: float = 1e-4) -> ProbeReading:
    """The non-leaf probe (NON_LEAF_SENSOR.how); `gravity` (m/s², along
    −y) for the tests' control case. Read and exact: the force (x, y) on
    the first link at the pivot; alphas: the two joints'."""
    m1, m2, c1, c2, l1, i1, i2 = 2.0, 1.0, 0.15, 0.2, 0.3, 0.02, 0.01
    client = _client(dt, -gravity)
    try:
        uid = _chain(client, (m1, m2), (i1, i2), (0.0, l1), (c1, c2), (p.JOINT_REVOLUTE,) * 2,
                     ((0.0, 0.0, 1.0),) * 2)
        p.resetJointState(uid, 0, 0.3, omega1, physicsClientId=client)
        p.resetJointState(uid, 1, 0.7, omega2, physicsClientId=client)
        before, after, sensors = _step_and_read(client, uid, 2, steps)
    finally:
        p.disconnect(client)
    (q1, u1), (q2, u2) = before
    # Absolute angles a1 = q1, a2 = q1 + q2: M(a)·ä = h(a, ȧ) − ∂V/∂a with
    # V = g·((m1·c1 + m2·l1)·sin a1 + m2·c2·sin a2).
    a1, a2, w1, w2 = q1, q1 + q2, u1, u1 + u2
    coupling = m2 * l1 * c2
    mass = np.array([[i1 + m1 * c1 * c1 + m2 * l1 * l1, coupling * math.cos(a2 - a1)],
                     [coupling * math.cos(a2 - a1), i2 + m2 * c2 * c2]])
    rhs = (coupling * math.sin(a2 - a1) * np.array([w2 * w2, -w1 * w1])
           - gravity * np.array([(m1 * c1 + m2 * l1) * math.cos(a1), m2 * c2 * math.cos(a2)]))
    al1, al2 = np.linalg.solve(mass, rhs)
    radial = lambda a: np.array([math.cos(a), math.sin(a)])       # noqa: E731
    normal = lambda a: np.array([-math.sin(a), math.cos(a)])      # noqa: E731
    a_link1 = al1 * normal(a1) - w1 * w1 * radial(a1)             # per unit length along link 1
    a_g2 = l1 * a_link1 + c2 * (al2 * normal(a2) - w2 * w2 * radial(a2))
    exact = m1 * c1 * a_link1 + m2 * a_g2 + np.array([0.0, (m1 + m2) * gravity])
    engine = np.array([(after[0][1] - u1) / dt, (after[1][1] - u2) / dt])
    return ProbeReading(np.array(sensors[0][:2]), exact, np.array([al1, al2 - al1]), engine)


def _version() -> str:
    return importlib.metadata.version("pybullet")


def probe_slide_sensor() -> Measurement:
    """SLIDE_SENSOR on the installed version: the normal force's error."""
    reading = rotating_slide()
    read, exact = float(reading.read[0]), float(reading.exact[0])
    return Measurement(SLIDE_SENSOR, _version(), abs(read - exact) / abs(exact), read, exact)


def probe_non_leaf_sensor() -> Measurement:
    """NON_LEAF_SENSOR on the installed version: the pivot force's error
    (read and exact as magnitudes)."""
    reading = two_link_chain()
    return Measurement(NON_LEAF_SENSOR, _version(), reading.relative_error,
                       float(np.linalg.norm(reading.read)), float(np.linalg.norm(reading.exact)))


PROBES = {SLIDE_SENSOR.key: probe_slide_sensor, NON_LEAF_SENSOR.key: probe_non_leaf_sensor}


EXPLICIT_GYROSCOPIC = Finding(
    key="pybullet.explicit-gyroscopic",
    engine=ENGINE,
    title="Free body: the gyroscopic term is integrated explicitly, energy and |L| grow O(dt)",
    wrong=("A torque-free body spinning about a non-principal axis gains kinetic energy and angular "
           "momentum at a rate proportional to the step: PyBullet's multibody step takes ω × Jω at the "
           "step's start (explicit), so the attitude of a free body is first order in dt. The tumbling "
           "T-handle through its intermediate-axis flip misses the quaternion bound (1e-3) by 3.5× at "
           "mechval's step rule, 1.8× at half its step; its ω and α stay within their bounds."),
    how=("A free body (1 kg, principal moments 0.01, 0.02, 0.03 kg·m², no damping, no gravity) from "
         "ω = (0, 4, 0.2) rad/s in its principal axes; 2 s at a 1e-3 s step. Exact: kinetic energy "
         "conserved."),
    figure="relative kinetic-energy gain after 2 s",
    present_above=1e-4,
    since="3.2.7 (earliest measured)",
    workaround="a finer step (the error halves with it); mechval reports the miss (tests/test_spatial_pybullet.py)",
)

FINDINGS = FINDINGS + (EXPLICIT_GYROSCOPIC,)


def tumbling_energy_gain(dt: float = 1e-3, duration: float = 2.0) -> float:
    """EXPLICIT_GYROSCOPIC's probe: the free body's relative energy gain."""
    inertia, omega = np.array([0.01, 0.02, 0.03]), np.array([0.0, 4.0, 0.2])
    client = p.connect(p.DIRECT)
    try:
        p.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0, physicsClientId=client)
        uid = p.createMultiBody(baseMass=1.0, physicsClientId=client)
        p.changeDynamics(uid, -1, localInertiaDiagonal=tuple(inertia), linearDamping=0.0, angularDamping=0.0,
                         physicsClientId=client)
        p.resetBaseVelocity(uid, (0.0, 0.0, 0.0), tuple(omega), physicsClientId=client)
        for _ in range(int(round(duration / dt))):
            p.stepSimulation(physicsClientId=client)
        q = p.getBasePositionAndOrientation(uid, physicsClientId=client)[1]
        w = np.array(p.getBaseVelocity(uid, physicsClientId=client)[1])
    finally:
        p.disconnect(client)
    body = np.array(p.getMatrixFromQuaternion(q)).reshape(3, 3).T @ w
    return float(inertia @ body ** 2 / (inertia @ omega ** 2) - 1.0)


def probe_explicit_gyroscopic() -> Measurement:
    """EXPLICIT_GYROSCOPIC on the installed version: the energy gain (exact 0)."""
    gain = tumbling_energy_gain()
    return Measurement(EXPLICIT_GYROSCOPIC, _version(), abs(gain), gain, 0.0)


PROBES = {**PROBES, EXPLICIT_GYROSCOPIC.key: probe_explicit_gyroscopic}
