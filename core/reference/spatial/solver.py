"""The spatial reference for prescribed motion: positions, rates,
reactions and drive efforts of a spatial system at any instants.

As the planar reference (`mechval.reference.planar.solver`): assemble at
the first instant (`structure.newton`), follow the branch by continuation
over nodes, then at every requested instant, in batches:
- positions: chord Newton from the nearest earlier node's second-order
  Taylor prediction (on the group for rotations), to the fixed point;
- velocities Φq·w = −Φt, accelerations Φq·ẇ = γ, multipliers from
  M·ẇ + Φqᵀ·λ = Q (`forces`, `outputs`): square solves with the
  independent rows.
The independent rows are those of the assembly (`structure.kept_rows`)
until their condition passes REPICK_CONDITION near some pose, where
others are picked: a set of rows can turn singular where the whole
Jacobian does not (Bennett's linkage folding flat).

Reactions from the multipliers (constraint loads are −Φqᵀ·λ, Nikravesh
1988, ch. 11): a joint's rows give the load (force F, moment about the
centre of mass) on body_j, or the opposite of body_i's where body_j is the
ground; the raw columns are F and its moment M about Pj, world axes, the
load BY body_i ON body_j. Drive efforts are −λ of their rows.

Redundant rows (a rank-deficient Φq) carry λ = 0 here; λ is undetermined
along the null space of Φqᵀ (one null vector per dependent row); a
reaction column that such a vector reaches is reported missing with the
reason, and every body's resultant constraint load (unique, −Φqᵀ·λ per
body) is added as B.R.Fx … B.R.Mz, as the planar reference does.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
import pandas as pd

from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.forces import AppliedForces
from mechval.reference.spatial.joints import Constraints, Pose
from mechval.reference.spatial.lu import LU
from mechval.reference.spatial.resultants import resultant_columns
from mechval.reference.spatial.rotation import exp_map
from mechval.reference.spatial import chord, motion, outputs
from mechval.reference.spatial.structure import (CHORD, NEWTON_ITERATIONS, ROUNDING, STAGNATION, Scaling, Structure,
                                                 initial_pose, kept, kept_rows, newton, refuse_unclosed, structure)
from mechval.reference.spatial.system import SpatialSystem

#: Instants per batch: a batch's Jacobians and factors (28 KB an instant
#: for the delta robot) are read back by the multipliers and reactions,
#: nearer the cache in smaller batches; fewer batches, less Python
#: between them (tests/bench/spatial_bench.py compares sizes).
CHUNK = 1 << 9
#: See `mechval.reference.planar.solver.UNIQUE_TOL`.
UNIQUE_TOL = 1e-8
#: Continuation: a node's prediction may miss its solution by this much
#: (scaled) before the step is halved; below a tenth of it, the step grows.
NODE_JUMP = 5e-3
#: A batch instant further than this (scaled) from its prediction may
#: have left the branch.
BRANCH_JUMP = 1e-2
SINGULAR_CONDITION = 1e10
#: A node where the kept rows' scaled Jacobian is worse conditioned than
#: this gets its rows picked afresh (the full Jacobian may be well
#: conditioned there: Bennett's linkage folding at θ1 = π).
REPICK_CONDITION = 1e3
#: Most continuation nodes one run may take (as the planar reference's
#: `positions.MAX_STEPS`; README, "Limits"): 2.7–4.5 ms of CPU a node and
#: 25–36 nodes a turn of the spherical four-bar and Bennett's linkage, so a
#: refused run ends within the fuzz tests' 120 s bound on one case.
MAX_NODES = 10_000
METHOD = "absolute coordinates, rotations on the group, Newton continuation, multipliers (Nikravesh 1988, Haug 1989)"


@dataclass(frozen=True)
class SpatialSolution:
    frame: pd.DataFrame
    missing: Mapping[str, str]
    structure: Structure
    facts: Mapping[str, Any] = field(default_factory=dict)
    #: Per instant, the condition number of the scaled square Jacobian.
    condition: np.ndarray | None = field(default=None, repr=False)


@dataclass
class State:
    """Positions, velocities (N, nb, 6), accelerations and multipliers at N instants."""

    t: np.ndarray
    pose: Pose
    w: np.ndarray
    dw: np.ndarray
    lam: np.ndarray
    jac: np.ndarray
    #: The rows its square solves kept, their Jacobian's LU factors and
    #: its scaled 1-norm condition per instant.
    rows: tuple[int, ...] = ()
    lu: LU | None = None
    condition: np.ndarray | None = None


def rates(c: Constraints, forces: AppliedForces, pose: Pose, t: np.ndarray, rows: tuple[int, ...],
          scaling: Scaling) -> State:
    """Velocities, accelerations and multipliers at solved positions by the
    kept rows' Jacobian, factorised once per instant for the three solves
    and its condition (`motion`, compiled)."""
    joint, shape, first, second = c.table_rows
    jac, factors, piv, w, dw, condition = motion.velocities(
        np.ascontiguousarray(pose.G), np.ascontiguousarray(pose.A), c.laws(t), *c.table_joints, shape, joint, first,
        second, np.array(rows, dtype=np.int64), scaling.row, scaling.column)
    return multipliers(c, forces, pose, t, rows, jac, factors, piv, w, dw, condition)


def multipliers(c: Constraints, forces: AppliedForces, pose: Pose, t: np.ndarray, rows: tuple[int, ...],
                jac: np.ndarray, factors: np.ndarray, piv: np.ndarray, w: np.ndarray, dw: np.ndarray,
                condition: np.ndarray) -> State:
    """The State from `motion`'s outputs: λ from M·ẇ + Φqᵀ·λ = Q by the
    kept rows' factors, transposed (`outputs.multipliers`)."""
    if not np.isfinite(condition).all():
        raise np.linalg.LinAlgError("Singular matrix")
    N, nb = len(t), len(c.bodies)
    applied = forces.applied(pose, w.reshape(N, nb, 6), t)
    lam = np.zeros((N, c.m))
    outputs.multipliers(factors, piv, np.ascontiguousarray(pose.A), w, dw, forces.mass, forces.inertia, forces.gravity,
                        np.empty((0, c.n)) if applied is None else applied, np.array(rows, dtype=np.int64), lam)
    return State(t, pose, w.reshape(N, nb, 6), dw.reshape(N, nb, 6), lam, jac, tuple(rows),
                 LU.from_factors(factors, piv), condition)


class SpatialSolver:
    """Solve one spatial system with as many drives as degrees of freedom."""

    def __init__(self, system: SpatialSystem):
        self.system = system
        self.c = Constraints(system)
        self.forces = AppliedForces(self.c)
        self.scaling = Scaling(self.c)
        c = self.c
        self._com = np.array([np.asarray(b.com, dtype=float) for b in system.bodies]).reshape(-1, 3)
        #: `outputs.reaction_columns`' table: the joints' ends and arms, their rows, the drives' rows.
        self._reaction_table = (*c.table_joints[:2],
                                *(np.array([getattr(c.joint_rows[j.name], end) for j in system.joints], dtype=np.int64)
                                  for end in ("start", "stop")),
                                np.array([c.drive_rows[d.name] for d in system.drives], dtype=np.int64))
        #: Per thread, `march`'s Jacobians and factors: a batch's are read
        #: before that thread marches its next.
        self._buffers = threading.local()

    def assemble(self, t0: float) -> tuple[Pose, Structure]:
        t = np.array([t0])
        pose = newton(self.c, self.scaling, initial_pose(self.c), t, None)
        found = structure(self.c, self.scaling, pose)
        drives = len(self.system.drives)
        if found.mobility != drives or len(found.independent) != self.c.n:
            raise MechanismError("drive", f"the mobility is {found.mobility} (rank of the joints' Jacobian, "
                                          f"Grübler–Kutzbach {found.grubler}) but {drives} drive"
                                          f"{'s prescribe' if drives != 1 else ' prescribes'} the motion"
                                          + ("" if found.mobility != drives else ": the drives are dependent"))
        angles = self.c.drive_angles(pose)
        for d in self.system.drives:
            if d.name in angles and np.cos(angles[d.name][0] - d.law.angle(t0)) < 0:
                raise MechanismError(f"drive.{d.name}", "the assembly lands half a turn from the drive's angle: "
                                                        "state body rotations closer to the assembled pose")
        return pose, found

    def _march(self, pose: Pose, found: Structure, t0: float, t_end: float) -> list[State]:
        """Solved nodes from t0 to t_end, steps halved where a prediction
        misses and grown where it is close."""
        rows = found.independent
        nodes = [rates(self.c, self.forces, pose, np.array([t0]), rows, self.scaling)]
        h = (t_end - t0) / 16 if t_end > t0 else 0.0
        while nodes[-1].t[0] < t_end:
            last = nodes[-1]
            if len(nodes) > MAX_NODES:
                raise MechanismError("time.end", f"the reference's continuation reached only t = {last.t[0]:.6g} s "
                                                 f"of {t_end:g} s in {MAX_NODES:,} steps, the limit; shorten time.end")
            step = min(h, t_end - last.t[0])
            t = last.t + step
            predicted = predict(last, t)
            shortest = step <= 1e-9 * max(1.0, abs(t_end - t0))
            try:
                rows, _, lu = self.rows_at(predicted, t, last.rows, found)
                solved = newton(self.c, self.scaling, predicted, t, rows, where="continuation",
                                lu=lu if rows == last.rows else None)
            except MechanismError:
                if shortest:
                    raise
                h = step / 4
                continue
            jump = self.scaling.step(flat_difference(solved, predicted))[0]
            if jump > NODE_JUMP and not shortest:
                h = step / 2
                continue
            nodes.append(rates(self.c, self.forces, solved, t, rows, self.scaling))
            if jump < NODE_JUMP / 10:
                h = step * 1.5
        return nodes

    def check(self, t0: float, t_end: float) -> Structure:
        """Assemble at t0 and follow the motion to t_end (the continuation
        alone, no batch): raises MechanismError where `solve` would for
        want of mobility, assembly or closure (the scenario loader's check)."""
        pose, found = self.assemble(t0)
        self._march(pose, found, t0, t_end)
        return found

    def solve(self, t: np.ndarray, reactions: bool = True) -> SpatialSolution:
        """The solution at instants t; without `reactions`, its motion
        columns only (what the step rule reads: the reactions' uniqueness
        check costs more than the motion where rows are redundant)."""
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or not t.size or not np.isfinite(t).all() or np.any(np.diff(t) < 0):
            raise MechanismError("time", "instants must be finite and nondecreasing")
        pose0, found = self.assemble(float(t[0]))
        nodes = self._march(pose0, found, float(t[0]), float(t[-1]))
        node_t = np.array([n.t[0] for n in nodes])
        continuation = tuple(np.ascontiguousarray(np.concatenate(x)) for x in (
            [n.pose.G for n in nodes], [n.pose.A for n in nodes], [n.w.reshape(1, -1) for n in nodes],
            [n.dw.reshape(1, -1) for n in nodes])) + (node_t,)
        columns = ["t"] + self.system.motion_columns() + self.system.reaction_columns()
        table = np.empty((len(columns), len(t)))
        undetermined = np.zeros(len(columns), dtype=bool)
        condition = np.empty(len(t))
        resultants = np.empty((6 * len(self.system.bodies) if found.redundant else 0, len(t)))
        parts = [slice(s, s + CHUNK) for s in range(0, len(t), CHUNK)]

        def batch(part: slice) -> np.ndarray:
            flags = np.zeros(len(columns) - 1, dtype=bool)
            tt = t[part]
            which = np.clip(np.searchsorted(node_t, tt, side="right") - 1, 0, len(nodes) - 1)
            sets = {nodes[k].rows for k in np.unique(which)}
            for rows in sets:         # the instants whose nodes kept the same rows
                mask = np.array([nodes[k].rows == rows for k in which])
                flags |= group(np.arange(part.start, part.start + len(tt))[mask], which[mask], rows)
            return flags

        def group(index: np.ndarray, which: np.ndarray, rows: tuple[int, ...]) -> np.ndarray:
            tt = t[index]
            pose, poor, done, residual, jump, *solved = self.march(continuation, which, tt, rows, index)
            better = rows
            if poor.any():         # near a pose where these rows turn singular: the poor instants get others
                k = int(np.argmax(poor))
                J = self.c.evaluate(predict(nodes[which[k]], tt[k:k + 1]), tt[k:k + 1])["jac"][0]
                better = kept_rows(self.c, self.scaling.jacobian(J), self.c.n - found.mobility)
            if better != rows:
                flags = group(index[poor], which[poor], better)
                if poor.all():
                    return flags
                keep = ~poor
                return flags | group(index[keep], which[keep], rows)
            refuse_unclosed(done, residual, tt, "batch", self.scaling.size)
            if jump.max() > BRANCH_JUMP:
                k = int(np.argmax(jump))
                raise MechanismError("time", f"at t = {tt[k]:.6g} s the solution lies {jump[k]:.3g} (scaled) from "
                                             "the continuation's prediction: a branch point or near-singular position")
            state = multipliers(self.c, self.forces, pose, tt, rows, *solved)
            condition[index] = state.condition
            table[0, index] = tt
            self._columns(state, reactions, table[1:], index)
            if found.redundant and reactions:    # −Φqᵀ·λ per body: unique however λ is split
                resultants[:, index] = -np.einsum("nrk,nr->kn", state.jac, state.lam)
                return self._undetermined(state)
            return np.zeros(len(columns) - 1, dtype=bool)

        pool = ThreadPoolExecutor(max_workers=min(len(parts), os.cpu_count() or 1))
        try:
            for flags in pool.map(batch, parts):
                undetermined[1:] |= flags
        finally:
            pool.shutdown(cancel_futures=True)
        if condition.max() > SINGULAR_CONDITION:
            k = int(np.argmax(condition))
            raise MechanismError("time", f"the Jacobian is singular at t = {t[k]:.6g} s (condition "
                                         f"{condition[k]:.3g} > {SINGULAR_CONDITION:.0e})")
        frame, missing = self.finish(table, undetermined, found, resultants, reactions)
        facts = {"method": METHOD, "grubler": found.grubler, "mobility": found.mobility, "rank": found.rank,
                 "redundant_constraints": found.redundant, "condition_max": float(condition.max()),
                 "continuation_nodes": len(nodes)}
        return SpatialSolution(frame, missing, found, facts, condition)

    def march(self, continuation: tuple, which: np.ndarray, t: np.ndarray, rows: tuple[int, ...],
              index: np.ndarray) -> tuple:
        """Positions and rates of a batch instant after instant (`chord`)
        from the continuation's nodes (their G, A, w, ẇ and t stacked;
        `which`: each instant's node): the solved poses, which instants'
        rows are poor, which settled, their closing residuals, their
        distances from the nodes' predictions, and `motion.velocities`'
        outputs. `index`: the instants' places in the run (an instant
        follows the one before it in the run, or is solved afresh)."""
        c = self.c
        joint, shape, first, second = c.table_rows
        follows = np.concatenate([[False], np.diff(index) == 1])
        if getattr(self._buffers, "jac", np.empty(0)).shape[:1] < t.shape:      # this thread's, reused
            self._buffers.jac, self._buffers.lu = np.empty((len(t), c.m, c.n)), np.empty((len(t), c.n, c.n))
        G, A, *rest = chord.march(
            *continuation, np.ascontiguousarray(which, dtype=np.int64), t, c.laws(t), *c.table_joints, shape, joint,
            first, second, np.array(rows, dtype=np.int64), self.scaling.row, self.scaling.column, follows,
            REPICK_CONDITION, CHORD, NEWTON_ITERATIONS, ROUNDING, STAGNATION, self._buffers.jac, self._buffers.lu)
        return Pose(G, A), *rest

    def rows_at(self, pose: Pose, t: np.ndarray, rows: tuple[int, ...],
                found: Structure) -> tuple[tuple[int, ...], np.ndarray, LU]:
        """Rows to keep near `pose`: `rows`, unless their scaled Jacobian's
        condition exceeds REPICK_CONDITION at some instant, then rows
        picked afresh at the first such instant; which instants those are;
        and the LU factors of `rows`' Jacobian at `pose` (Newton's first)."""
        J = self.c.evaluate(pose, t)["jac"]
        idx = list(rows)
        lu = LU(kept(J, rows))
        poor = lu.condition(self.scaling.row[idx], self.scaling.column) > REPICK_CONDITION
        if not poor.any():
            return rows, poor, lu
        k = int(np.argmax(poor))
        return kept_rows(self.c, self.scaling.jacobian(J[k]), self.c.n - found.mobility), poor, lu

    # -- columns ------------------------------------------------------------------------------

    def finish(self, table: np.ndarray, undetermined: np.ndarray, found: Structure,
               resultants: np.ndarray, reactions: bool = True) -> tuple[pd.DataFrame, dict[str, str]]:
        """The raw frame from a table of columns: reactions that are not
        unique blanked with their reason, resultants added where rows are
        redundant; without `reactions`, the motion columns only."""
        columns = ["t"] + self.system.motion_columns() + self.system.reaction_columns()
        if not reactions:
            motion = columns[:1 + len(self.system.motion_columns())]
            return pd.DataFrame(table[:len(motion)].T, columns=motion, copy=False), {}
        frame = pd.DataFrame(table.T, columns=columns, copy=False)
        missing = {}
        for k in np.flatnonzero(undetermined):
            frame[columns[k]] = np.nan
            missing[columns[k]] = (f"not unique: {found.redundant} redundant constraint"
                                   f"{'s' if found.redundant != 1 else ''} (Jacobian rank {found.rank} of "
                                   f"{found.rows} rows) make this reaction statically indeterminate")
        if found.redundant:
            names = resultant_columns(self.system)
            frame = frame.assign(**dict(zip(names, resultants)))
        return frame, missing

    def frame_of(self, s: State, found: Structure, reactions: bool = True) -> tuple[pd.DataFrame, dict[str, str]]:
        """`finish` for one state (the dynamics' outputs; without
        `reactions` its Jacobian and multipliers are not read)."""
        table = np.concatenate([s.t[None], self._columns(s, reactions)])
        flags = np.zeros(len(table), dtype=bool)
        if not reactions:
            return self.finish(table, flags, found, np.empty((0, len(s.t))), reactions)
        if found.redundant:
            flags[1:] = self._undetermined(s)
        return self.finish(table, flags, found, -np.einsum("nrk,nr->kn", s.jac, s.lam), reactions)

    def _columns(self, s: State, reactions: bool = True, out: np.ndarray | None = None,
                 index: np.ndarray | None = None) -> np.ndarray:
        """The raw columns after t (motion, then reactions unless not
        `reactions`), (columns, N); or into the columns `index` of `out`
        (the solution's table, C-ordered: its rows after t)."""
        N, motion = len(s.t), len(self.system.motion_columns())
        if out is None:
            out = np.empty((motion + (len(self.system.reaction_columns()) if reactions else 0), N))
            index = np.arange(N)
        outputs.motion_columns(*(np.ascontiguousarray(x) for x in (s.pose.G, s.pose.A, s.w.reshape(N, -1),
                                                                   s.dw.reshape(N, -1))),
                               self._com, out[:motion], index)
        if reactions:
            self.reactions(s, s.lam, True, out[motion:], index)
        return out

    def reactions(self, s: State, lam: np.ndarray, applied: bool = True, out: np.ndarray | None = None,
                  index: np.ndarray | None = None) -> np.ndarray:
        """Raw reaction columns from multipliers `lam`, (columns, N) (or
        into `out`'s columns `index`, as `_columns`): linear in them but for
        the joint torques' applied values (zeros unless `applied`)."""
        if out is None:
            out, index = np.empty((len(self.system.reaction_columns()), len(s.t))), np.arange(len(s.t))
        outputs.reaction_columns(*(np.ascontiguousarray(x) for x in (s.pose.G, s.pose.A, s.jac, lam)),
                                 *self._reaction_table, out, index)
        first = len(self.system.reaction_columns()) - len(self.system.torques)
        for k, tq in enumerate(self.system.torques):
            out[first + k, index] = np.asarray(tq.law.value(s.t), dtype=float) if applied else 0.0
        return out

    def _undetermined(self, s: State) -> np.ndarray:
        """Per raw column (motion ones never): does a null vector of Φqᵀ reach it?"""
        idx = list(s.rows)
        dependent = [k for k in range(self.c.m) if k not in s.rows]
        J = s.jac
        # each dependent row as a combination of the kept ones (least squares:
        # the dynamics keep fewer rows than coordinates)
        kept, rest = np.swapaxes(J[:, idx], 1, 2), np.swapaxes(J[:, dependent], 1, 2)
        coefficients = np.linalg.solve(kept, rest) if len(idx) == J.shape[2] else np.linalg.pinv(kept) @ rest
        flags = np.zeros(len(self.system.reaction_columns()), dtype=bool)
        scale = np.array([1.0 if q.startswith("F") else 1 / self.scaling.size
                          for j in self.system.joints for q in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")]
                         + [1.0] * (len(flags) - 6 * len(self.system.joints)))
        for col, k in enumerate(dependent):
            null = np.zeros((len(s.t), self.c.m))
            null[:, k] = 1.0
            null[:, idx] = -coefficients[:, :, col]
            reached = np.abs(self.reactions(s, null, applied=False)) * scale[:, None]
            flags |= (reached > UNIQUE_TOL * reached.max(axis=0, keepdims=True)).any(axis=1)
        motion = len(self.system.motion_columns())
        return np.concatenate([np.zeros(motion, dtype=bool), flags])


def predict(node: State, t: np.ndarray) -> Pose:
    """Second-order Taylor prediction from a solved node, rotations on the group."""
    dt = (t - node.t[0])[:, None, None]
    G = node.pose.G + node.w[:, :, :3] * dt + 0.5 * node.dw[:, :, :3] * dt * dt
    A = exp_map(node.w[:, :, 3:] * dt + 0.5 * node.dw[:, :, 3:] * dt * dt) @ node.pose.A
    return Pose(G, A)


def flat_difference(a: Pose, b: Pose) -> np.ndarray:
    """(δG, δπ) from b to a per instant, (N, n): δπ the small rotation A_a·A_bᵀ."""
    R = a.A @ np.swapaxes(b.A, -1, -2)
    dpi = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    return np.concatenate([a.G - b.G, dpi], axis=-1).reshape(len(a), -1)


def solve_spatial(system: SpatialSystem, t: np.ndarray, reactions: bool = True) -> SpatialSolution:
    """The spatial reference's raw columns of `system` at instants t."""
    return SpatialSolver(system).solve(t, reactions)
