"""The `Mechanism` of a torque-driven or free scene (docs/scenario-format.md:
`[drive] type = "torque"` or `"free"` for the four kinds, `[[torque]]` and
`[[initial]]` in planar files): the prescribed mechanism's bodies, joints
and force elements, its drive replaced by the scene's torque laws and
initial values, and its `motion` the forward-dynamics reference's
(`mechval.reference.dynamics`), so that everything that reads a mechanism's motion —
an engine's start, the step rule's peak rate Ω (`mechval.model.kinematics.
step_rate`), the assembly branch — reads the integrated motion.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from mechval.reference.dynamics import raw_dynamics
from mechval.model.mechanism import BodyPose, Mechanism
from mechval.reference.planar.solver import default_pose
from mechval.reference.planar.constraints import MechanismError
from mechval.model.scenario import ScenarioError
from mechval.model.scene import Scene


class IntegratedMotion:
    """A torque-driven or free mechanism's `motion`: the raw motion columns
    of the forward-dynamics reference from its initial values at t = 0
    (instants from 0 on; `raw_dynamics` keeps the last few runs). A run the reference
    refuses (too long, a toggle of the stated joints) is bad input of the
    scenario file `source`, whoever asked for the motion."""

    def __init__(self, source=None, mechanism: Mechanism | None = None):
        self.source, self.mechanism = source, mechanism

    def __call__(self, t: np.ndarray) -> pd.DataFrame:
        t = np.asarray(t, dtype=float)
        start = 0 if t.size and t[0] == 0.0 else 1     # the run starts at t = 0 whatever is asked
        try:
            frame = raw_dynamics(self.mechanism, np.concatenate([[0.0], t])[1 - start:]).frame
        except MechanismError as exc:
            raise ScenarioError(self.source, exc.key, exc.reason) from None
        return frame[["t"] + self.mechanism.motion_columns()].iloc[start:].reset_index(drop=True)


def with_dynamics(source, scene: Scene, prescribed: Mechanism) -> Mechanism:
    """`prescribed` (built with the scene's drives; for a closed-form kind
    with its closed form's motion from the crank's initial angle and rate)
    as the scene asks: the torque laws and initial values, the assembly pose
    of `prescribed` at t = 0 (it picks the branch), and the integrated
    motion (refused as bad input of the file `source`)."""
    pose = {name: BodyPose(p.theta, p.x, p.y) for name, p in default_pose(prescribed, 0.0).items()}
    motion = IntegratedMotion(source)
    mechanism = dataclasses.replace(
        prescribed, torque_drives=scene.torques, initial_values=scene.initial, assembly_pose=pose, motion=motion)
    # A free crank has no effort: its T12 is not a signal (a torque law's is the law).
    efforts = set(mechanism.reaction_columns())
    signals = {name: raw for name, raw in mechanism.signal_map.items()
               if not raw.endswith((".T", ".F")) or raw in efforts}
    mechanism = dataclasses.replace(mechanism, signal_map=signals)
    motion.mechanism = mechanism
    return mechanism
