"""The errors of the numerical layer, under one root named for it.

``solvers`` knows no robots, so its root is :class:`SolversError`, named for the layer.
A package built on it derives its own root from this one, so that one
``except SolversError`` catches every error raised on purpose, in either layer.
"""

from __future__ import annotations


class SolversError(Exception):
    """Root of every error raised on purpose by the numerical layer (and, below it, the domain's)."""


class SolverNotFound(SolversError, LookupError):
    """A backend name that is unknown or whose native package is not installed."""


class InvalidProblem(SolversError, ValueError):
    """A problem handed to a solver that is malformed (shapes, NaN, bounds) or beyond the backend."""


class InvalidOptions(SolversError, ValueError):
    """Solver options of the wrong type or out of range (``Options(max_iter=0)``)."""


class SolverError(SolversError, RuntimeError):
    """A backend failed; ``status`` carries the backend's own status text."""

    def __init__(self, message: str, *, backend: str = "", status: str = "") -> None:
        super().__init__(message)
        self.backend = backend
        self.status = status


class InfeasibleError(SolverError):
    """The backend proved (or reported) the problem infeasible."""
