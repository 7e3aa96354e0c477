"""Forward dynamics of a planar mechanism: the motion under applied torque
laws, force elements, gravity and damping, integrated from a consistent
initial state (the reference for torque-driven and free scenes).

Equations of motion in absolute coordinates (Nikravesh 1988, ch. 6; Haug
1989, ch. 11): M·q̈ + Φqᵀ·λ = Q(q, q̇, t), with Φ the joints' rows and any
prescribed drives' (`mechval.reference.planar.constraints`), M and Q from
`mechval.reference.planar.forces` plus the `TorqueLaw`s (T on body_j, −T on body_i).

Minimal coordinates by coordinate partitioning (Wehage & Haug 1982): the
stated joints' coordinates z (`mechval.reference.initial_state`) are integrated,
y = (z, ż), by scipy's DOP853 (Hairer, Nørsett & Wanner, *Solving ODEs
I*, §II.10; or Radau) at RTOL. At every evaluation:
- positions q: Newton on Φ(q, t) = 0 with the coordinate rows held at z,
  from the previous evaluation's q moved by ∂q/∂z·Δz, to its fixed point;
- velocities: Φq·q̇ = −Φt with the coordinate rows' rates ż;
- accelerations: Φq·q̈ = γ + E·z̈ (E the coordinate rows' unit columns), so
  q̈ = q̈0 + B·z̈ with Φq·q̈0 = γ, Φq·B = E; projecting the equations of
  motion on B (Bᵀ·Φqᵀ = Eᵀ, and the coordinate rows carry no force) gives
  (Bᵀ·M·B)·z̈ = Bᵀ·(Q − M·q̈0), a k×k solve for k degrees of freedom.
The constraints hold to rounding at every evaluation: no drift, no
stabilisation. The integrator's evaluations, one instant each, solve with
Φq by LU (QR with redundant rows) of the scaled Jacobian; the outputs, in
batches, by the tree elimination of `mechval.reference.planar.tree`.

Output at the requested instants: z, ż from the dense output of the steps
that hold them;
q predicted by quintic Hermite interpolation between the accepted steps
(`mechval.reference.planar.positions.Nodes`) and corrected by Newton in batches, then
q̇, q̈ as above and the multipliers from M·q̈ + Φqᵀ·λ = Q, turned into the
prescribed reference's raw columns (`mechval.reference.planar.solver`, same signs).
A torque law's column holds the torque it applies. The facts state the
integrator, its tolerances, steps and evaluations, and the largest
constraint residual at the outputs (`constraint_drift_max`, scaled: lengths
over the mechanism's size).
"""

from __future__ import annotations

import dataclasses
import time
from collections import OrderedDict
from typing import Mapping, Sequence

import numpy as np
import pandas as pd
from scipy.integrate import DOP853, Radau
from scipy.linalg import qr, solve_triangular
from scipy.linalg.lapack import dgetrf, dgetrs

from mechval.reference.initial_state import SINGULAR_CONDITION, consistent_state, coordinate_name, with_coordinates
from mechval.model.mechanism import BodyPose, InitialValue, Mechanism
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.planar.linear import settled
from mechval.reference.planar.positions import Nodes
from mechval.reference.planar.solver import CHUNK, UNIQUE_TOL, PlanarSolver, Solution, default_pose

#: The integrator's relative tolerance by default. It bounds each step's
#: error; over a run the steps' errors add up, about in proportion to the
#: turns the run makes, and the accelerations and forces of a fast run
#: inherit the angles' absolute error times Ω². 1e-10 (issue 15) left a
#: four-bar spun up to 100 rad/s over 13 turns 1e-7 of its acceleration peak
#: off; 1e-13 keeps the reference within 1e-9 of each class's peak of a
#: tighter integration up to about 15 turns (tests/test_dynamics_accuracy.py
#: holds it, tests/bench/dynamics_accuracy.py prints the figures). Below
#: 100 ulp (2.2e-14) scipy takes 100 ulp.
RTOL = 1e-13
SOLVERS = {"DOP853": DOP853, "Radau": Radau}
METHODS = tuple(SOLVERS)
NEWTON_ITERATIONS = 30
#: Most right-hand-side evaluations of one integration (README "Limits"):
#: each solves the positions by Newton, up to 3 ms on a loaded shared
#: machine (tests/bench/dynamics_bench.py prints the time per evaluation),
#: so a refused run ends within the fuzz tests' 120 s bound on one case.
#: At RTOL it leaves room for 15 turns of a fast four-bar with a sixth to
#: spare (tests/test_dynamics_accuracy.py). A longer run is refused rather
#: than left running for many minutes.
MAX_EVALUATIONS = 35_000


#: A rate beyond this (rad/s, m/s, or their derivatives) ends the run: its
#: square would overflow float64 (about 1.8e308) in the next evaluation.
RATE_LIMIT = 1e150


class StoppedAt(Exception):
    """The integration stops at instant t (the subclasses say why)."""

    def __init__(self, t: float):
        super().__init__(t)
        self.t = t


class TooLong(StoppedAt):
    """The integration reached MAX_EVALUATIONS at instant t."""


class Overflows(StoppedAt):
    """The state left float64's range at instant t (loads out of scale)."""


class NoInertia(MechanismError):
    """The mass matrix along the stated coordinates is singular: a refusal
    of the scene itself, not a stop of the integration."""


def check_torque_laws(mech: Mechanism) -> None:
    """Refuse torque laws on unknown or prismatic joints and clashing names."""
    joints = {j.name: j for j in mech.joints}
    names = [d.name for d in mech.drives]
    for law in mech.torque_drives:
        key = f"torque.{law.name}"
        if law.joint not in joints:
            raise MechanismError(key, f"unknown joint {law.joint!r} (joints: {', '.join(sorted(joints))})")
        if joints[law.joint].kind != "revolute":
            raise MechanismError(key, f"joint {law.joint!r} is prismatic: a torque law acts at a revolute joint")
        values = (law.torque, law.amplitude, law.frequency, law.phase)
        if not all(np.isfinite(v) for v in values):
            raise MechanismError(key, f"torque, amplitude, frequency and phase must be finite, not {values}")
        if law.name in names:
            raise MechanismError(key, "another drive or torque law has this name")
        names.append(law.name)


class DenseFactor:
    """Solves with Φq at one instant (the integrator's evaluations): LU of
    the scaled Jacobian, or QR when redundant rows make it tall (the
    systems solved are consistent, so least squares is exact). Same
    interface as `mechval.reference.planar.tree.Factor` for one instant: r (1, m)."""

    def __init__(self, J: np.ndarray, row: np.ndarray, col: np.ndarray):
        Js = J * row[:, None] * col[None, :]
        self.row, self.col = row, col
        self.square = Js.shape[0] == Js.shape[1]
        # LAPACK's getrf/getrs called directly: what scipy's lu_factor and
        # lu_solve call, without their checks, which cost more than the
        # solve itself at this size, thousands of times per run
        self.lu = dgetrf(Js)[:2] if self.square else qr(Js, mode="economic", check_finite=False)

    def solve(self, r: np.ndarray) -> np.ndarray:
        rs = self.row * r[0]
        if self.square:
            return (self.col * dgetrs(*self.lu, rs)[0])[None]
        q, R = self.lu
        return (self.col * solve_triangular(R, q.T @ rs, check_finite=False))[None]


class ForwardDynamics:
    """Integrate one mechanism from its stated initial values (the
    mechanism's own unless given; see the module docstring)."""

    def __init__(self, mech: Mechanism, initial: Sequence[InitialValue] | None = None,
                 pose: Mapping[str, BodyPose] | None = None, t0: float = 0.0):
        check_torque_laws(mech)
        initial = mech.initial_values if initial is None else tuple(initial)
        self.mech = mech
        self.start = consistent_state(mech, initial, pose or default_pose(mech, t0), t0)
        self.joints = tuple(v.joint for v in initial)
        self.solver = PlanarSolver(with_coordinates(mech, self.joints))
        c = self.solver.c
        self.rows = np.array([c.drive_rows[coordinate_name(j)] for j in self.joints], dtype=int)
        self.k = len(self.joints)
        ends = lambda j: (c.index.get(j.body_i, -1), c.index.get(j.body_j, -1))
        self.torque_bodies = [ends(mech.joint(law.joint)) for law in mech.torque_drives]
        self._restart()

    def _restart(self) -> None:
        """Warm-start the next evaluation's Newton from the initial state."""
        self.evaluations = 0
        self._last = (self.start.t0, self.start.z, self.start.q[None], np.zeros((1, self.solver.c.n, self.k)))

    # -- the state at instants (batched) --------------------------------------------------------

    def _torques(self, t: np.ndarray) -> np.ndarray:
        """The torque laws' generalised forces (instants, n)."""
        Q = np.zeros((len(t), self.solver.c.n))
        for law, (i, j) in zip(self.mech.torque_drives, self.torque_bodies):
            T = law.value(t)
            if j >= 0:
                Q[:, 3 * j + 2] += T
            if i >= 0:
                Q[:, 3 * i + 2] -= T
        return Q

    def _dense(self, q: np.ndarray, f: dict, t: np.ndarray) -> DenseFactor:
        scaling = self.solver.scaling
        return DenseFactor(self.solver.c.jacobian(q, f)[0], scaling.row, scaling.column)

    def _positions(self, q: np.ndarray, t: np.ndarray, z: np.ndarray, factor_of=None):
        """Newton on Φ(q, t) = 0 with the coordinate rows at z, from q, to
        the fixed point; returns q, its frames and the factor of Φq one
        rounding-level step before it (as `PlanarSolver._correct`).
        `factor_of(q, frames, t)`: the tree elimination unless given."""
        factor_of = factor_of or self.solver._factor
        c, scaling = self.solver.c, self.solver.scaling
        previous = np.full(len(q), np.inf)
        done = np.zeros(len(q), dtype=bool)   # settled stays settled (as `PlanarSolver._correct`)
        for _ in range(NEWTON_ITERATIONS):
            f = c.frames(q)
            factor = factor_of(q, f, t)
            residual = c.residual(q, t, f)
            residual[:, self.rows] -= z
            dq = -factor.solve(residual)
            q = q + dq
            size = scaling.step(dq)
            done |= settled(size, previous, scaling.tolerance(q))
            if done.all():
                return q, f, factor
            previous = size
        k = int(np.flatnonzero(~done)[0])
        raise MechanismError("time", f"the loop cannot close at t = {t[k]:.6g} s with "
                                     f"{', '.join(self.joints)} at {np.round(z[k], 6).tolist()}: Newton does not "
                                     f"settle (last step {size[k]:.3g}, scaled)")

    def _rates(self, q, t, zdot, f, factor):
        """q̇, q̈, z̈, Q and B = ∂q/∂z at positions q (module docstring)."""
        c, mass = self.solver.c, self.solver.mass
        rhs = c.velocity_rhs(t)
        rhs[:, self.rows] += zdot
        v = factor.solve(rhs)
        a0 = factor.solve(c.gamma(q, v, t, f))
        B = np.empty((len(t), c.n, self.k))
        for col, row in enumerate(self.rows):
            unit = np.zeros((len(t), c.m))
            unit[:, row] = 1.0
            B[:, :, col] = factor.solve(unit)
        Q = self.solver.forces.generalised(q, v, f) + self._torques(t)
        projected = np.einsum("tik,ti->tk", B, Q - mass * a0)
        inertia = np.einsum("tik,til->tkl", B, mass[None, :, None] * B)
        try:
            zddot = np.linalg.solve(inertia, projected[..., None])[..., 0]
        except np.linalg.LinAlgError:
            k = int(np.argmin(np.abs(np.linalg.det(inertia))))
            raise NoInertia("time", f"at t = {t[k]:.6g} s the bodies carry no inertia along the motion of "
                                         f"{', '.join(self.joints)} (a singular mass matrix BᵀMB): massless links "
                                         "or a degenerate geometry") from None
        a = a0 + np.einsum("tik,tk->ti", B, zddot)
        return v, a, zddot, Q, B

    # -- the integration ------------------------------------------------------------------------

    def _state(self, t: float, y: np.ndarray):
        """q, q̇, q̈, z̈ at one instant, Newton starting from the previous
        evaluation's q moved by B·Δz (B = ∂q/∂z there)."""
        z, zdot = y[:self.k], y[self.k:]
        _, z_last, q_last, B_last = self._last
        tt = np.array([t])
        q, f, factor = self._positions(q_last + B_last @ (z - z_last), tt, z[None], self._dense)
        v, a, zddot, _, B = self._rates(q, tt, zdot[None], f, factor)
        self._last = (t, z, q, B)
        self.evaluations += 1
        return q[0], v[0], a[0], zddot[0]

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """dy/dt for y = (z, ż): the ODE integrated."""
        if self.evaluations >= MAX_EVALUATIONS:
            raise TooLong(t)
        try:
            with np.errstate(over="raise", invalid="raise"):
                rate = np.concatenate([y[self.k:], self._state(t, y)[3]])
        except FloatingPointError:
            raise Overflows(t) from None
        if not np.all(np.abs(rate) < RATE_LIMIT):     # also NaN
            raise Overflows(t)
        return rate

    def tolerances(self, rtol: float, span: float) -> np.ndarray:
        """Absolute tolerances of (z, ż): rtol times each coordinate's scale
        (1 rad, or the mechanism's size for a slide) and times a rate scale
        Ω = max(|ż0|, √|z̈0|, 1/span) for the rates (a run from rest at an
        equilibrium still has a time scale: its span)."""
        start = self.start
        unit = np.array([1.0 if self.mech.joint(j).kind == "revolute" else self.solver.scaling.size
                         for j in self.joints])
        rate = self.rhs(start.t0, np.concatenate([start.z, start.zdot]))[self.k:]
        omega = max(float(np.max(np.abs(start.zdot) / unit, initial=0.0)),
                    float(np.sqrt(np.max(np.abs(rate) / unit, initial=0.0))), 1.0 / span)
        return rtol * np.concatenate([unit, unit * omega])

    def _stopped(self, failure: str) -> MechanismError:
        """The refusal of a run that stopped, with the Jacobian's condition
        at the last state reached: where it grows without bound the stated
        joints' coordinates cannot parametrise the motion."""
        t, _, q, _ = self._last
        condition = float(self.solver._factor(q, self.solver.c.frames(q), np.array([t])).condition()[0])
        return MechanismError("time", f"the integration stops after t = {t:.6g} s ({failure}); the Jacobian's "
                                      f"condition there is {condition:.3g}: where it grows without bound, the "
                                      f"coordinates of {', '.join(self.joints)} cannot parametrise the motion (a "
                                      "toggle of those joints): state the initial values at other joints")

    def _nodes(self, ts: np.ndarray, ys: np.ndarray) -> Nodes:
        """q, q̇, q̈ at the accepted steps (each Newton-solved from the last,
        from the initial state on: the branch and the turns the run took)."""
        self._restart()
        states = [self._state(t, y)[:3] for t, y in zip(ts, ys.T)]
        nodes = Nodes(ts, *(np.array(x) for x in zip(*states)))
        self._check_partition(ts, self.solver._factor(nodes.q, self.solver.c.frames(nodes.q), ts).condition())
        return nodes

    def _check_partition(self, t: np.ndarray, condition: np.ndarray) -> None:
        """Refuse a run that passes where the stated joints' coordinates
        cannot parametrise the motion (as `mechval.reference.initial_state` refuses
        such a start: the same bound on the Jacobian's condition)."""
        if condition.max() > SINGULAR_CONDITION:
            k = int(np.argmax(condition > SINGULAR_CONDITION))
            raise MechanismError("time", f"at t = {t[k]:.6g} s the coordinates of {', '.join(self.joints)} cannot "
                                         f"parametrise the motion (Jacobian condition {condition[k]:.3g} > "
                                         f"{SINGULAR_CONDITION:.0e}: a toggle of those joints): state the initial "
                                         "values at other joints")

    def _integrate(self, t: np.ndarray, y0: np.ndarray, rtol: float, atol: np.ndarray, method: str):
        """Step the integrator from t0 to t[-1]: the accepted steps' instants
        and states, and the state at the instants t from the dense output of
        the steps that hold them, only those (DOP853's costs three more
        evaluations a step, and most steps of a fast run hold no instant)."""
        start = self.start
        solver = SOLVERS[method](self.rhs, start.t0, y0, float(t[-1]), rtol=rtol, atol=atol)
        instants, states = [start.t0], [y0]
        y = np.empty((len(y0), len(t)))
        done = int(np.searchsorted(t, start.t0, side="right"))
        y[:, :done] = y0[:, None]
        while solver.status == "running":
            message = solver.step()
            if solver.status == "failed":
                raise MechanismError("time", f"the integrator stopped: {message}")
            instants.append(solver.t)
            states.append(solver.y)
            end = int(np.searchsorted(t, solver.t, side="right"))
            if end > done:
                y[:, done:end] = solver.dense_output()(t[done:end])
                done = end
        return np.array(instants), np.array(states).T, y

    def solve(self, t: np.ndarray, rtol: float = RTOL, method: str = "DOP853") -> Solution:
        """Raw motion and reaction columns at instants t (nondecreasing,
        from the initial instant on). Radau, of order 5, needs many times
        DOP853's evaluations at RTOL: give it a looser rtol."""
        t = np.asarray(t, dtype=float)
        start = self.start
        if t.ndim != 1 or not t.size or not np.isfinite(t).all() or np.any(np.diff(t) < 0) or t[0] < start.t0:
            raise MechanismError("time", f"instants must be finite, nondecreasing and from t0 = {start.t0:g} s on")
        if method not in METHODS:
            raise MechanismError("method", f"unknown integrator {method!r} (known: {', '.join(METHODS)})")
        y0 = np.concatenate([start.z, start.zdot])
        t_end = float(t[-1])
        clock = time.perf_counter()
        if t_end > start.t0:
            try:
                atol = self.tolerances(rtol, t_end - start.t0)
                self._restart()
                instants, states, y = self._integrate(t, y0, rtol, atol, method)
                failure = ""
            except Overflows as error:
                raise MechanismError("time", f"the motion leaves float64's range at t = {error.t:.6g} s "
                                             f"(a rate beyond {RATE_LIMIT:.0e}): the scene's loads (gravity, torques, "
                                             "springs) are out of scale for its masses and sizes") from None
            except NoInertia:      # a refusal as it stands, not a stop to explain
                raise
            except TooLong as error:
                share = (error.t - start.t0) / (t_end - start.t0)
                raise MechanismError("time.end", f"the reference's integration reached only t = {error.t:.6g} s of "
                                                 f"{t_end:g} s in {MAX_EVALUATIONS:,} evaluations, the limit (the "
                                                 f"run would need about {1 / max(share, 1e-300):.3g} times as "
                                                 "many); shorten time.end") from None
            except MechanismError as error:
                failure = error.reason
            if failure:
                raise self._stopped(failure)
            steps, evaluations = len(instants) - 1, self.evaluations
            nodes = self._nodes(instants, states)
        else:
            atol, steps, evaluations = rtol * np.ones(2 * self.k), 0, 0
            y = np.repeat(y0[:, None], len(t), axis=1)
            nodes = self._nodes(np.array([start.t0]), y0[:, None])
        integration = time.perf_counter() - clock
        frame, missing, measured = self._output(t, y, nodes)
        facts = {"method": "forward dynamics: coordinate partitioning on the joints "
                           f"{', '.join(self.joints) or '(none)'}, absolute coordinates, constraint multipliers "
                           "(Wehage & Haug 1982, Haug 1989)",
                 "integrator": f"scipy.integrate.{method}", "rtol": rtol,
                 "atol": [float(x) for x in atol], "steps": steps, "evaluations": evaluations,
                 "integration_time_s": integration, "mobility": start.structure.mobility,
                 "redundant_constraints": start.structure.redundant, **measured}
        return Solution(frame, missing, start.structure, facts)

    # -- output ---------------------------------------------------------------------------------

    def _batch(self, t: np.ndarray, y: np.ndarray, nodes: Nodes) -> dict[str, np.ndarray]:
        z, zdot = y[:self.k].T, y[self.k:].T
        q, f, factor = self._positions(nodes.predict(t), t, z)
        v, a, _, Q, _ = self._rates(q, t, zdot, f, factor)
        lam = factor.solve_transposed(Q - self.solver.mass * a)
        residual = self.solver.c.residual(q, t)
        residual[:, self.rows] -= z
        return dict(q=q, v=v, a=a, lam=lam, frames=f, condition=factor.condition(),
                    drift=np.abs(residual * self.solver.scaling.row).max(axis=-1),
                    undetermined=factor.undetermined(self.solver.scaling.row, UNIQUE_TOL))

    def _output(self, t: np.ndarray, y: np.ndarray, nodes: Nodes):
        """The raw columns at t (y: the integrated state there), their
        missing reasons and measured facts."""
        solver, mech = self.solver, self.mech
        augmented = ["t"] + solver.mech.motion_columns() + solver.mech.reaction_columns()
        table = np.empty((len(augmented), len(t)))
        table[0] = t
        condition, drift = np.empty(len(t)), np.empty(len(t))
        undetermined = np.zeros(solver.c.m, dtype=bool)
        for start in range(0, len(t), CHUNK):
            part = slice(start, start + CHUNK)
            out = self._batch(t[part], y[:, part], nodes)
            condition[part], drift[part] = out["condition"], out["drift"]
            undetermined |= out["undetermined"]
            table[1:, part] = solver._columns(out)
        self._check_partition(t, condition)
        undetermined[self.rows] = False
        resultants = solver._resultants(undetermined, table, augmented)
        missing = solver._missing(undetermined, table, augmented, self.start.structure)
        columns = {name: table[k] for k, name in enumerate(augmented)} | resultants
        for law in mech.torque_drives:
            columns[f"{law.name}.T"] = law.value(t)
        names = ["t"] + mech.motion_columns() + mech.reaction_columns() + list(resultants)
        measured = {"constraint_drift_max": float(drift.max()), "condition_max": float(condition.max())}
        frame = pd.DataFrame({name: columns[name] for name in names})
        return frame, {k: v for k, v in missing.items() if k in names}, measured


#: Forward-dynamics runs kept per process, the oldest dropped past this many
#: bytes of frames: one scene's run is asked for by the reference adapter
#: and the report's drawing, and on the step rule's grid by every engine's
#: settings, limits check and audit (a 20,001-instant grid of a four-bar is
#: about 5 MB).
CACHED_BYTES = 256 * 2**20
_runs: OrderedDict = OrderedDict()


def raw_dynamics(mech: Mechanism, t: np.ndarray, initial: Sequence[InitialValue] | None = None,
                 pose: Mapping[str, BodyPose] | None = None, rtol: float = RTOL,
                 method: str = "DOP853") -> Solution:
    """The forward-dynamics reference's raw columns of `mech` at instants t,
    from the stated initial values (the mechanism's own unless given) at t[0];
    the last runs are kept, up to CACHED_BYTES (each caller gets its own frame)."""
    t = np.asarray(t, dtype=float)
    # The pose picks the branch but takes no part in a Mechanism's equality.
    key = (mech, tuple(sorted((pose or mech.assembly_pose).items())), tuple(initial or ()), t.tobytes(), rtol,
           method)
    if key not in _runs:
        _runs[key] = ForwardDynamics(mech, initial, pose, float(t[0]) if t.size else 0.0).solve(t, rtol, method)
        while len(_runs) > 1 and sum(run.frame.memory_usage().sum() for run in _runs.values()) > CACHED_BYTES:
            _runs.popitem(last=False)
    _runs.move_to_end(key)
    return dataclasses.replace(_runs[key], frame=_runs[key].frame.copy())
