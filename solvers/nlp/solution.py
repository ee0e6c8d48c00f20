"""The one result type and the one options object of every NLP backend."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from solvers.errors import InvalidOptions
from solvers.options import check_fields
from solvers.status import Status

__all__ = ["Options", "Outcome", "Solution", "Status"]


@dataclass(frozen=True)
class Options:
    """Solver settings, translated per backend in one place (the backend's module).

    Parameters
    ----------
    tol
        First-order optimality tolerance: each backend's stopping test on its (scaled)
        optimality and feasibility measures, and its relative decrease test where it has
        one (each backend's module says which of its settings get it).
    max_iter
        Iteration cap (the backend's own iterations, not function evaluations).
    time_limit
        Seconds; ``None`` for no limit. Ipopt checks it natively; the other backends
        between iterations (an iteration callback), so a run can exceed it by one
        iteration.
    verbose
        Let the backend print.
    """

    tol: float = 1e-8
    max_iter: int = 1000
    time_limit: float | None = None
    verbose: bool = False

    def __post_init__(self) -> None:
        check_fields(self)
        if not 0 < self.tol < math.inf:  # inf: every backend called its start point optimal (a library tour)
            raise InvalidOptions(f"tol must be positive and finite, got {self.tol}")
        if self.max_iter < 1:
            raise InvalidOptions(f"max_iter must be >= 1, got {self.max_iter}")
        if self.time_limit is not None and not self.time_limit > 0:
            raise InvalidOptions(f"time_limit must be positive, got {self.time_limit}")


@dataclass(frozen=True)
class Outcome:
    """What a backend's entry returns to dispatch, which completes it into a :class:`Solution`.

    Attributes
    ----------
    x
        Final point (n,).
    status, raw_status
        The mapped :class:`Status` and the backend's own status text.
    iterations
        The backend's own iteration count.
    setup_time_s
        Wall time of building the solver (CasADi's ``nlpsol``); 0 for none.
    """

    x: np.ndarray
    status: Status
    raw_status: str
    iterations: int
    setup_time_s: float = 0.0


@dataclass(frozen=True)
class Solution:
    """What :func:`solvers.nlp.minimize` returns; nothing is raised for a failed run, check ``status``.

    Attributes
    ----------
    x
        Final point (n,) (for ``TIME_LIMIT`` or ``MAX_ITER``, the backend's last iterate).
    status
        The mapped :class:`Status`.
    objective
        ``f(x)``, the problem's own value (not the backend's report; NaN if ``f`` cannot
        be evaluated there).
    iterations
        Backend iterations.
    evaluations, gradient_evaluations
        Calls of ``fun`` and ``grad`` during the solve, counted by dispatch the same way
        for every backend.
    setup_time_s, solve_time_s
        Wall time of setting up (building the solver) and of solving, apart.
    backend
        The backend's registry name.
    raw_status
        The backend's own status text.
    """

    x: np.ndarray
    status: Status
    objective: float
    iterations: int
    evaluations: int
    gradient_evaluations: int
    setup_time_s: float
    solve_time_s: float
    backend: str
    raw_status: str = ""
