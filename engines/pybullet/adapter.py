"""PyBullet 3.2.7 adapter: build (`model`), drive, step, read.

Conversion of PyBullet's native output to the Fij convention (docs/conventions.md):
- A joint modelled as a multibody joint: its force/torque sensor, with
  `jointFeedbackMode = WORLD_SPACE | JOINT_FRAME`, gives the force by the
  parent link on the child link in world axes (`getJointState(...)[2][:2]`).
  Fij is that force when the child is the joint's body_j, its negative when
  the child is body_i.
- A joint modelled as a user constraint: `getConstraintState(cid)[:2]` is the
  force on the constraint's child (world axes); same rule.
- A prismatic joint's couple M on body_j: the sensor's z moment, taken
  about the child link's frame origin, which is the joint's point_j (the
  link frame sits at the joint point; checked against the reference),
  plus, for a slide drive, the moment its force F (which PyBullet applies
  through the link's centre of mass) has there in the reference, where F
  acts at point_j: (G − P)×u·F (`model.drive_force_arm`).
- A multibody joint that is not a leaf hung from the ground (a slide
  between two moving bodies: the slotted lever's slot, the inverted
  slider's sleeve; a drive hung below a moving link; a joint carrying
  another link; `layout`): F (and a slide's M) are NOT read but
  derived from the balance of the joint's child body with PyBullet's own
  motion and its other joint forces (`slide`), because the
  sensor misreports a joint whose parent turns (a Coriolis-like term in
  ω·ṡ that does not shrink with dt) or whose child carries further links
  (the engine finding probes, `findings`, measure both). The run
  info says so (`derived_reactions`).
- Drive torque: `getJointState(drive)[3]`, the motor torque on the child
  link (the crank), i.e. T on body_j (negated if the child is body_i).
  Dampers are applied as external loads, so they are not part of it.
- Time stamp: every force and torque read after stepping from t_n to
  t_n+1 is the one that acted during that step, i.e. at t_n (stamping it at
  t_n+1 would turn an O(dt²) error into O(dt); docs/engines.md).
- Semi-implicit Euler velocities stand for the step's middle, so the
  angular velocity at t_n is the mean of the readings before and after the
  step from t_n, and the angular acceleration their difference over dt
  (what the engine applied in that step); linear ones are central
  differences of the positions one step either side (`Stepper.assemble`
  says why).

Known limit of the sensor (measured, not corrected here): at a joint to
the ground its centripetal term uses the mid-step speed ω(t − dt/2), so F14
converges only as O(dt) (hence the finer RAD_PER_STEP).

Only in-plane force components and the z torque are reported: the
out-of-plane reactions of a planar loop built from 3D joints are
statically indeterminate, so engines may legitimately return anything there.
"""

from __future__ import annotations

from typing import Any, ClassVar, Mapping

import numpy as np
import pandas as pd

from mechval.adapter import FEATURES, SPATIAL, as_float, steps_per_interval
from mechval.model.mechanism import Mechanism
from mechval.settings import TIMESTEP, Choice, Number, Setting

from mechval.engines.base import EngineAdapter, PeakRates, RawRun, default_step, peak_rates
from mechval.engines.pybullet.audit import audit_model
from mechval.engines.pybullet.run import run_model
from mechval.engines.pybullet.spatial import run_spatial
from mechval.engines.pybullet.spatial_audit import audit_spatial
from mechval.engines.pybullet.spatial_build import TREE_KINDS

#: Step rule factor (rad per step at the run's peak rate Ω, see
#: base.default_step). PyBullet's rocker sensor converges only as O(dt)
#: (docs/engines.md), so it gets a finer step than the shared 0.01 rad.
RAD_PER_STEP = 0.002
#: Steps along φ(t) before t = 0, from the reference state: the loop
#: closure and the mid-step velocities settle before the first sample.
PREROLL_STEPS = 10
#: The step rule factor of a torque-driven or free run (its step from the
#: forward-dynamics reference's peak rates, `planned_motion`), measured:
#: docs/engines.md.
FREE_RAD_PER_STEP = 0.002

class PybulletAdapter(EngineAdapter):
    name = "pybullet"
    library = "pybullet"
    distribution = "pybullet"
    settings_spec: ClassVar[Mapping[str, Setting]] = {
        "timestep": TIMESTEP, "preroll_steps": Number(0, 100_000, whole=True), "layout": Choice(("split", "tree"))}
    #: `mechval cost` has one line here: the solver is not a setting (Dantzig
    #: LCP, exact; the iterative ones stop early, docs/engines.md).
    cost_variants = {"Dantzig": {}}
    #: Every drive is a position-controlled leaf joint; spring-dampers and
    #: body torques are external loads set every step (Stepper).
    features = frozenset(FEATURES) | {SPATIAL}
    #: Spatial scenes (`spatial`): PyBullet's own joints, composite kinds as
    #: chains through massless links, loops closed at spherical or revolute joints.
    spatial_joints = TREE_KINDS

    step_settings = ("timestep", "preroll_steps")
    output_copies, bytes_per_step = 32, 32

    def planned_steps(self, times: np.ndarray, settings: Mapping[str, Any]) -> tuple[float, float]:
        return steps_per_interval(times, as_float(settings["timestep"])), as_float(settings["preroll_steps"])

    uses_peak_rates = True

    def default_settings(self, mechanism: Mechanism, times: np.ndarray,
                         rates: PeakRates | None = None) -> dict[str, Any]:
        """The step rule at RAD_PER_STEP (FREE_RAD_PER_STEP for a
        torque-driven or free run, which starts at its first instant with
        no pre-roll); Ω is the prepared scene's (`rates`), else computed
        here."""
        rate = (peak_rates(mechanism, times) if rates is None else rates).rate
        if mechanism.forward_dynamics:
            return {"timestep": default_step(mechanism, times, rad_per_step=FREE_RAD_PER_STEP, rate=rate),
                    "preroll_steps": 0, "layout": "split"}
        return {
            "timestep": default_step(mechanism, times, rad_per_step=RAD_PER_STEP, rate=rate),
            "preroll_steps": PREROLL_STEPS,
            "layout": "split",
        }

    def audit(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
        if mechanism.spatial is not None:
            return audit_spatial(mechanism.spatial, times, settings)
        return audit_model(mechanism, times, settings)

    def run(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
        if mechanism.spatial is not None:
            return run_spatial(mechanism.spatial, times, settings)
        return run_model(mechanism, times, settings)


