"""The numerical layer of mrfswarm, independent of robots.

``solvers.qp``: quadratic programs behind one ``solve`` and one backend registry.
``solvers.nlp``: smooth nonlinear programs given by callables, behind one ``minimize`` and one registry.
``solvers.mrf``: discrete pairwise energy minimizers behind one ``minimize``.
This package never imports ``mrfswarm``; its errors derive from :class:`SolversError`.
"""

from solvers import mrf, nlp, qp
from solvers.errors import (
    InfeasibleError,
    InvalidOptions,
    InvalidProblem,
    SolveFailedError,
    SolverError,
    SolverNotFound,
    SolversError,
)

__all__ = [
    "InfeasibleError",
    "InvalidOptions",
    "InvalidProblem",
    "SolveFailedError",
    "SolverError",
    "SolverNotFound",
    "SolversError",
    "mrf",
    "nlp",
    "qp",
]
