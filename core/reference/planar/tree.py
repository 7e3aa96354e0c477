"""Batched linear solves with the constraint Jacobian by block elimination
along a spanning tree of revolute joints (`mechval.reference.planar.solver`).

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

from mechval.reference.planar.constraints import Constraints, MechanismError
from mechval.reference.planar.linear import inverse, matvec, norm_inf


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
    coefficients D, the cut rows' Jacobian, and K's scaled (pseudo-)inverse.

    Inside, arrays keep the instants on the last axis (`mechval.reference.planar.linear`):
    the cut rows' Jacobian Jt (rows, n, instants), K and its inverse (k, k,
    instants), every vector (entries, instants). Solves take arrays
    indexed instants first, as every other caller holds them, and return
    them so indexed: transposed views of instants-last storage, whose
    columns the callers then read contiguously."""

    def __init__(self, c: Constraints, tree: Tree, frames: dict, Jt_cut: np.ndarray,
                 row: np.ndarray, col: np.ndarray, t: np.ndarray):
        """`Jt_cut`: the cut rows' Jacobian, instants last
        (`Constraints.jacobian(..., instants_last=True)`)."""
        self.c, self.tree, self.Jt = c, tree, Jt_cut
        self.row_cut, self.z_scale = row[tree.cut][:, None], col[tree.columns][:, None]
        count = len(t)
        arm = {key: frames[key].T for key in ("rxi", "ryi", "rxj", "ryj")}      # (joints, instants)
        # D[(k, l)] = ∂ΔGk/∂Δθl as (x, y) vectors, built from the root down.
        self.D: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        for k in tree.order:
            p, s = tree.joint[k], tree.sign[k]
            ak = (arm["rxj"][p], arm["ryj"][p]) if s > 0 else (arm["rxi"][p], arm["ryi"][p])
            self.D[(k, k)] = (ak[1].copy(), -ak[0])                            # −ẑ × ak
            parent = tree.parent[k]
            if parent >= 0:
                ap = (arm["rxi"][p], arm["ryi"][p]) if s > 0 else (arm["rxj"][p], arm["ryj"][p])
                dx, dy = self.D[(parent, parent)]
                self.D[(k, parent)] = (dx - ap[1], dy + ap[0])                 # + ẑ × aπ
                for l in tree.ancestors[parent][1:]:
                    self.D[(k, l)] = self.D[(parent, l)]
        Jt = Jt_cut
        K = Jt[:, tree.columns].copy()
        for (k, l), (dx, dy) in self.D.items():
            K[:, l] += Jt[:, 3 * k] * dx + Jt[:, 3 * k + 1] * dy
        self.Ks = K * self.row_cut[:, None] * self.z_scale[None, :]
        self.square = self.Ks.shape[0] == self.Ks.shape[1]
        normal = self.Ks if self.square else self._normal()
        try:
            self.Bs = inverse(normal)
        except np.linalg.LinAlgError:
            k = int(np.flatnonzero(np.linalg.matrix_rank(normal.transpose(2, 0, 1)) < normal.shape[0])[0])
            raise MechanismError("time", f"the Jacobian is singular at t = {t[k]:.6g} s (a toggle or dead-centre "
                                         "position: the drives cannot move the mechanism there)") from None
        self.count = count

    def _normal(self) -> np.ndarray:
        """KsᵀKs, (k, k, instants)."""
        return np.einsum("cit,cjt->ijt", self.Ks, self.Ks)

    # -- J·x = r --------------------------------------------------------------------------------

    def _reduced(self, rs: np.ndarray) -> np.ndarray:
        """z from the scaled reduced right-hand side (entries, instants)."""
        if not self.square:
            rs = np.einsum("cit,ct->it", self.Ks, rs)
        return matvec(self.Bs, rs) * self.z_scale

    def solve(self, r: np.ndarray) -> np.ndarray:
        """x (instants, n) with J·x = r (least squares, exact for a
        consistent system), r (instants, m)."""
        tree, Jt = self.tree, self.Jt
        r = np.ascontiguousarray(r.T)
        x = np.zeros((self.c.n, len(r[0])))
        Gr = {}
        for k in tree.order:                                  # ΔG with Δθ = 0, root down
            row = tree.tree_rows[k]
            gx, gy = tree.sign[k] * r[row], tree.sign[k] * r[row + 1]
            parent = tree.parent[k]
            if parent >= 0:
                gx, gy = gx + Gr[parent][0], gy + Gr[parent][1]
            Gr[k] = (gx, gy)
        reduced = r[tree.cut]
        for k, (gx, gy) in Gr.items():
            reduced -= Jt[:, 3 * k] * gx + Jt[:, 3 * k + 1] * gy
        z = self._reduced(reduced * self.row_cut)
        x[tree.columns] = z
        for k in tree.order:
            gx, gy = Gr[k]
            for l in tree.ancestors[k]:
                dx, dy = self.D[(k, l)]
                gx, gy = gx + dx * z[l], gy + dy * z[l]
            x[3 * k], x[3 * k + 1] = gx, gy
        return x.T

    # -- Jᵀ·λ = f -------------------------------------------------------------------------------

    def _tree_multipliers(self, f: np.ndarray, lam_cut: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """The tree joints' multipliers from the body balances, leaves up:
        σk·μk − Σ children σc·μc = f_Gk − J_C,Gkᵀ·λ_C (f (n, instants),
        λ_C (cut rows, instants))."""
        tree, Jt = self.tree, self.Jt
        mu: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for k in reversed(tree.order):
            gx = f[3 * k] - (Jt[:, 3 * k] * lam_cut).sum(axis=0)
            gy = f[3 * k + 1] - (Jt[:, 3 * k + 1] * lam_cut).sum(axis=0)
            for child in tree.children[k]:
                gx, gy = gx + tree.sign[child] * mu[child][0], gy + tree.sign[child] * mu[child][1]
            mu[k] = (tree.sign[k] * gx, tree.sign[k] * gy)
        return mu

    def solve_transposed(self, f: np.ndarray) -> np.ndarray:
        """λ (instants, m) with Jᵀ·λ = f, f (instants, n) (minimum-norm in
        the cut rows, scaled, when there are redundant rows)."""
        tree = self.tree
        f = np.ascontiguousarray(f.T)
        reduced = f[tree.columns]
        for (k, l), (dx, dy) in self.D.items():           # f̃θ = fθ + Dᵀ·f_G
            reduced[l] += dx * f[3 * k] + dy * f[3 * k + 1]
        fs = reduced * self.z_scale
        if self.square:
            lam_cut = matvec(self.Bs.transpose(1, 0, 2), fs) * self.row_cut
        else:
            lam_cut = matvec(self.Ks, matvec(self.Bs, fs)) * self.row_cut
        lam = np.zeros((self.c.m, f.shape[1]))
        lam[tree.cut] = lam_cut
        for k, (mx, my) in self._tree_multipliers(f, lam_cut).items():
            lam[tree.tree_rows[k]], lam[tree.tree_rows[k] + 1] = mx, my
        return lam.T

    # -- diagnostics ----------------------------------------------------------------------------

    def condition(self) -> np.ndarray:
        """∞-norm condition number of the scaled K per instant (of KsᵀKs,
        square-rooted, with redundant rows)."""
        if self.square:
            return norm_inf(self.Ks) * norm_inf(self.Bs)
        return np.sqrt(norm_inf(self._normal()) * norm_inf(self.Bs))

    def undetermined(self, row_scale: np.ndarray, tolerance: float) -> np.ndarray:
        """Per multiplier row, whether the null space of Jᵀ reaches it at
        some instant. Null vectors: the cut part spans the range of the
        projector I − Ks·(KsᵀKs)⁻¹·Ksᵀ (scaled), the tree part follows from
        the body balances with no load. Compared scaled (λ/Dr), relative to
        each null vector's largest entry."""
        if self.square:
            return np.zeros(self.c.m, dtype=bool)
        C = len(self.tree.cut)
        projector = np.eye(C)[:, :, None] - np.einsum("cit,ijt,djt->cdt", self.Ks, self.Bs, self.Ks)
        found = np.zeros(self.c.m, dtype=bool)
        zero = np.zeros((self.c.n, self.count))
        for j in range(C):
            w = np.zeros((self.c.m, self.count))
            lam_cut = projector[:, j] * self.row_cut
            w[self.tree.cut] = lam_cut
            for k, (mx, my) in self._tree_multipliers(zero, lam_cut).items():
                w[self.tree.tree_rows[k]], w[self.tree.tree_rows[k] + 1] = mx, my
            ws = np.abs(w / row_scale[:, None])
            peak = ws.max(axis=0)
            found |= ((ws > tolerance * peak) & (peak > tolerance)).any(axis=1)
        return found
