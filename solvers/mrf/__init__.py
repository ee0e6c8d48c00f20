"""Discrete energy minimizers behind one ``minimize``.

>>> from solvers import mrf
>>> res = mrf.minimize(problem, method="icm")   # doctest: +SKIP

``METHODS`` is the one preference-ordered registry. Every method returns an
:class:`MRFResult`; a method whose raw labelling breaks a hard conflict has it repaired
here (:func:`repair`) before it is returned, and the repair is counted in
``MRFResult.repaired``.
"""

from __future__ import annotations

import dataclasses
import time

from solvers.mrf import bp, exact, gibbs, icm, lazy_flipper, trws
from solvers.mrf.capabilities import MRFCapabilities
from solvers.mrf.problem import PairwiseMRF, repair
from solvers.mrf.result import MRFResult, Options
from solvers.registry import Registry

METHODS: Registry[MRFCapabilities] = Registry(
    "MRF",
    [
        icm.BACKEND,
        gibbs.BACKEND,
        bp.BACKEND,
        trws.BACKEND,
        lazy_flipper.BACKEND,
        exact.BACKEND,
    ],
    noun="method",
)

DEFAULT_METHOD = "icm"


def available() -> list[str]:
    """Names of the installed MRF methods, in preference order."""
    return METHODS.available()


def minimize(mrf: PairwiseMRF, method: str = DEFAULT_METHOD, options: Options | None = None) -> MRFResult:
    """Minimize ``mrf`` with ``method``; the labelling returned is always feasible.

    Raises
    ------
    SolverNotFound
        Unknown method.
    """
    entry = METHODS.get(method).entry
    t0 = time.perf_counter()
    res = entry(mrf, options or Options())
    if not mrf.is_feasible(res.labels):
        labels, n = repair(mrf, res.labels)
        res = dataclasses.replace(res, labels=labels, energy=mrf.energy(labels), repaired=n)
    return dataclasses.replace(res, time_s=time.perf_counter() - t0)


__all__ = [
    "DEFAULT_METHOD",
    "METHODS",
    "MRFCapabilities",
    "MRFResult",
    "Options",
    "PairwiseMRF",
    "available",
    "minimize",
    "repair",
]
