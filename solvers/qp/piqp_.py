"""PIQP, a proximal interior-point QP solver (sparse backend).

Schwan, Jiang, Kuhn, Jones, "PIQP: A Proximal Interior-Point Quadratic Programming
Solver", IEEE Conference on Decision and Control (CDC), 2023.

PIQP solves

.. math::

    \\min_x \\tfrac12 x^\\top P x + c^\\top x \\quad \\text{s.t.} \\quad
    A x = b, \\quad h_l \\le G x \\le h_u, \\quad x_l \\le x \\le x_u,

so the rows of ``l <= Ax <= u`` are split: ``l == u`` rows become ``A x = b``, the other
rows with a finite side become ``h_l <= G x <= h_u`` (PIQP accepts infinite ``h_l``/``h_u``
for a one-sided row), and rows free on both sides are dropped. Box bounds ``x_l, x_u``
are not used: the standard form has no separate bounds, and detecting singleton rows
would only pay off on problems we do not have (min-snap corridors are not singletons).

Being an interior-point method, PIQP has no warm start: ``warm_start`` is accepted and
ignored. It has no time limit either (``Options.time_limit`` is ignored with a warning);
``Options.max_iter`` is capped at :data:`MAX_ITER`.
An update with the same sparsity pattern and the same split of rows reuses the solver
(``SparseSolver.update``); otherwise the problem is set up again.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from solvers.qp.base import PreparedQP, set_attributes, warn_once
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.problem import QPProblem
from solvers.qp.row_split import split_rows
from solvers.qp.solution import Options, Status
from solvers.registry import Backend

log = logging.getLogger(__name__)


#: PIQP converges in tens of iterations; one that has not in this many will not (an infeasible
#: problem it fails to detect would otherwise run ``Options.max_iter``, sized for first-order
#: methods: 50000 iterations took 26 s on a 5-robot window; 1000 took 15 s on a 50-robot window that the
#: lazy rows then solved in 3 rounds at other durations; the window QPs take 10 iterations on average).
#: Measured over the flight-quality maps (5 to 300 robots, 1,000 window QPs): solved ones took at most 96
#: iterations (99 % within 71), detected infeasible ones at most 150; at 250 the ones never settled
#: cost 40 % of a 300-robot crossing's QP time and 70 % of a 50-robot field's.
MAX_ITER = 120


def _settings(o: Options) -> dict:
    """``Options`` in PIQP's terms (the one place they are translated)."""
    if o.time_limit is not None:
        warn_once(log, f"piqp has no time limit; Options.time_limit={o.time_limit} is ignored")
    # polish: an interior-point solution needs no polishing; ignored.
    return dict(
        eps_abs=o.eps_abs,
        eps_rel=o.eps_rel,
        eps_duality_gap_abs=o.eps_abs,
        eps_duality_gap_rel=o.eps_rel,
        max_iter=min(o.max_iter, MAX_ITER),
        verbose=o.verbose,
        preconditioner_iter=10 if o.scaling else 0,  # PIQP's default is 10
    )


def _status(st) -> Status:
    import piqp

    table = {
        piqp.PIQP_SOLVED: Status.OPTIMAL,
        piqp.PIQP_MAX_ITER_REACHED: Status.MAX_ITER,
        piqp.PIQP_PRIMAL_INFEASIBLE: Status.INFEASIBLE,
        piqp.PIQP_DUAL_INFEASIBLE: Status.UNBOUNDED,
        # PIQP_NUMERICS, PIQP_UNSOLVED, PIQP_INVALID_SETTINGS and anything new: failures
    }
    return table.get(st, Status.ERROR)


class PiqpQP(PreparedQP):
    """PIQP's sparse solver, updated in place when the pattern and row split allow."""

    name = "piqp"

    def _setup(self, problem: QPProblem) -> None:
        import piqp

        split = split_rows(problem)
        solver = piqp.SparseSolver()
        set_attributes(solver.settings, _settings(self.options))
        P_triu = sp.triu(problem.P, format="csc")
        solver.setup(P_triu, problem.q, *self._constraints(split))
        self._solver, self._split, self._P_triu = solver, split, P_triu

    @staticmethod
    def _constraints(split) -> tuple:
        eq = (split.A_eq, split.b) if split.n_eq else (None, None)
        ineq = (split.A_in, split.l_in, split.u_in) if split.n_in else (None, None, None)
        return (*eq, *ineq)

    def update(self, problem: QPProblem) -> None:
        split = self._split_for_update(problem, self._split)
        if split is None:
            return
        P_triu = sp.triu(problem.P, format="csc")
        if not (np.array_equal(P_triu.indptr, self._P_triu.indptr) and np.array_equal(P_triu.indices, self._P_triu.indices)):
            super().update(problem)
            return
        self.problem = problem
        A, b, G, h_l, h_u = self._constraints(split)
        self._guarded(lambda: self._solver.update(P=P_triu, c=problem.q, A=A, b=b, G=G, h_l=h_l, h_u=h_u))
        self._split, self._P_triu = split, P_triu

    def _solve(self, warm_start):
        # interior point: no warm start
        st = self._solver.solve()
        r = self._solver.result
        y = self._split.scatter(r.y, np.asarray(r.z_u) - np.asarray(r.z_l))
        return r.x, _status(st), str(st), r.info.iter, y


BACKEND = Backend(
    name="piqp",
    entry=PiqpQP,
    requires=("piqp",),
    extra="piqp",
    summary="PIQP: proximal interior point, sparse, accurate",
    capabilities=QPCapabilities(inequalities=True, warm_start=False, detects_infeasibility=True, sparse=True,
                                iteration_cap=MAX_ITER),
)
