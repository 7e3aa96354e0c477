"""MuJoCo adapter: the generic planar mechanism in MuJoCo 4.0.

The model (see `model`): a spanning tree of hinge/slide joints, each
loop closed by an equality `connect` at one revolute pin, each driven joint
tied by a joint equality to its own heavy clock whose coordinate is φ(t),
dampers as fixed tendons, spring-dampers as spatial tendons, body torques as
constant actuator forces, no geoms, contacts and autoreset off, stiffened
soft constraints.

Modes (setting "mode"):
- "forward": MuJoCo integrates (`mujoco.rollout`, no Python per step) from
  the reference state a few steps before t = 0 (pre-roll along φ). At every
  sample the stored state is re-evaluated with `mj_forward` +
  `mj_rnePostConstraint`; these are exactly the forces of the step that
  starts at that instant, so they are stamped at the state's own time (not
  at the end of the step, which would make the error O(dt)). The read-out
  costs one `mj_forward` per sample plus vectorised numpy; everything it
  needs is in fixed mjData fields, copied in one piece (`Snapshot`).
  A torque-driven or free mechanism (`Mechanism.forward_dynamics`) starts
  at the first instant, with no pre-roll (there is no prescribed path to
  pre-roll along), from the forward-dynamics reference's consistent state
  there (`mechval.reference.dynamics.raw_dynamics` at times[:1]); only its remaining
  prescribed drives get clocks. Each `TorqueLaw` is an actuator on a fixed
  tendon whose length is the joint's θj − θi, with integrator activation
  dynamics and gain 1: its force is its activation, which starts at T(t0)
  and whose rate is the control. The rollout's control over step n is the
  law's slope (T(t_n+1) − T(t_n))/dt, so the applied torque is the law at
  every step boundary (every sample) and linear in between, in every RK4
  stage, with no Python per step. Why not the alternatives: a control held
  over the step (a motor, or qfrc_applied per step) is the law only at the
  step's start, an O(dt) error in the motion, and its column at a sample
  is not T(t); a control callback (mjcb_control) sees each stage's time
  but runs Python four times per step, process-wide, and rules out the
  rollout. The column "NAME.T" is the actuator's force read back at the
  sample. The default step takes Ω from the forward-dynamics reference at
  rtol 1e-6 (`PeakRates`, `planned_motion`): the mechanism's own `motion` describes
  no run there.
- "inverse": `mj_inverse` at the reference q, q̇, q̈ with constraints off;
  qfrc_inverse is split by least squares into the drive torque on its
  coordinate and the loop force through the cut pin's Jacobian. This checks
  frames, signs and inertias independently of time integration. For a
  torque-driven or free mechanism the reference state is the forward
  dynamics' integrated motion, and each torque law's generalized force is
  known (its activation set to T(t)) and taken out before the split.

Conversion of native outputs to Fij (force BY body_i ON body_j, world axes,
at the sample instant):
- Tree joint (parent → child): `cfrc_int[child]` is the spatial force
  [torque, force] by the parent on the child's subtree, world axes, torque
  about `subtree_com` of the root. Fij = +force when the child is body_j,
  −force when the child is body_i. For a slide joint the component along the
  axis is the joint-space force (the damper), not a reaction, and is removed
  by subtracting qfrc_passive of that coordinate along the axis; the couple M
  on body_j is the z torque shifted to body_j's joint point, signed likewise.
- Cut pins: the `connect` rows of `efc_force` are the world force on
  site1's body, which is body_j: Fij directly (inverse mode: the
  least-squares λ of all cuts and drives at once).
- Drive efforts (T or F): each joint equality's `efc_force` λ is the
  generalized force on its joint's coordinate; effort = sign·λ (sign −1 if
  the joint's child is body_i). It is read from `qfrc_constraint` of the
  drive's own clock (`drive_efforts`). A damper at the drive joint is a
  tendon, not part of this force. A prismatic joint's axial force (damper,
  drive) is not reaction: with a drive on it or force elements in the
  scene, the whole axial part is projected out.
- Force elements: MuJoCo 4.0's `mj_rnePostConstraint` adds the spatial
  tendons' forces (the spring-dampers, spring and damper parts) to
  `cfrc_ext` at their sites, so `cfrc_int` already leaves them out. A body
  torque's actuator acts through the hinges of the body's path (same
  motion), so a slide's couple M below it gets the torque taken out like
  the cut damper's couple (`torque_loads`); a pin's Fx, Fy do not see it.

  The cut pin's damper acts through its tendon on the tree's hinges, which
  moves its couple onto the path's bodies (same motion, other internal
  couples): it is taken out of a slide joint's M (`cut_damper_couple`).
  Likewise a point mass turning with another body (the block on its
  slotted lever) borrows MuJoCo's minimum inertia from that body
  (`planar_inertias`: same motion), and the borrowed inertia's couple is
  taken out of the slide's M (`inertia_shift_couple`).
Only in-plane force components and the z couple are reported: the
out-of-plane reactions of a planar loop closed in 3D are statically
indeterminate, so any engine value there is legitimate and meaningless.

High accuracy (variant "high-accuracy": refine = 4, solref_steps = 20): a
quarter of the rule's step, the loop's solref at 20 of those steps. The
soft constraints' error falls as the square of their time constant, but at
10 steps RK4 stops improving as dt shrinks (an error floor), hence the
longer time constant with the shorter step. The figures are in
docs/engines.md; tests/test_mujoco.py holds both settings to their goals
on fourbar-seed.
"""

from __future__ import annotations

import time
from typing import Any, ClassVar, Mapping

import numpy as np
import pandas as pd

from mechval.adapter import FEATURES, SPATIAL, PeakRates, as_float, ceil_or_inf, steps_per_interval
from mechval.engines.base import EngineAdapter, RawRun, RunInfo, default_step, peak_rates
from mechval.model.mechanism import Mechanism
from mechval.settings import TIMESTEP, Choice, Number, Setting

from mechval.engines.mujoco.audit import audit_model
from mechval.engines.mujoco.model import INTEGRATORS, SOLIMP
from mechval.engines.mujoco.run import Model, warnings_silenced
from mechval.engines.mujoco.spatial import run_spatial
from mechval.engines.mujoco.spatial_audit import audit_spatial
from mechval.reference.spatial.system import JOINT_KINDS

MODES = ("forward", "inverse")
class MujocoAdapter(EngineAdapter):
    name: ClassVar[str] = "mujoco"
    library: ClassVar[str] = "mujoco"
    distribution: ClassVar[str] = "mujoco"
    settings_spec: ClassVar[Mapping[str, Setting]] = {
        "mode": Choice(MODES),
        "integrator": Choice(INTEGRATORS),
        "timestep": TIMESTEP,
        "refine": Number(1, 1000, whole=True),
        # In steps of dt; the pre-roll lasts preroll_timeconsts of them.
        "solref_steps": Number(0.0, 1e4, low_open=True),
        "drive_solref_steps": Number(0.0, 1e4, low_open=True),
        # MuJoCo's standard solref needs dampratio > 0 (otherwise it
        # silently falls back to its default solref).
        "solref_dampratio": Number(0.0, 100.0, low_open=True),
        "solimp": SOLIMP,
        "tolerance": Number(0.0, 1.0),
        "iterations": Number(1, 1000, whole=True),
        # Far heavier than any mechanism (module docstring); MuJoCo refuses
        # a moving body lighter than 1e-15 kg.
        "clock_mass": Number(1.0, 1e20),
        "preroll_timeconsts": Number(0.0, 1000.0),
    }
    #: "high-accuracy": a quarter of the rule's step, solref 20 steps (the
    #: module docstring).
    variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "default": {}, "high-accuracy": {"refine": 4, "solref_steps": 20.0}}
    #: Integrators for `mechval cost` (the ladder sets `timestep`). Euler and
    #: implicitfast need solref ≥ 2·dt on both equalities (below that they
    #: blow up, docs/engines.md); RK4 with solref 20·dt lowers the error floor
    #: that 10·dt leaves (module docstring).
    cost_variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "RK4": {}, "RK4 solref 20dt": {"solref_steps": 20.0},
        "Euler": {"integrator": "Euler", "solref_steps": 2.0, "drive_solref_steps": 2.0},
        "implicitfast": {"integrator": "implicitfast", "solref_steps": 2.0, "drive_solref_steps": 2.0}}

    #: Each built by MuJoCo itself (module docstring): a drive per clock and
    #: joint equality (hinge or slide), spring-dampers as spatial tendons,
    #: body torques as constant actuator forces on fixed tendons.
    features: ClassVar[frozenset[str]] = frozenset(FEATURES) | {SPATIAL}
    #: Every kind, in the tree (`mechval.engines.mujoco.spatial_model`); a
    #: loop closes only at a spherical, revolute or universal joint (a loop
    #: of other kinds alone is refused when the model is built).
    spatial_joints: ClassVar[frozenset[str]] = frozenset(JOINT_KINDS)
    step_settings = ("timestep", "refine", "solref_steps", "preroll_timeconsts")
    output_copies, bytes_per_step = 24, 128       # the rollout keeps every state

    def planned_steps(self, times: np.ndarray, settings: Mapping[str, Any]) -> tuple[float, float]:
        """MuJoCo steps timestep / refine; the pre-roll lasts preroll_timeconsts
        of the loop's solref time constant (solref_steps steps): an upper
        bound, halved where the reference cannot give a state that early."""
        step = as_float(settings["timestep"]) / as_float(settings["refine"])
        preroll = ceil_or_inf(as_float(settings["preroll_timeconsts"]) * as_float(settings["solref_steps"]))
        return steps_per_interval(times, step), preroll

    uses_peak_rates = True

    def default_settings(self, mechanism: Mechanism, times: np.ndarray,
                         rates: PeakRates | None = None) -> dict[str, Any]:
        """RK4 at the shared step rule (`timestep`: 0.01 rad per step of the
        fastest motion, ≤ 1 ms), divided by `refine` (the step MuJoCo takes,
        dt; 1 by default); the loop's solref 10·dt, below which RK4 has an
        error floor; the drive's 1·dt (the drive equality has no such floor,
        and its lag is what α2 shows: smallest at 1·dt, docs/engines.md);
        solimp at MuJoCo's cap 0.9999; Newton with tolerance 0 and a few
        iterations (a non-zero tolerance stops Newton at 0 iterations with the
        heavy clock); clock mass 1e12 kg, so the drive's reaction moves the
        clock by < 1e-9 rad over a run. The pre-roll lasts 20 solref time
        constants: the rigidly consistent start is not the soft constraints'
        equilibrium, and that transient (critically damped) must have died
        out by t = 0 (4 time constants left visible errors in α2 and T12).
        Ω is the prepared scene's (`rates`), else computed here."""
        rate = (peak_rates(mechanism, times) if rates is None else rates).rate
        return {
            "mode": "forward",
            "integrator": "RK4",
            "timestep": default_step(mechanism, times, rate=rate),
            "refine": 1,
            "solref_steps": 10.0,
            "drive_solref_steps": 1.0,
            "solref_dampratio": 1.0,
            "solimp": "0.9999 0.9999 0.001 0.5 2",
            "tolerance": 0.0,
            "iterations": 3,
            "clock_mass": 1e12,
            # A torque-driven or free run has no path to pre-roll along.
            "preroll_timeconsts": 0.0 if mechanism.forward_dynamics else 20.0,
        }

    def check_settings(self, mechanism: Mechanism, settings: Mapping[str, Any]) -> list[tuple[str, str]]:
        """A pre-roll asked of a torque-driven or free run: such a run starts
        at the first instant from its initial state (`planned_steps` counts
        none)."""
        if mechanism.forward_dynamics and settings["preroll_timeconsts"]:
            return [("preroll_timeconsts", "a torque-driven or free run starts at the first instant from its initial "
                                           "state, with no pre-roll: leave it out or set 0")]
        return []

    def audit(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
        if mechanism.spatial is not None:
            return audit_spatial(mechanism.spatial, times, settings)
        return audit_model(mechanism, times, settings)

    def run(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
        if mechanism.spatial is not None:
            return run_spatial(mechanism.spatial, times, settings)
        if settings["mode"] not in MODES:
            raise ValueError(f"mujoco: unknown mode {settings['mode']!r} (forward, inverse)")
        start = time.perf_counter()
        model = Model(mechanism, times, settings)
        build_time = time.perf_counter() - start
        runner = model.forward if settings["mode"] == "forward" else model.inverse
        with warnings_silenced:
            frame, info = runner()
        solref = lambda eq: " ".join(f"{v:.6g}" for v in model.m.eq_solref[eq])
        info.update(build_time_s=build_time, step=model.dt, solimp=settings["solimp"],
                    solref=solref(model.loop_eq) if model.loop_eqs else "none",
                    drive_solref=solref(model.drive_eq) if model.drive_eqs else "none")
        return RawRun(frame, {}, RunInfo.of(info))


