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

import numpy as np

from solvers.errors import InvalidOptions, InvalidProblem, SolverError, check_argument
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
    capabilities=MRFCapabilities,
    group="solvers.mrf",
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
    InvalidProblem, InvalidOptions
        ``mrf`` not a :class:`PairwiseMRF`, ``options`` not an :class:`Options` (or None).
    SolverError
        The method raised (its error text), or returned something else than an :class:`MRFResult` whose labels are
        one whole number per node (a tour's methods returning a tuple, n + 1 labels or float labels ended in numpy's
        errors inside the planner), or an energy that is not its labelling's.
    """
    entry = METHODS.get(method).entry
    check_argument(mrf, PairwiseMRF, "mrf", InvalidProblem, "solvers.mrf.PairwiseMRF")
    if options is not None:
        check_argument(options, Options, "options", InvalidOptions, "solvers.mrf.Options")
    t0 = time.perf_counter()
    try:
        res = entry(mrf, options or Options())
    except (SolverError, InvalidProblem):
        raise
    except Exception as e:  # the method's own exception, wrapped with its text, as the QP and NLP backends'
        raise SolverError(f"{method} failed: {type(e).__name__}: {e}", backend=method, status=type(e).__name__) from e
    if not isinstance(res, MRFResult):
        raise SolverError(f"{method}: returned {type(res).__name__}, not a solvers.mrf MRFResult", backend=method,
                          status="bad result")
    labels = np.asarray(res.labels)
    if labels.shape != (mrf.n_nodes,) or not np.issubdtype(labels.dtype, np.integer):
        raise SolverError(f"{method}: returned labels of shape {labels.shape} and dtype {labels.dtype} for "
                          f"{mrf.n_nodes} nodes (one whole number each)", backend=method, status="bad labels")
    if not mrf.is_feasible(res.labels):
        labels, n = repair(mrf, res.labels)
        res = dataclasses.replace(res, labels=labels, energy=mrf.energy(labels), repaired=n)
    else:
        _check_energy(method, mrf, res)
    return dataclasses.replace(res, time_s=time.perf_counter() - t0)


#: How far a method's reported energy may be from its labelling's, relative to 1 + |that energy| (a sum of many
#: terms taken in another order).
ENERGY_SLACK = 1e-9


def _check_energy(method: str, mrf: PairwiseMRF, res: MRFResult) -> None:
    """A :class:`SolverError` unless ``res.energy`` is the energy of ``res.labels``: the planner reads it (its stop
    rule, and the escalation keeps the plan of lower energy), and a tour's method reporting -1e9 for an ICM labelling
    was taken at its word."""
    energy = mrf.energy(res.labels)
    if not abs(float(res.energy) - energy) <= ENERGY_SLACK * (1.0 + abs(energy)):
        raise SolverError(f"{method}: returned energy {float(res.energy):.10g} for a labelling whose energy is "
                          f"{energy:.10g}", backend=method, status="bad energy")


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
