"""The errors of the numerical layer, under one root named for it.

``solvers`` knows no robots, so its root is :class:`SolversError`, named for the layer.
A package built on it derives its own root from this one, so that one
``except SolversError`` catches every error raised on purpose, in either layer.
"""

from __future__ import annotations

import numpy as np


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


class SolveFailedError(SolverError):
    """The backend ended with a status neither optimal nor infeasible (an iteration or time limit, an inaccurate or
    dual infeasible end), or without a point; ``status`` is its own text. A caller that counts such ends reads it
    here, not from the message."""


def check_argument(value: object, cls: type, what: str, error: type[SolversError], public: str) -> None:
    """Raise ``error`` naming ``what`` unless ``value`` is a ``cls`` (``public``: its name for the user). A dict
    of options or a tuple as a problem ended in an AttributeError that blamed the backend ("piqp failed:
    AttributeError: 'dict' object has no attribute 'time_limit'")."""
    if not isinstance(value, cls):
        raise error(f"{what} must be a {public}, got {type(value).__name__}")


def real_array(value: object, name: str) -> np.ndarray:
    """``value`` as a float array, or :class:`InvalidProblem` naming ``name`` and the value unless it holds
    real numbers (bool, integer or float; any shape). Strings and None as a problem's array ended in NumPy's own
    ``ValueError: could not convert string to float: 'a'``, naming no argument, or (None, read as NaN) in a shape
    error about another argument; complex entries lost their imaginary parts with only a ``ComplexWarning``
    (a library tour)."""
    def wrong(why: str) -> InvalidProblem:
        shown = " ".join(repr(value).split())  # an array's repr on one line
        return InvalidProblem(f"{name} = {shown:.60}: must be an array of real numbers{why}")

    try:
        a = np.asarray(value)
    except ValueError as e:  # a ragged list
        raise wrong(f" ({e})") from None
    if a.dtype.kind == "O" and any(v is None for v in a.flat):
        raise wrong(", not None")
    if a.dtype.kind not in "biufO":
        raise wrong(f", got dtype {a.dtype}")
    try:
        return a.astype(float, copy=False)
    except (TypeError, ValueError) as e:  # an object array of other things than numbers
        raise wrong(f" ({e})") from None
