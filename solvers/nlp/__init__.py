"""Smooth nonlinear programs given by callables, solved by any registered backend.

.. math::

    \\min_x f(x) \\quad \\text{s.t.} \\quad \\ell \\le x \\le u, \\quad l_A \\le A x \\le u_A

>>> from solvers import nlp
>>> problem = nlp.NLPProblem(fun, grad, x0, lower, upper)   # doctest: +SKIP
>>> sol = nlp.minimize(problem, backend="ipopt")             # doctest: +SKIP

``BACKENDS`` is the one preference-ordered registry (:mod:`solvers.nlp.dispatch`);
``available()`` lists what is installed; each record's :class:`NLPCapabilities` says what
the backend can do. The QP backends are :mod:`solvers.qp`.
"""

from __future__ import annotations

from solvers.nlp.capabilities import NLPCapabilities
from solvers.nlp.dispatch import BACKENDS, DEFAULT_BACKEND, available, minimize
from solvers.nlp.problem import NLPProblem
from solvers.nlp.solution import Options, Solution, Status

__all__ = [
    "BACKENDS",
    "DEFAULT_BACKEND",
    "NLPCapabilities",
    "NLPProblem",
    "Options",
    "Solution",
    "Status",
    "available",
    "minimize",
]
