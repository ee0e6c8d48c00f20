"""Equality-constrained QPs in closed form: one sparse LU of the KKT matrix.

The optimality conditions of :math:`\\min \\tfrac12 x^\\top P x + q^\\top x` s.t.
:math:`A_{eq} x = b` are the linear system

.. math::

    \\begin{bmatrix} P & A_{eq}^\\top \\\\ A_{eq} & 0 \\end{bmatrix}
    \\begin{bmatrix} x \\\\ y \\end{bmatrix} =
    \\begin{bmatrix} -q \\\\ b \\end{bmatrix},

which has a unique solution exactly when :math:`A_{eq}` has full row rank and :math:`P`
is positive definite on the nullspace of :math:`A_{eq}` (for PSD :math:`P`). This is the
classical range/null-space-free KKT approach (Nocedal & Wright, *Numerical
Optimization*, 2nd ed., Springer 2006, ch. 16.1); for min-snap it is the closed form of
Mellinger & Kumar (ICRA 2011) and, since the pieces are chained, the KKT matrix is block
banded and a fill-reducing sparse factorization makes the solve linear in the number of
pieces (the observation behind MINCO: Wang et al., "Geometrically Constrained Trajectory
Optimization for Multicopters", IEEE T-RO 2022).

Numerics, because this backend is the accuracy reference:

- The KKT matrix is equilibrated symmetrically (a few Ruiz sweeps, ``D K D`` with
  ``D`` diagonal) before SuperLU (``scipy.sparse.linalg.splu``, COLAMD column ordering)
  factors it; min-snap matrices mix powers of the durations and scaling keeps pivots sane.
- A singular or numerically singular KKT matrix (rank-deficient ``A_eq``, ``P`` singular
  on the nullspace of ``A_eq``) raises :class:`InvalidProblem`: SuperLU's "exactly
  singular", or a 1-norm reciprocal condition estimate (Hager/Higham, ``onenormest`` on
  the factors) below ``RCOND_MIN``.
- Each solve does iterative refinement on the unscaled system until the relative
  residual stops improving (at most ``REFINE_STEPS`` steps) and reports it: a relative
  residual below ``1e-10`` is ``OPTIMAL``, up to ``1e-6`` ``OPTIMAL_INACCURATE``,
  worse is a :class:`SolverError`.

setup = equilibration + factorization; :meth:`update` refactors only if ``P`` or ``A``
changed (a new ``q``, ``l``, ``u`` just re-solves); solve = back-substitution. Rows free
on both sides are ignored; any inequality row raises :class:`InvalidProblem`. No
options apply to a direct solve (tolerances, iterations, time limit are ignored).
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from solvers.errors import InvalidProblem
from solvers.qp.base import PreparedQP
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.problem import QPProblem
from solvers.qp.row_split import same_matrices, split_rows
from solvers.qp.solution import Status
from solvers.registry import Backend

log = logging.getLogger(__name__)

#: Reciprocal 1-norm condition number (of the equilibrated KKT matrix) below which it is singular.
RCOND_MIN = 1e-14
#: Relative KKT residuals that make a solution optimal, resp. still usable.
RESIDUAL_OK, RESIDUAL_USABLE = 1e-10, 1e-6
REFINE_STEPS = 3
_RUIZ_SWEEPS = 8
_EQUALITY_ONLY = "backend {!r} solves equality-constrained problems only; this problem has inequality rows"


def _ruiz(K: sp.csc_matrix) -> np.ndarray:
    """Diagonal ``d`` such that ``diag(d) K diag(d)`` has rows of max-norm near 1."""
    d = np.ones(K.shape[0])
    Kabs = abs(K).tocsr()
    for _ in range(_RUIZ_SWEEPS):
        S = sp.diags(d) @ Kabs @ sp.diags(d)
        rmax = S.max(axis=1).toarray().ravel()
        rmax[rmax == 0.0] = 1.0  # an empty row: singular anyway, caught by the factorization
        d /= np.sqrt(rmax)
    return d


class ClosedFormQP(PreparedQP):
    """Equality-constrained QP by a sparse LU of the (equilibrated) KKT matrix."""

    name = "closed_form"

    def _setup(self, problem: QPProblem) -> None:
        from scipy.sparse.linalg import LinearOperator, onenormest, splu

        split = split_rows(problem)
        if split.n_in:  # dispatch refuses these first (the record has no inequalities); a direct caller too
            raise InvalidProblem(_EQUALITY_ONLY.format(self.name))
        n, me = problem.n, split.n_eq
        K = sp.bmat([[problem.P, split.A_eq.T], [split.A_eq, None]], format="csc")
        K = sp.csc_matrix(K)  # bmat of an (n, 0) block with None keeps shapes, make sure of CSC
        d = _ruiz(K)
        Ks = (sp.diags(d) @ K @ sp.diags(d)).tocsc()
        try:
            lu = splu(Ks, permc_spec="COLAMD", diag_pivot_thresh=1.0)
        except RuntimeError as e:  # SuperLU: "Factor is exactly singular"
            raise InvalidProblem(self._singular_message(n, me, f"SuperLU: {e}")) from e
        N = n + me
        inv = LinearOperator((N, N), matvec=lu.solve, rmatvec=lambda v: lu.solve(v, trans="T"), dtype=float)
        with np.errstate(all="ignore"):
            inv_norm = onenormest(inv)
        norm = abs(Ks).sum(axis=0).max()
        rcond = 1.0 / (norm * inv_norm) if np.isfinite(inv_norm) and inv_norm > 0 else 0.0
        if not rcond > RCOND_MIN:
            raise InvalidProblem(self._singular_message(n, me, f"reciprocal condition estimate {rcond:.1e}"))
        self._split, self._K, self._d, self._lu = split, K, d, lu
        #: Reciprocal condition estimate of the equilibrated KKT matrix, and nonzeros of its LU.
        self.rcond, self.factor_nnz = rcond, lu.L.nnz + lu.U.nnz
        log.debug("closed_form: KKT %d x %d, nnz(L+U) = %d, rcond ~ %.1e", N, N, lu.L.nnz + lu.U.nnz, rcond)

    def _singular_message(self, n: int, me: int, why: str) -> str:
        # self.name, not "closed_form": a subclass registered under another name (a plugin's copy) says its own
        return (
            f"{self.name}: the KKT matrix ({n} variables, {me} equality rows) is singular ({why}): "
            "the equality rows are linearly dependent, or P is not positive definite on their "
            "nullspace (the QP has no unique solution)"
        )

    def update(self, problem: QPProblem) -> None:
        self._check_same_shape(problem)
        split = split_rows(problem)
        if not split.same_partition(self._split):
            if problem.has_inequalities:
                raise InvalidProblem(_EQUALITY_ONLY.format(self.name))
            super().update(problem)
            return
        if same_matrices(self.problem, problem):
            self.problem, self._split = problem, split  # same factorization, new right-hand side
            return
        super().update(problem)

    def _solve(self, warm_start):
        # a direct solve: warm_start has nothing to start
        n = self.problem.n
        rhs = np.concatenate([-self.problem.q, self._split.b])
        d, K, lu = self._d, self._K, self._lu
        z = d * lu.solve(d * rhs)
        scale = abs(K).sum(axis=0).max() * np.abs(z).max(initial=0.0) + np.abs(rhs).max(initial=0.0)
        scale = scale if scale > 0 else 1.0
        r = rhs - K @ z
        res = np.abs(r).max(initial=0.0) / scale
        for _ in range(REFINE_STEPS):
            if res <= 1e-15:
                break
            z_new = z + d * lu.solve(d * r)
            r_new = rhs - K @ z_new
            res_new = np.abs(r_new).max(initial=0.0) / scale
            if not res_new < res:
                break
            z, r, res = z_new, r_new, res_new
        if res <= RESIDUAL_OK:
            status = Status.OPTIMAL
        elif res <= RESIDUAL_USABLE:
            status = Status.OPTIMAL_INACCURATE
        else:
            status = Status.ERROR
        raw = f"relative KKT residual {res:.1e}"
        y = self._split.scatter(z[n:], None)
        return z[:n], status, raw, 0, y


BACKEND = Backend(
    name="closed_form",
    entry=ClosedFormQP,
    requires=("scipy",),
    extra="",
    summary="closed form: sparse LU of the KKT system, equality constraints only (exact, linear in banded size)",
    capabilities=QPCapabilities(inequalities=False, warm_start=False, detects_infeasibility=False, sparse=True),
)
