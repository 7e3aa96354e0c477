"""Batched linear solves with the constraint Jacobian by block elimination
along a spanning tree of revolute joints (`mechval.planar_solver`).

The rows Pj − Pi of a revolute joint carry ±I in the two bodies' centre-of-
mass columns. Root a tree at the ground along revolute joints: the rows of
each tree body's parent joint then express that body's centre-of-mass
displacement through its parent's and the angles (unit pivots, no
numerical pivoting), linearised:

    ΔGk = σ·r_p − Δθk·(ẑ × ak) + ΔGπ + Δθπ·(ẑ × aπ)

(p the joint, ak and aπ its arms on body k and on its parent π, σ = ±1 as
k is body_j or body_i of p). What is left is the Schur complement
K = J_Cθ + J_CG·D on the other rows C (cut revolute joints, prismatic
joints, drives) in the angles θ (and the centres of bodies the tree does
not reach), with D = ∂G/∂θ the tree's displacement coefficients: 3×3 for a
four-bar or a slider-crank, 7×7 for Andrews' squeezer, instead of 9×9 and
21×21. Every solve is then this root-to-leaves sweep, one small solve with
K and a back-substitution; a transposed solve (the multipliers) runs the
same elimination backwards, leaves to root — the recursive form of the
free-body balances.

Solves use the scaled K (lengths over the mechanism's size). With redundant
constraints K has more rows than columns and full column rank; solves are
then least squares on the normal equations (the system being consistent,
exact), and multipliers minimum-norm; a multiplier row is undetermined
where the null space of Jᵀ reaches it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .planar_constraints import Constraints, MechanismError
from .planar_linear import inverse, matvec


@dataclass(frozen=True)
class Tree:
    """The spanning tree of revolute joints and the rows it leaves."""

    order: tuple[int, ...]           # tree bodies, parents first
    parent: dict[int, int]           # body → parent body (−1: the ground)
    joint: dict[int, int]            # body → its parent joint's index
    sign: dict[int, float]           # σ: +1 if the body is body_j of that joint
    children: dict[int, tuple[int, ...]]
    ancestors: dict[int, tuple[int, ...]]   # the body itself, then up to the root
    free: tuple[int, ...]            # bodies the tree does not reach
    cut: np.ndarray                  # rows not eliminated (indices into all rows)
    tree_rows: dict[int, int]        # body → first of its parent joint's two rows
    columns: np.ndarray              # full column of each reduced unknown

    @classmethod
    def of(cls, c: Constraints) -> "Tree":
        nb = len(c.bodies)
        revolute = [k for k, j in enumerate(c.mech.joints) if j.kind == "revolute"]
        parent, joint, sign, order = {}, {}, {}, []
        reached = {nb}                                   # the ground
        frontier = [nb]
        while frontier:
            body = frontier.pop(0)
            for k in revolute:
                if k in joint.values():
                    continue
                bi, bj = int(c.bi[k]), int(c.bj[k])
                for here, there, s in ((bi, bj, 1.0), (bj, bi, -1.0)):
                    if here == body and there not in reached:
                        parent[there], joint[there], sign[there] = (-1 if here == nb else here), k, s
                        reached.add(there), order.append(there), frontier.append(there)
        children = {b: tuple(k for k in order if parent[k] == b) for b in order}
        ancestors = {}
        for b in order:
            ancestors[b] = (b,) + (ancestors[parent[b]] if parent[b] >= 0 else ())
        tree_rows = {b: c.first[joint[b]] for b in order}
        used = {r for b in order for r in (tree_rows[b], tree_rows[b] + 1)}
        free = tuple(b for b in range(nb) if b not in parent)
        cut = np.array([r for r in range(c.m) if r not in used], dtype=int)
        columns = np.array([3 * b + 2 for b in range(nb)] + [3 * b + k for b in free for k in (0, 1)], dtype=int)
        return cls(tuple(order), parent, joint, sign, children, ancestors, free, cut, tree_rows, columns)


class Factor:
    """The elimination at one configuration per instant: displacement
    coefficients D, the cut rows' Jacobian, and K's scaled (pseudo-)inverse."""

    def __init__(self, c: Constraints, tree: Tree, frames: dict, J_cut: np.ndarray,
                 row: np.ndarray, col: np.ndarray, t: np.ndarray):
        self.c, self.tree, self.J_cut = c, tree, J_cut
        self.row_cut, self.z_scale = row[tree.cut], col[tree.columns]
        count = len(t)
        # D[(k, l)] = ∂ΔGk/∂Δθl as (x, y) arrays, built from the root down.
        self.D: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        for k in tree.order:
            p, s = tree.joint[k], tree.sign[k]
            ak = (frames["rxj"][:, p], frames["ryj"][:, p]) if s > 0 else (frames["rxi"][:, p], frames["ryi"][:, p])
            self.D[(k, k)] = (ak[1], -ak[0])                                  # −ẑ × ak
            parent = tree.parent[k]
            if parent >= 0:
                ap = (frames["rxi"][:, p], frames["ryi"][:, p]) if s > 0 else (frames["rxj"][:, p], frames["ryj"][:, p])
                dx, dy = self.D[(parent, parent)]
                self.D[(k, parent)] = (dx - ap[1], dy + ap[0])                # + ẑ × aπ
                for l in tree.ancestors[parent][1:]:
                    self.D[(k, l)] = self.D[(parent, l)]
        nb = len(c.bodies)
        K = J_cut[:, :, tree.columns].copy()
        for (k, l), (dx, dy) in self.D.items():
            K[:, :, l] += J_cut[:, :, 3 * k] * dx[:, None] + J_cut[:, :, 3 * k + 1] * dy[:, None]
        self.Ks = K * self.row_cut[:, None] * self.z_scale[None, :]
        self.square = self.Ks.shape[1] == self.Ks.shape[2]
        normal = self.Ks if self.square else self.Ks.transpose(0, 2, 1) @ self.Ks
        try:
            self.Bs = inverse(normal)
        except np.linalg.LinAlgError:
            k = int(np.flatnonzero(np.linalg.matrix_rank(normal) < normal.shape[-1])[0])
            raise MechanismError("time", f"the Jacobian is singular at t = {t[k]:.6g} s (a toggle or dead-centre "
                                         "position: the drives cannot move the mechanism there)") from None
        self.count, self.nb = count, nb

    # -- J·x = r --------------------------------------------------------------------------------

    def _reduced(self, rs: np.ndarray) -> np.ndarray:
        """z from the scaled reduced right-hand side."""
        if not self.square:
            rs = matvec(self.Ks.transpose(0, 2, 1), rs)
        return matvec(self.Bs, rs) * self.z_scale

    def solve(self, r: np.ndarray) -> np.ndarray:
        """x with J·x = r (least squares, exact for a consistent system)."""
        tree, J_cut = self.tree, self.J_cut
        x = np.zeros((len(r), self.c.n))
        Gr = {}
        for k in tree.order:                                  # ΔG with Δθ = 0, root down
            row = tree.tree_rows[k]
            gx, gy = tree.sign[k] * r[:, row], tree.sign[k] * r[:, row + 1]
            parent = tree.parent[k]
            if parent >= 0:
                gx, gy = gx + Gr[parent][0], gy + Gr[parent][1]
            Gr[k] = (gx, gy)
        reduced = r[:, tree.cut].copy()
        for k, (gx, gy) in Gr.items():
            reduced -= J_cut[:, :, 3 * k] * gx[:, None] + J_cut[:, :, 3 * k + 1] * gy[:, None]
        z = self._reduced(reduced * self.row_cut)
        x[:, tree.columns] = z
        for k in tree.order:
            gx, gy = Gr[k]
            for l in tree.ancestors[k]:
                dx, dy = self.D[(k, l)]
                gx, gy = gx + dx * z[:, l], gy + dy * z[:, l]
            x[:, 3 * k], x[:, 3 * k + 1] = gx, gy
        return x

    # -- Jᵀ·λ = f -------------------------------------------------------------------------------

    def _tree_multipliers(self, f: np.ndarray, lam_cut: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """The tree joints' multipliers from the body balances, leaves up:
        σk·μk − Σ children σc·μc = f_Gk − J_C,Gkᵀ·λ_C."""
        tree, J_cut = self.tree, self.J_cut
        mu: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for k in reversed(tree.order):
            gx = f[:, 3 * k] - np.einsum("tc,tc->t", J_cut[:, :, 3 * k], lam_cut)
            gy = f[:, 3 * k + 1] - np.einsum("tc,tc->t", J_cut[:, :, 3 * k + 1], lam_cut)
            for child in tree.children[k]:
                gx, gy = gx + tree.sign[child] * mu[child][0], gy + tree.sign[child] * mu[child][1]
            mu[k] = (tree.sign[k] * gx, tree.sign[k] * gy)
        return mu

    def solve_transposed(self, f: np.ndarray) -> np.ndarray:
        """λ with Jᵀ·λ = f (minimum-norm in the cut rows, scaled, when
        there are redundant rows)."""
        tree = self.tree
        reduced = f[:, tree.columns].copy()
        for (k, l), (dx, dy) in self.D.items():           # f̃θ = fθ + Dᵀ·f_G
            reduced[:, l] += dx * f[:, 3 * k] + dy * f[:, 3 * k + 1]
        fs = reduced * self.z_scale
        if self.square:
            lam_cut = matvec(self.Bs.transpose(0, 2, 1), fs) * self.row_cut
        else:
            lam_cut = matvec(self.Ks, matvec(self.Bs, fs)) * self.row_cut
        lam = np.zeros((len(f), self.c.m))
        lam[:, tree.cut] = lam_cut
        for k, (mx, my) in self._tree_multipliers(f, lam_cut).items():
            lam[:, tree.tree_rows[k]], lam[:, tree.tree_rows[k] + 1] = mx, my
        return lam

    # -- diagnostics ----------------------------------------------------------------------------

    def condition(self) -> np.ndarray:
        """∞-norm condition number of the scaled K per instant (of KsᵀKs,
        square-rooted, with redundant rows)."""
        if self.square:
            return np.abs(self.Ks).sum(axis=-1).max(axis=-1) * np.abs(self.Bs).sum(axis=-1).max(axis=-1)
        normal = self.Ks.transpose(0, 2, 1) @ self.Ks
        return np.sqrt(np.abs(normal).sum(axis=-1).max(axis=-1) * np.abs(self.Bs).sum(axis=-1).max(axis=-1))

    def undetermined(self, row_scale: np.ndarray, tolerance: float) -> np.ndarray:
        """Per multiplier row, whether the null space of Jᵀ reaches it at
        some instant. Null vectors: the cut part spans the range of the
        projector I − Ks·(KsᵀKs)⁻¹·Ksᵀ (scaled), the tree part follows from
        the body balances with no load. Compared scaled (λ/Dr), relative to
        each null vector's largest entry."""
        if self.square:
            return np.zeros(self.c.m, dtype=bool)
        C = len(self.tree.cut)
        projector = np.eye(C) - self.Ks @ self.Bs @ self.Ks.transpose(0, 2, 1)
        found = np.zeros(self.c.m, dtype=bool)
        zero = np.zeros((self.count, self.c.n))
        for j in range(C):
            w = np.zeros((self.count, self.c.m))
            lam_cut = projector[:, :, j] * self.row_cut
            w[:, self.tree.cut] = lam_cut
            for k, (mx, my) in self._tree_multipliers(zero, lam_cut).items():
                w[:, self.tree.tree_rows[k]], w[:, self.tree.tree_rows[k] + 1] = mx, my
            ws = np.abs(w / row_scale)
            peak = ws.max(axis=-1, keepdims=True)
            found |= ((ws > tolerance * peak) & (peak > tolerance)).any(axis=0)
        return found
