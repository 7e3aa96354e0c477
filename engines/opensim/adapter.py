"""OpenSim adapter: the planar mechanism as an OpenSim 4.6 model, solved by
Simbody's error-controlled integrators with exact constraint projection
(model building in `model`, the run and its read-out in `run`; a spatial
scene, `mechanism.spatial`, in `spatial_model` and `spatial_run`).

Conversion of OpenSim's native outputs to the mechval convention:
- Body motion: each OpenSim body's frame is the mechanism body's frame
  (centre of mass at `com`), so `getTransformInGround`,
  `getVelocityInGround` and `getAccelerationInGround` (spatial vectors,
  angular first, ground axes, of the frame origin) are the raw columns as
  they are; θ from the rotation matrix, unwrapped and anchored to the
  reference's angle at the start.
- Tree joint (`PinJoint`, `SliderJoint`):
  `calcReactionOnChildExpressedInGround` is the load (moment, force) on
  the joint's child at the child's joint point, ground axes. With the
  child body_j that is Fij as is; with the child body_i (a reversed tree
  joint) Fij is minus it, and a slide's couple is moved to point_j.
- Drive: a prescribed coordinate (`setPrescribedFunction` +
  `setDefaultIsPrescribed`); its effort is in the same reaction: the z
  moment on body_j (T) or the force along the axis (F), which is taken
  out of the slide's Fij. A damper at the drive joint is an applied force,
  not part of it.
- Loop-closing pin (`PointConstraint`): Simbody's constraint forces on its
  second body (body_j), negated (`run.closure_reaction`).
- Torque law: a `CoordinateActuator` (optimal force 1) whose control a
  `PrescribedController` sets to the law; "NAME.T" is its actuation.
- Spring-dampers: `ExpressionBasedPointToPointForce` (k·(d − ℓ0) + c·ḋ);
  body torques: `PrescribedForce`; joint dampers:
  `SpringGeneralizedForce` of stiffness 0 on a tree coordinate, a
  `BushingForce` with rotational damping alone at a loop-closing pin.
- Every run starts from the reference's state at its first instant (a
  prescribed motion's or the forward-dynamics reference's); Simbody
  integrates to each sample in turn and the state there is realised to
  accelerations, so values belong to their instant (no step shift).
"""

from __future__ import annotations

from typing import Any, ClassVar, Mapping

import numpy as np
import pandas as pd

from mechval.adapter import FEATURES, SPATIAL, PeakRates, as_float, steps_per_interval
from mechval.model.mechanism import Mechanism
from mechval.reference.spatial.system import JOINT_KINDS
from mechval.settings import TIMESTEP, Choice, Number, Setting

from mechval.engines.base import EngineAdapter, RawRun, RunInfo, default_step, peak_rates
from mechval.engines.opensim.run import INTEGRATORS, read_run

#: Simbody's relative accuracy of the error-controlled integrators. The
#: measured figures behind the choice: docs/engines.md ("OpenSim").
ACCURACY = 1e-9
#: The largest step as a rotation at the run's peak rate Ω (rad): at the
#: default accuracy Runge–Kutta–Merson's own steps are about 0.02–0.03 rad
#: (a cap of 0.05 costs ~10 % CPU on slider-crank-150, 0.02 costs 40 %), so
#: the declared run size (`planned_steps`) is within a small factor of the
#: steps taken.
MAX_STEP_RAD = 0.05
#: Simbody's tolerance on the constraint errors (position and velocity
#: projection), relative to its unit lengths.
CONSTRAINT_TOLERANCE = 1e-10


class OpensimAdapter(EngineAdapter):
    """OpenSim 4.6 (Simbody); see the module docstring for the conversion."""

    name = "opensim"
    library = "opensim"
    distribution = "opensim"
    settings_spec: ClassVar[Mapping[str, Setting]] = {
        "integrator": Choice(tuple(INTEGRATORS)),
        "accuracy": Number(0.0, 1.0, low_open=True),
        "constraint_tolerance": Number(0.0, 1.0, low_open=True),
        # The largest step Simbody may take (s); the error control takes
        # smaller ones where the accuracy needs them.
        "max_step": TIMESTEP,
    }
    step_setting = "max_step"
    step_settings = ("max_step",)
    #: High accuracy: Simbody's error control tightened a hundredfold.
    variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "default": {}, "high-accuracy": {"accuracy": 1e-11, "constraint_tolerance": 1e-12}}
    #: The ladder sets the largest step; at the default accuracy the error
    #: control decides, so a loose accuracy shows what the step does.
    cost_variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "default": {}, "accuracy-1e-5": {"accuracy": 1e-5, "constraint_tolerance": 1e-6}}
    #: The tree, point constraints, prescribed coordinates, actuators and
    #: force elements build every feature; Simbody projects redundant
    #: constraints (the parallelogram double four-bar) and its multipliers'
    #: body resultants meet the reference (tests/test_opensim.py).
    features = frozenset(FEATURES) | {SPATIAL}
    #: The tables a run keeps (per-sample Python lists of the raw columns,
    #: the frame, the signals): measured 10.5 copies of the samples × signals
    #: table (peak RSS of fourbar-seed at 10 rad/s, 30001 against 601
    #: samples; tests/bench/run_size_bench.py no longer runs on this tree);
    #: nothing per step (no storage, no states trajectory).
    output_copies, bytes_per_step = 12, 0

    #: Every kind: OpenSim's joints in the tree, Simbody's constraints at
    #: the loop closures (`spatial_model`).
    spatial_joints = frozenset(JOINT_KINDS)

    uses_peak_rates = True

    def default_settings(self, mechanism: Mechanism, times: np.ndarray,
                         rates: PeakRates | None = None) -> dict[str, Any]:
        """OpenSim's own integrator (Runge–Kutta–Merson) at an accuracy that
        puts every built-in within 1e-6 of its class peak (measured,
        docs/engines.md); the largest step MAX_STEP_RAD of a turn at the
        run's peak rate Ω (`default_step`; `rates`: the prepared scene's,
        else computed here), at most the sample interval."""
        interval = float(times[1] - times[0]) if len(times) > 1 else 1.0
        rate = (peak_rates(mechanism, times) if rates is None else rates).rate if len(times) > 1 else None
        max_step = default_step(mechanism, times, MAX_STEP_RAD, interval, rate) if rate is not None else interval
        return {"integrator": "RungeKuttaMerson", "accuracy": ACCURACY,
                "constraint_tolerance": CONSTRAINT_TOLERANCE, "max_step": max_step}

    def planned_steps(self, times: np.ndarray, settings: Mapping[str, Any]) -> tuple[float, float]:
        """One step per `max_step` of each sample interval: the error
        control takes about as many at the default accuracy (`MAX_STEP_RAD`),
        more at a tighter one."""
        return steps_per_interval(times, as_float(settings["max_step"])), 0.0

    def audit(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
        if mechanism.spatial is not None:
            from mechval.engines.opensim.spatial_audit import audit_spatial
            return audit_spatial(mechanism.spatial, times, settings)
        from mechval.engines.opensim.audit import audit_model
        return audit_model(mechanism, times, settings)

    def run(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
        if mechanism.spatial is not None:
            from mechval.engines.opensim.spatial_run import run_spatial
            return run_spatial(mechanism.spatial, times, settings)
        frame, info = read_run(mechanism, times, settings)
        return RawRun(frame, {}, RunInfo.of(info))
