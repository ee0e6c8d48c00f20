"""Errors of the domain package, under its root :class:`MrfswarmError`.

``MrfswarmError`` derives from the numerical layer's root :class:`solvers.errors.SolversError`
(``solvers`` knows no robots and never names this package), so ``except SolversError``
catches every error the toolkit raises on purpose, and ``except MrfswarmError`` every
error of the domain. The layer's own errors are re-exported here.
"""

from __future__ import annotations

from typing import Any

from solvers.errors import InfeasibleError, InvalidProblem, SolverError, SolverNotFound, SolversError


class MrfswarmError(SolversError):
    """Root of every error raised on purpose by the domain package."""


class ConfigError(MrfswarmError, ValueError):
    """A configuration key or value that is unknown or out of range; names the key."""


class ScenarioError(MrfswarmError, ValueError):
    """A scenario that cannot be planned: a robot in a wall, off the map, a bad map file."""


class UnsafeTrajectoryError(MrfswarmError, RuntimeError):
    """A trajectory failed the continuous safety check and could not be repaired."""


class ExportError(MrfswarmError, ValueError):
    """A plan that cannot be written in a client's format (a Crazyflie's memory), or an output folder
    that must not be written into; the message says which value and why."""


class OutputExistsError(ExportError):
    """An output folder that already holds a run (or a sweep), and no overwrite asked. The message names both ways to
    replace it (``--overwrite``, ``overwrite=True``); ``command_line`` is the one the ``mrfswarm`` command says, with
    the flag only."""

    def __init__(self, message: str, command_line: str) -> None:
        super().__init__(message)
        self.command_line = command_line

    def __reduce__(self) -> tuple:  # both texts through a process boundary (a sweep's worker)
        return type(self), (str(self), self.command_line)


class DeprecatedKeyWarning(FutureWarning):
    """A config key under the name it had in an earlier version: it still loads, as its new name.

    A :class:`FutureWarning`, which Python shows by default (a ``DeprecationWarning`` is
    hidden outside ``__main__``): it speaks to whoever wrote the config, not to a developer.
    """


class UnusedSettingWarning(UserWarning):
    """A setting asked for by name that the run does not use (``--nlp`` without the time refinement): the run goes
    on without it, and the warning says what would use it."""


class PlanWarning(UserWarning):
    """What a finished plan warns of (:meth:`~mrfswarm.pipeline.Result.warnings`): robots short of the goal or cut
    at ``mrf.max_steps``, windows flown as their rest-to-rest witness (slower, with stops), a QP backend that failed
    attempts of many windows, the NLP refinement's errors, a flight too long for a Crazyflie's memory, a simulated
    flight that came closer than the plan. :func:`~mrfswarm.pipeline.plan` issues one per text, pointing at its
    caller; ``mrfswarm run`` prints the same texts after its summary line."""


class PlanError(MrfswarmError):
    """A plan stopped after its discrete stage; ``result`` holds what was computed.

    The message is that of the error that stopped it (its ``__cause__``); ``result`` is
    the :class:`~mrfswarm.pipeline.Result` of the stages before, with ``result.failure``
    set to that message, so that a caller can still write it out.
    """

    def __init__(self, message: str, result: Any) -> None:
        super().__init__(message)
        self.result = result


__all__ = [
    "ConfigError",
    "DeprecatedKeyWarning",
    "UnusedSettingWarning",
    "ExportError",
    "InfeasibleError",
    "InvalidProblem",
    "MrfswarmError",
    "PlanError",
    "PlanWarning",
    "ScenarioError",
    "SolverError",
    "SolverNotFound",
    "SolversError",
    "UnsafeTrajectoryError",
]
