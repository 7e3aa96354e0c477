"""Pinocchio findings and their probes (`mechval.records.findings`).

The probe builds a three-joint tree (a crank and a slider on the ground, a
conrod on the crank) in the order the joints are added, takes the mass
matrix from `crba` and compares it with the exact one, column k being
`rnea(q, 0, e_k) − rnea(q, 0, 0)` (rnea is recursive over each joint's
parent, so the order does not matter to it; `aba` agrees with it too).
"""

from __future__ import annotations

import importlib.metadata

import numpy as np
import pinocchio as pin

from mechval.records.findings import Finding, Measurement

ENGINE = "pinocchio"

BREADTH_FIRST_TREE = Finding(
    key="pinocchio.breadth-first-tree",
    engine=ENGINE,
    title="A tree added breadth-first: crba and constraintDynamics drop mass-matrix couplings",
    wrong=("Model.addJoint accepts joints in any order whose parents come first, but crba, and with it "
           "constraintDynamics, take each joint's subtree to be the joints that follow it. Added "
           "breadth-first (a second ground joint between a joint and its child), the mass matrix silently "
           "loses the coupling between the two: on the slider-crank built that way the crank torque came "
           "out 115 % of its peak off while the motion and the other reactions were right. "
           "Model.check(data) returns False for such a model, but nothing calls it."),
    how=("A crank (1 kg, centre of mass 0.05 m, izz 1e-3 kg·m²) and a slider (0.5 kg) on the ground, a "
         "conrod (2 kg, centre of mass 0.2 m from the crank pin 0.1 m out, izz 0.03 kg·m²) on the crank, "
         "added in the order crank, slider, conrod; q = (0.4 rad, 0.1 m, −0.7 rad). The exact mass "
         "matrix's column k is rnea(q, 0, e_k) − rnea(q, 0, 0)."),
    figure="max |M crba − M exact| / max |M exact|",
    present_above=1e-6,
    since="4.1.0 (earliest measured)",
    workaround="add the joints depth-first (mechval does, and checks Model.check(data))",
)

FINDINGS = (BREADTH_FIRST_TREE,)


def breadth_first_chain() -> tuple[pin.Model, np.ndarray]:
    """The probe's model, added breadth-first, and its configuration."""
    model = pin.Model()
    inertia = lambda mass, com, izz: pin.Inertia(mass, np.array([com, 0.0, 0.0]), np.diag([0.0, 0.0, izz]))
    crank = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "crank")
    model.appendBodyToJoint(crank, inertia(1.0, 0.05, 1e-3), pin.SE3.Identity())
    slider = model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "slider")
    model.appendBodyToJoint(slider, inertia(0.5, 0.0, 1e-4), pin.SE3.Identity())
    conrod = model.addJoint(crank, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array([0.1, 0.0, 0.0])), "conrod")
    model.appendBodyToJoint(conrod, inertia(2.0, 0.2, 0.03), pin.SE3.Identity())
    model.gravity = pin.Motion.Zero()
    return model, np.array([0.4, 0.1, -0.7])


def mass_matrices(model: pin.Model, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(crba's mass matrix, the exact one from rnea's columns)."""
    data = model.createData()
    upper = pin.crba(model, data, q)
    crba = np.triu(upper) + np.triu(upper, 1).T      # crba fills the upper triangle
    zero = np.zeros(model.nv)
    bias = pin.rnea(model, data, q, zero, zero)         # gravity, if any
    exact = np.column_stack([pin.rnea(model, data, q, zero, e) - bias for e in np.eye(model.nv)])
    return crba, exact


def probe_breadth_first_tree() -> Measurement:
    """BREADTH_FIRST_TREE on the installed version (read and exact: the
    crank–conrod entry of the mass matrix)."""
    crba, exact = mass_matrices(*breadth_first_chain())
    figure = float(np.abs(crba - exact).max() / np.abs(exact).max())
    return Measurement(BREADTH_FIRST_TREE, importlib.metadata.version("pin"), figure, float(crba[0, 2]),
                       float(exact[0, 2]))


PROBES = {BREADTH_FIRST_TREE.key: probe_breadth_first_tree}
