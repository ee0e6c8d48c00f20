"""The one registry of QP backends and the one dispatch: ``prepare``, ``solve``, :class:`QPSolver`.

Dispatch reads each backend's :class:`~solvers.qp.capabilities.QPCapabilities`: a
problem with inequality rows is refused by a backend without ``inequalities`` before
any setup, and :class:`QPSolver` passes a warm start only to a backend with
``warm_start``.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from solvers.errors import InvalidOptions, InvalidProblem, check_argument
from solvers.qp import casadi_, clarabel_, closed_form, cvxpy_, ipopt_, osqp_, piqp_, proxsuite_, qpsolvers_
from solvers.qp.base import PreparedQP
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.problem import QPProblem
from solvers.qp.solution import Options, Solution
from solvers.registry import Backend, Registry

log = logging.getLogger(__name__)

BACKENDS: Registry[QPCapabilities] = Registry(
    "QP",
    [
        osqp_.BACKEND,
        piqp_.BACKEND,
        proxsuite_.BACKEND,
        clarabel_.BACKEND,
        cvxpy_.BACKEND,
        *qpsolvers_.BACKENDS,
        casadi_.BACKEND,
        ipopt_.BACKEND,
        closed_form.BACKEND,
    ],
    capabilities=QPCapabilities,
    group="solvers.qp",
    entry_class=PreparedQP,
)

DEFAULT_BACKEND = "osqp"


def available() -> list[str]:
    """Names of the installed QP backends, in preference order."""
    return BACKENDS.available()


def _accepts(record: Backend[QPCapabilities], problem: QPProblem) -> None:
    if problem.has_inequalities and not record.capabilities.inequalities:
        able = ", ".join(BACKENDS.available(lambda c: c.inequalities)) or "none"
        raise InvalidProblem(f"backend {record.name!r} solves equality-constrained problems only; this problem has "
                             f"inequality rows (installed backends that take them: {able})")


def prepare(problem: QPProblem, backend: str = DEFAULT_BACKEND, options: Options | None = None) -> PreparedQP:
    """Set ``problem`` up in ``backend`` and return the prepared solver.

    Raises
    ------
    SolverNotFound
        If ``backend`` is unknown or not installed.
    InvalidProblem
        If ``problem`` is not a :class:`QPProblem`, or has inequality rows and the backend takes none.
    InvalidOptions
        If ``options`` is not an :class:`Options` (or None).
    """
    record = BACKENDS.get(backend)
    check_argument(problem, QPProblem, "problem", InvalidProblem, "solvers.qp.QPProblem")
    if options is not None:
        check_argument(options, Options, "options", InvalidOptions, "solvers.qp.Options")
    _accepts(record, problem)
    prepared: PreparedQP = record.entry(problem, options)
    return prepared


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
    InvalidProblem
        Inequality rows for an equality-only backend.
    InfeasibleError
        The backend reports the problem infeasible.
    SolverError
        Any other failure, carrying the backend's status.
    """
    return prepare(problem, backend, options).solve(warm_start=warm_start)


class QPSolver:
    """Repeated solves with one backend, reusing its setup while the sparsity pattern stays.

    The first :meth:`solve` prepares the backend; each later one with the same shape and
    sparsity pattern only updates its data and, if the backend's record has
    ``warm_start``, starts from the previous solution. Any failure resets the handle: a
    failed solve leaves the backend's iterates (an infeasibility certificate, say) where
    they are, and they must not be the next start.

    Parameters
    ----------
    backend
        A name of :data:`BACKENDS`.
    options
        Options of every solve.
    reuse
        Keep the prepared backend between solves; with ``False`` every solve sets up
        afresh (benchmarks of cold solves).

    Raises
    ------
    SolverNotFound
        At construction, for an unknown or missing backend.
    InvalidOptions
        At construction, ``options`` that are not an :class:`Options` (or None).
    """

    def __init__(self, backend: str = DEFAULT_BACKEND, options: Options | None = None, *, reuse: bool = True) -> None:
        self.record = BACKENDS.get(backend)
        if options is not None:  # a dict failed at the first solve as "piqp failed: AttributeError: ..."
            check_argument(options, Options, "options", InvalidOptions, "solvers.qp.Options")
        self.options = options
        self.reuse = reuse
        self._prepared: PreparedQP | None = None
        self._x: np.ndarray | None = None

    @property
    def backend(self) -> str:
        """The backend's registry name."""
        return self.record.name

    def reset(self) -> None:
        """Forget the prepared backend and the last solution: the next solve sets up afresh."""
        self._prepared, self._x = None, None

    def solve(self, problem: QPProblem) -> Solution:
        """Solve ``problem``; ``Solution.setup_time_s`` is this call's setup or update.

        Raises
        ------
        InvalidProblem, InfeasibleError, SolverError
            As :func:`solve` (``problem`` not a :class:`QPProblem` too); the handle is reset first.
        """
        check_argument(problem, QPProblem, "problem", InvalidProblem, "solvers.qp.QPProblem")
        prepared = self._prepared
        try:
            if self.reuse and prepared is not None and prepared.same_pattern(problem):
                t0 = time.perf_counter()
                prepared.update(problem)
                setup = time.perf_counter() - t0
                sol = prepared.solve(warm_start=self._x if self.record.capabilities.warm_start else None)
            else:
                _accepts(self.record, problem)
                prepared = self.record.entry(problem, self.options)
                setup = prepared.setup_time_s
                sol = prepared.solve()
        except Exception:
            self.reset()
            raise
        if self.reuse:
            self._prepared, self._x = prepared, sol.x
        return Solution(x=sol.x, status=sol.status, objective=sol.objective, iterations=sol.iterations,
                        setup_time_s=setup, solve_time_s=sol.solve_time_s, backend=sol.backend,
                        raw_status=sol.raw_status, y=sol.y)
