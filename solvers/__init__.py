"""The numerical layer of mrfswarm, independent of robots.

``solvers.qp``: quadratic programs behind one ``solve`` and one backend registry.
``solvers.mrf``: discrete pairwise energy minimizers behind one ``minimize``.
This package never imports ``mrfswarm``.
"""

from solvers import mrf, qp
from solvers.errors import InfeasibleError, InvalidProblem, MrfswarmError, SolverError, SolverNotFound

__all__ = ["InfeasibleError", "InvalidProblem", "MrfswarmError", "SolverError", "SolverNotFound", "mrf", "qp"]
