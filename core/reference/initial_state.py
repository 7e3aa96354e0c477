"""The consistent initial state of a torque-driven or free mechanism, and
the independent coordinates its forward dynamics integrates
(`mechval.reference.dynamics`).

A forward-dynamics run starts from stated values: per degree of freedom
left by the prescribed drives, one joint's coordinate (the relative angle
θj − θi of a revolute joint, rad, or the slide s = u·(Pj − Pi) of a
prismatic one, m) and its rate. Those joints' coordinates are the
independent coordinates z of the run (coordinate partitioning, Wehage &
Haug 1982; Haug 1989, ch. 11): each becomes one extra constraint row, a
drive row of `mechval.reference.planar.constraints` with a zero law, whose value z
the caller adds. The initial state is then assembled as a prescribed
mechanism would be (`mechval.reference.planar.positions`): positions by Gauss–Newton
from the assembly pose with every stated coordinate held at its value,
velocities from Φq·q̇ = −Φt with the stated rates.

Refused, with the key `initial` (or `initial.JOINT`) and the reason:
- an unknown, repeated or non-finite joint value;
- fewer (or more) values than the degrees of freedom;
- values that do not fix the configuration (a coordinate that the others
  already determine) or that the loop cannot reach;
- a configuration where the stated coordinates cannot parametrise the
  motion (the Jacobian with their rows is singular: a toggle of that
  joint, e.g. a rocker at its extreme angle).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import BodyPose, Drive, InitialValue, Mechanism
from mechval.reference.planar.constraints import Constraints, MechanismError
from mechval.reference.planar.linear import solve_one
from mechval.reference.planar.positions import Scaling, Structure, gauss_newton, initial_guess, mechanism_size, rank
from mechval.reference.planar.tree import Factor, Tree

#: Condition number of the scaled reduced Jacobian above which the stated
#: coordinates are refused as unable to parametrise the motion: the state's
#: dependent positions and rates would carry errors of ~cond·eps (2e-9 at
#: 1e7, the order of the Andrews bound of issue 15). At a joint's toggle
#: itself the assembly ends ~√eps from it and the condition is ~1e8 (the
#: seed four-bar's rocker at its extreme: 3e8; 1e-14 rad inside: 3.8e7;
#: 1e-12 rad inside: 3.8e6).
SINGULAR_CONDITION = 1e7


def coordinate_name(joint: str) -> str:
    """The drive name of a joint's coordinate row (no scenario drive can
    clash with it: scenario names have no spaces)."""
    return f"coordinate {joint}"


def with_coordinates(mech: Mechanism, joints: Sequence[str], laws: Sequence[DriveLaw] | None = None) -> Mechanism:
    """The mechanism with one drive row per joint coordinate appended after
    its prescribed drives (zero laws unless given), and without its torque
    laws (they constrain nothing; the caller applies them)."""
    laws = laws or [DriveLaw() for _ in joints]
    drives = (*mech.drives, *(Drive(j, law, coordinate_name(j)) for j, law in zip(joints, laws)))
    return dataclasses.replace(mech, drive=drives[0] if drives else None, extra_drives=drives[1:], torque_drives=())


@dataclass(frozen=True)
class InitialState:
    """The assembled state at t0: q, q̇ (absolute coordinates), the
    independent coordinates z, ż and the mechanism's structure."""

    t0: float
    q: np.ndarray
    v: np.ndarray
    z: np.ndarray
    zdot: np.ndarray
    structure: Structure


def _check_values(mech: Mechanism, values: Sequence[InitialValue]) -> None:
    joints = {j.name for j in mech.joints}
    seen = set()
    for v in values:
        key = f"initial.{v.joint}"
        if v.joint not in joints:
            raise MechanismError(key, f"unknown joint (joints: {', '.join(sorted(joints))})")
        if v.joint in seen:
            raise MechanismError(key, "the joint is given two initial values")
        if v.joint in {d.joint for d in mech.drives}:
            raise MechanismError(key, "the joint's motion is prescribed by a drive; its state is not free")
        if not (np.isfinite(v.value) and np.isfinite(v.rate)):
            raise MechanismError(key, f"value {v.value!r} and rate {v.rate!r} must be finite")
        seen.add(v.joint)


def _mobility(mech: Mechanism, values: Sequence[InitialValue], pose: Mapping[str, BodyPose], t0: float) -> Structure:
    """Assemble the joints alone near the pose and count the degrees of
    freedom the prescribed drives leave; refuses too few or too many values."""
    c = Constraints(with_coordinates(mech, [v.joint for v in values]))
    scaling = Scaling(c, mechanism_size(mech))
    joint_rows = np.array([k for k, row in enumerate(c.rows) if row.kind != "drive"], dtype=int)
    q = gauss_newton(c, scaling, initial_guess(c, pose), t0, joint_rows, "assembly", "the joints")
    Js = scaling.jacobian(c.jacobian(q[None])[0])
    joint_rank = rank(Js[joint_rows]) if joint_rows.size else 0
    mobility = c.n - joint_rank
    free = mobility - len(mech.drives)
    counts = (f"the {len(joint_rows)} joint equations in {c.n} coordinates have rank {joint_rank}: mobility "
              f"{mobility}, {len(mech.drives)} prescribed by drives")
    if len(values) != free:
        few = "too few" if len(values) < free else "too many"
        raise MechanismError("initial", f"{few} initial values: {len(values)} given for {free} degree"
                                        f"{'s' if free != 1 else ''} of freedom ({counts}); state one joint "
                                        "angle (or slide) and rate per degree of freedom")
    full_rank = rank(Js)
    if full_rank < c.n:
        raise MechanismError("initial", f"inconsistent initial state: the joints {', '.join(v.joint for v in values)} "
                                        f"do not fix the configuration (with their coordinates the Jacobian has "
                                        f"rank {full_rank} < {c.n}; {counts}): one of them is determined by the others")
    grubler = 3 * len(mech.bodies) - 2 * len(mech.joints)
    return Structure(grubler, joint_rank, mobility, full_rank, c.m)


def consistent_state(mech: Mechanism, values: Sequence[InitialValue], pose: Mapping[str, BodyPose],
                     t0: float = 0.0) -> InitialState:
    """Assemble the state at t0 from the stated values (module docstring)."""
    _check_values(mech, values)
    found = _mobility(mech, values, pose, t0)
    laws = [DriveLaw(v.value - v.rate * t0, v.rate) for v in values]
    c = Constraints(with_coordinates(mech, [v.joint for v in values], laws))
    scaling = Scaling(c, mechanism_size(mech))
    stated = ", ".join(f"{v.joint} at {v.value:.6g}" for v in values)
    q = gauss_newton(c, scaling, initial_guess(c, pose), t0, np.arange(c.m), "initial",
                     f"the joints with {stated} (an inconsistent initial state)")
    t = np.array([t0])
    f = c.frames(q[None])
    tree = Tree.of(c)
    factor = Factor(c, tree, f, c.jacobian(q[None], f, tuple(int(r) for r in tree.cut), instants_last=True), scaling.row,
                    scaling.column, t)
    condition = float(factor.condition()[0])
    if condition > SINGULAR_CONDITION:
        raise MechanismError("initial", f"inconsistent initial state: at {stated} the stated coordinates cannot "
                                        f"move the mechanism (Jacobian condition {condition:.3g} > "
                                        f"{SINGULAR_CONDITION:.0e}: a toggle or dead-centre position of those joints)")
    v = solve_one(c.jacobian(q[None], f)[0], c.velocity_rhs(t)[0], scaling.row, scaling.column)
    z = np.array([float(v_.value) for v_ in values])
    zdot = np.array([float(v_.rate) for v_ in values])
    return InitialState(t0, q, v, z, zdot, found)
