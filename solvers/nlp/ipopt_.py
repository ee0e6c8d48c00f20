"""Ipopt through CasADi's ``nlpsol``, on a problem given by value and gradient callables.

Wächter, Biegler, "On the implementation of an interior-point filter line-search
algorithm for large-scale nonlinear programming", Mathematical Programming 106 (2006);
called through CasADi (Andersson et al., Mathematical Programming Computation 11, 2019).

Ipopt sees ``f`` and its gradient through CasADi callbacks
(:mod:`solvers.nlp.casadi_callbacks`) and approximates the Hessian by limited-memory
quasi-Newton (``hessian_approximation = limited-memory``). An interior-point method keeps
its iterates strictly inside the bounds; where ``f`` is NaN (cannot be evaluated) Ipopt
shortens its step, so ``f`` may be undefined on part of the box. CasADi's warnings about
those NaNs are switched off: here a NaN is an answer, not a fault.

Translation of :class:`~solvers.nlp.Options`: ``tol``, ``constr_viol_tol``,
``dual_inf_tol`` and ``compl_inf_tol`` are all ``tol``; ``max_iter``; ``time_limit`` is
``max_wall_time``; ``verbose`` sets ``print_level`` 5 (else 0). The QP backend called
``ipopt`` (:mod:`solvers.qp.ipopt_`) is the same engine on a QP written as an NLP; it maps
Ipopt's statuses with :func:`status_of` too.
"""

from __future__ import annotations

import time

import numpy as np

from solvers.nlp.capabilities import NLPCapabilities
from solvers.nlp.casadi_callbacks import casadi_nlp
from solvers.nlp.problem import NLPProblem
from solvers.nlp.solution import Options, Outcome
from solvers.registry import Backend
from solvers.status import Status

# Ipopt's ApplicationReturnStatus, as CasADi reports it -> Status
STATUS = {
    "Solve_Succeeded": Status.OPTIMAL,
    "Solved_To_Acceptable_Level": Status.OPTIMAL_INACCURATE,
    "Infeasible_Problem_Detected": Status.INFEASIBLE,
    "Diverging_Iterates": Status.UNBOUNDED,
    "Maximum_Iterations_Exceeded": Status.MAX_ITER,
    "Maximum_WallTime_Exceeded": Status.TIME_LIMIT,
    "Maximum_CpuTime_Exceeded": Status.TIME_LIMIT,
    # Search_Direction_Becomes_Too_Small, Restoration_Failed, Error_In_Step_Computation,
    # Not_Enough_Degrees_Of_Freedom, Invalid_Number_Detected, ... : failures (ERROR)
}


def status_of(stats: dict) -> tuple[Status, str]:
    """Ipopt's return status (from CasADi's ``stats()``) mapped onto :class:`Status`, and the raw text."""
    raw = str(stats.get("return_status", "unknown"))
    return STATUS.get(raw, Status.ERROR), raw


def _settings(o: Options) -> dict:
    """``Options`` as ``nlpsol('ipopt')`` options (the one place they are translated)."""
    ipopt: dict = {
        "tol": o.tol,
        "constr_viol_tol": o.tol,
        "dual_inf_tol": o.tol,
        "compl_inf_tol": o.tol,
        "max_iter": int(o.max_iter),
        "print_level": 5 if o.verbose else 0,
        "sb": "yes",  # no banner
        "hessian_approximation": "limited-memory",
    }
    if o.time_limit is not None:
        ipopt["max_wall_time"] = float(o.time_limit)
    # a NaN is an answer here ("cannot evaluate"), not a fault
    return {"ipopt": ipopt, "print_time": bool(o.verbose), "error_on_fail": False, "show_eval_warnings": False}


def solve(problem: NLPProblem, options: Options) -> Outcome:
    """Minimize ``problem`` with Ipopt (limited-memory quasi-Newton Hessian)."""
    import casadi as ca

    t0 = time.perf_counter()
    c = casadi_nlp(problem)
    solver = ca.nlpsol("nlp_ipopt", "ipopt", c.nlp, _settings(options))
    setup = time.perf_counter() - t0
    r = solver(**c.bounds)
    stats = solver.stats()
    status, raw = status_of(stats)
    return Outcome(x=np.asarray(r["x"], dtype=float).reshape(-1), status=status, raw_status=raw,
                   iterations=int(stats.get("iter_count", 0)), setup_time_s=setup)


BACKEND = Backend(
    name="ipopt",
    entry=solve,
    requires=("casadi",),
    extra="casadi",
    summary="Ipopt via CasADi nlpsol: interior point, limited-memory quasi-Newton, callbacks for f and its gradient",
    capabilities=NLPCapabilities(bounds=True, linear_constraints=True, needs_gradient=True, quasi_newton=True,
                                 nan_step_back=True, time_limit_native=True),
)
