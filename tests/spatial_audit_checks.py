"""What every engine's spatial model audit must see (tests/test_spatial_NAME.py):
a model built for the RSSR linkage, audited against the RSSR with one
centre of mass moved and against it with one bearing tilted."""

from __future__ import annotations

import dataclasses

import numpy as np

from mechval.records.audit import audit, failures
from mechval.records.spatial_audit import expected_spatial
from mechval.reference.spatial.system import SpatialSystem


def assert_the_audit_sees_a_moved_centre_and_a_tilted_axis(system: SpatialSystem, readings) -> None:
    """`readings`: the engine's read-back of a model built for `system` (the
    RSSR). Its coupler's centre of mass moved 1 mm: that row alone differs;
    its output bearing C tilted 1 mrad: exactly the axis rows that change."""
    moved = dataclasses.replace(system.bodies[1], com=tuple(np.add(system.bodies[1].com, (0.0, 0.001, 0.0))))
    other = dataclasses.replace(system, bodies=(system.bodies[0], moved, system.bodies[2]))
    wrong = failures(audit(expected_spatial(other), readings))
    assert list(zip(wrong["item"], wrong["quantity"])) == [("body coupler", "com y")]
    C = system.joint("C")
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(1e-3), -np.sin(1e-3)], [0.0, np.sin(1e-3), np.cos(1e-3)]])
    other = dataclasses.replace(system, joints=tuple(dataclasses.replace(j, frame_i=tilt @ j.frame_i) if j is C else j
                                                     for j in system.joints))
    changed = [(e.item, e.quantity) for e, f in zip(expected_spatial(system), expected_spatial(other))
               if e.value != f.value]
    wrong = failures(audit(expected_spatial(other), readings))
    assert changed and set(changed) <= {("joint C", f"axis i z{c}") for c in "xyz"}
    assert list(zip(wrong["item"], wrong["quantity"])) == changed
