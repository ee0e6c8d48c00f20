"""The one result type and the one options object of every QP backend.

:class:`Status` is the vocabulary of every kind of continuous solver (:mod:`solvers.status`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from solvers.errors import InvalidOptions
from solvers.options import check_fields
from solvers.status import Status

__all__ = ["Options", "Solution", "Status"]


@dataclass(frozen=True)
class Options:
    """Solver settings, translated per backend in one place (the backend's module).

    Parameters
    ----------
    eps_abs, eps_rel
        Absolute and relative tolerances (primal and dual residuals).
    max_iter
        Iteration cap.
    time_limit
        Seconds; ``None`` for no limit.
    verbose
        Let the backend print.
    polish
        Ask first-order backends (osqp) for a solution polishing step.
    scaling
        Let the backend equilibrate the problem (Ruiz scaling of its rows and columns)
        before solving: osqp, piqp, proxsuite, clarabel. ``False`` for problems already
        scaled by their formulation, where equilibration can cost iterations or even
        mislead infeasibility detection (the continuous stage's window problems: piqp
        declared feasible windows infeasible, osqp stopped inaccurate). Backends without
        such a step ignore it.
    """

    eps_abs: float = 1e-8
    eps_rel: float = 1e-8
    max_iter: int = 20000
    time_limit: float | None = None
    verbose: bool = False
    polish: bool = True
    scaling: bool = True

    def __post_init__(self) -> None:
        check_fields(self)
        # an infinite tolerance accepts any point: ipopt called x = 0 optimal where the optimum is 0.5, the
        # points of piqp, proxsuite, clarabel and cvxpy missed their rows, SCS refused it in its own words (a tour)
        if not (0 < self.eps_abs < math.inf and 0 <= self.eps_rel < math.inf):
            raise InvalidOptions(f"tolerances must be positive and finite (eps_rel may be 0), got "
                                 f"eps_abs={self.eps_abs}, eps_rel={self.eps_rel}")
        if self.max_iter < 1:
            raise InvalidOptions(f"max_iter must be >= 1, got {self.max_iter}")
        if self.time_limit is not None and not self.time_limit > 0:
            raise InvalidOptions(f"time_limit must be positive, got {self.time_limit}")


@dataclass(frozen=True)
class Solution:
    """What a solve returns.

    Attributes
    ----------
    x
        Primal solution (n,).
    status
        The mapped :class:`Status`.
    objective
        ``x'Px/2 + q'x`` evaluated by us (not the backend's own report).
    iterations
        Backend iterations (0 for direct solves).
    setup_time_s, solve_time_s
        Wall time of setting up (factorization, model building) and of solving, apart.
    backend
        The backend's registry name.
    raw_status
        The backend's own status text.
    y
        Constraint multipliers when the backend gives them, else ``None``.
    """

    x: np.ndarray
    status: Status
    objective: float
    iterations: int
    setup_time_s: float
    solve_time_s: float
    backend: str
    raw_status: str = ""
    y: np.ndarray | None = field(default=None, repr=False)
