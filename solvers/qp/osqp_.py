"""OSQP, the operator-splitting QP solver.

Stellato, Banjac, Goulart, Bemporad, Boyd, "OSQP: an operator splitting solver for
quadratic programs", Mathematical Programming Computation 12 (2020).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from solvers.qp.base import PreparedQP
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.problem import QPProblem
from solvers.qp.solution import Options, Status
from solvers.registry import Backend

_INF = 1e30  # OSQP's own infinity


def _settings(o: Options) -> dict:
    return dict(
        eps_abs=o.eps_abs,
        eps_rel=o.eps_rel,
        max_iter=o.max_iter,
        time_limit=o.time_limit or 1e10,
        verbose=o.verbose,
        polishing=o.polish,
        scaling=10 if o.scaling else 0,  # OSQP's default is 10
        eps_prim_inf=1e-6,
        eps_dual_inf=1e-6,
    )


def _status(val: int) -> Status:
    import osqp

    S = osqp.SolverStatus
    table = {
        S.OSQP_SOLVED: Status.OPTIMAL,
        S.OSQP_SOLVED_INACCURATE: Status.OPTIMAL_INACCURATE,
        S.OSQP_PRIMAL_INFEASIBLE: Status.INFEASIBLE,
        S.OSQP_PRIMAL_INFEASIBLE_INACCURATE: Status.INFEASIBLE,
        S.OSQP_DUAL_INFEASIBLE: Status.UNBOUNDED,
        S.OSQP_DUAL_INFEASIBLE_INACCURATE: Status.UNBOUNDED,
        S.OSQP_MAX_ITER_REACHED: Status.MAX_ITER,
        S.OSQP_TIME_LIMIT_REACHED: Status.TIME_LIMIT,
    }
    return table.get(S(val), Status.ERROR)


class OsqpQP(PreparedQP):
    """OSQP with cheap updates of vectors and matrix values, and warm starts."""

    name = "osqp"

    def _setup(self, problem: QPProblem) -> None:
        import osqp

        # OSQP takes the upper triangle; P's pattern is fixed across updates, so the
        # positions of its upper-triangle entries are found once.
        P = problem.P
        rows = P.indices
        cols = np.repeat(np.arange(P.shape[1]), np.diff(P.indptr))
        self._triu = rows <= cols
        indptr = np.concatenate(([0], np.cumsum(np.bincount(cols[self._triu], minlength=P.shape[1]))))
        P_triu = sp.csc_matrix((P.data[self._triu], rows[self._triu], indptr), shape=P.shape)
        self._solver = osqp.OSQP(algebra="builtin")  # without it, every construction probes for CUDA/MKL builds
        self._solver.setup(
            P_triu,
            problem.q,
            problem.A,
            np.clip(problem.l, -_INF, _INF),
            np.clip(problem.u, -_INF, _INF),
            **_settings(self.options),
        )

    def update(self, problem: QPProblem) -> None:
        self._check_same_shape(problem)  # same patterns of P and A, so the same triangle
        self.problem = problem
        self._solver.update(
            q=problem.q,
            l=np.clip(problem.l, -_INF, _INF),
            u=np.clip(problem.u, -_INF, _INF),
            Px=problem.P.data[self._triu],
            Ax=problem.A.data,
        )

    def _solve(self, warm_start):
        if warm_start is not None:
            self._solver.warm_start(x=warm_start)
        r = self._solver.solve(raise_error=False)  # statuses are mapped, not raised
        return r.x, _status(r.info.status_val), str(r.info.status), r.info.iter, r.y


BACKEND = Backend(
    name="osqp",
    entry=OsqpQP,
    requires=("osqp",),
    extra="osqp",
    summary="OSQP: operator splitting (ADMM), sparse, warm-startable",
    capabilities=QPCapabilities(inequalities=True, warm_start=True, detects_infeasibility=True, sparse=True),
)
