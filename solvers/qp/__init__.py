"""Quadratic programs, solved by any registered backend.

>>> from solvers import qp
>>> sol = qp.solve(problem, backend="osqp")          # doctest: +SKIP
>>> prepared = qp.prepare(problem, backend="piqp")   # setup once ...  # doctest: +SKIP
>>> prepared.update(next_problem); prepared.solve()  # ... solve many  # doctest: +SKIP

``BACKENDS`` is the one preference-ordered registry; ``available()`` lists what is
installed.
"""

from __future__ import annotations

import numpy as np

from solvers.qp import casadi_, closed_form, cvxpy_, ipopt_, osqp_, piqp_, proxsuite_
from solvers.qp.base import PreparedQP
from solvers.qp.problem import QPProblem
from solvers.qp.solution import Options, Solution, Status
from solvers.registry import Registry

BACKENDS = Registry(
    "QP",
    [
        osqp_.BACKEND,
        piqp_.BACKEND,
        proxsuite_.BACKEND,
        cvxpy_.BACKEND,
        casadi_.BACKEND,
        ipopt_.BACKEND,
        closed_form.BACKEND,
    ],
)

DEFAULT_BACKEND = "osqp"


def available() -> list[str]:
    """Names of the installed QP backends, in preference order."""
    return BACKENDS.available()


def prepare(problem: QPProblem, backend: str = DEFAULT_BACKEND, options: Options | None = None) -> PreparedQP:
    """Set ``problem`` up in ``backend`` and return the prepared solver.

    Raises
    ------
    SolverNotFound
        If ``backend`` is unknown or not installed.
    """
    return BACKENDS.get(backend).entry(problem, options)


def solve(
    problem: QPProblem,
    backend: str = DEFAULT_BACKEND,
    options: Options | None = None,
    *,
    warm_start: np.ndarray | None = None,
) -> Solution:
    """Set up and solve ``problem`` with ``backend``.

    Raises
    ------
    SolverNotFound
        Unknown or missing backend.
    InfeasibleError
        The backend reports the problem infeasible.
    SolverError
        Any other failure, carrying the backend's status.
    """
    return prepare(problem, backend, options).solve(warm_start=warm_start)


__all__ = [
    "BACKENDS",
    "DEFAULT_BACKEND",
    "Options",
    "PreparedQP",
    "QPProblem",
    "Solution",
    "Status",
    "available",
    "prepare",
    "solve",
]
