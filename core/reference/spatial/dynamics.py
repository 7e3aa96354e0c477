"""Forward dynamics of a spatial system: the motion under gravity, applied
loads, springs, dampers and joint torques from a stated initial state,
with the checks a user reads (energy, momentum, constraint drift).

Equations (Nikravesh 1988, §11.6; Haug 1989, ch. 11): per body
M·ẇ + Φqᵀ·λ = Q (`forces`) with the joints' rows and any drives', and
Φq·ẇ = γ; solved at every evaluation as one square system in (ẇ, λ)
with the independent rows only (`structure`), so redundant rows cost
nothing; picked afresh where their condition grows past REPICK_GROWTH times the
assembly's (a redundant mechanism's kept rows can turn dependent along
the motion while all its rows keep their rank: Bricard's do for half
the picks). The state integrated by scipy's DOP853 (Hairer, Nørsett &
Wanner, *Solving ODEs I*, §II.10), or for stiff force elements its Radau
IIA (implicit, order 5; *Solving ODEs II*, §IV.8) with a Jacobian by
batched forward differences, is per body G, its unit quaternion
p (ṗ = ½·(0, ω) ⊗ p, no singular attitude), Ġ and ω; the quaternion is
normalised where it is read. The constraints are integrated at the
acceleration level, so positions and velocities drift from them by the
integration error: the facts state that drift (scaled residuals) at the
outputs, with the energy and momentum a conservative run keeps.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
from scipy.integrate import solve_ivp

from mechval.reference.dynamics import MAX_EVALUATIONS
from mechval.reference.planar.constraints import MechanismError
from mechval.reference.spatial.forces import AppliedForces, mass_matrix, world_inertia
from mechval.reference.spatial.joints import Pose
from mechval.reference.spatial.rotation import cross, matrix_to_quaternion, quaternion_rate, quaternion_to_matrix
from mechval.reference.spatial.solver import SpatialSolution, SpatialSolver, State
from mechval.reference.spatial.structure import initial_pose, kept_rows, newton, structure
from mechval.reference.spatial.system import SpatialSystem

RTOL = 1e-12
ATOL = 1e-14
METHODS = {
    "DOP853": "DOP853 on (G, quaternion, Ġ, ω), constraints at the acceleration level (Nikravesh 1988, §11.6)",
    "Radau": "Radau IIA (order 5, implicit) on (G, quaternion, Ġ, ω), constraints at the acceleration level "
             "(Nikravesh 1988, §11.6; Hairer & Wanner, Solving ODEs II, §IV.8)",
}
#: A redundant mechanism's kept rows are picked afresh where their scaled
#: Jacobian's σmax/σmin grows past this multiple of its value at the
#: assembly's pick: the drift of the acceleration-level constraints grows
#: with it (tests/test_spatial_benchmarks.py bounds what it moves
#: Bricard's trajectory), and a multiple, not a bound, leaves a mechanism
#: ill-conditioned from the start to keep its rows.
REPICK_GROWTH = 5.0
#: Outputs evaluated at once after the integration (memory, not accuracy).
OUTPUT_CHUNK = 2048
#: Forward-difference step of the implicit method's Jacobian, relative to
#: each state component (at least FD_FLOOR): about √ε.
FD_STEP, FD_FLOOR = 1e-7, 1e-3


def energy(system: SpatialSystem, pose: Pose, w: np.ndarray) -> np.ndarray:
    """Kinetic plus gravitational energy (J), per instant (springs' energy is
    the caller's: `Spring` has its length and stiffness)."""
    J = world_inertia(system, pose)
    g = np.asarray(system.gravity, dtype=float)
    total = np.zeros(len(pose))
    for k, b in enumerate(system.bodies):
        v, om = w[:, k, :3], w[:, k, 3:]
        total += 0.5 * b.mass * np.einsum("ni,ni->n", v, v) + 0.5 * np.einsum("ni,nij,nj->n", om, J[:, k], om)
        total -= b.mass * pose.G[:, k] @ g
    return total


def momentum(system: SpatialSystem, pose: Pose, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear momentum and angular momentum about the world origin (N, 3) each."""
    J = world_inertia(system, pose)
    linear, angular = np.zeros((len(pose), 3)), np.zeros((len(pose), 3))
    for k, b in enumerate(system.bodies):
        p = b.mass * w[:, k, :3]
        linear += p
        angular += cross(pose.G[:, k], p) + np.einsum("nij,nj->ni", J[:, k], w[:, k, 3:])
    return linear, angular


def _condition(J: np.ndarray) -> np.ndarray:
    """σmax/σmin of each (rows, n) matrix of J."""
    s = np.linalg.svd(J, compute_uv=False)
    return s[:, 0] / s[:, -1]


class SpatialDynamics:
    """Integrate a spatial system from its bodies' stated poses and the
    given initial velocities: per body name, (velocity of the frame
    origin, angular velocity), world axes; missing bodies start at rest."""

    def __init__(self, system: SpatialSystem, velocities: Mapping[str, tuple] | None = None, t0: float = 0.0):
        self.system = system
        self.solver = SpatialSolver(system)
        c = self.c = self.solver.c
        self.forces = AppliedForces(c)
        pose = newton(c, self.solver.scaling, initial_pose(c), np.array([t0]), None)
        self.found = structure(c, self.solver.scaling, pose)
        self.rows = list(self.found.independent)
        if self.found.redundant:
            scaled = self._scaled(c.evaluate(pose, np.array([t0]))["jac"])
            self.assembly_condition = float(_condition(scaled[:, self.rows])[0])
        nb = len(system.bodies)
        w = np.zeros((1, nb, 6))
        for k, b in enumerate(system.bodies):
            v, om = (np.asarray(x, dtype=float) for x in (velocities or {}).get(b.name, ((0, 0, 0), (0, 0, 0))))
            w[0, k, 3:] = om
            w[0, k, :3] = v + cross(om, pose.A[0, k] @ np.asarray(b.com, dtype=float))
        # the nearest consistent velocities: w − Jᵀ(J·Jᵀ)⁻¹(J·w − rhs)
        out = c.evaluate(pose, np.array([t0]), w)
        J = out["jac"][0, self.rows]
        if len(self.rows):
            miss = J @ w[0].ravel() - out["rhs"][0, self.rows]
            w[0] = (w[0].ravel() - J.T @ np.linalg.solve(J @ J.T, miss)).reshape(nb, 6)
        self.t0, self.pose0, self.w0 = t0, pose, w
        self.evaluations, self.calls, self.limit, self.repicks = 0, 0, None, 0

    def accelerations(self, pose: Pose, w: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ẇ (N, nb, 6) and λ (N, m) from the square system [M Φqᵀ; Φq 0]."""
        c, n = self.c, self.c.n
        out = c.evaluate(pose, t, w)
        rows = self._rows_for(out["jac"])
        J = out["jac"][:, rows]
        K = np.zeros((len(t), n + len(rows), n + len(rows)))
        K[:, :n, :n] = mass_matrix(self.system, pose)
        K[:, :n, n:], K[:, n:, :n] = np.swapaxes(J, 1, 2), J
        rhs = np.concatenate([self.forces.generalised(pose, w, t), out["gamma"][:, rows]], axis=1)
        x = np.linalg.solve(K, rhs[..., None])[..., 0]
        lam = np.zeros((len(t), c.m))
        lam[:, rows] = x[:, n:]
        return x[:, :n].reshape(len(t), -1, 6), lam

    def _rows_for(self, jac: np.ndarray) -> list[int]:
        """The kept rows at states whose Jacobian is `jac` (N, m, n): those
        kept so far, or, where their scaled Jacobian's σmax/σmin passes
        REPICK_GROWTH times the assembly's at one of the states, rows
        picked afresh at the worst (these become the kept ones). A
        mechanism without redundant rows keeps all of them: nothing to
        pick."""
        if not self.found.redundant:
            return self.rows
        scaled = self._scaled(jac)
        condition = _condition(scaled[:, self.rows])
        if (condition > REPICK_GROWTH * self.assembly_condition).any():
            worst = int(np.argmax(condition))
            self.rows = list(kept_rows(self.c, scaled[worst], self.c.n - self.found.mobility))
            self.repicks += 1
        return self.rows

    def _scaled(self, jac: np.ndarray) -> np.ndarray:
        return jac * self.solver.scaling.row[:, None] * self.solver.scaling.column

    def _unpack(self, y: np.ndarray) -> tuple[Pose, np.ndarray]:
        """y (N, 13·nb) → pose and velocities."""
        nb = len(self.system.bodies)
        G = y[:, :3 * nb].reshape(-1, nb, 3)
        p = y[:, 3 * nb:7 * nb].reshape(-1, nb, 4)
        w = y[:, 7 * nb:].reshape(-1, nb, 6)
        return Pose(G, quaternion_to_matrix(p)), w

    def _rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        self.calls += 1
        if self.limit and self.calls % (self.limit // 10) == 0:
            self._check_progress(t)
        return self._rates(t, y[None])[0]

    def _check_progress(self, t: float) -> None:
        """Refuse a run that reaches the evaluation limit (as the planar
        integration's, README "Limits"), or, from a tenth of it on, one
        that at its pace would need ten times the limit: a hopelessly stiff
        scene ends in seconds rather than after the whole limit."""
        start, end = self.span
        done = (t - start) / (end - start)
        needed = self.calls / done if done > 0 else np.inf
        if self.calls >= self.limit or needed > 10 * self.limit:
            raise MechanismError("time.end", f"the reference's integration reached only t = {t:.6g} s of "
                                             f"{end:g} s in {self.calls:,} evaluations (the run would need about "
                                             f"{needed:.3g}, the limit is {self.limit:,}); shorten time.end")

    def _rates(self, t: float, Y: np.ndarray) -> np.ndarray:
        """ẏ at states Y (N, 13·nb), all at time t, in one batched solve."""
        self.evaluations += len(Y)
        nb = len(self.system.bodies)
        pose, w = self._unpack(Y)
        dw, _ = self.accelerations(pose, w, np.full(len(Y), t))
        p = Y[:, 3 * nb:7 * nb].reshape(len(Y), nb, 4)
        p = p / np.linalg.norm(p, axis=2, keepdims=True)
        return np.concatenate([w[:, :, :3].reshape(len(Y), -1), quaternion_rate(p, w[:, :, 3:]).reshape(len(Y), -1),
                               dw.reshape(len(Y), -1)], axis=1)

    def _jacobian(self, t: float, y: np.ndarray) -> np.ndarray:
        """∂ẏ/∂y by forward differences, every column in one batched call
        (the implicit method's Newton matrix; its accuracy sets how fast
        Newton converges, not the solution's)."""
        h = FD_STEP * np.maximum(np.abs(y), FD_FLOOR)
        F = self._rates(t, np.vstack([y, y + np.diag(h)]))
        return ((F[1:] - F[0]) / h[:, None]).T

    def _outputs(self, pose: Pose, w: np.ndarray, t: np.ndarray, full: bool = True) -> tuple:
        """ẇ, λ, Φq and the largest scaled position and velocity drifts at
        some outputs (`solve` asks in chunks: an (N, m, n) Jacobian of a
        dense grid at once would take hundreds of MB); not `full`: ẇ and λ
        only (the motion alone)."""
        dw, lam = self.accelerations(pose, w, t)
        if not full:
            return dw, lam, None, np.nan, np.nan
        out = self.c.evaluate(pose, t, w)
        row = self.solver.scaling.row
        rates = np.einsum("nrk,nk->nr", out["jac"], w.reshape(len(t), -1)) - out["rhs"]
        return (dw, lam, out["jac"], float(np.abs(out["phi"] * row).max(initial=0.0)),
                float(np.abs(rates * row).max(initial=0.0)))

    def initial_vector(self) -> np.ndarray:
        w, p = self.w0[0], matrix_to_quaternion(self.pose0.A[0])
        return np.concatenate([self.pose0.G[0].ravel(), p.ravel(), w.ravel()])

    def solve(self, t: np.ndarray, rtol: float = RTOL, atol: float = ATOL, method: str = "DOP853",
              reactions: bool = True) -> SpatialSolution:
        """The motion at instants t, integrated by `method`: "DOP853"
        (explicit, the default) or "Radau" (implicit, order 5, for stiff
        force elements, with `_jacobian`); without `reactions`, the motion
        columns only (`SpatialSolver.solve`)."""
        if method not in METHODS:
            raise MechanismError("method", f"unknown integrator {method!r} (known: {', '.join(METHODS)})")
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or not t.size or not np.isfinite(t).all() or np.any(np.diff(t) <= 0) or t[0] != self.t0:
            raise MechanismError("time", "instants must be finite, increasing and start at the initial state's")
        # the explicit method's evaluations are bounded as the planar
        # integration's; the implicit one is for stiff runs a caller chooses
        self.calls, self.limit = 0, MAX_EVALUATIONS if method == "DOP853" else None
        self.span = (float(t[0]), float(t[-1]))
        if len(t) == 1:         # the initial state itself (scipy integrates no empty span)
            states, steps = self.initial_vector()[None], 1
        else:
            try:
                with np.errstate(over="raise", invalid="raise", divide="raise"):
                    run = solve_ivp(self._rhs, (t[0], t[-1]), self.initial_vector(), method=method, t_eval=t,
                                    rtol=rtol, atol=atol, **({"jac": self._jacobian} if method == "Radau" else {}))
            except (FloatingPointError, np.linalg.LinAlgError) as exc:
                raise MechanismError("time", f"the integration fails ({exc}): loads out of scale for the masses "
                                             "and sizes, or a position where the joints' rows turn dependent") from None
            if run.status != 0:
                raise MechanismError("time", f"the integration stopped: {run.message}")
            states, steps = run.y.T, int(run.t.size)
        pose, w = self._unpack(states)
        parts = [self._outputs(Pose(pose.G[k], pose.A[k]), w[k], t[k], reactions)
                 for k in (slice(s, s + OUTPUT_CHUNK) for s in range(0, len(t), OUTPUT_CHUNK))]
        dw, lam = (np.concatenate([p[k] for p in parts]) for k in (0, 1))
        jac = np.concatenate([p[2] for p in parts]) if reactions else None
        drift_q, drift_v = max(p[3] for p in parts), max(p[4] for p in parts)
        state = State(t, pose, w, dw, lam, jac, tuple(self.rows))
        frame, missing = self.solver.frame_of(state, self.found, reactions)
        E = energy(self.system, pose, w)
        facts = {"method": METHODS[method], "rtol": rtol, "atol": atol, "steps": steps,
                 "evaluations": self.evaluations, "constraint_drift_max": float(drift_q),
                 "velocity_drift_max": float(drift_v), "energy_change_max": float(np.abs(E - E[0]).max()),
                 "mobility": self.found.mobility, "redundant_constraints": self.found.redundant,
                 "rows_picked_afresh": self.repicks}
        return SpatialSolution(frame, missing, self.found, facts)
