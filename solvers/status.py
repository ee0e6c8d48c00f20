"""What a continuous solver reported, mapped onto one vocabulary shared by QPs and NLPs."""

from __future__ import annotations

import enum


class Status(enum.Enum):
    """What a backend reported, mapped onto one vocabulary.

    For an NLP, ``OPTIMAL`` is a point that meets the backend's first-order optimality
    test: a local minimum for a nonconvex objective.
    """

    OPTIMAL = "optimal"
    OPTIMAL_INACCURATE = "optimal_inaccurate"
    INFEASIBLE = "infeasible"
    UNBOUNDED = "unbounded"
    MAX_ITER = "max_iter"
    TIME_LIMIT = "time_limit"
    ERROR = "error"

    @property
    def ok(self) -> bool:
        """True for a usable (optimal) solution."""
        return self in (Status.OPTIMAL, Status.OPTIMAL_INACCURATE)
