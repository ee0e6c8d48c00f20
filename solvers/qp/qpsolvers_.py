"""A bridge to qpsolvers, the unified interface to many QP solvers: SCS through it.

Caron, Arnström, Bonagamba, Escande, Kim, et al., "qpsolvers: Quadratic Programming
Solvers in Python", https://github.com/qpsolvers/qpsolvers (2024). The solver reached:
O'Donoghue, Chu, Parikh, Boyd, "Conic Optimization via Operator Splitting and
Homogeneous Self-Dual Embedding", J. Optim. Theory Appl., 2016 (SCS).

qpsolvers solves

.. math::

    \\min_x \\tfrac12 x^\\top P x + q^\\top x \\quad \\text{s.t.} \\quad
    G x \\le h, \\quad A x = b,

so the rows of ``l <= Ax <= u`` are stacked as Clarabel's are
(:func:`~solvers.qp.row_split.stack_one_sided`): equality rows into ``A x = b``, finite
upper sides into ``G x <= h`` as they are and finite lower sides negated. qpsolvers'
multipliers satisfy ``P x + q + G' z + A' y = 0``, the stacked form's convention, so
:func:`~solvers.qp.row_split.scatter_one_sided` maps them back. Box bounds are not used.

One class, :class:`QpsolversQP`, serves every solver qpsolvers opens; a backend is a
subclass naming the solver (``solver``) and the registry name, plus its record, its
options translation (:data:`_SETTINGS`) and its status translation (:data:`_STATUS`).
Only solvers whose qpsolvers result reports an iteration count and a status, and that
meet the shared tests' accuracy (``Options``' default 1e-8), are bridged: HiGHS through
qpsolvers reports neither count nor status; CVXOPT stops with status ``unknown`` at
tolerances of 1e-8 on the update and window tests. Adding one is a subclass, a record
and its two translations. qpsolvers hands a problem without any constraint row to
SciPy's LSQR instead, with an absolute residual test that fails well-posed problems
(2e-8 on an 8-variable one), so such a problem gets one vacuous row ``0 x <= 1``. The
problem is handed to qpsolvers at every solve (it keeps no solver between calls), so
an update only replaces the data. SCS's ``eps_abs``, ``eps_rel``, ``max_iters`` and
``time_limit_secs`` are ``Options``'; SCS is warm-started from ``warm_start``
(``initvals``).
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np
import scipy.sparse as sp

from solvers.qp.base import PreparedQP
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.problem import QPProblem
from solvers.qp.row_split import one_sided_rows, scatter_one_sided, stack_one_sided
from solvers.qp.solution import Options, Status
from solvers.registry import Backend

log = logging.getLogger(__name__)


def _scs_settings(o: Options) -> dict[str, Any]:
    s: dict[str, Any] = dict(eps_abs=o.eps_abs, eps_rel=o.eps_rel, max_iters=int(o.max_iter))
    if o.time_limit is not None:
        s["time_limit_secs"] = float(o.time_limit)
    return s  # polish: SCS has no polishing step; ignored


#: ``Options`` in each solver's terms (the one place they are translated).
_SETTINGS: dict[str, Callable[[Options], dict[str, Any]]] = {"scs": _scs_settings}

#: Each solver's statuses (as qpsolvers' ``extras["status"]`` spells them); anything else is a failure.
_STATUS: dict[str, dict[str, Status]] = {
    "scs": {
        "solved": Status.OPTIMAL,
        "solved_inaccurate": Status.OPTIMAL_INACCURATE,
        "infeasible": Status.INFEASIBLE,
        "infeasible_inaccurate": Status.INFEASIBLE,
        "unbounded": Status.UNBOUNDED,
        "unbounded_inaccurate": Status.UNBOUNDED,
    },
}

#: Where each solver's qpsolvers result keeps its iteration count.
_ITERATIONS = {"scs": "iter"}


class QpsolversQP(PreparedQP):
    """A solver reached through ``qpsolvers.solve_problem``; subclasses name it."""

    solver: ClassVar[str] = ""

    def _setup(self, problem: QPProblem) -> None:
        import qpsolvers

        rows = one_sided_rows(problem)
        A_K, b = stack_one_sided(problem, rows)
        ne = len(rows[0])
        eq = (A_K[:ne], b[:ne]) if ne else (None, None)
        ineq: tuple = (None, None)
        if A_K.shape[0] > ne:
            ineq = (A_K[ne:], b[ne:])
        elif not ne:  # no row at all: one vacuous row keeps the problem with the solver (module doc)
            ineq = (sp.csc_matrix((1, problem.n)), np.ones(1))
        self._qp = qpsolvers.Problem(problem.P, problem.q, *ineq, *eq)
        self._rows = rows

    def _solve(self, warm_start):
        import qpsolvers

        with warnings.catch_warnings():  # qpsolvers warns of a status it returns too: the status is reported
            warnings.filterwarnings("ignore", category=UserWarning, module=r"qpsolvers\.")
            sol = qpsolvers.solve_problem(self._qp, self.solver, initvals=warm_start, verbose=self.options.verbose,
                                          **_SETTINGS[self.solver](self.options))
        extras = sol.extras if isinstance(sol.extras, dict) else {}
        raw = str(extras.get("status", "no status"))
        status = _STATUS[self.solver].get(raw, Status.ERROR)
        y = None
        if status.ok and sol.x is not None:
            eq, hi, lo = self._rows
            z = np.concatenate([sol.y if len(eq) else np.zeros(0), sol.z if len(hi) + len(lo) else np.zeros(0)])
            y = scatter_one_sided(self.problem.m, self._rows, np.asarray(z, dtype=float))
        return sol.x, status, raw, int(extras.get(_ITERATIONS[self.solver], 0)), y


class ScsQP(QpsolversQP):
    """SCS (operator splitting) through qpsolvers, warm-started."""

    name = "qpsolvers_scs"
    solver = "scs"


BACKENDS = (
    Backend(
        name="qpsolvers_scs",
        entry=ScsQP,
        requires=("qpsolvers", "scs"),
        extra="qpsolvers",
        summary="SCS through qpsolvers: operator splitting (ADMM), sparse, warm-startable",
        capabilities=QPCapabilities(inequalities=True, warm_start=True, detects_infeasibility=True, sparse=True),
    ),
)
