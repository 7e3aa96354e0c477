"""Batched linear solves with the constraint Jacobian, one inversion per
instant (`mechval.planar_solver`).

All solves happen in dimensionless form, Js = Dr·J·Dc (lengths over the
mechanism's size, `planar_positions.Scaling`). `Inverse` holds, per instant,
an approximate inverse taken at one configuration (the continuation's
prediction) and serves every solve at the nearby solution by iterative
refinement (x ← x + B·(r − J·x)): the Newton corrections of the positions,
then Φq·q̇ = −Φt, Φq·q̈ = γ and Φqᵀ·λ = Q − M·q̈.

- Square Jacobian (no redundant constraint): B = Js⁻¹.
- Redundant constraints (m rows > n coordinates, full column rank, the
  equations consistent): B = (JsᵀJs)⁻¹·Jsᵀ, so the refinement converges to
  the exact solution of the consistent system, and Jsᵀ-solves give the
  minimum-norm multipliers Js·(JsᵀJs)⁻¹·f (in scaled units). A multiplier
  row k is undetermined where the projector onto the null space of Jsᵀ,
  I − Js·(JsᵀJs)⁻¹·Jsᵀ, has a nonzero diagonal entry k.
"""

from __future__ import annotations

import numpy as np

from .planar_constraints import MechanismError

#: A refinement or Newton iteration has reached its fixed point when its
#: step is within rounding of the iterate (`ROUNDING`·its largest component),
#: or when the step no longer halves (the noise floor of the residual,
#: cond·eps) while below `STAGNATION` of it.
ROUNDING = 8 * np.finfo(float).eps
STAGNATION = 1e-11
REFINEMENTS = 12


def settled(step: np.ndarray, previous: np.ndarray, floor: np.ndarray | float) -> np.ndarray:
    """Per instant: has the iteration reached its fixed point? (relative
    step sizes of this and the previous iteration, and the rounding floor)."""
    return (step <= floor) | ((step >= 0.5 * previous) & (step <= STAGNATION))


def matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    return (A @ x[..., None])[..., 0]


def solve_one(J: np.ndarray, r: np.ndarray, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """J·x = r at one instant (J (m, n)), exactly (square) or in the
    least-squares sense (redundant: consistent, so exactly too), scaled."""
    Js = J * row[:, None] * col[None, :]
    if Js.shape[0] == Js.shape[1]:
        return col * np.linalg.solve(Js, row * r)
    return col * np.linalg.lstsq(Js, row * r, rcond=None)[0]


class Inverse:
    """B ≈ Js⁻¹ (or the normal-equation pseudo-inverse) per instant, from
    the Jacobians J (instants, m, n) at one configuration."""

    def __init__(self, J: np.ndarray, row: np.ndarray, col: np.ndarray, t: np.ndarray):
        self.row, self.col = row, col
        Js = J * row[:, None] * col[None, :]
        self.square = J.shape[1] == J.shape[2]
        self.Js0 = None if self.square else Js
        normal = Js if self.square else Js.transpose(0, 2, 1) @ Js
        try:
            self.Bs = np.linalg.inv(normal)
        except np.linalg.LinAlgError:
            k = int(np.flatnonzero(np.linalg.matrix_rank(normal) < normal.shape[-1])[0])
            raise MechanismError("time", f"the Jacobian is singular at t = {t[k]:.6g} s (a toggle or dead-centre "
                                         "position: the drives cannot move the mechanism there)") from None

    def apply(self, r: np.ndarray) -> np.ndarray:
        """≈ J⁻¹·r (instants, m) → (instants, n)."""
        rs = r * self.row
        if not self.square:
            rs = matvec(self.Js0.transpose(0, 2, 1), rs)
        return matvec(self.Bs, rs) * self.col

    def apply_transposed(self, f: np.ndarray) -> np.ndarray:
        """≈ J⁻ᵀ·f (instants, n) → (instants, m), the minimum-norm solution
        (scaled) when there are redundant rows."""
        fs = f * self.col
        if self.square:
            return matvec(self.Bs.transpose(0, 2, 1), fs) * self.row
        return matvec(self.Js0, matvec(self.Bs, fs)) * self.row

    def refine(self, J: np.ndarray, r: np.ndarray, weight: np.ndarray, rate: np.ndarray,
               transpose: bool = False) -> np.ndarray:
        """Solve J·x = r (or Jᵀ·x = r) by iterative refinement until the
        error left, the last correction times the contraction bound `rate`
        ≥ ‖I − B·J‖ per instant, is within rounding of the instant's largest
        weighted component of x, or the corrections stagnate. Whole batches
        at a time: gathering the instants still moving would cost more than
        a matrix-vector product."""
        apply = self.apply_transposed if transpose else self.apply
        product = (lambda x: matvec(J.transpose(0, 2, 1), x)) if transpose else (lambda x: matvec(J, x))
        x = apply(r)
        previous = np.full(len(x), np.inf)
        for _ in range(REFINEMENTS):
            dx = apply(r - product(x))
            x += dx
            scale = np.maximum(np.abs(x * weight).max(axis=-1), np.finfo(float).tiny)
            size = np.abs(dx * weight).max(axis=-1) / scale
            done = settled(size, previous, ROUNDING) | (size * rate <= ROUNDING)
            if done.all():
                return x
            previous = size
        late = ~done
        x[late] = self._direct(J[late], r[late], transpose)
        return x

    def _direct(self, J: np.ndarray, r: np.ndarray, transpose: bool) -> np.ndarray:
        """A fresh solve for the instants that did not settle."""
        fresh = Inverse(J, self.row, self.col, np.zeros(len(J)))
        return fresh.apply_transposed(r) if transpose else fresh.apply(r)

    def norm(self) -> np.ndarray:
        """‖B‖∞ in scaled units, per instant (of (JsᵀJs)⁻¹·Jsᵀ when redundant)."""
        B = self.Bs if self.square else self.Bs @ self.Js0.transpose(0, 2, 1)
        return np.abs(B).sum(axis=-1).max(axis=-1)

    def condition(self, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """∞-norm condition number of the scaled Jacobian per instant,
        ‖Js‖·‖B‖, and ‖B‖."""
        norm_J = (self.row * matvec(np.abs(J), self.col)).max(axis=-1)
        norm_B = self.norm()
        return norm_J * norm_B, norm_B

    def undetermined(self, J: np.ndarray, tolerance: float) -> np.ndarray:
        """Per multiplier row, whether the null space of Jᵀ reaches it at
        some instant: the diagonal of I − Js·(JsᵀJs)⁻¹·Jsᵀ, from a fresh
        inverse at J (exact to ~cond²·eps), above `tolerance`."""
        if self.square:
            return np.zeros(J.shape[1], dtype=bool)
        Js = J * self.row[:, None] * self.col[None, :]
        inverse = np.linalg.inv(Js.transpose(0, 2, 1) @ Js)
        leverage = np.einsum("tmi,tij,tmj->tm", Js, inverse, Js)
        return (1.0 - leverage > tolerance).any(axis=0)
