"""What every QP backend module implements: a prepared (set-up) problem that solves.

A backend is a subclass of :class:`PreparedQP`. Its constructor does the setup (model
building, factorization) and is timed apart from :meth:`PreparedQP.solve`, so that
benchmarks and the receding horizon can reuse a setup: :meth:`PreparedQP.update` loads
new data with the same sparsity pattern, and ``solve(warm_start=x)`` starts from ``x``.
"""

from __future__ import annotations

import logging
import numbers
import time
from abc import ABC, abstractmethod
from typing import ClassVar

import numpy as np

from solvers.errors import InfeasibleError, InvalidProblem, SolveFailedError, SolverError
from solvers.qp.problem import QPProblem
from solvers.qp.row_split import RowSplit, split_rows
from solvers.qp.solution import Options, Solution, Status

#: A point a backend labels optimal (or optimal inaccurate) may miss a row by at most this much, relative to
#: 1 + |the row's bound|; further, it is not a solution of the problem, whatever the label (a backend that
#: returned its start as "optimal" had the continuous stage reject every window's certificate, for ten minutes,
#: instead of failing each solve at once). First-order backends stop within their tolerances, far below it.
ROW_SLACK = 1e-3

log = logging.getLogger(__name__)


_warned: set[tuple[str, str]] = set()


def warn_once(logger: logging.Logger, message: str) -> None:
    """``message`` as a warning of ``logger``, once per process (or since :func:`forget_warned`): an option a backend
    ignores is set once and solved with many times (a window's every QP), and one line says it."""
    key = (logger.name, message)
    if key not in _warned:
        _warned.add(key)
        logger.warning("%s", message)


def forget_warned() -> None:
    """Let :func:`warn_once` say each message again: a run starts, and one process may plan many (a sweep's points,
    each of which says its own)."""
    _warned.clear()


def set_attributes(target: object, values: dict) -> None:
    """Set each of ``values`` as an attribute of ``target`` (a backend's settings object)."""
    for key, val in values.items():
        setattr(target, key, val)


class PreparedQP(ABC):
    """A QP set up in one backend, ready to be solved (and re-solved after updates)."""

    name: ClassVar[str] = ""

    def __init__(self, problem: QPProblem, options: Options | None = None) -> None:
        self.problem = problem
        self.options = options or Options()
        t0 = time.perf_counter()
        self._guarded(self._setup, problem)
        self.setup_time_s = time.perf_counter() - t0

    def _guarded(self, fn, *args):
        """Call a backend function; its own exceptions become :class:`SolverError`."""
        try:
            return fn(*args)
        except (SolverError, InvalidProblem):
            raise
        except Exception as e:  # the backend's own exception, wrapped with its text
            raise SolverError(f"{self.name} failed: {type(e).__name__}: {e}", backend=self.name,
                              status=type(e).__name__) from e

    @abstractmethod
    def _setup(self, problem: QPProblem) -> None:
        """Build the backend's model for ``problem``."""

    def update(self, problem: QPProblem) -> None:
        """Load ``problem``, which must have the sparsity pattern of the current one.

        The default sets up again; backends with a cheaper update override it.
        """
        self._check_same_shape(problem)
        self.problem = problem
        t0 = time.perf_counter()
        self._guarded(self._setup, problem)
        self.setup_time_s = time.perf_counter() - t0

    @abstractmethod
    def _solve(self, warm_start: np.ndarray | None) -> tuple[np.ndarray | None, Status, str, int, np.ndarray | None]:
        """Solve; return ``(x, status, raw_status, iterations, y)``."""

    def solve(self, warm_start: np.ndarray | None = None) -> Solution:
        """Solve the loaded problem; ``warm_start`` (primal x only) where the backend takes one: it may not shorten
        the solve (osqp, SCS and qpOASES took as many iterations from the optimum itself); re-solving through
        :class:`solvers.qp.QPSolver`, which keeps the backend's own state, does.

        Raises
        ------
        InvalidProblem
            A ``warm_start`` of the wrong shape or not finite.
        InfeasibleError
            When the backend reports infeasibility.
        SolveFailedError
            For any other status than optimal (or no point), with the backend's status text.
        SolverError
            A point that is not a solution (not finite, of the wrong size, missing a row), whatever its label.
        """
        if warm_start is not None:
            warm_start = np.asarray(warm_start, dtype=float)
            if warm_start.shape != (self.problem.n,):
                raise InvalidProblem(f"warm_start has shape {warm_start.shape}, expected ({self.problem.n},)")
            if not np.all(np.isfinite(warm_start)):  # osqp ran its 20000 iterations from a NaN and failed
                bad = int(np.flatnonzero(~np.isfinite(warm_start))[0])
                raise InvalidProblem(f"warm_start[{bad}] = {warm_start[bad]}: must be finite")
        t0 = time.perf_counter()
        answer = self._guarded(self._solve, warm_start)
        solve_time = time.perf_counter() - t0
        if not (isinstance(answer, tuple) and len(answer) == 5):  # a traceback from unpacking it (a tour's plugin)
            got = f"a tuple of {len(answer)}" if isinstance(answer, tuple) else type(answer).__name__
            raise SolverError(f"{self.name}: _solve returned {got}, not (x, status, raw_status, iterations, y)",
                              backend=self.name, status="bad answer")
        x, status, raw, iters, y = answer
        if isinstance(iters, bool) or not isinstance(iters, numbers.Integral):
            raise SolverError(f"{self.name}: returned the iteration count {iters!r}, not a whole number (status "
                              f"{raw!r})", backend=self.name, status=str(raw))
        if not isinstance(status, Status):
            raise SolverError(f"{self.name}: returned the status {status!r}, not a solvers.qp.Status", backend=self.name,
                              status=str(raw))
        if status is Status.INFEASIBLE:
            raise InfeasibleError(f"{self.name}: problem infeasible (status {raw!r})", backend=self.name, status=raw)
        if not status.ok or x is None:
            raise SolveFailedError(f"{self.name}: solve failed (status {raw!r})", backend=self.name, status=raw)
        x = np.array(x, dtype=float).reshape(-1)  # a copy: piqp and proxsuite return views of their buffers
        if x.size != self.problem.n:
            raise SolverError(f"{self.name}: returned x of {x.size} entries for {self.problem.n} variables (status "
                              f"{raw!r})", backend=self.name, status=raw)
        if not np.all(np.isfinite(x)):
            raise SolverError(f"{self.name}: returned a non-finite solution (status {raw!r})", backend=self.name, status=raw)
        if y is not None and np.size(y) != self.problem.A.shape[0]:
            raise SolverError(f"{self.name}: returned {np.size(y)} multipliers for {self.problem.A.shape[0]} rows "
                              f"(status {raw!r})", backend=self.name, status=raw)
        row, miss = self._worst_row(x)
        if miss > ROW_SLACK:
            raise SolverError(f"{self.name}: returned a point labelled {status.name} that misses row {row} by "
                              f"{miss:.3g} (relative to its bound): not a solution (status {raw!r})",
                              backend=self.name, status=raw)
        if status is Status.OPTIMAL_INACCURATE:
            # once per process: a run solves thousands of window QPs (a tour counted 10-13 lines per run)
            warn_once(log, f"{self.name}: solution only optimal to reduced accuracy ({raw}); said once per run")
        return Solution(
            x=x,
            status=status,
            objective=self.problem.objective(x),
            iterations=int(iters),
            setup_time_s=self.setup_time_s,
            solve_time_s=solve_time,
            backend=self.name,
            raw_status=raw,
            y=None if y is None else np.array(y, dtype=float),
        )

    def _worst_row(self, x: np.ndarray) -> tuple[int, float]:
        """The row of the loaded problem that ``x`` misses most, and by how much relative to 1 + |its bound|
        (0 when every row holds)."""
        A = self.problem.A
        if A.shape[0] == 0:
            return -1, 0.0
        Ax = A @ x
        lo, hi = self.problem.l, self.problem.u
        with np.errstate(invalid="ignore"):
            miss = np.maximum(np.where(np.isfinite(lo), (lo - Ax) / (1 + np.abs(lo)), 0.0),
                              np.where(np.isfinite(hi), (Ax - hi) / (1 + np.abs(hi)), 0.0))
        k = int(np.argmax(miss))
        return k, max(float(miss[k]), 0.0)

    def same_pattern(self, problem: QPProblem) -> bool:
        """True when ``problem`` has the shape and sparsity pattern of the loaded one (so it can be an update)."""
        old = self.problem
        return (
            old.n == problem.n
            and old.m == problem.m
            and old.P.nnz == problem.P.nnz
            and old.A.nnz == problem.A.nnz
            and np.array_equal(old.P.indices, problem.P.indices)
            and np.array_equal(old.P.indptr, problem.P.indptr)
            and np.array_equal(old.A.indices, problem.A.indices)
            and np.array_equal(old.A.indptr, problem.A.indptr)
        )

    def _check_same_shape(self, problem: QPProblem) -> None:
        if not self.same_pattern(problem):
            raise InvalidProblem("update() needs a problem with the same shape and sparsity pattern")

    def _split_for_update(self, problem: QPProblem, current: RowSplit) -> RowSplit | None:
        """The row split of ``problem`` when it partitions the rows as ``current`` does.

        For backends that split ``l <= Ax <= u`` into equality and inequality rows: a new
        partition sets the backend up again (the default :meth:`update`) and returns None.
        """
        self._check_same_shape(problem)
        split = split_rows(problem)
        if split.same_partition(current):
            return split
        PreparedQP.update(self, problem)
        return None
