"""CasADi's QP interface (``conic``/``qpsol``), with qpOASES as the plugin.

Andersson, Gillis, Horn, Rawlings, Diehl, "CasADi: a software framework for nonlinear
optimization and optimal control", Mathematical Programming Computation 11 (2019).
The plugin is qpOASES: Ferreau, Kirches, Potschka, Bock, Diehl, "qpOASES: a parametric
active-set algorithm for quadratic programming", Mathematical Programming Computation 6
(2014).

CasADi solves ``min 1/2 x'Hx + g'x  s.t.  lba <= A x <= uba, lbx <= x <= ubx``: our
standard form with free variable bounds (infinite ``lba``/``uba`` are accepted). The
``conic`` Function is built once in setup from the sparsity patterns of ``P`` and ``A``;
every solve, and every :meth:`update` with the same pattern, only calls it with new
numbers. CasADi keeps qpOASES' working set between calls, so a re-solve after an update
is hot-started from the previous active set (that is this backend's warm start; the
``warm_start`` point itself is passed as ``x0``).

Why qpOASES (measured with casadi 3.8.2; the plugins shipped are osqp, qpoases, proxqp,
highs, qrqp, daqp, hpipm):

- accuracy: on random sparse QPs (n = 60..300, PD and PSD ``P``) qpOASES agrees with a
  tight PIQP solve to 1e-12 in the objective and 1e-10 in ``x``;
- HiGHS' QP solver was faster on a 2000-variable box-constrained chain (0.5 s against
  qpOASES' 170 s) but cycled on a random 300-variable QP (80 000 iterations, "Solve
  error"), is biased by its default Hessian regularization (5e-8), and segfaults
  when the ``highspy`` package (which CVXPY imports) was loaded first: both ship a
  ``libhighs.so.1`` of different versions and the dynamic loader reuses the first;
- qrqp and daqp fail on PSD ``P`` (min-snap costs are PSD); CasADi's proxqp and osqp
  plugins duplicate our own proxsuite and osqp backends, with fewer settings (no
  duality-gap check) so they stop early; hpipm needs an optimal-control structure.

qpOASES is a dense active-set method (``sparse=True`` stores the matrices sparsely but
the linear algebra stays dense): it suits the small and medium QPs of receding-horizon
smoothing (hundreds of variables); for thousands of variables prefer piqp or osqp.
It is exact on its working set, so ``eps_abs``/``eps_rel`` and ``polish`` do not apply;
``max_iter`` caps working-set changes (``nWSR``) and ``time_limit`` is its ``CPUtime``
(a run that hits either reports the same qpOASES status, mapped to ``MAX_ITER``).
qpOASES prints a licence banner from C when a solver is created; it is silenced (the
process' standard output is redirected around the creation) unless ``verbose``.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys

import numpy as np
import scipy.sparse as sp

from solvers.qp.base import PreparedQP
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.problem import QPProblem
from solvers.qp.solution import Options, Status
from solvers.registry import Backend

log = logging.getLogger(__name__)

#: The CasADi conic plugin used (the only one whose options are translated).
PLUGIN = "qpoases"


def _settings(o: Options, has_rows: bool) -> dict:
    """``Options`` in the terms of CasADi's conic + qpOASES (the one place they are translated).

    qpOASES' sparse mode fails without constraint rows (casadi issue #2358): dense then.
    """
    if PLUGIN != "qpoases":
        raise ValueError(f"casadi backend: no option translation for conic plugin {PLUGIN!r}")
    # eps_abs, eps_rel, polish: an active-set solution is exact on its working set.
    opts = {
        "printLevel": "medium" if o.verbose else "none",
        "sparse": has_rows,
        "nWSR": int(o.max_iter),
        "error_on_fail": False,
        "verbose": False,
    }
    if o.time_limit is not None:
        opts["CPUtime"] = float(o.time_limit)  # type: ignore[assignment]  # qpOASES takes seconds as a float
    return opts


def _status(stats: dict) -> tuple[Status, str]:
    """qpOASES' return message (as CasADi reports it) mapped onto :class:`Status`."""
    raw = str(stats.get("return_status", ""))
    text = raw.lower()
    if stats.get("success", False) and stats.get("unified_return_status") == "SOLVER_RET_SUCCESS":
        status = Status.OPTIMAL
    elif "infeasib" in text:  # "Initial QP could not be solved due to infeasibility!", "...QP is infeasible."
        status = Status.INFEASIBLE
    elif "unbounded" in text:
        status = Status.UNBOUNDED
    elif "working set recalculations" in text:  # nWSR or CPUtime exhausted
        status = Status.MAX_ITER
    else:
        status = Status.ERROR
    return status, raw


@contextlib.contextmanager
def _quiet_stdout(enabled: bool):
    """Redirect the process' file descriptor 1 to /dev/null (C-level prints)."""
    if not enabled:
        yield
        return
    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError, AttributeError):  # no usable fd 1: nothing to silence
        yield
        return
    try:
        with open(os.devnull, "wb") as devnull:
            os.dup2(devnull.fileno(), 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def to_casadi(M: sp.spmatrix):
    """A scipy sparse matrix as a CasADi ``DM`` with the same sparsity pattern."""
    import casadi as ca

    M = sp.csc_matrix(M)
    M.sort_indices()
    pattern = ca.Sparsity(M.shape[0], M.shape[1], M.indptr.tolist(), M.indices.tolist())
    return ca.DM(pattern, M.data)


class CasadiQP(PreparedQP):
    """CasADi ``conic`` Function built once per sparsity pattern, called per solve."""

    name = "casadi"

    def _setup(self, problem: QPProblem) -> None:
        import casadi as ca

        H, A = to_casadi(problem.P), to_casadi(problem.A)
        with _quiet_stdout(not self.options.verbose):
            self._f = ca.conic("mrfswarm_qp", PLUGIN, {"h": H.sparsity(), "a": A.sparsity()}, _settings(self.options, problem.m > 0))
        self._H, self._A = H, A

    def update(self, problem: QPProblem) -> None:
        self._check_same_shape(problem)  # same pattern: the conic Function is reused
        self.problem = problem
        self._H, self._A = to_casadi(problem.P), to_casadi(problem.A)

    def _solve(self, warm_start):
        p = self.problem
        args = dict(h=self._H, g=p.q, a=self._A, lba=p.l, uba=p.u)
        if warm_start is not None:
            args["x0"] = warm_start
        r = self._f(**args)
        stats = self._f.stats()
        status, raw = _status(stats)
        iters = max(int(stats.get("iter_count", 0) or 0), 0)
        x = np.asarray(r["x"]).reshape(-1)
        y = np.asarray(r["lam_a"]).reshape(-1)
        return x, status, raw, iters, y


BACKEND = Backend(
    name="casadi",
    entry=CasadiQP,
    requires=("casadi",),
    extra="casadi",
    summary=f"CasADi conic (qpsol) with {PLUGIN}: active set, hot-started re-solves, small QPs (a run's windows of "
            "many robots take minutes)",
    capabilities=QPCapabilities(inequalities=True, warm_start=True, detects_infeasibility=True, sparse=False),
)
