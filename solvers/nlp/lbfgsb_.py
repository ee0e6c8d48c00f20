"""SciPy's L-BFGS-B: limited-memory BFGS with bounds, by projected gradients.

Byrd, Lu, Nocedal, Zhu, "A limited memory algorithm for bound constrained optimization",
SIAM Journal on Scientific Computing 16 (1995); Morales, Nocedal, "Remark on algorithm
778", ACM Transactions on Mathematical Software 38 (2011). Called through
``scipy.optimize.minimize`` (:mod:`solvers.nlp.scipy_minimize`).

Bounds only: every iterate and every trial point is projected onto them. No linear rows
(dispatch refuses a problem with some).

Translation of :class:`~solvers.nlp.Options`: ``tol`` is ``gtol`` (the projected
gradient's largest entry), and ``ftol`` (the relative decrease of ``f`` per iteration) is
``tol**2`` (:func:`~solvers.nlp.scipy_minimize.decrease_tol`: near a minimum ``f``
falls by the square of the gradient; with ``ftol = tol`` L-BFGS-B stopped 5e-5 from the
tests' box-constrained quadratic's minimum); ``max_iter`` is ``maxiter``; ``time_limit``
is checked between iterations; ``verbose`` is ignored (SciPy deprecated L-BFGS-B's
printing).
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

# L-BFGS-B's warnflag -> Status (2: an abnormal line search, among others: ERROR)
STATUS = {0: Status.OPTIMAL, 1: Status.MAX_ITER}


def _settings(o: Options) -> dict:
    """``Options`` as L-BFGS-B's options (the one place they are translated)."""
    # verbose: SciPy deprecated L-BFGS-B's printing (iprint, disp) in 1.15; ignored
    return {"gtol": o.tol, "ftol": decrease_tol(o.tol), "maxiter": int(o.max_iter)}


def solve(problem: NLPProblem, options: Options) -> Outcome:
    """Minimize ``problem`` (bounds only) with L-BFGS-B."""
    res, timed_out = scipy_minimize.run(problem, "L-BFGS-B", _settings(options), options)
    status = Status.TIME_LIMIT if timed_out else STATUS.get(int(res.status), Status.ERROR)
    return Outcome(x=np.asarray(res.x, dtype=float), status=status, raw_status=str(res.message),
                   iterations=int(res.nit))


BACKEND = Backend(
    name="lbfgsb",
    entry=solve,
    requires=("scipy",),
    summary="SciPy L-BFGS-B: limited-memory BFGS with bounds (projected gradient); bounds only",
    capabilities=NLPCapabilities(bounds=True, linear_constraints=False, needs_gradient=True, quasi_newton=True,
                                 nan_step_back=False, time_limit_native=False),
)
