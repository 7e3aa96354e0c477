"""The load-time checks of a spatial file that need more than its keys
(docs/scenario-format.md#spatial-files): the bounds of what is simulated
(`mechval.reference.limits`, the same figures as for planar files), then,
as the planar front end does, the assembled mechanism:

- a prescribed scene is assembled and followed over its whole run by the
  spatial reference's continuation (`SpatialSolver.check`): a loop that
  cannot close, drives that do not match the mobility (Grübler's count and
  the rank both stated), a singular position, a run too long;
- a torque-driven or free scene is assembled at t = 0
  (`SpatialDynamics`): a loop that cannot close; drives beyond the
  mobility or dependent; torque laws or initial velocities where the
  drives prescribe every degree of freedom; stated velocities the joints
  do not allow (the reference would replace them by the nearest ones that
  they do: the run would not start where the file says).

The reference's MechanismError keys are translated to the file's
(`Scenario.keys`).
"""

from __future__ import annotations

import math
import re

import numpy as np

from mechval.model.scenario import Scenario, ScenarioError
from mechval.reference.limits import (MAX_COM_DISTANCE, MAX_CRANK_ANGLE, MAX_MASS_RATIO, MAX_SAMPLES, MIN_INERTIA,
                                      MIN_MASS, MIN_SAMPLE_INTERVAL, crank_angle_peak, shown_int)
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.dynamics import SpatialDynamics
from mechval.reference.spatial.rotation import cross
from mechval.reference.spatial.solver import SpatialSolver
from mechval.reference.spatial.system import SpatialSystem

#: Stated initial velocities must satisfy the joints to this, relative to
#: their size (scaled: m/s over the mechanism's size, rad/s): rounding of
#: velocities derived by hand or by a script passes.
CONSISTENT = 1e-9


def check_spatial(scenario: Scenario) -> None:
    check_limits(scenario)
    try:
        if scenario.scene.forward_dynamics:
            _initial_state(scenario)
        else:
            SpatialSolver(scenario.scene).check(0.0, scenario.time.end)
    except MechanismError as exc:
        reason = exc.reason
        mobility = re.match(r"the mobility is (\d+) ", reason)
        if exc.key == "drive" and mobility and int(mobility.group(1)) > len(scenario.scene.drives):
            reason += ("; fewer drives than degrees of freedom make an integrated run: give the bodies' "
                       "velocities at t = 0 in [initial] (or a torque law)")
        raise ScenarioError(scenario.source, scenario.key(exc.key), reason) from None
    except np.linalg.LinAlgError:       # rows exactly dependent at some pose the continuation reached
        raise ScenarioError(scenario.source, "time", "the Jacobian of the rows the reference keeps is exactly "
                                                     "singular at a position of the run") from None


def check_limits(scenario: Scenario) -> None:
    """`mechval.reference.limits.check_scene` for a spatial scene."""
    system: SpatialSystem = scenario.scene

    def fail(key: str, reason: str):
        raise ScenarioError(scenario.source, scenario.key(key), reason)

    samples, end = scenario.time.samples, scenario.time.end
    if samples > MAX_SAMPLES:
        fail("time.samples", f"{shown_int(samples)} samples exceed the limit of {MAX_SAMPLES:,}")
    interval = end / (samples - 1)
    if not interval >= MIN_SAMPLE_INTERVAL:
        fail("time.end", f"the sample interval end / (samples − 1) = {interval:.3g} s is below "
                         f"{MIN_SAMPLE_INTERVAL:g} s, where the engines' steps lose their accuracy")
    for drive in system.drives:
        law = drive.law
        angle, when = crank_angle_peak(law.phi0, law.omega0, law.alpha, end)
        if angle > MAX_CRANK_ANGLE:
            fail(f"drive.{drive.name}", f"the drive's coordinate reaches {angle:.3g} at t = {when:.6g} s, beyond "
                                        f"{MAX_CRANK_ANGLE:.0e}: float64 resolves it only to {math.ulp(angle):.2g}")
    heaviest = max(b.mass for b in system.bodies)
    for b in system.bodies:
        if b.mass < MIN_MASS:
            fail(f"body.{b.name}.mass", f"{b.mass:g} kg is below {MIN_MASS:g} kg (MuJoCo refuses masses "
                                        "≤ 1e-15 kg; PyBullet takes them for fixed bodies)")
        if heaviest / b.mass > MAX_MASS_RATIO:
            fail(f"body.{b.name}.mass", f"{b.mass:g} kg is {heaviest / b.mass:.3g} times lighter than the "
                                        f"heaviest body ({heaviest:g} kg); beyond {MAX_MASS_RATIO:.0e} the "
                                        "engines' solvers lose the light body")
        smallest = np.linalg.eigvalsh(b.inertia)[0]
        if smallest < MIN_INERTIA:
            fail(f"body.{b.name}.inertia", f"the smallest principal moment {smallest:.3g} kg·m² is below "
                                           f"{MIN_INERTIA:g} kg·m²: the tensor must be positive definite (MuJoCo "
                                           "refuses inertias ≤ 1e-15 kg·m² per axis)")
    points = [p for j in system.joints for p in (j.point_i, j.point_j)]
    size = max((abs(v) for p in points for v in p), default=0.0) or 1.0
    for b in system.bodies:
        own = [p for j in system.joints for body, p in ((j.body_i, j.point_i), (j.body_j, j.point_j))
               if body == b.name]
        distance = min((math.dist(b.com, p) for p in own), default=0.0)
        if not distance <= MAX_COM_DISTANCE * size:
            fail(f"body.{b.name}.com", f"the centre of mass lies {distance:.3g} m from its body's nearest joint, "
                                       f"more than {MAX_COM_DISTANCE:.0e} times the mechanism's size ({size:.3g} m): "
                                       "the joints would drown in the rounding of its coordinates")


def _initial_state(scenario: Scenario) -> None:
    """Assemble a torque-driven or free scene at t = 0 and check its drives,
    torque laws and stated velocities against its mobility and joints."""
    system: SpatialSystem = scenario.scene
    dynamics = SpatialDynamics(system, system.velocities, t0=0.0)
    found, rows = dynamics.found, set(dynamics.rows)
    drives = len(system.drives)
    drive_rows = [dynamics.c.drive_rows[d.name] for d in system.drives]
    if drives > found.mobility or not rows.issuperset(drive_rows):
        raise MechanismError("drive", f"the mobility is {found.mobility} (rank of the joints' Jacobian, "
                                      f"Grübler–Kutzbach {found.grubler}) and {drives} drive"
                                      f"{'s' if drives != 1 else ''} cannot prescribe it"
                                      + (": the drives are dependent" if drives <= found.mobility else ""))
    if drives and drives == found.mobility:
        key = "torque" if system.torques else "initial"
        raise MechanismError(key, "the drives prescribe every degree of freedom: "
                                  + ("a torque law would move nothing (leave its joint undriven)" if system.torques
                                     else "the velocities at t = 0 follow from them (leave out [initial])"))
    _consistent(scenario, dynamics)


def _consistent(scenario: Scenario, dynamics: SpatialDynamics) -> None:
    """Refuse stated velocities that the reference's projection onto the
    joints would change (only the bodies the file names)."""
    system: SpatialSystem = scenario.scene
    size = dynamics.solver.scaling.size
    scale = np.array([1 / size] * 3 + [1.0] * 3)
    stated, projected = {}, {}
    for k, b in enumerate(system.bodies):
        if b.name not in system.velocities:
            continue
        v, om = (np.asarray(x, dtype=float) for x in system.velocities[b.name])
        arm = dynamics.pose0.A[0, k] @ np.asarray(b.com, dtype=float)
        stated[b.name] = np.concatenate([v + cross(om, arm), om]) * scale
        projected[b.name] = dynamics.w0[0, k] * scale
    if not stated:
        return
    size_of = max(max(np.abs(w).max() for w in stated.values()), np.abs(dynamics.w0[0] * scale).max())
    name, miss = max(((n, np.abs(projected[n] - stated[n]).max()) for n in stated), key=lambda x: x[1])
    if miss > CONSISTENT * size_of:
        raise MechanismError(f"initial.{name}", f"the stated velocities do not satisfy the joints (and drives): the "
                                                f"nearest that do differ by {miss / max(size_of, 1e-300):.3g} of their "
                                                "size here; state every moving body's velocity, consistently")
