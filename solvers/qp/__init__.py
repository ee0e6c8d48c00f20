"""Quadratic programs, solved by any registered backend.

>>> from solvers import qp
>>> sol = qp.solve(problem, backend="osqp")          # doctest: +SKIP
>>> solver = qp.QPSolver("osqp")                      # set up once ...  # doctest: +SKIP
>>> solver.solve(problem); solver.solve(next_problem)  # ... update and warm-start  # doctest: +SKIP

``BACKENDS`` is the one preference-ordered registry (:mod:`solvers.qp.dispatch`);
``available()`` lists what is installed; each record's :class:`QPCapabilities` says
what the backend can do.
"""

from __future__ import annotations

from solvers.qp.base import PreparedQP
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.dispatch import BACKENDS, DEFAULT_BACKEND, QPSolver, available, prepare, solve
from solvers.qp.problem import QPProblem
from solvers.qp.solution import Options, Solution, Status

__all__ = [
    "BACKENDS",
    "DEFAULT_BACKEND",
    "Options",
    "PreparedQP",
    "QPCapabilities",
    "QPProblem",
    "QPSolver",
    "Solution",
    "Status",
    "available",
    "prepare",
    "solve",
]
