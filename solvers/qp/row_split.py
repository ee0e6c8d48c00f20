"""The rows of ``l <= Ax <= u`` sorted into equalities and inequalities.

Several backends (piqp, proxsuite, cvxpy, closed_form) take equality rows ``A_eq x = b``
apart from inequality rows ``l_in <= A_in x <= u_in``; rows free on both sides
(``-inf <= a'x <= inf``) constrain nothing and are dropped. The multipliers a backend
returns for the two groups are scattered back into one vector ``y`` of length ``m``
with the sign convention of the standard form (OSQP's):

.. math::

    P x + q + A^\\top y = 0, \\qquad y_i > 0 \\text{ at an active upper bound},
    \\; y_i < 0 \\text{ at an active lower bound}.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from solvers.errors import InvalidProblem
from solvers.qp.problem import QPProblem


@dataclass(frozen=True, eq=False)
class RowSplit:
    """The equality and inequality rows of a :class:`QPProblem`.

    Attributes
    ----------
    eq, ineq
        Row indices (into ``A``) of the equalities and of the inequalities (one- or
        two-sided); the remaining rows are free on both sides.
    A_eq, b
        Equality rows (CSC) and their right-hand side.
    A_in, l_in, u_in
        Inequality rows (CSC) and their bounds, infinite where a side is open.
    """

    m: int
    eq: np.ndarray
    ineq: np.ndarray
    A_eq: sp.csc_matrix
    b: np.ndarray
    A_in: sp.csc_matrix
    l_in: np.ndarray
    u_in: np.ndarray

    @property
    def n_eq(self) -> int:
        """Number of equality rows."""
        return self.eq.size

    @property
    def n_in(self) -> int:
        """Number of inequality rows."""
        return self.ineq.size

    def same_partition(self, other: RowSplit) -> bool:
        """True when ``other`` sorts the rows the same way (so a backend can update in place)."""
        return np.array_equal(self.eq, other.eq) and np.array_equal(self.ineq, other.ineq)

    def scatter(self, y_eq: np.ndarray | None, y_in: np.ndarray | None) -> np.ndarray:
        """One multiplier vector of length ``m`` (zero on free rows) from the two groups."""
        y = np.zeros(self.m)
        if y_eq is not None and self.n_eq:
            y[self.eq] = np.asarray(y_eq, dtype=float).reshape(-1)
        if y_in is not None and self.n_in:
            y[self.ineq] = np.asarray(y_in, dtype=float).reshape(-1)
        return y


def split_rows(problem: QPProblem) -> RowSplit:
    """Sort the rows of ``problem`` into equalities, inequalities and free rows.

    Raises
    ------
    InvalidProblem
        If a row is an "equality" with an infinite right-hand side (``l == u == +-inf``).
    """
    l, u = problem.l, problem.u
    is_eq = l == u
    bad = is_eq & ~np.isfinite(l)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise InvalidProblem(f"row {i} has l = u = {l[i]}: an equality needs a finite right-hand side")
    is_in = ~is_eq & (np.isfinite(l) | np.isfinite(u))
    eq = np.flatnonzero(is_eq)
    ineq = np.flatnonzero(is_in)
    A = problem.A.tocsr()
    A_eq = A[eq].tocsc()
    A_in = A[ineq].tocsc()
    A_eq.sort_indices()
    A_in.sort_indices()
    return RowSplit(
        m=problem.m, eq=eq, ineq=ineq,
        A_eq=A_eq, b=l[eq].copy(),
        A_in=A_in, l_in=l[ineq].copy(), u_in=u[ineq].copy(),
    )


def one_sided_rows(problem: QPProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row indices of the equalities, of the finite upper sides and of the finite lower sides.

    For backends that take ``A_eq x = b`` and one-sided rows ``G x <= h`` (a two-sided row
    is in both inequality blocks, a row free on both sides in neither).
    """
    split = split_rows(problem)  # validates l == u == inf rows
    ineq = np.zeros(problem.m, dtype=bool)
    ineq[split.ineq] = True
    return split.eq, np.flatnonzero(ineq & np.isfinite(problem.u)), np.flatnonzero(ineq & np.isfinite(problem.l))


def stack_one_sided(problem: QPProblem, rows: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[sp.csc_matrix, np.ndarray]:
    """``[A_eq; A_hi; -A_lo]`` (CSC) and ``[l_eq; u_hi; -l_lo]`` for the row blocks ``rows``.

    The first ``len(rows[0])`` rows are the equalities, the others read ``G x <= h``.
    """
    eq, hi, lo = rows
    A = problem.A.tocsr()
    A_K = sp.vstack([A[eq], A[hi], -A[lo]], format="csc")
    A_K.sort_indices()
    b = np.concatenate([problem.l[eq], problem.u[hi], -problem.l[lo]])
    return A_K, b


def scatter_one_sided(m: int, rows: tuple[np.ndarray, np.ndarray, np.ndarray], z: np.ndarray) -> np.ndarray:
    """The standard form's multipliers (length ``m``) from those ``z`` of the stacked rows.

    ``z`` in the stacked form's convention, ``P x + q + A_K' z = 0``: the equalities' and
    upper sides' multipliers carry over, the lower sides' change sign.
    """
    eq, hi, lo = rows
    y = np.zeros(m)
    k = len(eq) + len(hi)
    y[eq] = z[:len(eq)]
    y[hi] += z[len(eq):k]
    y[lo] -= z[k:]
    return y


def same_matrices(old: QPProblem, new: QPProblem) -> bool:
    """True when ``new`` has the very same ``P`` and ``A`` as ``old`` (only q, l, u differ).

    Both problems must already have the same sparsity pattern.
    """
    return np.array_equal(old.P.data, new.P.data) and np.array_equal(old.A.data, new.A.data)
