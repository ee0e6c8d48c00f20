"""The one call of ``scipy.optimize.minimize`` that the SciPy backends share.

Bounds are passed with ``keep_feasible=True`` (every SciPy method here then evaluates
``f`` inside them only), the linear rows as two ``LinearConstraint`` (equalities,
inequalities), and
``Options.time_limit`` as an iteration ``callback`` that raises ``StopIteration`` once the
time is up (SciPy then ends the run and returns its last iterate): SciPy's methods have no
time limit of their own. Each backend module translates the other options and its
method's statuses.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from solvers.nlp.problem import NLPProblem
from solvers.nlp.solution import Options


def decrease_tol(tol: float) -> float:
    """The tolerance of a test on the decrease of ``f`` that matches a first-order ``tol``.

    Near a minimum, ``f`` is within about the square of the gradient's norm of its least
    value, so a decrease test gets ``tol**2``; never below ten machine epsilons, where the
    test would only end in a failed line search.
    """
    return max(tol**2, 10 * float(np.finfo(float).eps))


def run(problem: NLPProblem, method: str, settings: dict[str, Any], options: Options, **extra: Any) -> tuple[Any, bool]:
    """Minimize ``problem`` with ``scipy.optimize.minimize(method=...)``.

    Parameters
    ----------
    problem
        The problem (its callables are dispatch's counted ones).
    method
        SciPy's method name.
    settings
        The method's ``options`` dict, translated by the backend.
    options
        For ``time_limit``.
    extra
        Further keywords of ``minimize`` (``hess=`` for trust-constr).

    Returns
    -------
    result, timed_out
        SciPy's ``OptimizeResult``, and whether the time limit ended the run.
    """
    from scipy.optimize import Bounds, LinearConstraint, minimize

    deadline = None if options.time_limit is None else time.perf_counter() + options.time_limit
    timed_out = False

    def callback(intermediate_result) -> None:
        nonlocal timed_out
        if deadline is not None and time.perf_counter() >= deadline:
            timed_out = True
            raise StopIteration

    # equalities and inequalities apart: SciPy handles them apart (and warns otherwise)
    lb, ub = np.asarray(problem.lb), np.asarray(problem.ub)
    eq = lb == ub
    ineq = ~eq & (np.isfinite(lb) | np.isfinite(ub))
    constraints = [LinearConstraint(problem.rows[rows], lb[rows], ub[rows])
                   for rows in (eq, ineq) if rows.any()]
    res = minimize(problem.fun, problem.x0, jac=problem.grad, method=method,
                   bounds=Bounds(problem.lower, problem.upper, keep_feasible=True),
                   constraints=constraints, options=settings, callback=callback, **extra)
    return res, timed_out
