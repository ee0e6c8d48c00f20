"""Clarabel, an interior-point solver for conic programs with quadratic objectives, called directly.

Goulart, Chen, "Clarabel: An interior-point solver for conic programs with quadratic
objectives", arXiv:2405.12762 (2024).

Clarabel solves

.. math::

    \\min_x \\tfrac12 x^\\top P x + q^\\top x \\quad \\text{s.t.} \\quad
    A x + s = b, \\quad s \\in \\mathcal{K},

so the rows of ``l <= Ax <= u`` become three blocks of one conic constraint: equality
rows ``A_eq x + s = b`` with ``s`` in the zero cone, finite upper sides
``A_hi x + s = u_hi`` and finite lower sides ``-A_lo x + s = -l_lo`` with ``s`` in the
nonnegative cone (a two-sided row is in both; a row free on both sides in neither).
Clarabel's multipliers ``z`` satisfy ``P x + q + A_K' z = 0`` for the stacked matrix,
so the standard form's ``y`` is ``z`` on equality and upper rows and ``-z`` on lower
rows (:func:`~solvers.qp.row_split.scatter_one_sided`). ``P`` is passed as its upper triangle, as Clarabel expects.

Tolerances: ``tol_gap_abs``, ``tol_gap_rel`` and ``tol_feas`` are ``eps_abs``,
``eps_rel`` and ``eps_abs``; ``max_iter`` and ``time_limit`` are Clarabel's own.
``warm_start`` is accepted and ignored: Clarabel is an interior-point method (the
record says so). An :meth:`~ClarabelQP.update` with the same pattern and the same
partition of rows loads the new numbers into the existing solver (Clarabel's data
updates, which keep its symbolic factorization) when Clarabel allows it (its presolve
can forbid updates); otherwise it sets the problem up again.

The cvxpy backend reaches the same solver through a modeling layer; this one skips the
canonicalization and calls Clarabel's Python API on the standard form.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from solvers.qp.base import PreparedQP
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.problem import QPProblem
from solvers.qp.row_split import one_sided_rows, scatter_one_sided, stack_one_sided
from solvers.qp.solution import Options, Status
from solvers.registry import Backend

log = logging.getLogger(__name__)


def _settings(o: Options):
    """``Options`` in Clarabel's terms (the one place they are translated)."""
    import clarabel

    s = clarabel.DefaultSettings()
    # polish: an interior-point solution needs no polishing; ignored.
    s.tol_gap_abs = o.eps_abs
    s.tol_gap_rel = o.eps_rel
    s.tol_feas = o.eps_abs
    s.max_iter = int(o.max_iter)
    if o.time_limit is not None:
        s.time_limit = float(o.time_limit)
    s.verbose = bool(o.verbose)
    s.equilibrate_enable = bool(o.scaling)
    return s


def _status(st) -> Status:
    import clarabel

    S = clarabel.SolverStatus
    table = {
        S.Solved: Status.OPTIMAL,
        S.AlmostSolved: Status.OPTIMAL_INACCURATE,
        S.PrimalInfeasible: Status.INFEASIBLE,
        S.AlmostPrimalInfeasible: Status.INFEASIBLE,
        S.DualInfeasible: Status.UNBOUNDED,
        S.AlmostDualInfeasible: Status.UNBOUNDED,
        S.MaxIterations: Status.MAX_ITER,
        S.MaxTime: Status.TIME_LIMIT,
        # NumericalError, InsufficientProgress, CallbackTerminated, Unsolved: failures
    }
    return table.get(st, Status.ERROR)


class ClarabelQP(PreparedQP):
    """Clarabel's ``DefaultSolver`` on the standard form, updated in place when allowed."""

    name = "clarabel"

    def _setup(self, problem: QPProblem) -> None:
        import clarabel

        rows = one_sided_rows(problem)
        A_K, b = stack_one_sided(problem, rows)
        eq, hi, lo = rows
        cones = []
        if len(eq):
            cones.append(clarabel.ZeroConeT(len(eq)))
        if len(hi) + len(lo):
            cones.append(clarabel.NonnegativeConeT(len(hi) + len(lo)))
        P_triu = sp.triu(problem.P, format="csc")
        self._solver = clarabel.DefaultSolver(P_triu, problem.q, A_K, b, cones, _settings(self.options))
        self._rows, self._P_triu, self._A_K = rows, P_triu, A_K

    def update(self, problem: QPProblem) -> None:
        self._check_same_shape(problem)
        rows = one_sided_rows(problem)
        if not (all(np.array_equal(a, b) for a, b in zip(rows, self._rows, strict=True))
                and self._solver.is_data_update_allowed()):
            super().update(problem)
            return
        A_K, b = stack_one_sided(problem, rows)
        P_triu = sp.triu(problem.P, format="csc")
        same_patterns = (np.array_equal(P_triu.indptr, self._P_triu.indptr)
                         and np.array_equal(P_triu.indices, self._P_triu.indices)
                         and np.array_equal(A_K.indptr, self._A_K.indptr)
                         and np.array_equal(A_K.indices, self._A_K.indices))
        if not same_patterns:  # explicit zeros dropped differently: set up again
            super().update(problem)
            return
        self.problem = problem
        self._guarded(lambda: self._solver.update(P=P_triu.data, q=problem.q, A=A_K.data, b=b))
        self._P_triu, self._A_K = P_triu, A_K

    def _solve(self, warm_start):
        # interior point: warm_start ignored
        r = self._solver.solve()
        status = _status(r.status)
        y = scatter_one_sided(self.problem.m, self._rows, np.asarray(r.z, dtype=float)) if status.ok else None
        return np.asarray(r.x, dtype=float), status, str(r.status), r.iterations, y


BACKEND = Backend(
    name="clarabel",
    entry=ClarabelQP,
    requires=("clarabel",),
    extra="clarabel",
    summary="Clarabel: interior point (conic), sparse, called directly on the standard form",
    capabilities=QPCapabilities(inequalities=True, warm_start=False, detects_infeasibility=True, sparse=True),
)
