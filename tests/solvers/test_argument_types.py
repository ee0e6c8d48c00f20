"""A problem or options of the wrong type is refused by dispatch, naming the argument (a library tour,
2026-11-30): a dict of options ended in "piqp failed: AttributeError: 'dict' object has no attribute
'time_limit'", blaming the backend, and a tuple as a QP in a bare AttributeError."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import solvers.mrf
import solvers.nlp
import solvers.qp
from solvers.errors import InvalidOptions, InvalidProblem


def _qp() -> solvers.qp.QPProblem:
    return solvers.qp.QPProblem(sp.eye(2, format="csc"), np.array([-1.0, -1.0]), sp.csc_matrix((0, 2)),
                                np.zeros(0), np.zeros(0))


def _nlp() -> solvers.nlp.NLPProblem:
    return solvers.nlp.NLPProblem(lambda x: float(x @ x), lambda x: 2 * x, np.ones(2))


def _mrf() -> solvers.mrf.PairwiseMRF:
    return solvers.mrf.PairwiseMRF(np.array([[0.0, 1.0], [1.0, 0.0]]), np.zeros((0, 2), int), np.zeros((0, 2, 2)),
                                   np.zeros((0, 2), int), np.zeros((0, 2, 2), bool), np.zeros(2, int))


@pytest.mark.parametrize("backend", ["osqp", "piqp"])
def test_qp_options_of_another_type(backend):
    with pytest.raises(InvalidOptions, match=r"^options must be a solvers\.qp\.Options, got dict$"):
        solvers.qp.solve(_qp(), backend=backend, options={"eps_abs": 1e-6})


@pytest.mark.parametrize("problem", [None, (1, 2)])
def test_qp_problem_of_another_type(problem):
    with pytest.raises(InvalidProblem, match=r"^problem must be a solvers\.qp\.QPProblem, got "):
        solvers.qp.solve(problem, backend="osqp")


def test_qp_solver_arguments_of_another_type():
    """The same for the re-solving handle: a dict of options failed at its first solve as "piqp failed:
    AttributeError: 'dict' object has no attribute 'time_limit'", a tuple as a problem in a bare AttributeError, also
    after a first solve (a library tour)."""
    with pytest.raises(InvalidOptions, match=r"^options must be a solvers\.qp\.Options, got dict$"):
        solvers.qp.QPSolver("piqp", options={"max_iter": 3})
    solver = solvers.qp.QPSolver("piqp")
    with pytest.raises(InvalidProblem, match=r"^problem must be a solvers\.qp\.QPProblem, got tuple$"):
        solver.solve((1, 2))
    solver.solve(_qp())
    with pytest.raises(InvalidProblem, match=r"^problem must be a solvers\.qp\.QPProblem, got tuple$"):
        solver.solve((1, 2))
    assert np.allclose(solver.solve(_qp()).x, [1, 1], atol=1e-6)


def test_nlp_arguments_of_another_type():
    with pytest.raises(InvalidOptions, match=r"^options must be a solvers\.nlp\.Options, got dict$"):
        solvers.nlp.minimize(_nlp(), backend="slsqp", options={"tol": 1e-6})
    with pytest.raises(InvalidProblem, match=r"^problem must be a solvers\.nlp\.NLPProblem, got tuple$"):
        solvers.nlp.minimize((1, 2), backend="slsqp")


def test_mrf_arguments_of_another_type():
    with pytest.raises(InvalidOptions, match=r"^options must be a solvers\.mrf\.Options, got dict$"):
        solvers.mrf.minimize(_mrf(), method="icm", options={"seed": 1})
    with pytest.raises(InvalidProblem, match=r"^mrf must be a solvers\.mrf\.PairwiseMRF, got tuple$"):
        solvers.mrf.minimize((1,), method="icm")


def test_the_right_types_still_solve():
    assert np.allclose(solvers.qp.solve(_qp(), backend="osqp", options=solvers.qp.Options()).x, [1, 1], atol=1e-5)
    assert np.allclose(solvers.nlp.minimize(_nlp(), backend="slsqp", options=solvers.nlp.Options()).x, 0, atol=1e-5)
    assert solvers.mrf.minimize(_mrf(), method="icm", options=solvers.mrf.Options(seed=1)).labels.tolist() == [0, 1]


def _qp_with(**arrays) -> solvers.qp.QPProblem:
    data = dict(P=np.eye(2), q=[1.0, 1.0], A=[[1.0, 1.0]], l=[0.0], u=[1.0])
    return solvers.qp.QPProblem(**{**data, **arrays})


def _nlp_with(**arrays) -> solvers.nlp.NLPProblem:
    return solvers.nlp.NLPProblem(lambda x: float(x @ x), lambda x: 2 * x, **{"x0": [1.0, 1.0], **arrays})


def _mrf_with(**arrays) -> solvers.mrf.PairwiseMRF:
    data = dict(unary=[[0.0, 1.0], [1.0, 0.0]], edges=[[0, 1]], pairwise=[[[0.0, 1.0], [1.0, 0.0]]],
                conflicts=np.zeros((0, 2), int), conflict_mask=np.zeros((0, 2, 2), bool), initial=[0, 0])
    return solvers.mrf.PairwiseMRF(**{**data, **arrays})


@pytest.mark.parametrize("build, name, value, why", [
    (_qp_with, "P", [["a", "b"], ["c", "d"]], "got dtype <U1"),
    (_qp_with, "P", None, "not None"),  # read as a 1 x 1 matrix: "P has shape (1, 1), expected (2, 2) from q"
    (_qp_with, "P", np.eye(2) + 0j, "got dtype complex128"),  # its imaginary part dropped with a ComplexWarning
    (_qp_with, "q", None, "not None"),  # read as one NaN: "P has shape (2, 2), expected (1, 1) from q"
    (_qp_with, "q", ["a", "b"], "got dtype <U1"),
    (_qp_with, "A", [[1.0, None]], "not None"),
    (_qp_with, "u", ["1"], "got dtype <U1"),
    (_nlp_with, "x0", ["a", "b"], "got dtype <U1"),
    (_nlp_with, "lower", [0.0, "a"], "got dtype <U32"),
    (_nlp_with, "A", [[1.0, 2.0], [3.0]], "inhomogeneous"),
    (_mrf_with, "unary", [["a", "b"], ["c", "d"]], "got dtype <U1"),
    (_mrf_with, "pairwise", [[["a", "b"], ["c", "d"]]], "got dtype <U1"),
], ids=lambda v: v if isinstance(v, str) else None)
def test_a_problem_array_that_is_not_real_numbers_is_named(build, name, value, why):
    """Strings, None or complex numbers as a problem's array: NumPy's or SciPy's own ValueError naming no argument
    ("could not convert string to float: 'a'"), a shape error about another argument, or a silent cast (a library
    tour)."""
    with pytest.raises(InvalidProblem, match=rf"^{name} = .*: must be an array of real numbers.*{why}"):
        build(**{name: value})


def test_a_qp_matrix_of_three_axes_is_named():
    with pytest.raises(InvalidProblem, match=r"^P has shape \(2, 2, 2\): must be a matrix$"):  # "CSR arrays don't..."
        _qp_with(P=np.zeros((2, 2, 2)))


def test_real_arrays_of_any_number_type_are_still_taken():
    assert _qp_with(P=np.eye(2, dtype=int), q=np.array([1, 1], dtype=np.int32), l=[False]).q.dtype == float
    assert _nlp_with(x0=np.array([1, 2], dtype=np.float32)).x0.tolist() == [1.0, 2.0]
    assert _mrf_with(edges=[[0.0, 1.0]]).edges.tolist() == [[0, 1]]
