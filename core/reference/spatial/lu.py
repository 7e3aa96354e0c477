"""Square solves of many small systems at once: one LU factorisation per
instant (partial pivoting, as LAPACK's dgetrf: Golub & Van Loan 2013,
Algorithm 3.4.1), reused for every solve with the matrix and with its
transpose, and for the 1-norm condition number (the inverse formed from
the factors, as LAPACK's dgetri, only for its column sums).

Compiled as `kernel` says (cached, releasing the GIL, so the
reference's batches run in threads). The loops skip the exact zeros of the sparse
Jacobians (skipping a zero changes no rounding). Figures are in
tests/bench/spatial_bench.py's output, not here.

A condition ESTIMATE (Higham 1988, LAPACK dlacn2) would cost fewer
solves, but measured on the built-ins it fell to 0.11 of the exact value
and was exact at only 25–80 % of the instants: the reported condition,
and the thresholds that read it, stay exact.
"""

from __future__ import annotations

import numpy as np

from mechval.reference.spatial.kernel import kernel


@kernel
def _factor(a: np.ndarray, piv: np.ndarray) -> bool:
    """LU of every a[k] in place (unit lower L below the diagonal, U on and
    above), row k swapped with piv[k] at step k; False if a pivot is zero."""
    N, n, _ = a.shape
    regular = True
    nonzero = np.empty(n, dtype=np.int64)
    for k in range(N):
        A = a[k]
        for j in range(n):
            p, big = j, abs(A[j, j])
            for i in range(j + 1, n):
                if abs(A[i, j]) > big:
                    p, big = i, abs(A[i, j])
            piv[k, j] = p
            if p != j:
                for c in range(n):
                    A[j, c], A[p, c] = A[p, c], A[j, c]
            if A[j, j] == 0.0:
                regular = False
                continue
            # the Jacobians are sparse (a tenth of the delta robot's entries):
            # only the pivot row's nonzeros update, only rows with a nonzero
            # below the pivot (skipping exact zeros changes no rounding)
            count = 0
            for c in range(j + 1, n):
                if A[j, c] != 0.0:
                    nonzero[count] = c
                    count += 1
            reciprocal = 1.0 / A[j, j]
            for i in range(j + 1, n):
                if A[i, j] != 0.0:
                    f = A[i, j] * reciprocal
                    A[i, j] = f
                    for q in range(count):
                        c = nonzero[q]
                        A[i, c] -= f * A[j, c]
    return regular


@kernel
def _solve_one(A: np.ndarray, piv: np.ndarray, x: np.ndarray) -> None:
    """x ← A⁻¹·x from A's LU (skipping the factors' exact zeros, as `_factor`)."""
    n = len(x)
    for j in range(n):
        p = piv[j]
        if p != j:
            x[j], x[p] = x[p], x[j]
    for i in range(n):
        s = x[i]
        for c in range(i):
            if A[i, c] != 0.0:
                s -= A[i, c] * x[c]
        x[i] = s
    for i in range(n - 1, -1, -1):
        s = x[i]
        for c in range(i + 1, n):
            if A[i, c] != 0.0:
                s -= A[i, c] * x[c]
        x[i] = s / A[i, i]


@kernel
def _solve_transposed_one(A: np.ndarray, piv: np.ndarray, x: np.ndarray) -> None:
    """x ← A⁻ᵀ·x from A's LU: Uᵀ then Lᵀ, then the swaps in reverse."""
    n = len(x)
    for i in range(n):       # Uᵀ by rows of U (contiguous): each x[c] still subtracts in the order c = 0, 1, …
        x[i] = x[i] / A[i, i]
        xi = x[i]
        for c in range(i + 1, n):
            if A[i, c] != 0.0:
                x[c] -= A[i, c] * xi
    for i in range(n - 1, -1, -1):
        s = x[i]
        for c in range(i + 1, n):
            if A[c, i] != 0.0:
                s -= A[c, i] * x[c]
        x[i] = s
    for j in range(n - 1, -1, -1):
        p = piv[j]
        if p != j:
            x[j], x[p] = x[p], x[j]


@kernel
def _solve(lu: np.ndarray, piv: np.ndarray, b: np.ndarray, transposed: bool) -> np.ndarray:
    x = b.copy()
    for k in range(len(b)):
        if transposed:
            _solve_transposed_one(lu[k], piv[k], x[k])
        else:
            _solve_one(lu[k], piv[k], x[k])
    return x


@kernel
def _inverse_norm(A, piv, row, column, X):
    """‖(Dr·J·Dc)⁻¹‖₁ from J's LU: X = J⁻¹ by solving J·X = I with all
    right-hand sides at once, row by row (whole rows of X at a time:
    contiguous, so compiled to vector instructions), skipping the zeros
    of the sparse factors."""
    n = len(piv)
    X[:] = 0.0
    for i in range(n):
        X[i, i] = 1.0
    for j in range(n):
        p = piv[j]
        if p != j:
            for q in range(n):
                X[j, q], X[p, q] = X[p, q], X[j, q]
    for i in range(n):
        for c in range(i):
            f = A[i, c]
            if f != 0.0:
                for q in range(n):
                    X[i, q] -= f * X[c, q]
    for i in range(n - 1, -1, -1):
        for c in range(i + 1, n):
            f = A[i, c]
            if f != 0.0:
                for q in range(n):
                    X[i, q] -= f * X[c, q]
        d = 1.0 / A[i, i]          # X only feeds the norm: a product's rounding instead of a quotient's
        for q in range(n):
            X[i, q] *= d
    sums = X[0]                    # row by row: contiguous; each column summed in row order still
    scale = 1.0 / column[0]
    for q in range(n):
        sums[q] = abs(sums[q]) * scale
    for i in range(1, n):
        scale = 1.0 / column[i]
        for q in range(n):
            sums[q] += abs(X[i, q]) * scale
    norm = 0.0
    for q in range(n):
        norm = max(norm, sums[q] / row[q])
    return norm


@kernel
def norm1(M, row, column, sums):
    """‖Dr·M·Dc‖₁, D = diag(row), diag(column); `sums` (n,) scratch. Row by
    row (contiguous), each column summed in row order."""
    sums[:] = 0.0
    for i in range(M.shape[0]):
        for c in range(M.shape[1]):
            sums[c] += abs(M[i, c] * row[i] * column[c])
    return sums.max()


@kernel
def _condition(J: np.ndarray, lu: np.ndarray, piv: np.ndarray, row: np.ndarray, column: np.ndarray) -> np.ndarray:
    """‖Dr·J·Dc‖₁·‖(Dr·J·Dc)⁻¹‖₁ per instant."""
    N, n, _ = J.shape
    out = np.empty(N)
    X = np.empty((n, n))
    sums = np.empty(n)
    for k in range(N):
        out[k] = norm1(J[k], row, column, sums) * _inverse_norm(lu[k], piv[k], row, column, X)
    return out


class LU:
    """The LU factors of J (N, n, n): solves with J and Jᵀ, the condition."""

    def __init__(self, J: np.ndarray):
        self.matrix = np.ascontiguousarray(J, dtype=float)
        self.lu = self.matrix.copy()
        self.piv = np.empty(J.shape[:2], dtype=np.int64)
        if not _factor(self.lu, self.piv):
            raise np.linalg.LinAlgError("Singular matrix")

    @classmethod
    def from_factors(cls, lu: np.ndarray, piv: np.ndarray) -> "LU":
        """The factors computed elsewhere (`motion`); no `condition` then."""
        self = cls.__new__(cls)
        self.matrix, self.lu, self.piv = None, lu, piv
        return self

    def solve(self, b: np.ndarray) -> np.ndarray:
        """J⁻¹·b per instant, b (N, n)."""
        return _solve(self.lu, self.piv, np.ascontiguousarray(b, dtype=float), False)

    def solve_transposed(self, b: np.ndarray) -> np.ndarray:
        """J⁻ᵀ·b per instant, b (N, n)."""
        return _solve(self.lu, self.piv, np.ascontiguousarray(b, dtype=float), True)

    def condition(self, row: np.ndarray, column: np.ndarray) -> np.ndarray:
        """The 1-norm condition number of Dr·J·Dc per instant, D = diag(row),
        diag(column), exactly (the inverse from the factors)."""
        return _condition(self.matrix, self.lu, self.piv, np.asarray(row, dtype=float),
                          np.asarray(column, dtype=float))
