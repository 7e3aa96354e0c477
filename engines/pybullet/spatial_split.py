"""Where a loop can only close at a joint no PyBullet user constraint makes
(a universal joint between two driven legs: the delta robot), mechval
closes it inside a body instead (`plan`): the body is built as two halves,
each with half its mass and half its inertia tensor about the same centre
of mass (together exactly the body), the awkward joint hung on the second
half (its "twin", named BODY~) as a multibody joint, and the halves welded
by a fixed user constraint (6 rows; PyBullet reports its load on the
constraint's parent, the force in world axes, the moment about the pivot
in the parent's centre-of-mass axes: measured, `spatial.Stepper`). The body's motion
is read from its first half; the weld's load enters the halves' balances
(`spatial_reactions`), never the output.
"""

from __future__ import annotations

import dataclasses

from mechval.engines.base import Unrepresentable
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.system import SpatialJoint, SpatialSystem

#: Suffixes of a split body's second half and of its weld joint.
TWIN, WELD = "~", "~weld"


def twin_of(body: str) -> str:
    return body + TWIN


def is_weld(joint: SpatialJoint) -> bool:
    return joint.name.endswith(WELD)


def plan(system: SpatialSystem, closable, cuts_of) -> tuple[SpatialSystem, dict[str, str]]:
    """The system PyBullet builds ({twin: body} of the bodies split): each
    loop whose cut (`cuts_of`) cannot close (`closable` False) is closed in
    one of the cut joint's bodies instead; a body split once only."""
    twins: dict[str, str] = {}
    while True:
        bad = [j for j in cuts_of(system) if not closable(system, j)]
        if not bad:
            return system, twins
        joint = bad[0]
        body = next((b for b in (joint.body_i, joint.body_j) if b != GROUND and b not in twins.values()
                     and b not in twins), None)
        if body is None or any(d.joint == joint.name for d in system.drives):
            raise Unrepresentable(f"joint.{joint.name}.kind",
                                  f"a {joint.kind} joint closes a loop, and PyBullet 3.2.7's user constraints "
                                  "between multibodies are fixed, point-to-point, slider and gear only; no body "
                                  "of it is left to close the loop in")
        system = _split(system, body, joint)
        twins[twin_of(body)] = body


def _split(system: SpatialSystem, body: str, joint: SpatialJoint) -> SpatialSystem:
    whole = system.body(body)
    half = dataclasses.replace(whole, mass=whole.mass / 2, inertia=whole.inertia / 2)
    twin = dataclasses.replace(half, name=twin_of(body))
    bodies = tuple(half if b.name == body else b for b in system.bodies) + (twin,)
    moved = dataclasses.replace(joint, body_i=twin.name if joint.body_i == body else joint.body_i,
                                body_j=twin.name if joint.body_j == body else joint.body_j)
    weld = SpatialJoint(body + WELD, "fixed", body, twin.name, whole.com, whole.com)
    joints = tuple(moved if j.name == joint.name else j for j in system.joints) + (weld,)
    velocities = dict(system.velocities)
    if body in velocities:
        velocities[twin.name] = velocities[body]
    return dataclasses.replace(system, bodies=bodies, joints=joints, velocities=velocities)
