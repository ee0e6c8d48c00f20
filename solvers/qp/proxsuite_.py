"""ProxQP (ProxSuite), a primal-dual proximal augmented-Lagrangian QP solver.

Bambade, El-Kazdadi, Taylor, Carpentier, "PROX-QP: Yet another Quadratic Programming
Solver for Robotics and beyond", Robotics: Science and Systems (RSS), 2022.

ProxQP solves

.. math::

    \\min_x \\tfrac12 x^\\top H x + g^\\top x \\quad \\text{s.t.} \\quad
    A x = b, \\quad l \\le C x \\le u,

so the rows of the standard form are split: ``l == u`` rows go to ``A x = b``, the
other rows with a finite side to ``l <= C x <= u`` with the open side clipped to
``+-1e20`` (ProxQP's infinity), and rows free on both sides are dropped.

Tuning (measured, see ``tests/solvers/qp/test_backends.py``): by default ProxQP stops on
the primal and dual residuals alone, which leaves complementarity loose — on a
3-variable problem with ``eps_abs = 1e-9`` a variable that should sit on its bound
stayed 2e-5 away. We therefore turn on ``check_duality_gap`` with the gap tolerances set
to the residual ones; then the solution is accurate to about ``eps_abs``.

The dense API is used for small problems (``n <= DENSE_MAX_N``), the sparse API above:
on random QPs with 1.5 n rows the dense API solved 3x faster at n = 50 and 5x at n = 200
(0.6 against 1.6 ms, 8.8 against 41 ms).

Infeasibility: ProxQP did not detect the infeasible test problem (``x1 + x2 = 1``,
``x >= 1``), neither API nor with ``primal_infeasibility_solving``: it runs to
``max_iter`` and reports ``PROXQP_MAX_ITER_REACHED``, so an infeasible problem raises a
:class:`SolverError` with that status, not :class:`InfeasibleError` (the record lacks the
``detects_infeasibility`` capability). With ``max_iter = 20000`` the dense API spent
about 9 s there (its inner iterations ran to 9 million), the sparse one 0.06 s: hence the cap
:data:`MAX_ITER`. Warm starts use
``InitialGuess.WARM_START`` with the given primal point; cold solves use ProxQP's
default equality-constrained initial guess. An update with the same pattern and the
same split of rows calls ``QP.update`` (no new allocation); otherwise it sets up again.
ProxQP has no time limit (``Options.time_limit`` is ignored with a warning).

``Options.max_iter`` is capped at :data:`MAX_ITER`.
"""

from __future__ import annotations

import logging

import numpy as np

from solvers.qp.base import PreparedQP, set_attributes, warn_once
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.problem import QPProblem
from solvers.qp.row_split import RowSplit, split_rows
from solvers.qp.solution import Options, Status
from solvers.registry import Backend

log = logging.getLogger(__name__)

_INF = 1e20  # ProxQP's own infinity
#: Largest number of variables solved with ProxQP's dense API.
DENSE_MAX_N = 200
#: ProxQP's ``max_iter`` counts its outer (proximal) iterations; ``info.iter``, the count it reports, its inner
#: ones. The continuous stage's window QPs take tens of outer iterations; one that has not settled in this many
#: will not. Without a cap, ``Options.max_iter`` (sized for first-order methods, 50000 in the receding horizon) let
#: the window attempts that have no solution run for minutes: a 5-robot, 20 x 20 map planned in 112 s, 104 s of
#: it in two solves (2026-11-29). Measured on six maps of 5 to 12 robots (that map, the corridor, forest_01,
#: rooms_01, the arena, blocks12; 113 solved window QPs): solved ones took at most 24 outer iterations. Capped
#: at 200, every map flew the same flight, certified, that map in 11 s of planning.
MAX_ITER = 200


def _settings(o: Options) -> dict:
    """``Options`` in ProxQP's terms (the one place they are translated)."""
    if o.time_limit is not None:
        warn_once(log, f"proxsuite has no time limit; Options.time_limit={o.time_limit} is ignored")
    # polish: no polishing step in ProxQP; ignored.
    return dict(
        eps_abs=o.eps_abs,
        eps_rel=o.eps_rel,
        check_duality_gap=True,
        eps_duality_gap_abs=o.eps_abs,
        eps_duality_gap_rel=o.eps_rel,
        max_iter=min(o.max_iter, MAX_ITER),
        verbose=o.verbose,
    )


def _status(st) -> Status:
    from proxsuite import proxqp

    S = proxqp.QPSolverOutput
    table = {
        S.PROXQP_SOLVED: Status.OPTIMAL,
        S.PROXQP_MAX_ITER_REACHED: Status.MAX_ITER,
        S.PROXQP_PRIMAL_INFEASIBLE: Status.INFEASIBLE,
        S.PROXQP_DUAL_INFEASIBLE: Status.UNBOUNDED,
        # PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE (only with primal_infeasibility_solving,
        # which we leave off) and PROXQP_NOT_RUN are failures.
    }
    return table.get(st, Status.ERROR)


class ProxsuiteQP(PreparedQP):
    """ProxQP, dense API for small problems and sparse API otherwise."""

    name = "proxsuite"

    def _setup(self, problem: QPProblem) -> None:
        from proxsuite import proxqp

        split = split_rows(problem)
        self._dense = problem.n <= DENSE_MAX_N
        api = proxqp.dense if self._dense else proxqp.sparse
        qp = api.QP(problem.n, split.n_eq, split.n_in)
        set_attributes(qp.settings, _settings(self.options))
        qp.init(*self._data(problem, split), compute_preconditioner=self.options.scaling)
        self._qp, self._split = qp, split

    def _data(self, problem: QPProblem, split: RowSplit) -> tuple:
        """``(H, g, A, b, C, l, u)`` for ProxQP, dense arrays or CSC by the API in use."""
        conv = (lambda M: M.toarray()) if self._dense else (lambda M: M)
        eq = (conv(split.A_eq), split.b) if split.n_eq else (None, None)
        ineq = (
            (conv(split.A_in), np.clip(split.l_in, -_INF, _INF), np.clip(split.u_in, -_INF, _INF))
            if split.n_in else (None, None, None)
        )
        return (conv(problem.P), problem.q, *eq, *ineq)

    def update(self, problem: QPProblem) -> None:
        split = self._split_for_update(problem, self._split)
        if split is None:
            return
        self.problem = problem
        self._split = split
        self._guarded(lambda: self._qp.update(*self._data(problem, split)))

    def _solve(self, warm_start):
        from proxsuite import proxqp

        if warm_start is not None:
            self._qp.settings.initial_guess = proxqp.InitialGuess.WARM_START
            self._qp.solve(warm_start, None, None)
        else:
            self._qp.settings.initial_guess = proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS
            self._qp.solve()
        r = self._qp.results
        y = self._split.scatter(r.y, r.z)
        return r.x, _status(r.info.status), str(r.info.status), r.info.iter, y


BACKEND = Backend(
    name="proxsuite",
    entry=ProxsuiteQP,
    requires=("proxsuite",),
    extra="proxsuite",
    summary="ProxQP (ProxSuite): proximal augmented Lagrangian, dense or sparse, warm-startable",
    capabilities=QPCapabilities(inequalities=True, warm_start=True, detects_infeasibility=False, sparse=True,
                                iteration_cap=MAX_ITER),  # infeasibility: see the module docstring
)
