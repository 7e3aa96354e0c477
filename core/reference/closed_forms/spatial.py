"""Closed forms of spatial mechanisms and rigid bodies, for checking the
spatial reference (`mechval.reference.spatial`) against something it did
not compute. Each is derived in its docstring from the geometry alone;
angles in rad, SI units.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ellipj, ellipk


def _cos_sin_equation(A, B, C, branch: int) -> np.ndarray:
    """ψ with A·cos ψ + B·sin ψ = C on the branch ±1 (the classic
    half-angle-free solution: ψ = atan2(B, A) ± acos(C/√(A² + B²)))."""
    r = np.hypot(A, B)
    if np.any(np.abs(C) > r * (1 + 1e-12)):
        raise ValueError("the loop cannot close at some input angle")
    return np.arctan2(B, A) + branch * np.arccos(np.clip(C / r, -1.0, 1.0))


def spherical_fourbar_output(theta, alpha1: float, alpha2: float, alpha3: float, alpha4: float,
                             branch: int = 1) -> np.ndarray:
    """Output angle ψ of a spherical four-bar (all four revolute axes meet
    at the centre O) at input angle θ.

    Fixed axes u = ẑ (input) and w = Ry(α1)·ẑ (output), the moving
    axes v(θ) = (sin α2 cos θ, sin α2 sin θ, cos α2) on the input link and
    s(ψ) = Ry(α1)·(sin α4 cos ψ, sin α4 sin ψ, cos α4) on the output link;
    the coupler keeps v·s = cos α3, so (expanding)
    A·cos ψ + B·sin ψ = C with
    A = sin α2 sin α4 cos α1 cos θ − cos α2 sin α4 sin α1,
    B = sin α2 sin α4 sin θ,
    C = cos α3 − sin α2 cos α4 sin α1 cos θ − cos α2 cos α4 cos α1:
    the input–output equation of the spherical 4R chain (Chiang,
    *Kinematics of Spherical Mechanisms*, 1988; McCarthy & Soh, *Geometric
    Design of Linkages*, 2nd ed. 2011, ch. 7)."""
    theta = np.asarray(theta, dtype=float)
    s1, c1, s2, c2, s4, c4 = (np.sin(alpha1), np.cos(alpha1), np.sin(alpha2), np.cos(alpha2),
                              np.sin(alpha4), np.cos(alpha4))
    A = s2 * s4 * c1 * np.cos(theta) - c2 * s4 * s1
    B = s2 * s4 * np.sin(theta)
    C = np.cos(alpha3) - s2 * c4 * s1 * np.cos(theta) - c2 * c4 * c1
    return _cos_sin_equation(A, B, C, branch)


def rssr_output(theta, a: float, b: float, length: float, centre, e1, e2, branch: int = 1) -> np.ndarray:
    """Output angle ψ of an RSSR linkage at input angle θ.

    The input crank turns about ẑ through the origin, its ball at
    P = a·(cos θ, sin θ, 0); the output crank turns about e1 × e2 through
    `centre` C, its ball at Q = C + b·(cos ψ·e1 + sin ψ·e2) (e1, e2
    orthonormal). The coupler keeps |Q − P| = ℓ, which expands to
    A·cos ψ + B·sin ψ = D with A = 2b·(C − P)·e1, B = 2b·(C − P)·e2,
    D = ℓ² − |C − P|² − b² (the RSSR displacement equation, Suh &
    Radcliffe, *Kinematics and Mechanisms Design*, 1978)."""
    theta = np.asarray(theta, dtype=float)
    P = a * np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=-1)
    d = np.asarray(centre, dtype=float) - P
    A, B = 2 * b * d @ np.asarray(e1, float), 2 * b * d @ np.asarray(e2, float)
    D = length ** 2 - np.einsum("...i,...i->...", d, d) - b ** 2
    return _cos_sin_equation(A, B, D, branch)


def bennett_angle(theta1, alpha: float, beta: float) -> np.ndarray:
    """θ2 of a Bennett linkage at θ1 (Bennett, "A new mechanism",
    *Engineering* 76, 1903; McCarthy & Soh 2011, ch. 9): links 1 and 3 of
    length a and twist α, links 2 and 4 of length b and twist β with
    a/sin α = b/sin β, Denavit–Hartenberg joint angles θ1 … θ4, closed
    by θ3 = −θ1, θ4 = −θ2 and tan(θ1/2)·tan(θ2/2) = sin((β + α)/2) /
    sin((β − α)/2). (tests check the DH loop product is the identity.)"""
    theta1 = np.asarray(theta1, dtype=float)
    ratio = np.sin((beta + alpha) / 2) / np.sin((beta - alpha) / 2)
    return 2 * np.arctan2(ratio * np.cos(theta1 / 2), np.sin(theta1 / 2))


def dh_transform(theta: float, a: float, alpha: float) -> np.ndarray:
    """Rz(θ)·Tx(a)·Rx(α), the Denavit–Hartenberg link transform with d = 0."""
    c, s, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0, sa, ca, 0], [0, 0, 0, 1.0]])


def torque_free_omega(t, inertia, omega0_scale: tuple[float, float], energy: float, momentum: float) -> np.ndarray:
    """Body-axes angular velocity of a torque-free rigid body, Euler's
    equations solved in Jacobi elliptic functions (Landau & Lifshitz,
    *Mechanics*, 3rd ed., §37, eqs. 37.10–37.12).

    Principal moments I1 < I2 < I3, energy E and |L| = M with
    M² > 2E·I2 (the body tumbles about axis 3; for M² < 2E·I2 pass the
    moments in reverse order and read the components reversed): with
    τ = t·√((I3 − I2)(M² − 2E·I1)/(I1·I2·I3)) and modulus
    k² = (I2 − I1)(2E·I3 − M²)/((I3 − I2)(M² − 2E·I1)),
    ω1 = √((2E·I3 − M²)/(I1(I3 − I1)))·cn τ,
    ω2 = √((2E·I3 − M²)/(I2(I3 − I2)))·sn τ,
    ω3 = √((M² − 2E·I1)/(I3(I3 − I1)))·dn τ,
    so ω2 = 0 at t = 0 and ω1, ω3 > 0. `omega0_scale` signs (ω1, ω3)."""
    I1, I2, I3 = inertia
    E2, M2 = 2 * energy, momentum ** 2
    tau = np.asarray(t, dtype=float) * np.sqrt((I3 - I2) * (M2 - E2 * I1) / (I1 * I2 * I3))
    k2 = (I2 - I1) * (E2 * I3 - M2) / ((I3 - I2) * (M2 - E2 * I1))
    sn, cn, dn, _ = ellipj(tau, k2)
    return np.stack([omega0_scale[0] * np.sqrt((E2 * I3 - M2) / (I1 * (I3 - I1))) * cn,
                     omega0_scale[0] * omega0_scale[1] * np.sqrt((E2 * I3 - M2) / (I2 * (I3 - I2))) * sn,
                     omega0_scale[1] * np.sqrt((M2 - E2 * I1) / (I3 * (I3 - I1))) * dn], axis=-1)


def torque_free_quarter_period(inertia, energy: float, momentum: float) -> float:
    """The time K(k)/rate from ω2 = 0 to ω2's extreme (`torque_free_omega`)."""
    I1, I2, I3 = inertia
    E2, M2 = 2 * energy, momentum ** 2
    rate = np.sqrt((I3 - I2) * (M2 - E2 * I1) / (I1 * I2 * I3))
    return float(ellipk((I2 - I1) * (E2 * I3 - M2) / ((I3 - I2) * (M2 - E2 * I1))) / rate)


def top_precession_rates(tilt: float, spin: float, mass: float, arm: float, gravity: float,
                         transverse: float, axial: float) -> tuple[float, float]:
    """Slow and fast steady precession rates Ω of a heavy symmetric top
    on a fixed point: its axis e3 at `tilt` θ from the upward vertical,
    centre of mass `arm` l up the axis, moments about the fixed point A
    (transverse) and C (axial), spin ω3 = ω·e3. The configuration turns
    rigidly about ẑ at Ω, so dL/dt = Ω ẑ × L with
    L = A·Ω(ẑ − cos θ·e3) + C·ω3·e3; equal to the gravity moment
    m·g·l ẑ × e3: A·cos θ·Ω² − C·ω3·Ω + m·g·l = 0 (Goldstein, *Classical
    Mechanics*, 3rd ed., §5.7, eq. 5.76)."""
    a, b, c = transverse * np.cos(tilt), -axial * spin, mass * gravity * arm
    root = np.sqrt(b * b - 4 * a * c)
    return float((-b - root) / (2 * a)), float((-b + root) / (2 * a))


def delta_arm_angle(platform, base_radius: float, platform_radius: float, arm: float, rod: float,
                    leg_angle: float, branch: int = -1) -> np.ndarray:
    """Inverse kinematics of one leg of a delta robot whose platform
    translates: the arm angle θ (down from the horizontal) that puts the
    elbow B = A + arm·(cos θ·e − sin θ·ẑ) at `rod` from the platform's
    joint C = p + platform_radius·e, with A = base_radius·e and
    e = (cos φ, sin φ, 0) the leg's radial direction. |B − C|² = rod²
    expands, with D = C − A, to (e·D)·cos θ − D_z·sin θ =
    (arm² + |D|² − rod²)/(2·arm) (Clavel's delta; e.g. Williams, "The
    Delta Parallel Robot: Kinematics Solutions", 2016, and any text on it).
    `platform` (..., 3); branch −1 is the elbow out."""
    p = np.asarray(platform, dtype=float)
    e = np.array([np.cos(leg_angle), np.sin(leg_angle), 0.0])
    D = p + (platform_radius - base_radius) * e
    C = (arm ** 2 + np.einsum("...i,...i->...", D, D) - rod ** 2) / (2 * arm)
    return _cos_sin_equation(D @ e, -D[..., 2], C, branch)
