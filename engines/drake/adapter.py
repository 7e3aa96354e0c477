"""Drake adapter: the generic planar mechanism as a discrete Drake 1.51
MultibodyPlant with the SAP solver (model building in `model`, the run
and its read-out in `run`).

Conversion of Drake's native outputs to the mechval convention, at the
sample instant t_n (the state x_n after n steps from the run's start):
- Body motion: each body's frame is the mechanism's body frame, so its
  pose in world (`EvalBodyPoseInWorld`) is (x, y, θ) as is; θ unwrapped
  and anchored to the reference's angle at the start. Drake's step sets
  q_{n+1} = q_n + dt·v_{n+1}: v_n is the mean rate over the step that
  ends at t_n, half a step late, so the reported rate at t_n is v_n +
  dt/2·a_n, the mean of the two steps' rates (a half-step lag in every
  velocity otherwise: docs/engines.md). Accelerations are Drake's body
  spatial accelerations of the step from t_n, (v_{n+1} − v_n)/dt.
- Output ports are live (`SetUseSampledOutputPorts(False)`): evaluated at
  x_n, the accelerations, reactions and actuation are those of the step
  from t_n, which Drake takes at the positions q_n: the forces at t_n.
  Drake's default, sampled ports give the step that ended at t_n, whose
  forces belong to t_{n−1} (an error of one step's change; measured in
  docs/engines.md).
- Tree joint: the reaction port's F_CJc_Jc is the force on the joint's
  child body at its child frame (the joint point), in that frame's axes;
  turned to world axes, it is Fij when the child is body_j and −Fij when
  it is body_i. A slide's axial part is its damper or its drive, not a
  reaction, and is projected out; its couple M on body_j about P_j is the
  port's z torque (child body_j) or the opposite of it plus the moment of
  Fij taken from P_i to P_j (child body_i).
- Cut pin (a ball constraint: Drake 1.51 reports no constraint force):
  from the momentum balance of the bodies it joins, with Drake's own
  motion and reactions (`run.cut_forces`).
- Drive effort: the net actuation of its PD-controlled actuator (the
  generalized force on the joint's coordinate), times the tree joint's
  sign. A damper at the drive joint is Drake's joint damping, not part
  of it.
- A torque law's column is the law itself, T(t): it is applied as spatial
  torques by `model.AppliedForces` at the start of every step.
- A torque-driven or free mechanism starts at its first instant, in the
  forward-dynamics reference's consistent state; a prescribed one a
  pre-roll of `preroll_steps` steps before it along φ(t), so that the
  drive's lag (T/Kp) has settled by the first sample.
Only in-plane forces and the z couple are reported: the out-of-plane
reactions of a planar loop closed in 3D are statically indeterminate.

A spatial scene (`Mechanism.spatial`) is built and read by `spatial`
(`run_spatial`; its conversions in `spatial_reactions`), with the same
settings and step rule, and by default a continuous plant where the scene
has no loop or prescribed drive (docs/engines.md, "Drake: spatial scenes").
"""

from __future__ import annotations

import time
from typing import Any, ClassVar, Mapping

import numpy as np

from mechval.adapter import FEATURES, SPATIAL, PeakRates, as_float, steps_per_interval
from mechval.model.mechanism import Mechanism
from mechval.settings import TIMESTEP, Choice, Number, Setting

from mechval.engines.base import EngineAdapter, RawRun, RunInfo, default_step, peak_rates


def sap_defaults(timestep: float, forward_dynamics: bool) -> dict[str, Any]:
    """The discrete plant's defaults, planar or spatial (`default_settings`
    says why each)."""
    return {"timestep": timestep, "refine": 1, "drive_stiffness": 1e4, "drive_damping": 0.0,
            "preroll_steps": 0 if forward_dynamics else 20, "near_rigid_threshold": 1.0}


class DrakeAdapter(EngineAdapter):
    """Drake 1.51.1; see the module docstring for the conversions."""

    name: ClassVar[str] = "drake"
    library: ClassVar[str] = "pydrake"
    distribution: ClassVar[str] = "drake"
    settings_spec: ClassVar[Mapping[str, Setting]] = {
        "timestep": TIMESTEP,
        # Drake steps timestep / refine (the sample grid needs `timestep`
        # to divide the sample interval; refine divides it further).
        "refine": Number(1, 1000, whole=True),
        # Kp = drive_stiffness·m/dt², Kd = drive_damping·m/dt (`model.drive_gains`).
        "drive_stiffness": Number(0.0, 1e8, low_open=True),
        "drive_damping": Number(0.0, 1e8),
        "preroll_steps": Number(0, 100_000, whole=True),
        # SAP's near-rigid threshold β (Drake's default 1): the ball
        # constraints' regularisation, as a fraction of the step.
        "near_rigid_threshold": Number(0.0, 1.0, low_open=True),
        # Spatial scenes only (`spatial`): "sap", the discrete plant above,
        # or "rk3", a continuous plant stepped by Drake's error-controlled
        # third-order Runge–Kutta, at most `timestep` per step, to the
        # target `accuracy`: for scenes without loops or prescribed drives
        # (Drake takes neither in continuous time).
        "integrator": Choice(("sap", "rk3")),
        "accuracy": Number(0.0, 1.0, low_open=True),
    }
    #: High accuracy is a finer step, `refine = 4` (a quarter of it: every
    #: error of the first-order step falls fourfold; tests/test_drake.py
    #: holds it), not a reported variant: each variant is re-run by every
    #: baseline check of the default test suite, and Drake's share of that
    #: suite is over budget already (docs/engines.md, Drake: Speed).
    variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {"default": {}}
    cost_variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "SAP": {}, "SAP soft drive": {"drive_stiffness": 100.0}}
    step_settings = ("timestep", "refine", "preroll_steps")
    #: Not redundant constraints of planar scenes: not built or measured
    #: yet (spatial scenes' redundant loops are built: `spatial_tree`).
    features: ClassVar[frozenset[str]] = (frozenset(FEATURES) - {"redundant constraints"}) | {SPATIAL}
    spatial_joints: ClassVar[frozenset[str]] = frozenset(
        ("revolute", "prismatic", "cylindrical", "spherical", "universal", "planar", "fixed"))
    output_copies, bytes_per_step = 8, 64         # samples are read as the run goes; nothing per step
    uses_peak_rates = True

    def planned_steps(self, times: np.ndarray, settings: Mapping[str, Any]) -> tuple[float, float]:
        step = as_float(settings["timestep"]) / as_float(settings["refine"])
        return steps_per_interval(times, step), as_float(settings["preroll_steps"])

    def default_settings(self, mechanism: Mechanism, times: np.ndarray,
                         rates: PeakRates | None = None) -> dict[str, Any]:
        """The shared step rule (0.01 rad per step of the fastest motion,
        ≤ 1 ms); drive_stiffness 1e4 (a lag T/Kp of 1e-4 of what the
        drive's own inertia gives in one step squared: 2.2e-8 rad on
        fourbar-seed; fourbar-mass-ratio needs it),
        no drive damping (the implicit PD needs none, and a Kd pulls v
        toward the desired rate against Kp); a pre-roll of 20 steps
        (none for a torque-driven or free run); SAP's near-rigid threshold
        at Drake's default 1. Figures: docs/engines.md."""
        if mechanism.spatial is not None:
            from mechval.engines.drake.spatial import spatial_defaults
            return spatial_defaults(mechanism.spatial, times, (peak_rates(mechanism, times) if rates is None
                                                                else rates).rate)
        rate = (peak_rates(mechanism, times) if rates is None else rates).rate
        # The planar plant is always SAP; `accuracy` is read by "rk3" only.
        return {**sap_defaults(default_step(mechanism, times, rate=rate), mechanism.forward_dynamics),
                "integrator": "sap", "accuracy": 1e-6}

    def check_settings(self, mechanism: Mechanism, settings: Mapping[str, Any]) -> list[tuple[str, str]]:
        """A pre-roll asked of a torque-driven or free run, which starts at
        its first instant from its initial state."""
        if mechanism.forward_dynamics and settings["preroll_steps"]:
            return [("preroll_steps", "a torque-driven or free run starts at the first instant from its initial "
                                      "state, with no pre-roll: leave it out or set 0")]
        if settings.get("integrator", "sap") != "sap":
            if mechanism.spatial is None:
                return [("integrator", "the continuous plant is built for spatial scenes only")]
            from mechval.engines.drake.spatial import has_constraints
            if has_constraints(mechanism.spatial):
                return [("integrator", "Drake 1.51's continuous plant takes no constraints and no PD-controlled "
                                       "drive: this scene has a loop or a prescribed drive, use \"sap\"")]
            if "accuracy" not in settings:
                return [("accuracy", "the continuous plant needs a target accuracy")]
        return []

    def audit(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]):
        if mechanism.spatial is not None:
            from mechval.engines.drake.spatial_audit import audit_spatial
            return audit_spatial(mechanism.spatial, times, settings)
        from mechval.engines.drake.audit import audit_model
        return audit_model(mechanism, times, settings)

    def run(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
        if mechanism.spatial is not None:
            from mechval.engines.drake.spatial import run_spatial
            return run_spatial(mechanism.spatial, times, settings)
        from mechval.engines.drake.run import Run
        clock = time.perf_counter()
        run = Run(mechanism, times, settings)
        build_time = time.perf_counter() - clock
        frame, facts = run.simulate()
        facts.update(build_time_s=build_time, step=run.dt)
        return RawRun(frame, {}, RunInfo.of(facts))
