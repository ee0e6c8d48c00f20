"""Exhaustive search: the exact minimum of a small MRF, the reference in tests.

Enumerates every labelling in the product of the label sets, in vectorized chunks, and
keeps the feasible one of least energy. Exponential in N; refuses problems with more
than ``MAX_LABELLINGS`` labellings.
"""

from __future__ import annotations

import time

import numpy as np

from solvers.errors import InvalidProblem
from solvers.mrf.capabilities import MRFCapabilities
from solvers.mrf.problem import PairwiseMRF
from solvers.mrf.result import MRFResult, Options
from solvers.registry import Backend

MAX_LABELLINGS = 5_000_000
_CHUNK = 100_000


def _count(n: int) -> str:
    """``n`` in digits up to nine of them, else as "about 3.2e54" (a swarm's count has dozens of digits)."""
    if n < 10**9:
        return str(n)
    exp = len(str(n)) - 1
    mantissa = round(n / 10**exp, 1)  # int / int: exact to the float, whatever the size of n
    if mantissa >= 10:
        mantissa, exp = mantissa / 10, exp + 1
    return f"about {mantissa:.1f}e{exp}"


def minimize(mrf: PairwiseMRF, options: Options) -> MRFResult:
    """The global minimum of ``mrf`` over its feasible labellings."""
    t0 = time.perf_counter()
    sizes = mrf.n_labels.astype(np.int64)
    total = int(np.prod(sizes.astype(object)))
    if total > MAX_LABELLINGS:
        raise InvalidProblem(f"exact: {_count(total)} labellings exceed the limit of {MAX_LABELLINGS}; "
                             "use a heuristic method")
    N = mrf.n_nodes
    e0, e1 = (mrf.edges[:, 0], mrf.edges[:, 1]) if len(mrf.edges) else (None, None)
    c0, c1 = (mrf.conflicts[:, 0], mrf.conflicts[:, 1]) if len(mrf.conflicts) else (None, None)
    best_e, best_x = np.inf, mrf.initial.copy()
    for start in range(0, total, _CHUNK):
        idx = np.arange(start, min(total, start + _CHUNK), dtype=np.int64)
        X = np.empty((idx.size, N), dtype=np.intp)
        rem = idx
        for i in range(N - 1, -1, -1):
            X[:, i] = rem % sizes[i]
            rem = rem // sizes[i]
        E = mrf.unary[np.arange(N)[None, :], X].sum(axis=1)
        if e0 is not None:
            E = E + mrf.pairwise[np.arange(len(e0))[None, :], X[:, e0], X[:, e1]].sum(axis=1)
        if c0 is not None:
            bad = mrf.conflict_mask[np.arange(len(c0))[None, :], X[:, c0], X[:, c1]].any(axis=1)
            E = np.where(bad, np.inf, E)
        k = int(np.argmin(E))
        if E[k] < best_e:
            best_e, best_x = float(E[k]), X[k].copy()
    return MRFResult(
        labels=best_x,
        energy=best_e,
        energy_trace=np.array([best_e]),
        iterations=1,
        time_s=time.perf_counter() - t0,
        method="exact",
        lower_bound=best_e,
        stats={"labellings": total},
    )


BACKEND = Backend(
    name="exact",
    entry=minimize,
    summary="exhaustive enumeration (tiny problems only; the reference)",
    capabilities=MRFCapabilities(optimal=True, lower_bound=True, exact_on_trees=True, monotone=True, stochastic=False),
)
