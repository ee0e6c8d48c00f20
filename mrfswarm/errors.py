"""Errors of the domain package; the root and solver errors come from ``solvers``."""

from __future__ import annotations

from solvers.errors import InfeasibleError, InvalidProblem, MrfswarmError, SolverError, SolverNotFound


class ConfigError(MrfswarmError, ValueError):
    """A configuration key or value that is unknown or out of range; names the key."""


class ScenarioError(MrfswarmError, ValueError):
    """A scenario that cannot be planned: a robot in a wall, off the map, a bad map file."""


class UnsafeTrajectoryError(MrfswarmError, RuntimeError):
    """A trajectory failed the continuous safety check and could not be repaired."""


__all__ = [
    "ConfigError",
    "InfeasibleError",
    "InvalidProblem",
    "MrfswarmError",
    "ScenarioError",
    "SolverError",
    "SolverNotFound",
    "UnsafeTrajectoryError",
]
