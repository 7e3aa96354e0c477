"""The general reference: any planar mechanism of rigid bodies, revolute and
prismatic joints, drives and force elements, solved numerically.

Absolute coordinates q = (x, y, θ) of every moving body's centre of mass,
constraints Φ(q, t) = 0 (`mechval.reference.planar.constraints`), applied forces Q
(`mechval.reference.planar.forces`), assembly and the branch followed by continuation
(`mechval.reference.planar.positions`). At every requested instant, in batches of
`CHUNK` instants (on a thread per core: numpy releases the GIL):

- positions: Newton from the continuation's quintic Hermite predictor,
  with Φq eliminated once at the prediction (chord iterations), until the
  step is within rounding of q (a fixed point);
- velocities Φq·q̇ = −Φt, accelerations Φq·q̈ = γ, then the multipliers from
  M·q̈ + Φqᵀ·λ = Q: three solves with Φq eliminated at the solution.
Every solve with Φq goes through its elimination along a spanning tree of
revolute joints (`mechval.reference.planar.tree`): a sweep from the ground out, one
small dense solve per instant (3×3 for a four-bar, 7×7 for Andrews'
squeezer, all instants at once) and a sweep back.

Which λ is which (constraint forces are −Φqᵀ·λ, Nikravesh 1988, ch. 6):
- revolute joint, rows Pj − Pi: its reaction, the force BY body_i ON body_j
  at the joint (world axes, docs/conventions.md's Fij), is (Fx, Fy) = −λ;
- prismatic joint, rows θj − θi − θ0 and n·(Pj − Pi): its couple on body_j
  is M = −λ_angle and its force on body_j, acting at body_j's point Pj, is
  F = −λ_slide·n, so its normal force is N = F·n = −λ_slide (n = ẑ × u);
- drive: its torque (revolute) or force along u (prismatic) on body_j is
  −λ_drive, and the opposite acts on body_i.

Redundant constraints (a rank-deficient Φq) leave λ undetermined along the
null space of Φqᵀ: the kinematics and every λ row orthogonal to it (drive
efforts, typically) are still exact; reactions that depend on an
undetermined row are reported missing with the reason, never a made-up
value.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
import pandas as pd

from mechval.model.mechanism import MOTION_QUANTITIES, BodyPose, Mechanism
from mechval.reference.planar.constraints import Constraints, MechanismError
from mechval.reference.planar.forces import AppliedForces, mass_diagonal
from mechval.reference.planar.linear import settled, solve_one
from mechval.reference.planar.positions import Nodes, Scaling, Structure, assemble, march, mechanism_size, redundant_joint_rows
from mechval.reference.planar.tree import Factor, Tree
from mechval.reference.resultants import body_resultants

#: Instants per batch: bounds memory; fewer, longer array operations
#: (tests/bench/planar_bench.py measures the batch sizes).
CHUNK = 1 << 14
#: `check`'s continuation aims at this Taylor error (scaled): nodes about
#: twice as far apart as a solve's, enough to follow the branch.
CHECK_DELTA = 1e-2
#: Chord iterations before an instant that has not settled gets a fresh elimination.
CHORD_ITERATIONS = 12
#: Condition number (∞-norm) of the scaled reduced Jacobian K above which
#: an instant is refused as singular: results there would carry errors of
#: cond·eps ≈ 2e-6. K is singular exactly where Φq is (the elimination's
#: pivots are ±1).
SINGULAR_CONDITION = 1e10
#: A λ row counts as undetermined where a null vector of Φqᵀ (scaled)
#: reaches it by more than this fraction of its largest entry: exactly 0
#: for a determined row, computed to ~cond²·eps.
UNIQUE_TOL = 1e-8
#: A corrected position further than this (scaled) from its prediction
#: means the batch may have left the branch the continuation followed.
BRANCH_JUMP = 1e-2
METHOD = "absolute coordinates, Newton continuation, constraint multipliers (Nikravesh 1988, Haug 1989)"


@dataclass(frozen=True)
class Solution:
    """A reference solution, prescribed (`PlanarSolver`) or integrated
    (`mechval.reference.dynamics`): raw columns (mechval.model.mechanism names), reasons for
    missing columns, the mechanism's structure and facts about the solve."""

    frame: pd.DataFrame
    missing: Mapping[str, str]
    structure: Structure
    facts: Mapping[str, Any] = field(default_factory=dict)
    #: Per instant, the condition number of the scaled reduced Jacobian.
    condition: np.ndarray | None = field(default=None, repr=False)


def default_pose(mech: Mechanism, t0: float) -> dict[str, BodyPose]:
    """The mechanism's assembly pose, or else the body angles of its own
    `motion` at t0 (the four closed-form kinds): angles only, which pick
    the branch; the solver closes the loop itself."""
    if mech.assembly_pose:
        return dict(mech.assembly_pose)
    motion = mech.motion(np.array([t0]))
    return {b.name: BodyPose(float(motion[f"{b.name}.theta"].iloc[0])) for b in mech.bodies}


class PlanarSolver:
    """Solve one mechanism at any instants (see the module docstring)."""

    def __init__(self, mech: Mechanism):
        self.mech = mech
        self.c = Constraints(mech)
        self.forces = AppliedForces(self.c)
        self.mass = mass_diagonal(mech)
        self.scaling = Scaling(self.c, mechanism_size(mech))
        self.tree = Tree.of(self.c)
        self.cut_rows = tuple(int(r) for r in self.tree.cut)

    # -- one instant (the continuation's nodes) -----------------------------------------------

    def _rates(self, q: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """q̇ and q̈ at a node; refuses a node where Φq is singular."""
        f = self.c.frames(q)
        J = self.c.jacobian(q, f)[0]
        row, col = self.scaling.row, self.scaling.column
        condition = np.linalg.cond(J * row[:, None] * col[None, :])
        if not condition <= SINGULAR_CONDITION:
            raise MechanismError("time", f"the Jacobian is singular at t = {t[0]:.6g} s (condition {condition:.3g} > "
                                         f"{SINGULAR_CONDITION:.0e}): a toggle or dead-centre position")
        v = solve_one(J, self.c.velocity_rhs(t)[0], row, col)[None]
        a = solve_one(J, self.c.gamma(q, v, t, f)[0], row, col)[None]
        return v, a

    # -- batches --------------------------------------------------------------------------------

    def _factor(self, q: np.ndarray, f: dict, t: np.ndarray) -> Factor:
        """The tree elimination of Φq at q (frames f)."""
        Jt_cut = self.c.jacobian(q, f, self.cut_rows, instants_last=True)
        return Factor(self.c, self.tree, f, Jt_cut, self.scaling.row, self.scaling.column, t)

    def _correct(self, q: np.ndarray, factor: Factor, t: np.ndarray, f: dict) -> tuple[np.ndarray, dict]:
        """Chord Newton iterations q ← q − B·Φ(q, t), B the elimination at
        the prediction, to the fixed point (a scaled step within rounding
        of q); instants that do not settle get a fresh elimination. `f` are
        the frames of q; returns the solution and the frames of the last
        iterate evaluated, one rounding-level step before it (used for Φq
        and γ there: they differ by ~eps)."""
        scaling = self.scaling
        previous = np.full(len(q), np.inf)
        # an instant once settled stays so: at the residual's noise floor
        # (cond·eps, above the rounding floor where the condition is some
        # hundreds, as near a dead centre) its steps wander by a factor of
        # a few, so a batch of such instants would seldom be judged settled
        # all in the same iteration
        done = np.zeros(len(q), dtype=bool)
        floor = scaling.tolerance(q)     # the Newton steps change q far less than its rounding scale
        for it in range(2 * CHORD_ITERATIONS):
            if it:
                f = self.c.frames(q)
            if it == CHORD_ITERATIONS:   # slow to settle: Newton with fresh Jacobians from here
                factor = self._factor(q, f, t)
            dq = -factor.solve(self.c.residual(q, t, f))
            q += dq
            size = scaling.step(dq)
            done |= settled(size, previous, floor)
            if done.all():
                return q, f
            previous = size
        k = int(np.flatnonzero(~done)[0])
        condition = self._factor(q[k:k + 1], self.c.frames(q[k:k + 1]), t[k:k + 1]).condition()[0]
        raise MechanismError("time", f"the loop cannot close at t = {t[k]:.6g} s: Newton does not settle (last "
                                     f"step {size[k]:.3g}, scaled by the size {scaling.size:.3g} m; Jacobian "
                                     f"condition there {condition:.3g}, singular above {SINGULAR_CONDITION:.0e})")

    def _batch(self, t: np.ndarray, nodes: Nodes) -> dict[str, np.ndarray]:
        c, scaling = self.c, self.scaling
        predicted = nodes.predict(t)
        f = c.frames(predicted)
        q, f = self._correct(predicted.copy(), self._factor(predicted, f, t), t, f)
        jump = scaling.step(q - predicted)
        if jump.max() > BRANCH_JUMP:
            k = int(np.argmax(jump))
            raise MechanismError("time", f"at t = {t[k]:.6g} s the solution lies {jump[k]:.3g} (scaled) from the "
                                         "continuation's prediction: a branch point or near-singular position")
        factor = self._factor(q, f, t)
        v = factor.solve(c.velocity_rhs(t))
        a = factor.solve(c.gamma(q, v, t, f))
        lam = factor.solve_transposed(self.forces.generalised(q, v, f) - self.mass * a)
        return dict(q=q, v=v, a=a, lam=lam, condition=factor.condition(), frames=f,
                    undetermined=factor.undetermined(scaling.row, UNIQUE_TOL))

    # -- the run --------------------------------------------------------------------------------

    def check(self, t0: float, t_end: float, pose: Mapping[str, BodyPose] | None = None) -> Structure:
        """Assemble at t0 and follow the mechanism to t_end (the
        continuation alone, no batch): raises MechanismError where `solve`
        would for want of mobility, assembly or closure."""
        q0, found = assemble(self.c, self.scaling, pose or default_pose(self.mech, t0), t0)
        march(self.c, self.scaling, q0, t0, t_end, self._rates, delta_target=CHECK_DELTA)
        return found

    def solve(self, t: np.ndarray, pose: Mapping[str, BodyPose] | None = None) -> Solution:
        """Raw motion and reaction columns at instants t (nondecreasing)."""
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or not t.size or not np.isfinite(t).all() or np.any(np.diff(t) < 0):
            raise MechanismError("time", "instants must be finite and nondecreasing")
        q0, found = assemble(self.c, self.scaling, pose or default_pose(self.mech, float(t[0])), float(t[0]))
        nodes = march(self.c, self.scaling, q0, float(t[0]), float(t[-1]), self._rates)
        columns = ["t"] + self.mech.motion_columns() + self.mech.reaction_columns()
        table = np.empty((len(columns), len(t)))
        table[0] = t
        condition = np.empty(len(t))
        undetermined = np.zeros(self.c.m, dtype=bool)
        parts = [slice(start, start + CHUNK) for start in range(0, len(t), CHUNK)]

        def batch(part: slice) -> np.ndarray:     # each batch fills its own slice of the table
            out = self._batch(t[part], nodes)
            condition[part] = out["condition"]
            if out["condition"].max() <= SINGULAR_CONDITION:
                table[1:, part] = self._columns(out)
            return out["undetermined"]

        # numpy releases the GIL in its array loops and LAPACK calls
        pool = ThreadPoolExecutor(max_workers=min(len(parts), os.cpu_count() or 1))
        try:
            for part, rows in zip(parts, pool.map(batch, parts)):
                if condition[part].max() > SINGULAR_CONDITION:
                    k = int(np.argmax(condition[part] > SINGULAR_CONDITION))
                    raise MechanismError("time", f"the Jacobian is singular at t = {t[part][k]:.6g} s (condition "
                                                 f"{condition[part][k]:.3g} > {SINGULAR_CONDITION:.0e}): a toggle "
                                                 "or dead-centre position")
                undetermined |= rows
        finally:   # a refusal need not wait for the later batches
            pool.shutdown(cancel_futures=True)
        resultants = self._resultants(undetermined, table, columns)
        missing = self._missing(undetermined, table, columns, found)
        facts = {"method": METHOD, "grubler": found.grubler, "mobility": found.mobility, "rank": found.rank,
                 "redundant_constraints": found.redundant, "condition_max": float(condition.max()),
                 "continuation_nodes": len(nodes.t)}
        frame = pd.DataFrame(table.T, columns=columns, copy=False)
        return Solution(frame.assign(**resultants), missing, found, facts, condition)

    def _columns(self, out: Mapping[str, np.ndarray]) -> np.ndarray:
        """Motion of every body frame (origin O = G − R·com) and reactions."""
        q, v, a, lam = out["q"], out["v"], out["a"], out["lam"]
        cos, sin = out["frames"]["cos"], out["frames"]["sin"]
        values = []
        for k, body in enumerate(self.mech.bodies):
            th, w, al = q[:, 3 * k + 2], v[:, 3 * k + 2], a[:, 3 * k + 2]
            c, s = cos[:, k], sin[:, k]
            rx, ry = c * body.com[0] - s * body.com[1], s * body.com[0] + c * body.com[1]
            frame = dict(x=q[:, 3 * k] - rx, y=q[:, 3 * k + 1] - ry, theta=th,
                         vx=v[:, 3 * k] + w * ry, vy=v[:, 3 * k + 1] - w * rx, omega=w,
                         ax=a[:, 3 * k] + al * ry + w * w * rx, ay=a[:, 3 * k + 1] - al * rx + w * w * ry, alpha=al)
            values += [frame[quantity] for quantity in MOTION_QUANTITIES]
        for k, j in enumerate(self.mech.joints):
            r = self.c.joint_rows[j.name]
            if j.kind == "revolute":
                values += [-lam[:, r], -lam[:, r + 1]]
            else:
                ux, uy = out["frames"]["ux"][:, k], out["frames"]["uy"][:, k]
                values += [lam[:, r + 1] * uy, -lam[:, r + 1] * ux, -lam[:, r]]     # −λ·n, n = (−uy, ux)
        values += [-lam[:, self.c.drive_rows[d.name]] for d in self.mech.drives]
        return np.array(values)

    def _row_columns(self) -> list[list[str]]:
        """The raw reaction columns that rest on each λ row."""
        names: list[list[str]] = []
        for row in self.c.rows:
            kind = self.mech.joint(row.joint).kind
            if row.kind == "drive":
                names.append([f"{row.drive}.{'T' if kind == 'revolute' else 'F'}"])
            elif row.kind.startswith("pin"):
                names.append([f"{row.joint}.F{row.kind[-1]}"])
            else:
                names.append([f"{row.joint}.M"] if row.kind == "angle" else [f"{row.joint}.Fx", f"{row.joint}.Fy"])
        return names

    def _resultants(self, undetermined: np.ndarray, table: np.ndarray, columns: list[str]) -> dict[str, np.ndarray]:
        """Each body's resultant constraint load, from this particular λ
        before `_missing` blanks the reactions that are not unique: the
        resultant is unique all the same (`mechval.reference.resultants`)."""
        if not undetermined.any():
            return {}
        return body_resultants(self.mech, {name: table[k] for k, name in enumerate(columns)})

    def _missing(self, undetermined: np.ndarray, table: np.ndarray, columns: list[str],
                 found: Structure) -> dict[str, str]:
        """NaN out, with the reason, every reaction resting on an undetermined λ row."""
        missing = {}
        for k, names in enumerate(self._row_columns()):
            if not undetermined[k]:
                continue
            for name in names:
                table[columns.index(name)] = np.nan
                missing[name] = (f"not unique: {found.redundant} redundant constraint"
                                 f"{'s' if found.redundant != 1 else ''} (Jacobian rank {found.rank} of "
                                 f"{found.rows} rows) make this reaction statically indeterminate in a "
                                 "rigid-body model")
        return missing


def redundant_constraints(mech: Mechanism, t0: float = 0.0) -> int:
    """How many of the mechanism's joint equations are redundant at its
    assembly pose (rank of the joints' Jacobian; see `Structure`)."""
    c = Constraints(mech)
    return redundant_joint_rows(c, Scaling(c, mechanism_size(mech)), default_pose(mech, t0), t0)


def raw_planar(mech: Mechanism, t: np.ndarray, pose: Mapping[str, BodyPose] | None = None) -> Solution:
    """The general reference's raw columns of `mech` at instants t."""
    return PlanarSolver(mech).solve(t, pose)
