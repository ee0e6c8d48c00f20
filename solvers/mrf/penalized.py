"""Edges and conflicts merged into one pairwise model with finite penalties, for message passing.

Message passing (BP, TRW-S) cannot carry hard constraints as infinite costs: a message
``min_a h(a) + W(a, b)`` with ``W = inf`` on forbidden pairs can become ``inf`` for a
label ``b`` and then ``inf - inf`` in the next normalization or damping step. So the
conflicts enter message passing as a finite penalty ``P`` on forbidden label pairs:

.. math::

    E_P(x) = E(x) + P \\sum_c \\mathrm{mask}_c(x_i, x_j).

``E_P = E`` on feasible labellings, so for every ``P >= 0``
``min E_P <= min_{feasible} E_P = min_{feasible} E``: a lower bound of ``E_P`` (TRW-S's)
is a lower bound of the constrained optimum. :func:`auto_penalty`
picks ``P`` larger than any change of local energy one node can make, so that breaking a
conflict never pays for a single node.
"""

from __future__ import annotations

import numpy as np

from solvers.mrf.problem import PairwiseMRF


def auto_penalty(mrf: PairwiseMRF) -> float:
    """1 + the largest range, over nodes, of the unary plus incident pairwise tables."""
    U = np.where(np.isfinite(mrf.unary), mrf.unary, np.nan)
    spread = np.nanmax(U, axis=1) - np.nanmin(U, axis=1)
    if len(mrf.edges):
        rng = (mrf.pairwise.max(axis=(1, 2)) - mrf.pairwise.min(axis=(1, 2)))
        spread = spread + np.bincount(mrf.edges.ravel(), weights=np.repeat(rng, 2), minlength=mrf.n_nodes)
    return 1.0 + float(spread.max())


def _unordered_key(pairs: np.ndarray, n: int) -> np.ndarray:
    return np.minimum(pairs[:, 0], pairs[:, 1]).astype(np.int64) * n + np.maximum(pairs[:, 0], pairs[:, 1])


def penalized_pairs(mrf: PairwiseMRF, penalty: float) -> tuple[np.ndarray, np.ndarray]:
    """The union of edges and conflicts with their tables ``W + penalty * mask``.

    Returns
    -------
    pairs
        (P, 2) the edges (first, in their order and orientation), then the conflict pairs
        that are not edges. With ``penalty == 0`` just the edges.
    tables
        (P, L, L) finite costs, ``tables[p, a, b]`` for ``x[pairs[p, 0]] = a``,
        ``x[pairs[p, 1]] = b``.
    """
    N, L = mrf.n_nodes, mrf.max_labels
    E, C = len(mrf.edges), len(mrf.conflicts)
    if penalty == 0 or C == 0:
        return mrf.edges, mrf.pairwise
    ckey = _unordered_key(mrf.conflicts, N)
    target = np.full(C, -1, dtype=np.intp)
    if E:
        ekey = _unordered_key(mrf.edges, N)
        order = np.argsort(ekey)
        at = order[np.minimum(np.searchsorted(ekey[order], ckey), E - 1)]
        hit = ekey[at] == ckey
        target[hit] = at[hit]
    new = np.flatnonzero(target < 0)
    target[new] = E + np.arange(new.size)
    pairs = np.concatenate([mrf.edges, mrf.conflicts[new]])
    tables = np.concatenate([mrf.pairwise, np.zeros((new.size, L, L))])
    same = mrf.conflicts[:, 0] == pairs[target, 0]
    oriented = np.where(same[:, None, None], mrf.conflict_mask, mrf.conflict_mask.transpose(0, 2, 1))
    tables[target] += penalty * oriented  # targets are distinct: pairs never repeat
    return pairs, tables
