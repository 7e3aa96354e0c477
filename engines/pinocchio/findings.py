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

MASSLESS_WELDED_JOINT = Finding(
    key="pinocchio.massless-welded-joint",
    engine=ENGINE,
    title="constraintDynamics returns NaN for a joint with no inertia, though its constraints determine it",
    wrong=("A joint that carries no body, welded by a CONTACT_6D constraint to a body whose motion the rest "
           "of the model determines, makes the KKT system regular (the mass matrix is positive definite on "
           "the constraints' null space), but constraintDynamics returns NaN for every acceleration, with "
           "no error, at any proximal μ (1e-8, 1e-4, 1e-2 and 1 measured); 1e-12 kg on the joint gives the "
           "exact answer. A user closing a "
           "loop through a massless intermediate frame (a universal joint's cross) gets NaN."),
    how=("A pendulum on a ground RZ joint (1 kg, centre of mass 0.5 m along x, 0.01 kg·m² about it), a "
         "second ground RZ joint with no body, welded to the pendulum (CONTACT_6D, LOCAL); gravity 9.81 "
         "m/s² along −y, q = (0.3, 0.3) rad at rest, ProximalSettings(1e-12, 1e-8, 50). Exact: the "
         "pendulum's −m·g·x_G·cos q / (I_G + m·x_G²) for both coordinates."),
    figure="|q̈ read − q̈ exact| / |q̈ exact| of the pendulum (inf when NaN)",
    present_above=1e-6,
    since="4.1.0 (earliest measured)",
    workaround="give the intermediate joint 1e-9 of the scene's inertia (mechval's spatial carriers)",
)

FINDINGS = (BREADTH_FIRST_TREE, MASSLESS_WELDED_JOINT)


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


def welded_pendulum(carrier_mass: float = 0.0, q: float = 0.3) -> tuple[float, float]:
    """MASSLESS_WELDED_JOINT's model: (the pendulum's q̈ read, exact)."""
    mass, arm, inertia = 1.0, 0.5, 0.01
    model = pin.Model()
    pendulum = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "pendulum")
    model.appendBodyToJoint(pendulum, pin.Inertia(mass, np.array([arm, 0.0, 0.0]), inertia * np.eye(3)),
                            pin.SE3.Identity())
    carrier = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "carrier")
    if carrier_mass:
        model.appendBodyToJoint(carrier, pin.Inertia(carrier_mass, np.zeros(3), carrier_mass * np.eye(3)),
                                pin.SE3.Identity())
    model.gravity = pin.Motion(np.array([0.0, -9.81, 0.0]), np.zeros(3))
    weld = pin.RigidConstraintModel(pin.ContactType.CONTACT_6D, model, carrier, pin.SE3.Identity(), pendulum,
                                    pin.SE3.Identity(), pin.ReferenceFrame.LOCAL)
    constraints, constraint_data = pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
    constraints.append(weld)
    constraint_data.append(weld.createData())
    data = model.createData()
    pin.initConstraintDynamics(model, data, constraints, constraint_data)
    a = pin.constraintDynamics(model, data, np.array([q, q]), np.zeros(2), np.zeros(2), constraints,
                               constraint_data, pin.ProximalSettings(1e-12, 1e-8, 50))
    return float(a[0]), -mass * 9.81 * arm * np.cos(q) / (inertia + mass * arm**2)


def probe_massless_welded_joint() -> Measurement:
    read, exact = welded_pendulum()
    figure = abs(read - exact) / abs(exact) if np.isfinite(read) else float("inf")
    return Measurement(MASSLESS_WELDED_JOINT, importlib.metadata.version("pin"), figure, read, exact)


PROBES = {BREADTH_FIRST_TREE.key: probe_breadth_first_tree, MASSLESS_WELDED_JOINT.key: probe_massless_welded_joint}
