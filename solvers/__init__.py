"""The numerical layer of mrfswarm, independent of robots.

``solvers.qp``: quadratic programs behind one ``solve`` and one backend registry.
``solvers.mrf``: discrete pairwise energy minimizers behind one ``minimize``.
This package never imports ``mrfswarm``; its errors derive from :class:`SolversError`.
"""

from solvers import mrf, qp
from solvers.errors import InfeasibleError, InvalidProblem, SolverError, SolverNotFound, SolversError

__all__ = ["InfeasibleError", "InvalidProblem", "SolverError", "SolverNotFound", "SolversError", "mrf", "qp"]
