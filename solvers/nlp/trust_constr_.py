"""SciPy's ``trust-constr``: a trust-region interior-point method.

Byrd, Hribar, Nocedal, "An interior point algorithm for large-scale nonlinear
programming", SIAM Journal on Optimization 9 (1999); Conn, Gould, Toint,
"Trust-Region Methods" (2000). Called through ``scipy.optimize.minimize``
(:mod:`solvers.nlp.scipy_minimize`).

With bounds or rows SciPy runs its ``tr_interior_point`` algorithm (a barrier problem
solved by equality-constrained SQP in a trust region). The Hessian is SciPy's ``BFGS()``
quasi-Newton approximation. Bounds are kept feasible (``keep_feasible=True``): ``f`` is
evaluated inside them only. A start on a bound is moved inside first, as Ipopt moves it
(:func:`interior_start`).

Translation of :class:`~solvers.nlp.Options`: ``tol`` is ``gtol`` (the Lagrangian
gradient's norm, with the constraint violation) and ``xtol`` (the trust radius), and
the final barrier parameter ``barrier_tol``; ``max_iter`` is ``maxiter``; ``verbose``
sets ``verbose`` 2 (else 0); ``time_limit`` is checked between iterations.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from solvers.nlp import scipy_minimize
from solvers.nlp.capabilities import NLPCapabilities
from solvers.nlp.problem import NLPProblem
from solvers.nlp.solution import Options, Outcome
from solvers.registry import Backend
from solvers.status import Status

# trust-constr's status -> Status (0: the iteration cap, called "function evaluations" in
# SciPy's message; 4: the constraint violation is still above gtol: ERROR). 2, the trust radius
# below xtol, is no test of optimality but steps that kept failing, as sqpmethod's
# Search_Direction_Becomes_Too_Small: ERROR, which dispatch's verdict makes OPTIMAL_INACCURATE at a
# first-order point. Called OPTIMAL_INACCURATE here, it was so on Rosenbrock with a forward-difference
# gradient at (0.970, 0.942), first-order residual 5e-3, where Ipopt and sqpmethod said MAX_ITER.
STATUS = {0: Status.MAX_ITER, 1: Status.OPTIMAL}


def _settings(o: Options) -> dict:
    """``Options`` as trust-constr's options (the one place they are translated)."""
    return {"gtol": o.tol, "xtol": o.tol, "barrier_tol": o.tol, "maxiter": int(o.max_iter),
            "verbose": 2 if o.verbose else 0}


#: How far a start on a bound is moved inside, relative to the bound's size and to the width between the bounds
#: (Ipopt's ``bound_push`` and ``bound_frac``, whose defaults these are).
BOUND_PUSH = 1e-2


def interior_start(problem: NLPProblem) -> NLPProblem:
    """``problem`` with ``x0`` at least ``min(BOUND_PUSH max(1, |bound|), BOUND_PUSH (upper - lower))`` inside
    each bound, as Ipopt places its start; fixed variables (``lower == upper``) stay.

    trust-constr keeps the bounds feasible by slacks whose barrier is ``log s``; a start on a bound has ``s = 0``
    and the variable never left it: from (2, -2) in [-2, 2]^2 trust-constr called Rosenbrock's corner (f = 3601)
    optimal, from a start on one bound a point at f = 0.25 (SciPy issue 15093).
    """
    lo, hi, x = np.asarray(problem.lower), np.asarray(problem.upper), problem.x0
    width = hi - lo
    with np.errstate(invalid="ignore"):  # inf - inf of a free side: not used
        lo_in = np.where(np.isfinite(lo), lo + np.minimum(BOUND_PUSH * np.maximum(1.0, np.abs(lo)), BOUND_PUSH * width),
                         -np.inf)
        hi_in = np.where(np.isfinite(hi), hi - np.minimum(BOUND_PUSH * np.maximum(1.0, np.abs(hi)), BOUND_PUSH * width),
                         np.inf)
    inside = np.minimum(np.maximum(x, lo_in), hi_in)
    return problem if np.array_equal(inside, x) else dataclasses.replace(problem, x0=inside)


def solve(problem: NLPProblem, options: Options) -> Outcome:
    """Minimize ``problem`` with trust-constr (BFGS Hessian), from ``x0`` moved inside its bounds
    (:func:`interior_start`)."""
    from scipy.optimize import BFGS

    problem = interior_start(problem)

    with warnings.catch_warnings():
        # after a NaN, dispatch repeats the last gradient (solvers.nlp.evaluation): BFGS then
        # skips its update and SciPy warns that f looks linear, which it is not
        warnings.filterwarnings("ignore", message="delta_grad == 0.0", category=UserWarning)
        # rows that are linearly dependent (x + y >= 3 and x + y <= 1): SciPy factorizes them by SVD instead, as it
        # should, and said so on stderr at every solve, twice
        warnings.filterwarnings("ignore", message="Singular Jacobian matrix", category=UserWarning)
        res, timed_out = scipy_minimize.run(problem, "trust-constr", _settings(options), options, hess=BFGS())
    status = Status.TIME_LIMIT if timed_out else STATUS.get(int(res.status), Status.ERROR)
    return Outcome(x=np.asarray(res.x, dtype=float), status=status, raw_status=str(res.message),
                   iterations=int(res.nit))


BACKEND = Backend(
    name="trust_constr",
    entry=solve,
    requires=("scipy",),
    summary="SciPy trust-constr: trust-region interior point (Byrd-Hribar-Nocedal), BFGS Hessian, bounds and rows",
    capabilities=NLPCapabilities(bounds=True, linear_constraints=True, needs_gradient=True, quasi_newton=True,
                                 nan_step_back=False, time_limit_native=False),
)
