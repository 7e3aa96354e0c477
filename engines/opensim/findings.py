"""OpenSim findings and their probes (`mechval.records.findings`).

The probe builds the four-bar of issue 25 twice with the adapter's model
code (`model.build_model`): its loop closed the adapter's way, by a Simbody
`PointConstraint` at O4, and OpenSim's way, by a fourth `PinJoint` that
OpenSim's automatic loop breaking turns into a split body. Both start from
the closed-form state and integrate one second at accuracy 1e-9; the exact
crank torque and pivot force at t = 1 s come from mechval's closed form
(Norton's kinematics, Newton–Euler). The motion agrees to 4e-12 rad either
way, so the force error is not integration error.
"""

from __future__ import annotations

import importlib.metadata

import numpy as np

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND, Body, Drive, Joint, Mechanism
from mechval.records.findings import Finding, Measurement
from mechval.reference.adapter import raw_reference
from mechval.reference.closed_forms.fourbar import FourBarGeometry, body_motion

from mechval.engines.opensim.run import integrate, prepare

ENGINE = "opensim"

LOOP_PIN = Finding(
    key="opensim.loop-pin-reactions",
    engine=ENGINE,
    title="A loop closed by a further PinJoint (automatic loop breaking): wrong drive torque and pin forces",
    wrong=("Closing a kinematic loop with one more PinJoint, which OpenSim turns into a split body and a "
           "weld, gives the right motion but wrong reactions: on the four-bar of issue 25 the crank torque "
           "is 0.053 N·m off and the pivot forces 0.21 N, with or without gravity. mechval closes every loop "
           "with a PointConstraint at a pin instead, which reads the reference to 1e-9 of the peaks."),
    how=("Four-bar ground 0.6 m, crank 0.25, coupler 0.5, rocker 0.5 (uniform rods 12.5/25/25 kg), "
         "φ(t) = 0.5 + t + t²/2, elbow-up, gravity off; loop closed at O4 by a fourth PinJoint; "
         "RungeKuttaMerson at accuracy 1e-9 from the closed-form state at t = 0 to t = 1 s. Exact "
         "crank torque from mechval's closed form (2.654861 N·m)."),
    figure="|T read − T exact| (N·m)",
    present_above=1e-6,
    since="4.6 (earliest measured)",
    workaround="close loops with a PointConstraint (mechval does)",
)

FINDINGS = (LOOP_PIN,)

#: The four-bar of issue 25 (m, kg) and its drive law.
LENGTHS = {"crank": 0.25, "coupler": 0.5, "rocker": 0.5}
MASSES = {"crank": 12.5, "coupler": 25.0, "rocker": 25.0}
GROUND_LENGTH = 0.6
LAW = DriveLaw(phi0=0.5, omega0=1.0, alpha=1.0)
SETTINGS = {"integrator": "RungeKuttaMerson", "accuracy": 1e-9, "constraint_tolerance": 1e-10, "max_step": 1.0}


def issue_fourbar(gravity: float = 0.0) -> Mechanism:
    """The four-bar with its closed-form motion (frames at each link's
    first pin, x along the link; joints in the Fij order)."""
    geometry = FourBarGeometry(GROUND_LENGTH, LENGTHS["crank"], LENGTHS["coupler"], LENGTHS["rocker"])
    bodies = tuple(Body(link, MASSES[link], (LENGTHS[link] / 2, 0.0), MASSES[link] * LENGTHS[link] ** 2 / 12)
                   for link in LENGTHS)
    joints = (Joint("O2", "revolute", GROUND, "crank", (0.0, 0.0), (0.0, 0.0)),
              Joint("A", "revolute", "coupler", "crank", (0.0, 0.0), (LENGTHS["crank"], 0.0)),
              Joint("B", "revolute", "rocker", "coupler", (LENGTHS["rocker"], 0.0), (LENGTHS["coupler"], 0.0)),
              Joint("O4", "revolute", GROUND, "rocker", (GROUND_LENGTH, 0.0), (0.0, 0.0)))
    return Mechanism("issue-25-fourbar", "fourbar", bodies, joints, Drive("O2", LAW), (0.0, -gravity),
                     motion=lambda t: body_motion(geometry, LAW, t), signal_map={})


def loop_reactions(closure: str, gravity: float = 0.0, end: float = 1.0) -> tuple[dict, dict]:
    """(OpenSim's, the closed form's) raw columns at t = end, the loop
    closed at O4 by `closure` ("point" or "pin")."""
    mechanism = issue_fourbar(gravity)
    t = np.array([0.0, end])
    read = integrate(prepare(mechanism, t, SETTINGS, closure), mechanism, t)
    exact = raw_reference(mechanism, t)
    return ({name: float(values[-1]) for name, values in read.items()},
            {name: float(exact[name].iloc[-1]) for name in exact.columns})


def probe_loop_pin() -> Measurement:
    """LOOP_PIN on the installed version: the crank torque's error."""
    read, exact = loop_reactions("pin")
    return Measurement(LOOP_PIN, importlib.metadata.version("opensim"), abs(read["drive.T"] - exact["drive.T"]),
                       read["drive.T"], exact["drive.T"])


PROBES = {LOOP_PIN.key: probe_loop_pin}
