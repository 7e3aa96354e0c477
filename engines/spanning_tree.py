"""The loops' cut joints of a mechanism (planar, or a spatial scene's
`SpatialSystem`: both have bodies and joints between named bodies), as
the adapters that build a spanning tree of joints and close each loop by
a constraint choose them; and a tree joint's direction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from mechval.model.mechanism import GROUND, Joint, Mechanism


def cut_joints(mech: Mechanism, rank: Callable[[Joint], object]) -> list[Joint]:
    """The joints left out of a spanning tree grown greedily (Kruskal) over
    the joints sorted by `rank` (stable: the file's order within a rank):
    one per independent loop, each closing the loop its tree path makes.
    An adapter ranks first what must be a tree coordinate (a drive, a
    slide), so that the cuts fall on what its constraint can close."""
    group = {name: name for name in [GROUND] + [b.name for b in mech.bodies]}

    def root(name: str) -> str:
        while group[name] != name:
            name = group[name]
        return name

    cuts = []
    for j in sorted(mech.joints, key=rank):
        a, b = root(j.body_i), root(j.body_j)
        if a == b:
            cuts.append(j)
        else:
            group[a] = b
    return cuts


@dataclass(frozen=True)
class TreeJoint:
    """A scene joint (planar or spatial) as a tree joint from `parent` to
    `child`: the engine's coordinate is body_j's motion relative to body_i
    when the child is body_j (`sign` +1), the reverse otherwise (−1)."""

    joint: Any
    parent: str
    child: str

    @property
    def sign(self) -> float:
        return 1.0 if self.child == self.joint.body_j else -1.0
