"""Norton's 9×9 four-bar system, written out independently of mechval's
generic Newton–Euler assembly (R. L. Norton, *Design of Machinery*, §11.5,
eqs. 11.8–11.9), with the weights added to the right-hand sides.

Used as an independent check of the reference and as the per-instant loop
the reference benchmark compares against (the published study's method:
build and solve the 9×9 system at every instant).
"""

from __future__ import annotations

import numpy as np

UNKNOWNS = ("F12x", "F12y", "F32x", "F32y", "F43x", "F43y", "F14x", "F14y", "T12")


def cross(r, f) -> float:
    return r[0] * f[1] - r[1] * f[0]


def norton_system(k: dict, m2, m3, m4, I2, I3, I4, g=(0.0, 0.0), a=0.25, b=0.5, c=0.5, d=0.6,
                  com=(None, None, None)):
    """A, rhs of eq. 11.9 at one instant from θ, ω, α of links 2–4 (floats).

    Position vectors from each link's centre of mass to its pins (Norton's
    R12, R32, R23, R43, R34, R14); centres of mass at `com` along each link
    from its first pin (mid-length when None).
    """
    th2, th3, th4 = k["theta2"], k["theta3"], k["theta4"]
    w2, w3, w4 = k["omega2"], k["omega3"], k["omega4"]
    al2, al3, al4 = k["alpha2"], k["alpha3"], k["alpha4"]
    p2, p3, p4 = (x if x is not None else L / 2 for x, L in zip(com, (a, b, c)))
    e = lambda th: np.array([np.cos(th), np.sin(th)])
    A = a * e(th2)
    G2, G3, G4 = p2 * e(th2), A + p3 * e(th3), np.array([d, 0.0]) + p4 * e(th4)
    B = A + b * e(th3)
    R12, R32 = -G2, A - G2
    R23, R43 = A - G3, B - G3
    R34, R14 = B - G4, np.array([d, 0.0]) - G4
    jx = lambda th: np.array([-np.sin(th), np.cos(th)])
    aA = a * (al2 * jx(th2) - w2**2 * e(th2))
    aG2 = p2 * (al2 * jx(th2) - w2**2 * e(th2))
    aG3 = aA + p3 * (al3 * jx(th3) - w3**2 * e(th3))
    aG4 = p4 * (al4 * jx(th4) - w4**2 * e(th4))
    M = np.zeros((9, 9))
    M[0, [0, 2]] = 1
    M[1, [1, 3]] = 1
    M[2] = [-R12[1], R12[0], -R32[1], R32[0], 0, 0, 0, 0, 1]
    M[3, [2, 4]] = [-1, 1]
    M[4, [3, 5]] = [-1, 1]
    M[5] = [0, 0, R23[1], -R23[0], -R43[1], R43[0], 0, 0, 0]
    M[6, [4, 6]] = [-1, 1]
    M[7, [5, 7]] = [-1, 1]
    M[8] = [0, 0, 0, 0, R34[1], -R34[0], -R14[1], R14[0], 0]
    g = np.asarray(g)
    rhs = np.concatenate([m2 * (aG2 - g), [I2 * al2], m3 * (aG3 - g), [I3 * al3], m4 * (aG4 - g), [I4 * al4]])
    return M, rhs
