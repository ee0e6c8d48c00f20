"""One verdict on a backend's end point, the same for every backend: is the problem feasible, is the point a
first-order point.

The backends report the same situation in their own words. With linear rows that no ``x`` meets, Ipopt says
``Infeasible_Problem_Detected``, sqpmethod runs out of iterations, SLSQP and trust-constr fail their line
search or their violation test; at Rosenbrock's minimum under an equality row, sqpmethod ends with
``Search_Direction_Becomes_Too_Small``, a failure in its words, at a point every other backend calls optimal.
Dispatch (:func:`solvers.nlp.minimize`) therefore checks what it can check the same way for all of them:

- whether the bounds and rows admit any ``x`` at all: a linear program (SciPy's HiGHS), solved only after a
  run that did not end optimal (:func:`rows_feasible`);
- whether the point a failed run returned meets the first-order (KKT) conditions to
  :data:`ACCEPTABLE`: feasible, and the gradient a non-negative combination of the active constraints' outward
  normals (a bounded least-squares problem, :func:`first_order_residual`). Such a point is reported
  ``OPTIMAL_INACCURATE``, as Ipopt's ``Solved_To_Acceptable_Level`` is.

Backends' raw statuses stay in ``Solution.raw_status``.
"""

from __future__ import annotations

import numpy as np

from solvers.nlp.problem import NLPProblem

#: First-order tolerance of a point that a backend did not call optimal: its violation (relative to the size of
#: the bound) and the gradient's residual (relative to max(1, the gradient's largest entry)). Ipopt's own
#: acceptable level (``acceptable_tol``) is 1e-6.
ACCEPTABLE = 1e-6

#: A point a backend labels optimal may miss a linear row by at most this much, relative to 1 + |the row's bound|
#: (the QP backends' ``solvers.qp.base.ROW_SLACK``); further, it is not a solution, whatever the label: a backend
#: whose record claims ``linear_constraints`` without honouring them (L-BFGS-B's) had its point outside the rows
#: reported optimal.
ROW_SLACK = 1e-3


def rows_feasible(problem: NLPProblem) -> bool:
    """Whether some ``x`` meets the bounds and the linear rows (a linear program; bounds alone always admit
    one, checked at construction)."""
    if not problem.has_linear_rows:
        return True
    from scipy.optimize import linprog

    A, lb, ub = problem.rows, np.asarray(problem.lb), np.asarray(problem.ub)
    up, lo = np.isfinite(ub), np.isfinite(lb)
    A_ub = np.vstack([A[up], -A[lo]])
    b_ub = np.concatenate([ub[up], -lb[lo]])
    res = linprog(np.zeros(problem.n), A_ub=A_ub if len(b_ub) else None, b_ub=b_ub if len(b_ub) else None,
                  bounds=np.column_stack([problem.lower, problem.upper]), method="highs")
    # status 2 is HiGHS's proof of infeasibility; anything else (solved, or a numerical failure) is no proof
    return int(res.status) != 2


def worst_row(problem: NLPProblem, x: np.ndarray) -> tuple[int, float]:
    """The linear row that ``x`` misses most, and by how much relative to 1 + |its bound| (-1, 0 when every row
    holds, or there are none)."""
    if not problem.has_linear_rows:
        return -1, 0.0
    ax = problem.rows @ np.asarray(x, dtype=float)
    lb, ub = np.asarray(problem.lb, dtype=float), np.asarray(problem.ub, dtype=float)
    with np.errstate(invalid="ignore"):
        miss = np.maximum(np.where(np.isfinite(lb), (lb - ax) / (1 + np.abs(lb)), 0.0),
                          np.where(np.isfinite(ub), (ax - ub) / (1 + np.abs(ub)), 0.0))
    k = int(np.argmax(miss))
    return k, max(float(miss[k]), 0.0)


def first_order_residual(problem: NLPProblem, x: np.ndarray, g: np.ndarray, tol: float = ACCEPTABLE) -> float:
    """The least ``|g + N lam|_inf`` over ``lam >= 0``, relative to max(1, ``|g|_inf``), with N the outward
    normals of the constraints active at ``x`` (within ``tol`` of their bound, relative to its size): 0 at a
    KKT point. Infinite if ``x`` violates a constraint by more than ``tol``."""
    x, g = np.asarray(x, dtype=float), np.asarray(g, dtype=float)
    if not np.all(np.isfinite(g)):
        return float("inf")

    def near(value: np.ndarray, bound: np.ndarray) -> np.ndarray:
        return np.isfinite(bound) & (np.abs(value - bound) <= tol * np.maximum(1.0, np.abs(bound)))

    def beyond(excess: np.ndarray, bound: np.ndarray) -> bool:
        return bool(np.any(np.isfinite(bound) & (excess > tol * np.maximum(1.0, np.abs(bound)))))

    eye = np.eye(problem.n)
    ax = problem.rows @ x if problem.m else np.zeros(0)
    lb, ub = np.asarray(problem.lb), np.asarray(problem.ub)
    lower, upper = np.asarray(problem.lower), np.asarray(problem.upper)
    if beyond(lower - x, lower) or beyond(x - upper, upper) \
            or beyond(lb - ax, lb) or beyond(ax - ub, ub):
        return float("inf")
    # outward normals: an upper side's row, a lower side's row negated (an equality row has both)
    normals = [eye[near(x, upper)], -eye[near(x, lower)]]
    if problem.m:
        normals += [problem.rows[near(ax, ub)], -problem.rows[near(ax, lb)]]
    N = np.vstack(normals).T  # (n, k)
    scale = max(1.0, float(np.abs(g).max(initial=0.0)))
    if N.shape[1] == 0:
        return float(np.abs(g).max(initial=0.0)) / scale
    from scipy.optimize import lsq_linear

    lam = lsq_linear(N, -g, bounds=(0.0, np.inf), method="bvls").x
    return float(np.abs(g + N @ lam).max(initial=0.0)) / scale
