"""What a backend returns is checked before it is trusted: its status's type, x's and y's sizes, and that a point
labelled optimal meets the rows (a backend that returned its start as "optimal" had the continuous stage reject
every window's certificate for ten minutes; one returning an x one entry too long ended in numpy's matmul error)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from solvers import qp
from solvers.errors import SolverError
from solvers.qp.base import ROW_SLACK, PreparedQP


def problem() -> qp.QPProblem:
    """min |x|^2 / 2 subject to x0 + x1 = 1 and 0 <= x <= 1: x* = (0.5, 0.5), y* = (-0.5, 0, 0) in piqp's signs."""
    A = sp.csc_matrix(np.array([[1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]))
    return qp.QPProblem(P=sp.eye(2, format="csc"), q=np.zeros(2), A=A, l=np.array([1.0, 0.0, 0.0]),
                        u=np.array([1.0, 1.0, 1.0]))


def backend(x, status=qp.Status.OPTIMAL, y=None) -> PreparedQP:
    class Returns(PreparedQP):
        name = "returns"

        def _setup(self, problem):
            pass

        def _solve(self, warm_start):
            return x, status, "said so", 1, y

    return Returns(problem())


def test_a_point_that_meets_the_rows_is_a_solution():
    sol = backend(np.array([0.5, 0.5]), y=np.array([-0.5, 0.0, 0.0])).solve()
    assert sol.status is qp.Status.OPTIMAL and np.allclose(sol.x, 0.5)
    # within the slack: an inaccurate first-order solve
    near = backend(np.array([0.5, 0.5 + 0.5 * ROW_SLACK]), status=qp.Status.OPTIMAL_INACCURATE).solve()
    assert near.status is qp.Status.OPTIMAL_INACCURATE


@pytest.mark.parametrize("x, status, y, match", [
    (np.zeros(2), qp.Status.OPTIMAL, None, r"returns: returned a point labelled OPTIMAL that misses row 0 by 0\.5"),
    (np.array([0.5, 0.5 + 3 * ROW_SLACK]), qp.Status.OPTIMAL_INACCURATE, None, "labelled OPTIMAL_INACCURATE that misses row 0"),
    (np.array([0.5, 0.5, 0.0]), qp.Status.OPTIMAL, None, "returned x of 3 entries for 2 variables"),
    (np.array([0.5, 0.5]), "optimal", None, "returned the status 'optimal', not a solvers.qp.Status"),
    (np.array([0.5, 0.5]), qp.Status.OPTIMAL, np.zeros(2), "returned 2 multipliers for 3 rows"),
])
def test_what_is_not_a_solution_is_a_solver_error(x, status, y, match):
    with pytest.raises(SolverError, match=match):
        backend(x, status, y).solve()


def test_every_installed_backend_passes_the_guards():
    """The checks are loose enough for every backend (the first-order ones at their default tolerances too)."""
    for name in qp.available():
        if not qp.BACKENDS.get(name).capabilities.inequalities:
            continue
        sol = qp.solve(problem(), name)
        assert np.allclose(sol.x, 0.5, atol=1e-3), name


@pytest.mark.parametrize("answer, match", [
    ((np.array([0.5, 0.5]), qp.Status.OPTIMAL, "said so", 1),
     r"^returns: _solve returned a tuple of 4, not \(x, status, raw_status, iterations, y\)$"),
    (None, r"^returns: _solve returned NoneType, not \(x, status, raw_status, iterations, y\)$"),
    ((np.array([0.5, 0.5]), qp.Status.OPTIMAL, "said so", None, None),
     r"^returns: returned the iteration count None, not a whole number \(status 'said so'\)$"),
])
def test_an_answer_of_another_form_is_a_solver_error(answer, match):
    """A tour's plugin returning (x, status, raw, iterations) without y: `mrfswarm run --qp` ended in a traceback,
    "ValueError: not enough values to unpack (expected 5, got 4)"; an iteration count None in int()'s TypeError."""
    class Returns(PreparedQP):
        name = "returns"

        def _setup(self, problem):
            pass

        def _solve(self, warm_start):
            return answer

    with pytest.raises(SolverError, match=match):
        Returns(problem()).solve()
