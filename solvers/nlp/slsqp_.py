"""SciPy's SLSQP: sequential least-squares quadratic programming (Kraft's code).

Kraft, "A software package for sequential quadratic programming", Technical Report
DFVLR-FB 88-28, DLR German Aerospace Center (1988). Called through
``scipy.optimize.minimize`` (:mod:`solvers.nlp.scipy_minimize`).

A dense SQP method with a BFGS Hessian kept as an LDL' factor; each step solves a
least-squares QP under the linearized rows and the bounds. SciPy clips every point to the
bounds before evaluating ``f``.

Translation of :class:`~solvers.nlp.Options`: ``ftol`` (SLSQP's one stopping test: the
precision goal for ``f`` in its optimality measure) is ``tol**2``
(:func:`~solvers.nlp.scipy_minimize.decrease_tol`: near a minimum ``f`` is accurate to the
square of the gradient; with ``ftol = tol`` SLSQP stopped 1.4e-5 from Rosenbrock's
minimum); ``max_iter`` is ``maxiter``; ``verbose`` is ``disp``; ``time_limit`` is
checked between iterations.
"""

from __future__ import annotations

import numpy as np

from solvers.nlp import scipy_minimize
from solvers.nlp.capabilities import NLPCapabilities
from solvers.nlp.problem import NLPProblem
from solvers.nlp.scipy_minimize import decrease_tol
from solvers.nlp.solution import Options, Outcome
from solvers.registry import Backend
from solvers.status import Status

# SLSQP's exit mode -> Status (2, 3, 5, 6, 7: failures of the subproblem; 8: a line search
# along an ascent direction: ERROR)
STATUS = {0: Status.OPTIMAL, 4: Status.INFEASIBLE, 9: Status.MAX_ITER}


def _settings(o: Options) -> dict:
    """``Options`` as SLSQP's options (the one place they are translated)."""
    return {"ftol": decrease_tol(o.tol), "maxiter": int(o.max_iter), "disp": o.verbose}


def solve(problem: NLPProblem, options: Options) -> Outcome:
    """Minimize ``problem`` with SLSQP."""
    res, timed_out = scipy_minimize.run(problem, "SLSQP", _settings(options), options)
    status = Status.TIME_LIMIT if timed_out else STATUS.get(int(res.status), Status.ERROR)
    return Outcome(x=np.asarray(res.x, dtype=float), status=status, raw_status=str(res.message),
                   iterations=int(res.nit))


BACKEND = Backend(
    name="slsqp",
    entry=solve,
    requires=("scipy",),
    summary="SciPy SLSQP: dense sequential least-squares QP (Kraft), BFGS Hessian, bounds and linear rows",
    capabilities=NLPCapabilities(bounds=True, linear_constraints=True, needs_gradient=True, quasi_newton=True,
                                 nan_step_back=False, time_limit_native=False),
)
