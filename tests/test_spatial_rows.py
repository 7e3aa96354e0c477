"""The spatial reference's compiled pieces checked independently: the
constraint rows (`assembly`, encoded from `joints.ROW_NAMES`) against
finite differences of Φ on the group, for every joint kind and both
drive kinds; the LU solves and condition (`lu`) against numpy's."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import qr

from mechval.model.drive import DriveLaw
from mechval.model.mechanism import GROUND
from mechval.reference.spatial.joints import Constraints, Pose
from mechval.reference.spatial.lu import LU
from mechval.reference.spatial.rotation import exp_map, frame_from_axis
from mechval.reference.spatial.structure import Scaling, initial_pose, moved, newton, pivoted_rows
from mechval.reference.spatial.system import JOINT_KINDS, SpatialBody, SpatialDrive, SpatialJoint, SpatialSystem
from spatial_benchmarks import Bricard
from spatial_mechanisms import inertia

#: Central differences with step H: truncation ~H² times the rows' third
#: derivatives (order one here), rounding ~eps/H (2e-11 per unit of Φ);
#: measured 7.8e-11 (Φq) and 8.3e-10 (Φ̇).
H = 1e-5
FIRST = 1e-8
#: The second difference: truncation ~H2², rounding ~eps/H2² = 2e-8 per
#: unit of Φ (|Φ| up to ~5 here); measured 1.9e-8 of γ's peak.
H2 = 1e-4
SECOND = 1e-6
#: numpy's LAPACK and our LU round differently: a few eps times the condition (≤ 1e3 here).
SOLVE = 1e-11


def every_kind() -> SpatialSystem:
    """Four bodies joined by every joint kind (no mobility needed: only the
    rows are evaluated), a revolute and a prismatic drive."""
    rng = np.random.default_rng(7)
    frame = lambda: frame_from_axis(rng.standard_normal(3), rng.standard_normal(3))   # noqa: E731
    point = lambda: tuple(rng.standard_normal(3))                                    # noqa: E731
    bodies = tuple(SpatialBody(f"b{k}", 1.0, point(), inertia(k)) for k in range(4))
    names = [GROUND] + [b.name for b in bodies]
    ends = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 1), (0, 4), (2, 4)]     # the ground on either side
    joints = [SpatialJoint(f"J{k}", kind, names[i], names[j], point(), point(), frame(), frame())
              for k, (kind, (i, j)) in enumerate(zip(JOINT_KINDS, ends))]
    drives = (SpatialDrive(joints[0].name, DriveLaw(0.3, 1.1, 0.7), "turn"),
              SpatialDrive(joints[1].name, DriveLaw(0.1, -0.4, 0.9), "slide"))
    assert (joints[0].kind, joints[1].kind) == ("revolute", "prismatic")
    return SpatialSystem("every kind", bodies, tuple(joints), drives)


@pytest.fixture(scope="module")
def rows():
    system = every_kind()
    rng = np.random.default_rng(3)
    nb = len(system.bodies)
    pose = Pose(rng.standard_normal((4, nb, 3)), exp_map(rng.standard_normal((4, nb, 3))))
    return Constraints(system), pose, rng.standard_normal((4, nb, 6)), rng.uniform(0.0, 2.0, 4)


def test_every_row_kind_is_encoded(rows):
    c, *_ = rows
    kinds = {r.kind for r in c.rows}
    assert {"dx", "xi.zj", "yi.d", "zi.d", "xi.yj", "zi.zj", "drive"} <= kinds


def test_jacobian_is_the_derivative_of_the_rows_on_the_group(rows):
    c, pose, w, t = rows
    J = c.evaluate(pose, t)["jac"]
    for k in range(c.n):
        step = np.zeros((len(t), c.n))
        step[:, k] = H
        ahead, behind = (c.evaluate(moved(pose, s), t, jacobian=False)["phi"] for s in (step, -step))
        error = np.abs((ahead - behind) / (2 * H) - J[:, :, k]).max()
        assert error <= FIRST, f"column {k}: Φq off its central difference by {error:.3g}"


def test_rates_and_gamma_are_the_derivatives_along_a_motion(rows):
    """Along G(s) = G + s·Ġ, A(s) = exp(s·ω̃)·A, t + s (ẇ = 0 on this path):
    Φ̇ = Φq·w − (−Φt) and Φ̈ = −γ."""
    c, pose, w, t = rows
    out = c.evaluate(pose, t, w)
    at = lambda s: c.evaluate(moved(pose, s * w.reshape(len(t), -1)), t + s, jacobian=False)["phi"]   # noqa: E731
    rate = np.einsum("nrk,nk->nr", out["jac"], w.reshape(len(t), -1)) - out["rhs"]
    first = np.abs((at(H) - at(-H)) / (2 * H) - rate).max()
    second = np.abs((at(H2) - 2 * out["phi"] + at(-H2)) / H2 ** 2 + out["gamma"]).max()
    assert first <= FIRST, f"Φ̇ off its central difference by {first:.3g}"
    assert second <= SECOND * max(1.0, np.abs(out["gamma"]).max()), f"γ off −Φ̈ by {second:.3g}"


def test_lu_solves_as_numpy_does():
    rng = np.random.default_rng(5)
    J = rng.standard_normal((50, 12, 12)) * (rng.random((50, 12, 12)) < 0.4) + 3 * np.eye(12)
    b = rng.standard_normal((50, 12))
    lu = LU(J)
    x, y = np.linalg.solve(J, b[..., None])[..., 0], np.linalg.solve(np.swapaxes(J, 1, 2), b[..., None])[..., 0]
    assert np.abs(lu.solve(b) - x).max() <= SOLVE * np.abs(x).max()
    assert np.abs(lu.solve_transposed(b) - y).max() <= SOLVE * np.abs(y).max()
    row, column = rng.uniform(0.5, 2.0, 12), rng.uniform(0.5, 2.0, 12)
    expected = np.linalg.cond(J * row[:, None] * column, 1)
    assert np.abs(lu.condition(row, column) / expected - 1).max() <= SOLVE


def test_lu_refuses_a_singular_matrix():
    J = np.eye(4)[None].repeat(2, axis=0)
    J[1, 2] = J[1, 1]
    with pytest.raises(np.linalg.LinAlgError):
        LU(J)


@pytest.mark.parametrize("angle", [0.0, 3e-5, 0.3, 3.0])
def test_the_compiled_group_update_is_rodrigues(angle):
    """`chord`'s update A ← exp(φ̃)·A against `rotation.exp_map`, either
    side of its series switch."""
    from mechval.reference.spatial.chord import _turn
    rng = np.random.default_rng(11)
    phi = angle * frame_from_axis(rng.standard_normal(3))[:, 2]
    A = exp_map(rng.standard_normal(3))
    expected = exp_map(phi) @ A
    poses = A[None, None].copy()          # (instants, bodies, 3, 3), as `march` holds them
    _turn(*phi, poses, 0, 0, np.empty((3, 3)), np.empty((3, 3)))
    assert np.abs(poses[0, 0] - expected).max() <= 4 * np.finfo(float).eps


def test_a_change_to_any_kernel_file_drops_every_cached_kernel(tmp_path, monkeypatch):
    """numba keys each cached kernel on its own file; `kernel` drops the
    whole cache when any kernel file changes (they inline each other)."""
    from mechval.reference.spatial import kernel
    (tmp_path / "kernel.py").write_text("kernel = ...\n")
    (tmp_path / "rows.py").write_text("@kernel\ndef f():\n    pass\n")
    (tmp_path / "plain.py").write_text("def g():\n    pass\n")
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    monkeypatch.setattr(kernel, "HERE", tmp_path)
    monkeypatch.setattr(kernel, "STAMP", cache / "kernels.sha256")
    compiled = cache / "rows.f-1.py311.nbi"
    compiled.write_text("")
    kernel.drop_stale_cache()               # no stamp yet: compiled from unknown files
    assert not compiled.exists() and (cache / "kernels.sha256").exists()
    compiled.write_text("")
    kernel.drop_stale_cache()
    (tmp_path / "plain.py").write_text("def g():\n    return 1\n")      # not a kernel file
    kernel.drop_stale_cache()
    assert compiled.exists()
    (tmp_path / "rows.py").write_text("@kernel\ndef f():\n    return 1\n")
    kernel.drop_stale_cache()
    assert not compiled.exists()


def test_a_batch_carried_from_instant_to_instant_closes_its_rows_to_rounding(monkeypatch):
    """Each instant starts from the one before's Taylor step; without
    making the carried rotations orthogonal again, their rounding walks
    (2.7e-14 scaled on the spherical four-bar within one batch of 1024,
    measured) and Newton cannot close the rows below it. Bound: 8 eps,
    the `settled` step size (the earlier march, from the continuation's
    predictions, reached 1.1e-15 on 2·10⁴ instants)."""
    from spatial_mechanisms import SphericalFourBar
    from mechval.reference.spatial.solver import SpatialSolver
    residuals = []
    march = SpatialSolver.march

    def kept(self, *args):
        out = march(self, *args)
        residuals.append(out[3])
        return out

    monkeypatch.setattr(SpatialSolver, "march", kept)
    SpatialSolver(SphericalFourBar().system).solve(np.linspace(0.0, 1.0, 4096))
    closing = np.concatenate(residuals)
    assert len(closing) == 4096 and closing.max() <= 8 * np.finfo(float).eps


def test_the_kept_rows_do_not_hang_on_the_last_bits():
    """`structure.pivoted_rows` picks the rows LAPACK's pivoted QR would,
    but a tie between rows (exact in a symmetric mechanism: Bricard's)
    goes to the first, so the rounding a machine's BLAS kernels leave
    (perturbations of a few eps here) does not change which rows are
    kept; and its pick is QR's where nothing ties: independent rows, as
    many as the rank, of a well-conditioned set."""
    c = Constraints(Bricard().system)
    scaling = Scaling(c)
    pose = newton(c, scaling, initial_pose(c), np.zeros(1), None)
    J = scaling.jacobian(c.evaluate(pose, np.zeros(1))["jac"][0])
    picked = pivoted_rows(J, 29)
    assert len(set(picked)) == 29 and np.linalg.matrix_rank(J[picked]) == 29
    rng = np.random.default_rng(3)
    for _ in range(20):
        noisy = J * (1 + 4 * np.finfo(float).eps * rng.standard_normal(J.shape))
        assert pivoted_rows(noisy, 29) == picked
    s = np.linalg.svd(J[picked], compute_uv=False)
    assert s[0] / s[-1] < 100, s[0] / s[-1]
    generic = rng.standard_normal((6, 6))
    assert sorted(pivoted_rows(generic, 4)) == sorted(qr(generic.T, pivoting=True)[2][:4].tolist())
