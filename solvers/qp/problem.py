"""The one standard form every QP backend receives.

.. math::

    \\min_x \\tfrac12 x^\\top P x + q^\\top x \\quad \\text{s.t.} \\quad l \\le A x \\le u

with ``P`` symmetric positive semidefinite (stored whole, not a triangle), ``A`` sparse,
and ``l``/``u`` possibly infinite. A row with ``l == u`` is an equality. Shapes, symmetry
and finiteness are checked once, at construction, so backends never see a malformed
problem.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from solvers.errors import InvalidProblem, real_array


def _is_csc_float(M) -> bool:
    return sp.issparse(M) and M.format == "csc" and M.dtype == np.float64


def _csc(M, name: str) -> sp.csc_matrix:
    """``M`` (sparse, or dense of at most two axes) as a float CSC matrix, or InvalidProblem naming ``name``."""
    if _is_csc_float(M):
        return M
    if sp.issparse(M):
        if M.dtype.kind not in "biuf":
            raise InvalidProblem(f"{name} must hold real numbers, got a sparse matrix of dtype {M.dtype}")
        return sp.csc_matrix(M, dtype=float)
    a = real_array(M, name)
    if a.ndim > 2:  # scipy's own words: "CSR arrays don't yet support 3D"
        raise InvalidProblem(f"{name} has shape {a.shape}: must be a matrix")
    return sp.csc_matrix(a)


def _sorted(M: sp.csc_matrix) -> sp.csc_matrix:
    """M with sorted indices; a copy when they are not (the caller's matrix is left alone)."""
    if M.has_sorted_indices:
        return M
    M = M.copy()
    M.sort_indices()
    return M


@lru_cache(maxsize=128)
def _transpose_permutation(n: int, indices: bytes, indptr: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """For a structurally symmetric CSC pattern, orders a, b of its entries with entry a[k]
    at (i, j) and b[k] at (j, i); None if the pattern is not symmetric. Cached per pattern:
    a formulation evaluated many times reuses one pattern."""
    rows = np.frombuffer(indices, dtype=np.int64)
    ptr: np.ndarray = np.frombuffer(indptr, dtype=np.int64)
    cols = np.repeat(np.arange(n, dtype=np.int64), np.diff(ptr))
    a = np.argsort(rows * n + cols, kind="stable")
    b = np.argsort(cols * n + rows, kind="stable")
    if not np.array_equal((rows * n + cols)[a], (cols * n + rows)[b]):
        return None
    return a, b


def _is_symmetric(P: sp.csc_matrix, rtol: float = 1e-9) -> bool:
    """P == P' up to rtol (relative to the largest entry)."""
    n = P.shape[0]
    scale = max(1.0, float(np.abs(P.data).max(initial=0.0)))
    perm = _transpose_permutation(n, P.indices.astype(np.int64).tobytes(), P.indptr.astype(np.int64).tobytes())
    if perm is not None:
        return bool(np.all(np.abs(P.data[perm[0]] - P.data[perm[1]]) <= rtol * scale))
    # not structurally symmetric: compare the nonzero entries only (explicit zeros match absent ones)
    nz = P.copy()
    nz.eliminate_zeros()
    perm = _transpose_permutation(n, nz.indices.astype(np.int64).tobytes(), nz.indptr.astype(np.int64).tobytes())
    return perm is not None and bool(np.all(np.abs(nz.data[perm[0]] - nz.data[perm[1]]) <= rtol * scale))


#: Relative size below which a negative diagonal entry of P counts as rounding (see QPProblem).
DIAGONAL_TOL = 1e-12


@dataclass(frozen=True, eq=False)
class QPProblem:
    """A validated quadratic program in standard form.

    Parameters
    ----------
    P
        (n, n) symmetric PSD cost matrix, converted to CSC.
    q
        (n,) linear cost.
    A
        (m, n) constraint matrix, converted to CSC; m may be 0.
    l, u
        (m,) lower and upper bounds; ``-inf``/``inf`` allowed, ``l <= u``, ``l < inf``, ``u > -inf``.

    Positive semidefiniteness is the caller's to ensure: only its necessary condition, a diagonal without
    negative entries, is checked (the whole check would cost more than most solves).
    """

    P: sp.csc_matrix
    q: np.ndarray
    A: sp.csc_matrix
    l: np.ndarray
    u: np.ndarray

    def __post_init__(self) -> None:
        P = _csc(self.P, "P")
        q = real_array(self.q, "q").reshape(-1)
        n = q.size
        A = sp.csc_matrix((0, n)) if self.A is None else _csc(self.A, "A")
        # no rows: l and u may be None too (np.asarray(None, dtype=float) is one NaN: "got (1,) and (1,)", a tour)
        if A.shape[0] and (self.l is None or self.u is None):
            raise InvalidProblem(f"l and u are needed with A's {A.shape[0]} rows (-inf / inf for a free side)")
        l = np.zeros(0) if self.l is None and A.shape[0] == 0 else real_array(self.l, "l").reshape(-1)
        u = np.zeros(0) if self.u is None and A.shape[0] == 0 else real_array(self.u, "u").reshape(-1)
        if P.shape != (n, n):
            raise InvalidProblem(f"P has shape {P.shape}, expected ({n}, {n}) from q")
        if A.shape[1] != n:
            raise InvalidProblem(f"A has {A.shape[1]} columns, expected {n}")
        m = A.shape[0]
        if l.shape != (m,) or u.shape != (m,):
            raise InvalidProblem(f"l and u must have shape ({m},), got {l.shape} and {u.shape}")
        if not (np.all(np.isfinite(P.data)) and np.all(np.isfinite(q)) and np.all(np.isfinite(A.data))):
            raise InvalidProblem("P, q and A must be finite (found NaN or inf)")
        if np.any(np.isnan(l)) or np.any(np.isnan(u)):
            raise InvalidProblem("l and u must not contain NaN")
        if np.any(l > u):
            i = int(np.argmax(l > u))
            raise InvalidProblem(f"l[{i}] = {l[i]} > u[{i}] = {u[i]}")
        if np.any(l == np.inf) or np.any(u == -np.inf):  # no x meets such a row (OSQP "solved" one to x ~ 1e29)
            i = int(np.argmax((l == np.inf) | (u == -np.inf)))
            raise InvalidProblem(f"row {i}: l = {l[i]}, u = {u[i]}: no x meets it (l < inf and u > -inf needed)")
        P, A = _sorted(P), _sorted(A)
        if not _is_symmetric(P):
            raise InvalidProblem("P must be symmetric (store the whole matrix, not a triangle)")
        diagonal = P.diagonal()
        if diagonal.size and diagonal.min() < -DIAGONAL_TOL * max(1.0, float(np.abs(diagonal).max())):
            # a necessary condition of PSD, checked for free (the whole check would cost more than a solve): with
            # P = -I most backends returned "optimal" at the maximizer of an unbounded problem
            i = int(np.argmin(diagonal))
            raise InvalidProblem(f"P[{i}, {i}] = {diagonal[i]:g} < 0: P must be positive semidefinite")
        object.__setattr__(self, "P", P)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "l", l)
        object.__setattr__(self, "u", u)

    @property
    def n(self) -> int:
        """Number of variables."""
        return self.q.size

    @property
    def m(self) -> int:
        """Number of constraint rows."""
        return self.A.shape[0]

    @property
    def equality_rows(self) -> np.ndarray:
        """Boolean mask of rows with ``l == u``."""
        return self.l == self.u

    @property
    def has_inequalities(self) -> bool:
        """True if some row is a (one- or two-sided) inequality rather than an equality."""
        ineq = ~self.equality_rows
        # rows free on both sides constrain nothing
        return bool(np.any(ineq & (np.isfinite(self.l) | np.isfinite(self.u))))

    def objective(self, x: np.ndarray) -> float:
        """The cost ``x'Px/2 + q'x`` at ``x``."""
        return float(0.5 * x @ (self.P @ x) + self.q @ x)

    def max_violation(self, x: np.ndarray) -> float:
        """The largest violation of ``l <= Ax <= u`` at ``x`` (0 when feasible)."""
        if self.m == 0:
            return 0.0
        ax = self.A @ x
        return float(max(np.max(self.l - ax, initial=0.0), np.max(ax - self.u, initial=0.0)))
