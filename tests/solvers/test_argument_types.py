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
