"""Pinocchio adapter: the planar mechanism as a spanning tree in minimal
coordinates, its loops closed by `RigidConstraintModel` point constraints,
its motion from Pinocchio's `constraintDynamics` integrated by a
fixed-step RK4 (Pinocchio has no integrator); the model in `model`, the
dynamics and the drives' computed efforts in `dynamics`, the applied
effects in `forces`, the read-out in `readout`.

Conversion of Pinocchio's native outputs to the mechval convention:
- Body motion: a `Frame` per body at its frame origin; position, the
  origin's velocity and classical acceleration in world axes
  (`LOCAL_WORLD_ALIGNED`); θ the sum of the tree's revolute coordinates
  (and held slide angles) from the ground, continuous and equal to the
  reference's angle at the start (q is taken from it).
- Loop-closing pin: its constraint's force λ (`lambda_c`, first constraint
  frame's axes) acts as +λ on the constraint's first body (the sign that
  makes `rnea`'s passive-joint torques vanish, `readout.LAMBDA_ON_FIRST`);
  Fij is that force when the first body is body_j, else its opposite.
- Tree joint: `rnea` with the loops' forces and the applied effects as
  external forces gives the wrench by the parent on the child at the
  joint point (`data.f`, child joint frame); its part along the joint's
  motion subspace is removed (drive effort, torque law, damper), the rest
  turned to world axes is Fij (and M of a slide) when the child is body_j;
  when the child is body_i, Fij is its opposite and M is moved to body_j's
  point.
- Drive: the effort on its tree coordinate that gives ±φ''(t), times the
  joint's orientation in the tree (T or F on body_j).
- Torque law: its value, applied as a generalised force at a tree joint (or
  a pair of body torques at a loop-closing pin); spring-dampers and body
  torques: body wrenches (world, τ = Jᵀw); dampers: on the tree coordinate,
  or a pair of body torques at a loop-closing pin.
- Time stamp: the state at a sample is RK4's after a whole number of steps;
  accelerations and forces are solved at that very state and instant.
Only in-plane force components and the z couple are reported: the model is
planar (a point constraint's z row is redundant and its λ_z is whatever
the proximal solver leaves, ~0).

A spatial scene (`Mechanism.spatial`) runs in `spatial_run` (model,
dynamics with its Lie-group RKMK4, read-out in the other spatial_*
modules; docs/engines.md, "Spatial scenes").
"""

from __future__ import annotations

from typing import Any, ClassVar, Mapping

import numpy as np
import pandas as pd

from mechval.adapter import FEATURES, SPATIAL, PeakRates
from mechval.model.mechanism import Mechanism
from mechval.reference.spatial.system import JOINT_KINDS
from mechval.settings import TIMESTEP, Number, Setting

from mechval.engines.base import EngineAdapter, RawRun, default_step, peak_rates

#: Rotation per RK4 step at the run's peak rate Ω (`default_step`),
#: measured on every built-in (docs/engines.md, "Pinocchio").
RAD_PER_STEP = 0.02
#: No cap on the step beyond the sample interval: RK4's error follows the
#: rotation per step, not the step's length (the shared cap of 1e-3 s
#: only made slow scenes cost more).
MAX_STEP = float("inf")
#: Pinocchio's proximal solver of the KKT system: stop when the constraint
#: residual is this small (its default 1e-12 relative and absolute), with
#: this regularisation μ and at most this many iterations (docs/engines.md).
PROXIMAL_ACCURACY = 1e-12
PROXIMAL_MU = 1e-8
PROXIMAL_MAX_ITERATIONS = 50
#: Baumgarte's stabilisation, time constant in RK4 steps: RK4 alone lets
#: the loops drift apart, quadratically in time (docs/engines.md).
BAUMGARTE_STEPS = 300.0


class PinocchioAdapter(EngineAdapter):
    """Pinocchio 4.1.0; see the module docstring for the conversions."""

    name = "pinocchio"
    library = "pinocchio"
    distribution = "pin"
    settings_spec: ClassVar[Mapping[str, Setting]] = {
        "timestep": TIMESTEP,
        "proximal_accuracy": Number(0.0, 1.0, low_open=True),
        "proximal_mu": Number(0.0, 1.0, low_open=True),
        "proximal_max_iterations": Number(1, 10_000, whole=True),
        # Baumgarte's stabilisation of the loops' constraints: its time
        # constant in RK4 steps (0: off).
        "baumgarte_steps": Number(0.0, 1e9),
    }
    #: Drives are tree coordinates with computed efforts; dampers, torque
    #: laws, springs and body torques applied forces; free motion the same
    #: integration with no drive; redundant constraints too (the proximal
    #: solver picks one of the many λ; the harness compares each body's
    #: resultant of them, which is unique).
    features = frozenset(FEATURES) | {SPATIAL}
    #: Spatial scenes (`spatial_run`): every joint kind, in the tree or
    #: closing a loop (docs/engines.md, "Pinocchio", "Spatial scenes").
    spatial_joints = frozenset(JOINT_KINDS)
    step_settings = ("timestep",)
    #: Nothing kept per step (RK4 keeps one state); per sample a row of
    #: raw columns: measured 31 copies of the samples × signals table at
    #: 20001 samples of fourbar-seed (peak RSS, the harness's share
    #: included), the same with 10× the steps.
    output_copies, bytes_per_step = 32, 0
    uses_peak_rates = True

    def default_settings(self, mechanism: Mechanism, times: np.ndarray,
                         rates: PeakRates | None = None) -> dict[str, Any]:
        """The RK4 step from the scene's peak rate (`default_step` at
        RAD_PER_STEP; a spatial scene's Ω at least its dampers' rate for
        RK4, `spatial_run.force_rate`); the proximal solver at PROXIMAL_*."""
        if len(times) < 2:
            step = 1e-3
        elif mechanism.spatial is not None:
            from mechval.engines.pinocchio.spatial_run import force_rate
            rate = max((peak_rates(mechanism, times) if rates is None else rates).rate, force_rate(mechanism.spatial))
            step = default_step(mechanism, times, rad_per_step=RAD_PER_STEP, max_step=MAX_STEP, rate=rate)
        else:
            rates = peak_rates(mechanism, times) if rates is None else rates
            step = default_step(mechanism, times, rad_per_step=RAD_PER_STEP, max_step=MAX_STEP, rate=rates.rate)
        return {"timestep": step, "proximal_accuracy": PROXIMAL_ACCURACY, "proximal_mu": PROXIMAL_MU,
                "proximal_max_iterations": PROXIMAL_MAX_ITERATIONS, "baumgarte_steps": BAUMGARTE_STEPS}

    def run(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
        if mechanism.spatial is not None:
            from mechval.engines.pinocchio.spatial_run import run_spatial
            return run_spatial(mechanism.spatial, np.asarray(times, dtype=float), settings)
        from mechval.engines.pinocchio.run import simulate_run
        return simulate_run(mechanism, np.asarray(times, dtype=float), settings)

    def audit(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
        if mechanism.spatial is not None:
            from mechval.engines.pinocchio.spatial_audit import audit_spatial
            return audit_spatial(mechanism.spatial, times, settings)
        from mechval.engines.pinocchio.audit import audit_model
        return audit_model(mechanism, times, settings)
