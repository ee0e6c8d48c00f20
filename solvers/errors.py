"""The error hierarchy shared by the numerical layer and the domain package.

`solvers` never imports `mrfswarm`, so the root of every error the toolkit raises lives
here; `mrfswarm.errors` re-exports it and adds the domain's own errors.
"""

from __future__ import annotations


class MrfswarmError(Exception):
    """Root of every error raised on purpose by mrfswarm and solvers."""


class SolverNotFound(MrfswarmError, LookupError):
    """A backend name that is unknown or whose native package is not installed."""


class InvalidProblem(MrfswarmError, ValueError):
    """A problem handed to a solver that is malformed (shapes, NaN, bounds)."""


class SolverError(MrfswarmError, RuntimeError):
    """A backend failed; ``status`` carries the backend's own status text."""

    def __init__(self, message: str, *, backend: str = "", status: str = "") -> None:
        super().__init__(message)
        self.backend = backend
        self.status = status


class InfeasibleError(SolverError):
    """The backend proved (or reported) the problem infeasible."""
