"""Andrews' squeezing mechanism as a `Mechanism`, with its published data.

The problem `andrews` of the Test Set for IVP Solvers (Mazzia, Magherini et
al., Bari; E. Hairer, G. Wanner, *Solving Ordinary Differential Equations
II*, 2nd ed., §VII.7, formula (7.11); W. Schiehlen (ed.),
*Multibody Systems Handbook*, 1990). Every number below is copied from the
Test Set's own source as shipped by the R package deTestSet, in the public
repository rforge/bvpsolve:

- `pkg/deTestSet/R/ex_andrews.R` (the `parameter` vector and `yini`): the
  model constants and the consistent initial state at t = 0 (q, q̇ = 0,
  q̈, λ), given there to 30 digits;
- `pkg/deTestSet/src/Ex_andrews.f` ("derived from the Test Set for IVP
  solvers … andrews.F,v 1.2 2006/10/02"; subroutine `andfunc` for the
  model, subroutine `andsoln` for the solution y(1…27) at t = 0.03 s,
  "computed at Cray C90 … using PSIDE" with tolerances 1e-14).

The Test Set's coordinates are q = (β, Θ, γ, Φ, δ, Ω, ε): β the angle of
the crank K1 at O = (0, 0), Θ that of K2 relative to K1, γ of K3 at B,
δ of K5 at A and Φ of K4 relative to K5, ε of K7 at A and Ω of K6 relative
to K7. Its constraints g(q) = 0 close three loops at the point E where K2
meets K3, K4 and K6 (g1,2: K2's E = K3's E; g3,4: K2's E = K4's E; g5,6:
K2's E = K6's E, each as K2's point minus the other's), and its equations
of motion are M·q̈ = f − gqᵀ·λ. So (λ1, λ2) is the force BY K2 ON K3 at E,
(λ3, λ4) BY K2 ON K4 and (λ5, λ6) BY K2 ON K6, in world axes: exactly the
Fij of joints E3, E4 and E6 below (docs/conventions.md).

Body frames here: each at the body's pivot, turned by its absolute angle
(K1: β, K2: β + Θ, K3: γ, K4: Φ + δ, K5: δ, K6: Ω + ε, K7: ε), so that the
points of `andfunc` sit at fixed body coordinates. The model fixes where
the centres of mass of K2, K4 and K6 lie (on their lines, at da, e − ea and
zf − fa from their pivots) but, for the bodies pivoted at the ground (K1,
K3, K5, K7), only their distance from the pivot (m1·ra², m3·(sa² + sb²),
…): without gravity the motion and the multipliers depend on nothing else.
Their direction here (the first coordinate along the body's line to its
other joint, the second across it) only changes the ground pivots'
reactions, which the Test Set does not publish.

The spring (c0, l0) joins K3's point D to the ground point C. The motor
torque mom = 0.033 N·m drives K1; here it is the drive's torque: the drive
prescribes β(t), and since the published motion is the free motion under
mom, the drive must supply exactly mom.
"""

from __future__ import annotations

import numpy as np

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND, Body, BodyPose, Drive, Joint, Mechanism, SpringDamper

# pkg/deTestSet/R/ex_andrews.R, `parameter` (SI units).
m1, m2, m3, m4, m5, m6, m7 = .04325, .00365, .02373, .00706, .07050, .00706, .05498
xa, ya, xb, yb, xc, yc, c0 = -.06934, -.00227, -0.03635, .03273, .014, .072, 4530.0
i1, i2, i3, i4, i5, i6, i7 = 2.194e-6, 4.410e-7, 5.255e-6, 5.667e-7, 1.169e-5, 5.667e-7, 1.912e-5
d, da, e, ea, rr, ra, l0 = 28e-3, 115e-4, 2e-2, 1421e-5, 7e-3, 92e-5, 7785e-5
ss, sa, sb, sc, sd = 35e-3, 1874e-5, 1043e-5, 18e-3, 2e-2
ta, tb, u, ua, ub = 2308e-5, 916e-5, 4e-2, 1228e-5, 449e-5
zf, zt, fa, mom = 2e-2, 4e-2, 1421e-5, 33e-3

# pkg/deTestSet/R/ex_andrews.R, `yini`: q, q̈ (q̇ = 0) and λ at t = 0.
Q0 = np.array([-0.0617138900142764496358948458001, 0.0, 0.455279819163070380255912382449,
               0.222668390165885884674473185609, 0.487364979543842550225598953530,
               -0.222668390165885884674473185609, 1.23054744454982119249735015568])
QDOT0 = np.zeros(7)
QDDOT0 = np.array([14222.4439199541138705911625887, -10666.8329399655854029433719415, 0, 0, 0, 0, 0])
LAMBDA0 = np.array([98.5668703962410896057654982170, -6.12268834425566265503114393122, 0, 0, 0, 0])

# pkg/deTestSet/src/Ex_andrews.f, subroutine andsoln: y(1…27) at t = 0.03 s.
T1 = 0.03
_Y1 = np.array([
    0.1581077119629904e+2, -0.1575637105984298e+2, 0.4082224013073101e-1, -0.5347301163226948e+0,
    0.5244099658805304e+0, 0.5347301163226948e+0, 0.1048080741042263e+1, 0.1139920302151208e+4,
    -0.1424379294994111e+4, 0.1103291221937134e+2, 0.1929337464421385e+2, 0.5735699284790808e+0,
    -0.1929337464421385e+2, 0.3231791658026955e+0, -0.2463176316945196e+5, 0.5185037701610329e+5,
    0.3241025686413781e+6, 0.5667493645176213e+6, 0.1674362929479361e+5, -0.5667493645176222e+6,
    0.9826520791458422e+4, 0.1991753333731910e+3, -0.2975531228015052e+2, 0.2306654119098399e+2,
    0.3145271365475927e+2, 0.2264249232082739e+2, 0.1161740700019673e+2])
Q1, QDOT1, QDDOT1, LAMBDA1 = _Y1[:7], _Y1[7:14], _Y1[14:21], _Y1[21:]

BODIES = ("K1", "K2", "K3", "K4", "K5", "K6", "K7")
#: Joints whose Fij are (λ1, λ2), (λ3, λ4), (λ5, λ6).
LAMBDA_JOINTS = ("E3", "E4", "E6")


def absolute_angles(q: np.ndarray) -> dict[str, float]:
    """Body angles (K1 … K7) of the Test Set's coordinates q."""
    beta, theta, gamma, phi, delta, omega, eps = q
    return dict(K1=beta, K2=beta + theta, K3=gamma, K4=phi + delta, K5=delta, K6=omega + eps, K7=eps)


def test_set_coordinates(raw, quantity: str = "theta") -> np.ndarray:
    """The Test Set's q (or q̇, q̈ with quantity "omega", "alpha") from the
    raw columns of the K1 … K7 frames: shape (7, instants)."""
    k = {b: np.asarray(raw[f"{b}.{quantity}"]) for b in BODIES}
    return np.array([k["K1"], k["K2"] - k["K1"], k["K3"], k["K4"] - k["K5"], k["K5"], k["K6"] - k["K7"], k["K7"]])


def local_law(t0: float, q: np.ndarray, qdot: np.ndarray, qddot: np.ndarray) -> DriveLaw:
    """The drive law with β(t0), β̇(t0), β̈(t0) as published: β(t) = β0 +
    β̇0·(t − t0) + ½·β̈0·(t − t0)² written as φ0 + ω0·t + ½·α·t²."""
    b, bd, bdd = q[0], qdot[0], qddot[0]
    return DriveLaw(phi0=b - bd * t0 + 0.5 * bdd * t0 * t0, omega0=bd - bdd * t0, alpha=bdd)


def pose_near(q: np.ndarray, decimals: int = 2) -> dict[str, BodyPose]:
    """An approximate assembly pose: the body angles of q rounded."""
    return {b: BodyPose(round(float(angle), decimals)) for b, angle in absolute_angles(q).items()}


def _no_closed_form(t):
    raise NotImplementedError("Andrews' squeezer has no closed-form motion; solve it with mechval.reference.planar.solver")


def andrews_mechanism(law: DriveLaw | None = None, pose: dict[str, BodyPose] | None = None) -> Mechanism:
    """The squeezer, driven at β by `law` (default: the published β, β̇, β̈
    at t = 0), assembled near `pose` (default: the published angles at t = 0
    rounded to 0.01 rad)."""
    bodies = (
        Body("K1", m1, (ra, 0.0), i1),
        Body("K2", m2, (-da, 0.0), i2),
        Body("K3", m3, (sb, -sa), i3),
        Body("K4", m4, (0.0, -(e - ea)), i4),
        Body("K5", m5, (ta, tb), i5),
        Body("K6", m6, (zf - fa, 0.0), i6),
        Body("K7", m7, (ub, -ua), i7),
    )
    joints = (
        Joint("O", "revolute", GROUND, "K1", (0.0, 0.0), (0.0, 0.0)),
        Joint("F", "revolute", "K1", "K2", (rr, 0.0), (0.0, 0.0)),
        Joint("B", "revolute", GROUND, "K3", (xb, yb), (0.0, 0.0)),
        Joint("A5", "revolute", GROUND, "K5", (xa, ya), (0.0, 0.0)),
        Joint("A7", "revolute", GROUND, "K7", (xa, ya), (0.0, 0.0)),
        Joint("H", "revolute", "K5", "K4", (zt, 0.0), (0.0, 0.0)),
        Joint("G", "revolute", "K7", "K6", (0.0, -u), (0.0, 0.0)),
        Joint("E3", "revolute", "K2", "K3", (-d, 0.0), (0.0, -ss)),
        Joint("E4", "revolute", "K2", "K4", (-d, 0.0), (0.0, -e)),
        Joint("E6", "revolute", "K2", "K6", (-d, 0.0), (zf, 0.0)),
    )
    law = law or local_law(0.0, Q0, QDOT0, QDDOT0)
    return Mechanism(
        name="andrews", kind="planar", bodies=bodies, joints=joints, drive=Drive("O", law), gravity=(0.0, 0.0),
        motion=_no_closed_form, signal_map={},
        forces=(SpringDamper("spring", "K3", (sd, -sc), GROUND, (xc, yc), c0, l0),),
        assembly_pose=pose or pose_near(Q0),
    )
