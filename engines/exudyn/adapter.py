"""Exudyn adapter: a planar multibody model solved by Exudyn's implicit
second-order solvers (model building in `model`). A spatial scene
(`Mechanism.spatial`) goes to `spatial` (settings, run, read-out) and
`spatial_model` (docs/engines.md, Exudyn, "Spatial scenes"); the rest of
this docstring is about planar ones.

Conversion of Exudyn's native outputs to the mechval convention:
- Body motion: `NodeRigidBody2D` coordinates are displacements of (x_G,
  y_G, θ) at the centre of mass from the reference coordinates; adding the
  reference gives the absolute, unwrapped state (θ anchored to the
  reference's angle at the start, since the reference pose *is* the node's
  reference). The body frame origin follows from the rigid-body relations
  (`point_motion` at −com).
- Revolute joint: `ObjectJointRevolute2D` `Force` is the force on its
  marker-0 body from its marker-1 body, world axes. Markers are ordered
  [body_j, body_i], so `Force` is Fij as is.
- Prismatic joint: marker 0 must be the axis holder body_i.
  `ObjectJointPrismatic2D` has no `Force` output; its `ForceLocal` (x, y)
  is the force on body_i from body_j in body_i's frame (measured with a
  turned guide), so Fij = −R(θi)·ForceLocal. Its third component stays 0
  even under a couple: M is derived from the moment balance of one of the
  joint's bodies with Exudyn's own motion and reactions (`slide`).
- Drives: each a coordinate constraint q1 − q0 = offset(t), on the
  rotation coordinates (revolute) or on a ground coordinate and the slide
  (prismatic); its multiplier λ (`Force` output) gives the effort on
  body_j, T = −λ or F = −λ along the axis (docs/engines.md; the sign tests
  against the reference confirm both).
- Spring-dampers and body torques are engine elements
  (`ObjectConnectorSpringDamper`, `LoadTorqueVector`); they have no
  column of their own. A torque law is a pair of `LoadTorqueVector`s
  (T on body_j, −T on body_i) whose user function evaluates the law; its
  column "NAME.T" is the applied torque read back by a load sensor.
- A torque-driven or free mechanism runs from its first instant, in the
  forward-dynamics reference's initial state; its degrees of freedom that
  no drive prescribes carry no constraint.
- Time stamp: the implicit solvers satisfy the equations of motion and the
  constraints at the end of every step, so the sensor value recorded after
  the step to t_n+1 belongs to t_n+1 (no half-step shift as in explicit
  engines; a one-step shift would turn the O(dt²) error into O(dt)).
  Sensors record every step (write period 0), in memory only.
Only in-plane force components and the z couple/torque are reported: the
model is planar, and out-of-plane reactions of a planar loop are statically
indeterminate anyway, so no engine's value there could be compared.
"""

from __future__ import annotations

import time
from typing import Any, ClassVar, Mapping

import numpy as np
import pandas as pd

from mechval.adapter import FEATURES, SPATIAL, PeakRates, as_float, steps_per_interval
from mechval.model.kinematics import dense_grid
from mechval.model.mechanism import Mechanism
from mechval.settings import TIMESTEP, Choice, Flag, Number, Setting

from mechval.engines.base import EngineAdapter, RawRun, RunInfo, default_step, peak_rates
from mechval.reference.spatial.system import JOINT_KINDS
from mechval.engines.exudyn.audit import audit_model
from mechval.engines.exudyn.model import solve
from mechval.engines.exudyn.run import force_scale, frame_of, index3_transient_steps, node_states, prepare, sample_rows
from mechval.engines.exudyn.slide import derived_note

#: Newton's absolute tolerance per newton of force scale. Newton stops at the
#: relative goal (1e-12 of the step's first residual) or at this floor,
#: whichever comes first; when round-off puts the relative goal out of reach,
#: only the floor ends the iteration, and since the residual is a force a
#: fixed floor such as 1e-14 N is never reached (the solver aborts).
NEWTON_TOLERANCE_PER_NEWTON = 1e-13
#: Rotation per step for the step rule (`default_step`): finer than the
#: shared 0.01 rad, so that index-2 meets SEED_DEFAULT_ERROR of
#: tests/test_exudyn.py on fourbar-seed (figures: docs/engines.md); cost
#: grows as 1/rad_per_step.
RAD_PER_STEP = 0.007
#: Instants of the force estimate over the run; a torque-driven or free
#: mechanism's uses the step rule's grid and motion (`PeakRates`), so that
#: its motion is integrated once.
FORCE_SCALE_GRID = 2001


def own_start(mechanism: Mechanism) -> bool:
    """Whether Exudyn's own initial-acceleration solve gives the first
    instant: for a torque-driven or free mechanism (which starts there, with
    no pre-roll, so that its reactions there come only from this solve)
    whose remaining drives do not accelerate (the solve ignores a drive's
    φ''; docs/engines.md)."""
    return mechanism.forward_dynamics and all(d.law.alpha == 0.0 for d in mechanism.drives)


class ExudynAdapter(EngineAdapter):
    """Exudyn 1.13.6; see the module docstring for the reaction conversion."""

    name = "exudyn"
    library = "exudyn"
    distribution = "exudyn"
    settings_spec: ClassVar[Mapping[str, Setting]] = {
        "solver": Choice(("index2", "index3")),
        "timestep": TIMESTEP,
        # At least one for prescribed motion (t = 0 must be a solved step),
        # 0 for a torque-driven or free mechanism, which starts at its
        # first instant (`check_settings`, `prepare`).
        "pre_roll_steps": Number(0, 100_000, whole=True),
        # Index-3 needs ρ < 1 (`index3_transient_steps`).
        "spectral_radius": Number(0.0, 1.0, high_open=True),
        "compute_initial_accelerations": Flag(),
        "full_newton": Flag(),
        "newton_relative_tolerance": Number(0.0, 1.0, low_open=True),
        "newton_absolute_tolerance": Number(0.0, low_open=True),
        "adaptive_step": Flag(),
    }
    #: Also report the index-3 solver. (High accuracy is a smaller step, e.g.
    #: timestep 1e-4 on fourbar-seed, held by tests/test_exudyn.py's
    #: HIGH_ACCURACY_ERROR; a fixed step is no variant for every scene.)
    variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {"default": {}, "index3": {"solver": "index3"}}
    #: Both solvers for `mechval cost` (the ladder sets `timestep`).
    cost_variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {"index2": {}, "index3": {"solver": "index3"}}

    step_settings = ("timestep", "pre_roll_steps", "spectral_radius")
    #: Every drive a coordinate constraint, springs and torques engine
    #: elements (`model`). Not redundant constraints: measured on
    #: Exudyn 1.13.6 with the parallelogram double four-bar (docs/engines.md).
    features = (frozenset(FEATURES) - {"redundant constraints"}) | {SPATIAL}
    #: Every kind, each an `ObjectJointGeneric` (`spatial_model`).
    spatial_joints = frozenset(JOINT_KINDS)
    feature_limits = {"redundant constraints": "its solver stops at the first step on the singular system "
                                               "Jacobian ('System Jacobian seems to be singular' with the index-2 "
                                               "solver, 'SolveDynamic terminated' with index-3)"}
    output_copies, bytes_per_step = 4, 1600       # every sensor at every step

    def planned_steps(self, times: np.ndarray, settings: Mapping[str, Any]) -> tuple[float, float]:
        """The pre-roll covers index-3's start-up transient (`prepare`)."""
        pre_roll = as_float(settings["pre_roll_steps"])
        rho = settings["spectral_radius"]
        if settings["solver"] == "index3" and 0.0 <= rho < 1.0 and pre_roll:
            pre_roll = max(pre_roll, index3_transient_steps(rho))
        return steps_per_interval(times, as_float(settings["timestep"])), pre_roll

    uses_peak_rates = True

    def default_settings(self, mechanism: Mechanism, times: np.ndarray,
                         rates: PeakRates | None = None) -> dict[str, Any]:
        """Step from the scenario's motion (`default_step`); each deliberate
        deviation from Exudyn's defaults is a named setting:

        - solver "index2" (trapezoidal index-2, no start-up transient) or
          "index3" (generalised-α, exact closure, force transient after the
          start, decaying like ρ^n: the pre-roll is lengthened to
          `index3_transient_steps(ρ)` steps so it is over before t = 0);
        - pre_roll_steps: steps along φ(t) before t = 0 from the reference
          state (Exudyn reports zero reactions at its first instant);
        - compute_initial_accelerations False: Exudyn's own solve ignores φ''
          of the drive; the kinematic accelerations are supplied instead;
        - full_newton True, tolerances 1e-12 relative and an absolute floor
          scaled by a force estimate: modified Newton at Exudyn's default
          tolerances caps the force accuracy, at no saving (docs/engines.md);
        - adaptive_step False: it silently shrinks steps;
        - spectral_radius (index-3 only): numerical damping; must stay < 1
          (at 1, λ zig-zags from step to step without decay).

        A torque-driven or free mechanism (`Mechanism.forward_dynamics`)
        starts at its first instant: no pre-roll, and Exudyn's own
        initial-acceleration solve (`own_start`) gives the reactions there;
        its step rule and force scale read the forward-dynamics reference
        (`rates`: the prepared scene's, else computed here).
        """
        if mechanism.spatial is not None:      # Ω from the spatial reference unless the harness gives it
            from mechval.engines.exudyn.spatial import spatial_settings
            return spatial_settings(mechanism, times, rates, RAD_PER_STEP)
        rates = peak_rates(mechanism, times) if rates is None else rates
        if mechanism.forward_dynamics:
            scale = force_scale(mechanism, rates.motion, rates.t)
        else:
            t = dense_grid(times, FORCE_SCALE_GRID)
            scale = force_scale(mechanism, mechanism.motion(t), t)
        return {
            "solver": "index2",
            "timestep": default_step(mechanism, times, rad_per_step=RAD_PER_STEP, rate=rates.rate),
            "pre_roll_steps": 0 if mechanism.forward_dynamics else 10,
            "spectral_radius": 0.9,
            "compute_initial_accelerations": own_start(mechanism),
            "full_newton": True,
            "newton_relative_tolerance": 1e-12,
            "newton_absolute_tolerance": NEWTON_TOLERANCE_PER_NEWTON * scale,
            "adaptive_step": False,
        }

    def check_settings(self, mechanism: Mechanism, settings: Mapping[str, Any]) -> list[tuple[str, str]]:
        """A pre-roll that does not fit the motion: at least one step for
        prescribed motion (Exudyn reports zero reactions at its first
        instant), none for a torque-driven or free mechanism (its motion is
        known only from its first instant on)."""
        if (settings["pre_roll_steps"] == 0) != mechanism.forward_dynamics:
            return [("pre_roll_steps", "must be 0 for a torque-driven or free mechanism: it starts at its first instant"
                     if mechanism.forward_dynamics else
                     "must be at least 1: Exudyn reports zero reactions at its first instant")]
        return []

    def audit(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
        if mechanism.spatial is not None:
            from mechval.engines.exudyn.spatial_audit import audit_spatial
            return audit_spatial(mechanism.spatial, times, settings)
        return audit_model(mechanism, times, settings)

    def run(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
        if mechanism.spatial is not None:
            from mechval.engines.exudyn.spatial import run_spatial
            return run_spatial(mechanism.spatial, times, settings)
        clock = time.perf_counter()
        model, simulation, t0 = prepare(mechanism, times, settings)
        build_time = time.perf_counter() - clock
        clock = time.perf_counter()
        solver = solve(model, simulation, settings["solver"])
        wall_time = time.perf_counter() - clock

        state = node_states(model)
        t_all = t0 + model.mbs.GetSensorStoredData(model.clock_sensor)[:, 0]
        rows = sample_rows(t_all, times)
        frame, missing, gap, drive_error = frame_of(mechanism, model, state, rows, times, t_all,
                                                    bool(settings["compute_initial_accelerations"]))
        info = {
            "steps": len(t_all) - 1,
            "pre_roll_start": t0, "pre_roll_steps_used": int(round((times[0] - t0) / float(settings["timestep"]))),
            "newton_iterations": int(solver.it.newtonStepsCount),
            "jacobian_updates": int(solver.it.newtonJacobiCount),
            "closure_gap_max": float(gap.max()), "drive_error_max": float(drive_error.max()),
            "build_time_s": build_time, "wall_time_s": wall_time,
        }
        if derived := derived_note(mechanism):
            info["derived_reactions"] = derived
        if settings["solver"] == "index3":       # lowered after a shortened pre-roll (`prepare`)
            info["spectral_radius_used"] = simulation.timeIntegration.generalizedAlpha.spectralRadius
        return RawRun(frame, missing, RunInfo.of(info))
