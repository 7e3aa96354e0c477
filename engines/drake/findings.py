"""Drake findings and their probes (`mechval.records.findings`).

The probe runs in a child process of its own: what it measures is a crash
(SIGSEGV), which must not take the caller down.
"""

from __future__ import annotations

import importlib.metadata
import signal
import subprocess
import sys

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

FINDINGS = (BALL_ON_WORLD,)

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


PROBES = {BALL_ON_WORLD.key: probe_ball_on_world}
