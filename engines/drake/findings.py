"""Drake findings and their probes (`mechval.records.findings`).

The probe runs in a child process of its own: what it measures is a crash
(SIGSEGV), which must not take the caller down.
"""

from __future__ import annotations

import importlib.metadata
import signal
import subprocess
import sys

import numpy as np

from mechval.records.findings import Finding, Measurement

ENGINE = "drake"

BALL_ON_WORLD = Finding(
    key="drake.ball-constraint-on-world-body",
    engine=ENGINE,
    title="A ball constraint on the world body crashes the discrete SAP plant",
    wrong=("A discrete MultibodyPlant (SAP) with AddBallConstraint between a moving body and the world body "
           "(either side) dies with SIGSEGV at its first step, with no exception or message: a loop closed at a "
           "ground pin takes the whole Python process down. mechval closes every loop at a pin between two "
           "moving bodies (engines/drake/topology.py) and refuses a loop that has none."),
    how=("Two bodies (1 kg, centre of mass 0.5 m out, izz 0.1 kg·m²) on revolute joints to the world, a ball "
         "constraint between the world point (1, 0, 0) and the point (1, 0, 0) of the first body, time step "
         "1e-3 s, SAP; one Simulator.AdvanceTo(0.01) in a child process. The figure is 1 when the child dies of "
         "a signal, 0 when it finishes."),
    figure="1 if the step crashes the process, else 0",
    present_above=0.5,
    since="1.51.1 (earliest measured)",
    workaround="close loops at pins between two moving bodies (mechval does)",
)

FIXED_POINT_BALL = Finding(
    key="drake.ball-constraint-between-fixed-points",
    engine=ENGINE,
    title="A ball constraint whose two points the tree holds still blows the SAP step up",
    wrong=("A ball constraint whose points cannot move (each lies on its body's fixed hinge axis: its Jacobian is "
           "zero, the constraint wholly redundant, as at the cross of Hooke's joint between two shafts on the "
           "ground) makes the discrete SAP plant's velocities grow without bound within a second, though the "
           "constraint holds by itself; with the same constraint left out the motion is right. mechval "
           "switches off, at the start, every ball constraint whose relative Jacobian is zero "
           "(engines/drake/spatial.py); the loop stays closed by the other constraints and the tree."),
    how=("Two bodies (1 kg, centre of mass 0.2 m out along their hinge's normal, inertia 1e-3·diag(1, 1.5, 2) "
         "kg·m²) on revolute joints to the world about x and about (cos 35°, sin 35°, 0), both through the "
         "origin, gravity −9.81 z; a ball constraint between the origin on one and on the other; time step 1e-3 "
         "s, SAP, 0.5 s from rest turned 0.3 rad. The figure is the largest generalized speed (rad/s) with the "
         "constraint over the largest without it: 1 when the constraint is harmless, inf when SAP stops on a "
         "NaN (it does on this plant; in mechval's Hooke scene it ran on to drive torques of 3e10 N·m)."),
    figure="peak speed with the constraint / peak speed without it",
    present_above=10.0,
    since="1.51.1 (earliest measured)",
    workaround="switch off a ball constraint whose relative Jacobian is zero (mechval does, at the start)",
)

FINDINGS = (BALL_ON_WORLD, FIXED_POINT_BALL)

PROBE_SCRIPT = """
import numpy as np
from pydrake.multibody.plant import MultibodyPlant, DiscreteContactApproximation
from pydrake.multibody.tree import RevoluteJoint, SpatialInertia, RotationalInertia
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.analysis import Simulator
builder = DiagramBuilder()
plant = builder.AddSystem(MultibodyPlant(time_step=1e-3))
plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
instance = plant.AddModelInstance("probe")
inertia = SpatialInertia.MakeFromCentralInertia(1.0, [0.5, 0, 0], RotationalInertia(0.05, 0.05, 0.1))
bodies = [plant.AddRigidBody(f"b{k}", instance, inertia) for k in range(2)]
for k, body in enumerate(bodies):
    plant.AddJoint(RevoluteJoint(f"j{k}", plant.world_frame(), body.body_frame(), [0, 0, 1.0], 0.0))
plant.AddBallConstraint(plant.world_body(), np.array([1.0, 0, 0]), bodies[0], np.array([1.0, 0, 0]))
plant.Finalize()
simulator = Simulator(builder.Build())
simulator.Initialize()
simulator.AdvanceTo(0.01)
print("stepped")
"""


def probe_ball_on_world() -> Measurement:
    """Step the probe's plant in a child process: a crash is the finding."""
    child = subprocess.run([sys.executable, "-c", PROBE_SCRIPT], capture_output=True, text=True, timeout=120)
    crashed = child.returncode < 0
    if not crashed and child.returncode != 0:
        raise RuntimeError(f"the probe failed without crashing: {child.stderr.strip().splitlines()[-1:]}")
    figure = 1.0 if crashed else 0.0
    note = signal.Signals(-child.returncode).name if crashed else "finished"
    return Measurement(BALL_ON_WORLD, importlib.metadata.version("drake"), figure=figure, read=figure, exact=0.0,
                       error="" if crashed or "stepped" in child.stdout else note)


def _fixed_point_run(with_ball: bool) -> float:
    """The largest generalized speed over 0.5 s of FIXED_POINT_BALL's plant
    (inf when SAP stops on a NaN it met)."""
    from pydrake.multibody.plant import DiscreteContactApproximation, MultibodyPlant
    from pydrake.multibody.tree import RevoluteJoint, RotationalInertia, SpatialInertia
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultibodyPlant(time_step=1e-3))
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    instance = plant.AddModelInstance("probe")
    angle = np.radians(35.0)
    axes = (np.array([1.0, 0.0, 0.0]), np.array([np.cos(angle), np.sin(angle), 0.0]))
    bodies, joints = [], []
    for k, axis in enumerate(axes):
        arm = 0.2 * np.cross(axis, [0.0, 0.0, 1.0]) if k else np.array([0.0, 0.2, 0.0])
        inertia = SpatialInertia.MakeFromCentralInertia(1.0, arm, RotationalInertia(1e-3, 1.5e-3, 2e-3))
        bodies.append(plant.AddRigidBody(f"b{k}", instance, inertia))
        joints.append(plant.AddJoint(RevoluteJoint(f"j{k}", plant.world_frame(), bodies[k].body_frame(), axis, 0.0)))
    if with_ball:
        plant.AddBallConstraint(bodies[0], np.zeros(3), bodies[1], np.zeros(3))
    plant.Finalize()
    simulator = Simulator(builder.Build())
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    joints[0].set_angle(context, 0.3)
    simulator.Initialize()
    peak = 0.0
    for k in range(1, 51):
        try:
            simulator.AdvanceTo(0.01 * k)
        except RuntimeError:            # SAP's own check: "the Hessian … is NaN"
            return float("inf")
        peak = max(peak, float(np.abs(plant.GetVelocities(context)).max()))
    return peak


def probe_fixed_point_ball() -> Measurement:
    """Run the plant with and without the ball constraint."""
    with_ball, without = _fixed_point_run(True), _fixed_point_run(False)
    figure = with_ball / without
    return Measurement(FIXED_POINT_BALL, importlib.metadata.version("drake"), figure=figure, read=with_ball,
                       exact=without)


PROBES = {BALL_ON_WORLD.key: probe_ball_on_world, FIXED_POINT_BALL.key: probe_fixed_point_ball}
