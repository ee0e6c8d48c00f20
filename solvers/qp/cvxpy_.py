"""CVXPY, the modeling language, with the Clarabel interior-point conic solver.

Diamond, Boyd, "CVXPY: A Python-embedded modeling language for convex optimization",
Journal of Machine Learning Research 17 (2016); Agrawal, Verschueren, Diamond, Boyd, "A
rewriting system for convex optimization problems", J. Control and Decision 5 (2018)
(the DPP parameter canonicalization used here). The solver is Clarabel: Goulart, Chen,
"Clarabel: An interior-point solver for conic programs with quadratic objectives",
arXiv:2405.12762 (2024).

The problem is built once with ``cvxpy.Parameter`` for ``q`` and for the finite sides of
the constraints, and compiled in setup (``get_problem_data``, which fills CVXPY's DPP
cache), so a re-solve after :meth:`update` with new ``q``/``l``/``u`` skips the
canonicalization. ``P`` and ``A`` are constants (``quad_form`` with a parameter ``P`` is
not DPP): an update that changes their values builds the problem again.

Rows are split into ``A_eq x == b``, ``A_lo x >= l_lo`` (finite ``l``) and
``A_hi x <= u_hi`` (finite ``u``); a two-sided row is in both of the last two groups,
a row free on both sides in none. Its multiplier is ``y_hi - y_lo`` (``y_eq`` for an
equality), which matches the standard form's ``P x + q + A'y = 0``.

Solver choice: Clarabel (installed with CVXPY), never OSQP (which would make the
cross-backend agreement tests compare OSQP with itself); if Clarabel is missing, SCS with
a logged warning (SCS is first order and rarely reaches 1e-8). ``warm_start`` is ignored:
Clarabel is an interior-point method.
"""

from __future__ import annotations

import logging

import numpy as np

from solvers.qp.base import PreparedQP
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.problem import QPProblem
from solvers.qp.row_split import same_matrices
from solvers.qp.solution import Options, Status
from solvers.registry import Backend

log = logging.getLogger(__name__)

#: Conic solvers tried in order (never OSQP: see the module docstring).
SOLVERS = ("CLARABEL", "SCS")


def _pick_solver() -> str:
    import cvxpy as cp

    installed = cp.installed_solvers()
    for name in SOLVERS:
        if name in installed:
            if name != SOLVERS[0]:
                log.warning("cvxpy: %s is not installed; falling back to %s (first order, less accurate)",
                            SOLVERS[0], name)
            return name
    from solvers.errors import SolverError

    raise SolverError(f"cvxpy: none of {', '.join(SOLVERS)} is installed (have: {', '.join(installed)})",
                      backend="cvxpy", status="no solver")


def _settings(o: Options, solver: str) -> dict:
    """``Options`` as keyword arguments of ``Problem.solve`` (the one place they are translated)."""
    # polish: interior point (Clarabel) needs none, SCS has none; ignored.
    if solver == "CLARABEL":
        kw = dict(tol_gap_abs=o.eps_abs, tol_gap_rel=o.eps_rel, tol_feas=o.eps_abs, max_iter=int(o.max_iter))
        if o.time_limit is not None:
            kw["time_limit"] = float(o.time_limit)
    elif solver == "SCS":
        kw = dict(eps_abs=o.eps_abs, eps_rel=o.eps_rel, max_iters=int(o.max_iter))
        if o.time_limit is not None:
            kw["time_limit_secs"] = float(o.time_limit)
    else:
        raise ValueError(f"cvxpy backend: no option translation for solver {solver!r}")
    return dict(kw, verbose=bool(o.verbose))


# cvxpy.settings status strings -> Status
_STATUS = {
    "optimal": Status.OPTIMAL,
    "optimal_inaccurate": Status.OPTIMAL_INACCURATE,
    "infeasible": Status.INFEASIBLE,
    "infeasible_inaccurate": Status.INFEASIBLE,
    "unbounded": Status.UNBOUNDED,
    "unbounded_inaccurate": Status.UNBOUNDED,
    "user_limit": Status.TIME_LIMIT,
    # "solver_error" and anything else: failures (ERROR)
}


def _partition(problem: QPProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row indices of the equalities, of the finite lower sides and of the finite upper sides."""
    from solvers.qp.row_split import split_rows

    split = split_rows(problem)  # validates l == u == inf rows
    ineq = np.zeros(problem.m, dtype=bool)
    ineq[split.ineq] = True
    lo = np.flatnonzero(ineq & np.isfinite(problem.l))
    hi = np.flatnonzero(ineq & np.isfinite(problem.u))
    return split.eq, lo, hi


class CvxpyQP(PreparedQP):
    """A parametrized CVXPY problem, compiled once, re-solved with new q, l, u."""

    name = "cvxpy"

    def _setup(self, problem: QPProblem) -> None:
        import cvxpy as cp

        self._solver = _pick_solver()
        eq, lo, hi = self._rows = _partition(problem)
        A = problem.A.tocsr()
        x = cp.Variable(problem.n)
        self._q = cp.Parameter(problem.n)
        self._b, self._l, self._u = (cp.Parameter(len(r)) if len(r) else None for r in (eq, lo, hi))
        cons = []
        if len(eq):
            cons.append(A[eq] @ x == self._b)
        if len(lo):
            cons.append(A[lo] @ x >= self._l)
        if len(hi):
            cons.append(A[hi] @ x <= self._u)
        self._cons = cons
        objective = 0.5 * cp.quad_form(x, cp.psd_wrap(problem.P)) + self._q @ x
        self._x = x
        self._prob = cp.Problem(cp.Minimize(objective), cons)
        self._set_values(problem)
        self._prob.get_problem_data(self._solver)  # compile now (setup), reused by every solve

    def _set_values(self, problem: QPProblem) -> None:
        eq, lo, hi = self._rows
        self._q.value = problem.q
        for param, vals in ((self._b, problem.l[eq]), (self._l, problem.l[lo]), (self._u, problem.u[hi])):
            if param is not None:
                param.value = vals

    def update(self, problem: QPProblem) -> None:
        self._check_same_shape(problem)
        rows = _partition(problem)
        if not (all(np.array_equal(a, b) for a, b in zip(rows, self._rows)) and same_matrices(self.problem, problem)):
            super().update(problem)
            return
        self.problem = problem
        self._set_values(problem)

    def _solve(self, warm_start):
        # interior point: warm_start ignored
        prob = self._prob
        prob.solve(solver=self._solver, **_settings(self.options, self._solver))
        status = _STATUS.get(prob.status, Status.ERROR)
        stats = prob.solver_stats
        iters = stats.num_iters if stats is not None and stats.num_iters is not None else 0
        y = None
        if status.ok:
            eq, lo, hi = self._rows
            y = np.zeros(self.problem.m)
            it = iter(self._cons)
            if len(eq):
                y[eq] += next(it).dual_value
            if len(lo):
                y[lo] -= next(it).dual_value
            if len(hi):
                y[hi] += next(it).dual_value
        return self._x.value, status, str(prob.status), iters, y


BACKEND = Backend(
    name="cvxpy",
    entry=CvxpyQP,
    requires=("cvxpy",),
    extra="cvxpy",
    summary="CVXPY modeling layer with Clarabel (interior point); parametrized, compiled once",
    capabilities=QPCapabilities(inequalities=True, warm_start=False, detects_infeasibility=True, sparse=True),
)
