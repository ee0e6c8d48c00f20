"""CasADi's ``sqpmethod``: sequential quadratic programming with a BFGS Hessian and OSQP.

Andersson, Gillis, Horn, Rawlings, Diehl, "CasADi: a software framework for nonlinear
optimization and optimal control", Mathematical Programming Computation 11 (2019); the
method is the line-search SQP of Nocedal & Wright, "Numerical Optimization", 2nd ed.
(2006), chapter 18, with an L1 merit function.

Each iteration solves a QP in the step: the model of ``f`` with a damped BFGS Hessian
(``hessian_approximation = limited-memory``: CasADi's update needs no Hessian callable)
under the bounds and the linear rows. The QP solver is CasADi's ``osqp`` plugin (the OSQP
that CasADi ships; Stellato et al., Mathematical Programming Computation 12, 2020) at
tolerance 1e-9. Measured with casadi 3.8.2 on a 4-step time-allocation window of the
tests: with ``qrqp`` (CasADi's own active-set QP) sqpmethod declared convergence at
141.72, 9 % above the optimum 130.499 that Ipopt, SLSQP, trust-constr and L-BFGS-B reach
(a zero step from a wrong active set); with ``qpoases`` it reached 130.499 in 32
iterations and 281 evaluations, with ``osqp`` in 19 and 145.

Its line search accepts the last trial point when it runs out of backtracking steps, so
it is given ``max_iter_ls`` = 30 instead of CasADi's 3 (a step into a region where ``f``
is not defined needs more), and it is not ``nan_step_back``: dispatch hands it a value
above every one seen instead of NaN (:mod:`solvers.nlp.evaluation`).

Translation of :class:`~solvers.nlp.Options`: ``tol`` is ``tol_pr`` and ``tol_du``;
``max_iter``; ``verbose`` turns on the iteration, header and status prints (and OSQP's).
sqpmethod has no time limit: ``time_limit`` is an ``iteration_callback`` that asks the
method to stop between iterations once the time is up (``User_Requested_Stop``, mapped to
``TIME_LIMIT``).
"""

from __future__ import annotations

import time

import numpy as np

from solvers.nlp.capabilities import NLPCapabilities
from solvers.nlp.casadi_callbacks import USER_STOP, casadi_nlp, deadline_callback
from solvers.nlp.problem import NLPProblem
from solvers.nlp.solution import Options, Outcome
from solvers.registry import Backend
from solvers.status import Status

#: Backtracking steps of the line search (CasADi's default, 3, is too few to step back far
#: enough from a region where f is not defined, and sqpmethod then takes the failed step).
MAX_LINE_SEARCH = 30
#: The QP solver of the subproblems (a CasADi conic plugin that CasADi always ships).
QPSOL = "osqp"
#: Its tolerances: the step must be accurate for the SQP's own test (tol_du) to mean anything.
QP_EPS = 1e-9


# sqpmethod's return status -> Status; anything else (Search_Direction_Becomes_Too_Small,
# Non_Regular_Sensitivities, a failed QP) is a failure (ERROR)
STATUS = {
    "Solve_Succeeded": Status.OPTIMAL,
    "Maximum_Iterations_Exceeded": Status.MAX_ITER,
    USER_STOP: Status.TIME_LIMIT,  # only the deadline callback asks to stop
}


def _settings(o: Options) -> dict:
    """``Options`` as ``nlpsol('sqpmethod')`` options (the one place they are translated)."""
    return {
        "hessian_approximation": "limited-memory",
        "qpsol": QPSOL,
        "max_iter_ls": MAX_LINE_SEARCH,
        "qpsol_options": {"osqp": {"verbose": o.verbose, "eps_abs": QP_EPS, "eps_rel": QP_EPS}, "error_on_fail": False},
        "tol_pr": o.tol,
        "tol_du": o.tol,
        "max_iter": int(o.max_iter),
        "print_header": o.verbose,
        "print_iteration": o.verbose,
        "print_status": o.verbose,
        "print_time": o.verbose,
        "error_on_fail": False,
        "show_eval_warnings": False,
    }


def solve(problem: NLPProblem, options: Options) -> Outcome:
    """Minimize ``problem`` with CasADi's SQP method."""
    import casadi as ca

    t0 = time.perf_counter()
    c = casadi_nlp(problem)
    settings = _settings(options)
    deadline = None
    if options.time_limit is not None:
        deadline = deadline_callback(problem, options.time_limit)
        settings["iteration_callback"] = deadline
    solver = ca.nlpsol("nlp_sqpmethod", "sqpmethod", c.nlp, settings)
    setup = time.perf_counter() - t0
    if deadline is not None:
        deadline.start()
    r = solver(**c.bounds)
    stats = solver.stats()
    raw = str(stats.get("return_status", "unknown"))
    return Outcome(x=np.asarray(r["x"], dtype=float).reshape(-1), status=STATUS.get(raw, Status.ERROR),
                   raw_status=raw, iterations=int(stats.get("iter_count", 0)), setup_time_s=setup)


BACKEND = Backend(
    name="sqpmethod",
    entry=solve,
    requires=("casadi",),
    extra="casadi",
    summary=f"CasADi sqpmethod: line-search SQP, BFGS Hessian, {QPSOL} subproblems, callbacks for f and its gradient",
    capabilities=NLPCapabilities(bounds=True, linear_constraints=True, needs_gradient=True, quasi_newton=True,
                                 nan_step_back=False, time_limit_native=False),
)
