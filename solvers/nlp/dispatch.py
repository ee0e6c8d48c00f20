"""The one registry of NLP backends and the one dispatch, :func:`minimize`.

Dispatch reads each backend's :class:`~solvers.nlp.capabilities.NLPCapabilities`: a
problem with linear rows is refused by a backend without ``linear_constraints`` before
any work. It hands the backend a copy of the problem whose callables are counted
(:class:`~solvers.nlp.evaluation.Evaluations`), times the run, and completes the backend's
:class:`~solvers.nlp.solution.Outcome` into a :class:`~solvers.nlp.solution.Solution`
with ``f`` at the returned point.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from solvers.errors import InvalidOptions, InvalidProblem, SolverError, check_argument
from solvers.nlp import ipopt_, lbfgsb_, slsqp_, sqpmethod_, trust_constr_
from solvers.nlp.capabilities import NLPCapabilities
from solvers.nlp.evaluation import Evaluations
from solvers.nlp.problem import NLPProblem
from solvers.nlp.solution import Options, Outcome, Solution
from solvers.nlp.verdict import ACCEPTABLE, ROW_SLACK, first_order_residual, rows_feasible, worst_row
from solvers.registry import Backend, Registry
from solvers.status import Status

log = logging.getLogger(__name__)

BACKENDS: Registry[NLPCapabilities] = Registry(
    "NLP",
    [
        ipopt_.BACKEND,
        sqpmethod_.BACKEND,
        slsqp_.BACKEND,
        trust_constr_.BACKEND,
        lbfgsb_.BACKEND,
    ],
    capabilities=NLPCapabilities,
    group="solvers.nlp",
)

DEFAULT_BACKEND = "ipopt"


def available() -> list[str]:
    """Names of the installed NLP backends, in preference order."""
    return BACKENDS.available()


def _accepts(record: Backend[NLPCapabilities], problem: NLPProblem) -> None:
    if not record.capabilities.bounds and np.isfinite(np.concatenate([problem.lower, problem.upper])).any():
        able = ", ".join(BACKENDS.available(lambda c: c.bounds)) or "none"
        raise InvalidProblem(f"backend {record.name!r} takes no bounds; this problem has some (installed backends "
                             f"that take them: {able})")
    if problem.has_linear_rows and not record.capabilities.linear_constraints:
        able = ", ".join(BACKENDS.available(lambda c: c.linear_constraints)) or "none"
        raise InvalidProblem(f"backend {record.name!r} takes bounds only; this problem has linear rows "
                             f"(installed backends that take them: {able})")


def _verdict(problem: NLPProblem, x: np.ndarray, objective: float, status: Status) -> Status:
    """The backend's status as every backend's would be (:mod:`solvers.nlp.verdict`): never optimal where ``f``
    is not finite (sqpmethod can end on a failed line search's point); ``INFEASIBLE`` exactly when no ``x``
    meets the bounds and rows; a failure (``ERROR``) at a first-order point ``OPTIMAL_INACCURATE``."""
    if status.ok and not np.isfinite(objective):
        return Status.ERROR
    if status in (Status.INFEASIBLE, Status.ERROR, Status.MAX_ITER) and problem.has_linear_rows:
        if not rows_feasible(problem):
            return Status.INFEASIBLE
        if status is Status.INFEASIBLE:  # a local verdict (Ipopt's restoration failed): the rows admit points
            status = Status.ERROR
    if status is Status.ERROR and np.isfinite(objective):
        try:
            g = np.asarray(problem.grad(x), dtype=float).reshape(-1)
        except Exception:  # the user's gradient: no verdict without it
            return status
        if g.size == problem.n and first_order_residual(problem, x, g) <= ACCEPTABLE:
            return Status.OPTIMAL_INACCURATE
    return status


def _check_outcome(name: str, out: Outcome, n: int) -> None:
    """A backend's :class:`Outcome` as dispatch needs it, or a :class:`SolverError` saying what is not: its status a
    :class:`Status`, x of ``n`` entries (a scalar was broadcast over every variable and reported optimal; a status
    string ended in an AttributeError). A non-finite x is the verdict's (a failed run's point: never optimal)."""
    if not isinstance(out, Outcome):
        raise SolverError(f"{name}: returned {type(out).__name__}, not a solvers.nlp Outcome", backend=name,
                          status="bad outcome")
    if not isinstance(out.status, Status):
        raise SolverError(f"{name}: returned the status {out.status!r}, not a solvers.nlp.Status", backend=name,
                          status=str(out.raw_status))
    size = np.size(out.x)
    if size != n:
        raise SolverError(f"{name}: returned x of {size} entries for {n} variables (status {out.raw_status!r})",
                          backend=name, status=str(out.raw_status))


def minimize(problem: NLPProblem, backend: str = DEFAULT_BACKEND, options: Options | None = None) -> Solution:
    """Minimize ``problem`` with ``backend``, from ``problem.x0``.

    A run that stops short (``MAX_ITER``, ``TIME_LIMIT``, a failed line search) is not an
    exception: the solution says so in ``status`` and holds the last iterate, which a
    caller with an iteration budget uses; a run that ends where ``f`` is not finite hands back the lowest finite
    point it evaluated that meets the bounds and rows, if any. The point returned is inside the bounds. The status
    is the same
    verdict for every backend (:mod:`solvers.nlp.verdict`): a point where ``f`` or its gradient is not finite is
    never reported
    optimal (``ERROR``), whatever the backend said; ``INFEASIBLE`` means that no ``x`` meets the bounds and
    rows (checked by a linear program after any run that did not end optimal); a failure at a point that
    meets the first-order conditions to :data:`~solvers.nlp.verdict.ACCEPTABLE` is ``OPTIMAL_INACCURATE``.
    The backend's own word is ``raw_status``.

    Raises
    ------
    SolverNotFound
        If ``backend`` is unknown or not installed.
    InvalidProblem
        If ``problem`` is not an :class:`NLPProblem`, has linear rows or finite bounds and the backend takes none,
        or ``grad`` returns a vector of the wrong size.
    InvalidOptions
        If ``options`` is not an :class:`Options` (or None).
    SolverError
        If the backend itself fails (raises), carrying its error text, labels optimal a point that misses a
        linear row by more than :data:`~solvers.nlp.verdict.ROW_SLACK`, or (its record claiming ``bounds``)
        evaluates ``f`` or its gradient outside the bounds.
    Exception
        Whatever ``problem.fun`` or ``problem.grad`` raised, as itself.
    """
    record = BACKENDS.get(backend)
    check_argument(problem, NLPProblem, "problem", InvalidProblem, "solvers.nlp.NLPProblem")
    if options is not None:
        check_argument(options, Options, "options", InvalidOptions, "solvers.nlp.Options")
    _accepts(record, problem)
    options = options or Options()
    ev = Evaluations(problem, replace_nan=not record.capabilities.nan_step_back,
                     inside=record.name if record.capabilities.bounds else None)
    t0 = time.perf_counter()
    try:
        out: Outcome = record.entry(ev.counted(), options)
    except Exception as e:
        if ev.raised is not None:  # the user's callable (or the gradient's shape check) failed
            raise ev.raised from None
        raise SolverError(f"{record.name} failed: {type(e).__name__}: {e}", backend=record.name,
                          status=type(e).__name__) from e
    if ev.raised is not None:  # a backend that swallowed it
        raise ev.raised
    total = time.perf_counter() - t0
    _check_outcome(record.name, out, problem.n)
    x = np.clip(np.asarray(out.x, dtype=float).reshape(-1), problem.lower, problem.upper)  # Ipopt relaxes by 1e-8
    row, miss = worst_row(problem, x)
    if out.status.ok and miss > ROW_SLACK:
        raise SolverError(f"{record.name}: returned a point labelled {out.status.name} that misses row {row} by "
                          f"{miss:.3g} (relative to its bound): not a solution (status {out.raw_status!r})",
                          backend=record.name, status=str(out.raw_status))
    objective = ev.value_at(x)
    if not np.isfinite(objective) and ev.best is not None and problem.max_violation(ev.best[1]) <= 1e-9:
        # sqpmethod and SLSQP ended where f is NaN (or at a far point): the caller gets the best finite point seen,
        # never reported optimal (the status is the run's, which the verdict keeps below optimal)
        objective, x = ev.best[0], ev.best[1].copy()
        status = Status.ERROR if out.status.ok else out.status
    else:
        status = out.status
    status = _verdict(problem, x, objective, status)
    finite = ev.gradient_finite_at(x)
    if finite is None:
        finite = ev.gradient_finite_at(np.asarray(out.x, dtype=float))
    if status.ok and finite is False:  # a NaN gradient was handed on as zeros (or the last finite one)
        status = Status.ERROR
    sol = Solution(x=x, status=status, objective=objective, iterations=out.iterations,
                   evaluations=ev.fun_calls, gradient_evaluations=ev.grad_calls, setup_time_s=out.setup_time_s,
                   solve_time_s=total - out.setup_time_s, backend=record.name, raw_status=out.raw_status)
    log.debug("%s: %s in %d iterations, %d evaluations, f = %.6g", record.name, sol.raw_status, sol.iterations,
              sol.evaluations, sol.objective)
    return sol
