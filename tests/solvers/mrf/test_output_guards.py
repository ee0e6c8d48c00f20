"""An MRF method's answer is checked before the planner takes it, and its exceptions carry its name, as the QP and
NLP backends' (a tour's method that raised gave a traceback; one returning a tuple, n + 1 labels or float labels
ended in numpy's errors inside the planner)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import solvers.mrf as mrf
from solvers.errors import SolverError


def chain(n: int = 4) -> mrf.PairwiseMRF:
    e = np.stack([np.arange(n - 1), np.arange(1, n)], 1)
    return mrf.PairwiseMRF(np.zeros((n, 2)), e, np.zeros((n - 1, 2, 2)), np.zeros((0, 2)), np.zeros((0, 2, 2)),
                           np.zeros(n, int))


def result(labels) -> mrf.MRFResult:
    return mrf.MRFResult(labels=labels, energy=0.0, energy_trace=np.zeros(1), iterations=1, time_s=0.0, method="mine")


def with_entry(monkeypatch, entry) -> str:
    record = dataclasses.replace(mrf.METHODS.get("icm"), entry=entry)
    real = mrf.METHODS.get
    monkeypatch.setattr(mrf.METHODS, "get", lambda name: record if name == "mine" else real(name))
    return "mine"


def boom(problem, options):
    raise RuntimeError("mrf boom")


@pytest.mark.parametrize("entry, match", [
    (boom, "mine failed: RuntimeError: mrf boom"),
    (lambda p, o: (np.zeros(4, int), 0.0), "mine: returned tuple, not a solvers.mrf MRFResult"),
    (lambda p, o: result(np.zeros(5, int)), r"mine: returned labels of shape \(5,\) and dtype int64 for 4 nodes"),
    (lambda p, o: result(np.zeros(4)), r"mine: returned labels of shape \(4,\) and dtype float64 for 4 nodes"),
])
def test_what_is_not_a_labelling_is_a_solver_error(monkeypatch, entry, match):
    name = with_entry(monkeypatch, entry)
    with pytest.raises(SolverError, match=match):
        mrf.minimize(chain(), name)


def test_a_labelling_out_of_range_is_still_repaired(monkeypatch):
    """Whole numbers of the right shape pass the check; labels out of range are the repair's, as before."""
    name = with_entry(monkeypatch, lambda p, o: result(np.array([0, 7, 1, 0])))
    res = mrf.minimize(chain(), name)
    assert res.repaired == 1 and res.labels.tolist() == [0, 0, 1, 0]


def test_an_energy_that_is_not_the_labellings_is_a_solver_error(monkeypatch):
    """The planner reads the method's energy (its stop rule; the escalation keeps the lower one): a tour's method
    reporting -1e9 for ICM's labelling was taken at its word."""
    def lying(problem, options):
        return dataclasses.replace(mrf.METHODS.get("icm").entry(problem, options), energy=-1e9)

    name = with_entry(monkeypatch, lying)
    with pytest.raises(SolverError, match=r"^mine: returned energy -1000000000 for a labelling whose energy is 0$"):
        mrf.minimize(chain(), name)
    name = with_entry(monkeypatch, lambda p, o: result(np.zeros(4, int)))  # energy 0.0, the labelling's
    assert mrf.minimize(chain(), name).energy == 0.0
