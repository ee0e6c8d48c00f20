"""Local energies of many nodes at once, and the colour classes that make that exact.

The local energy of node i given the labels x of the others is

.. math::

    \\ell_i(a \\mid x) = U_i(a) + \\sum_{e=(i,j)} W_e(a, x_j) + \\sum_{e=(j,i)} W_e(x_j, a),

and label a is *forbidden* for i if some conflict pair (i, j) or (j, i) forbids (a, x_j).
Changing x_i by one label changes E(x) by exactly the change of \\ell_i, so single-site
methods (ICM, Gibbs, the lazy flipper's size-one flips) only need \\ell.

Two nodes that share neither an edge nor a conflict do not see each other's labels in
\\ell, so all nodes of an independent set of the union graph (edges + conflicts) can be
updated in one array expression, and that is *exactly* a sequential update in any order
of the set. :func:`colour_classes` splits the nodes into such sets (a proper colouring);
:class:`LocalEnergy` evaluates \\ell and the forbidden labels for one set in a handful of
numpy calls (gather of the incident tables' rows + ``np.bincount`` scatter-add).
"""

from __future__ import annotations

import numpy as np

from solvers.mrf.problem import PairwiseMRF


def union_adjacency(mrf: PairwiseMRF) -> tuple[np.ndarray, np.ndarray]:
    """CSR adjacency (indptr, indices) of the union of edges and conflicts, symmetric, no repeats."""
    N = mrf.n_nodes
    pairs = np.concatenate([mrf.edges, mrf.conflicts]).astype(np.int64)
    if len(pairs) == 0:
        return np.zeros(N + 1, dtype=np.intp), np.zeros(0, dtype=np.intp)
    src = np.concatenate([pairs[:, 0], pairs[:, 1]])
    dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
    key = np.unique(src * N + dst)
    src, dst = key // N, key % N
    indptr = np.zeros(N + 1, dtype=np.intp)
    np.cumsum(np.bincount(src, minlength=N), out=indptr[1:])
    return indptr, dst.astype(np.intp)


def colour_classes(mrf: PairwiseMRF, seed: int = 0) -> list[np.ndarray]:
    """A proper colouring of the union graph (edges + conflicts), as a list of node arrays.

    Jones–Plassmann colouring, vectorized: every round, each uncoloured node whose
    priority beats all its uncoloured neighbours takes the smallest colour its coloured
    neighbours do not use. Priority = degree plus a seeded random fraction (largest
    degree first, as Welsh–Powell; the random part keeps the number of rounds
    logarithmic on paths and grids). At most max degree + 1 colours. Each class is
    sorted by node index; the classes are ordered by colour.
    """
    N = mrf.n_nodes
    indptr, nbr = union_adjacency(mrf)
    if nbr.size == 0:
        return [np.arange(N, dtype=np.intp)]
    deg = np.diff(indptr)
    owner = np.repeat(np.arange(N, dtype=np.intp), deg)
    prio = deg + np.random.default_rng(seed).random(N)
    colour = np.full(N, -1, dtype=np.intp)
    beats = prio[nbr] > prio[owner]  # neighbour outranks the owner
    width = int(deg.max()) + 1
    while True:
        open_ = colour < 0
        if not open_.any():
            break
        blocked = np.zeros(N, dtype=bool)
        blocked[owner[beats & open_[nbr] & open_[owner]]] = True
        chosen = open_ & ~blocked
        # colours already taken around each chosen node
        sel = chosen[owner] & ~open_[nbr]
        used = np.zeros((N, width + 1), dtype=bool)
        used[owner[sel], colour[nbr[sel]]] = True
        idx = np.flatnonzero(chosen)
        colour[idx] = np.argmin(used[idx], axis=1)
    order = np.argsort(colour, kind="stable")
    counts = np.bincount(colour)
    return [c for c in np.split(order, np.cumsum(counts)[:-1]) if c.size]


class LocalEnergy:
    """Local energies \\ell_i(. | x) and forbidden labels of a fixed set of nodes.

    Parameters
    ----------
    mrf
        The problem.
    nodes
        (S,) distinct node indices. For a simultaneous *update* they must form an
        independent set of the union graph; for mere evaluation any set will do.
    """

    def __init__(self, mrf: PairwiseMRF, nodes: np.ndarray) -> None:
        self.mrf = mrf
        self.nodes = np.asarray(nodes, dtype=np.intp)
        N, L = mrf.n_nodes, mrf.max_labels
        S = self.nodes.size
        pos = np.full(N, -1, dtype=np.intp)
        pos[self.nodes] = np.arange(S)
        self._unary = mrf.unary[self.nodes]
        lab = np.arange(L, dtype=np.intp)

        def half_edges(pairs: np.ndarray) -> tuple:
            # For pair p = (u, v): u's row is table[p, :, x[v]], v's row is table[p, x[u], :].
            p0 = np.flatnonzero(pos[pairs[:, 0]] >= 0) if len(pairs) else np.zeros(0, np.intp)
            p1 = np.flatnonzero(pos[pairs[:, 1]] >= 0) if len(pairs) else np.zeros(0, np.intp)
            f0 = (pos[pairs[p0, 0]][:, None] * L + lab).ravel()
            f1 = (pos[pairs[p1, 1]][:, None] * L + lab).ravel()
            return p0, pairs[p0, 1], f0, p1, pairs[p1, 0], f1

        self._edge = half_edges(mrf.edges)
        self._conf = half_edges(mrf.conflicts)
        self._size = S * L
        self.n_incident = int(self._edge[0].size + self._edge[3].size)

    def costs(self, x: np.ndarray) -> np.ndarray:
        """(S, L) local energies given the others' labels ``x`` (padding stays ``inf``)."""
        mrf = self.mrf
        out = self._unary.copy()
        p0, o0, f0, p1, o1, f1 = self._edge
        flat = out.reshape(-1)
        if p0.size:
            flat += np.bincount(f0, weights=mrf.pairwise[p0, :, x[o0]].ravel(), minlength=self._size)
        if p1.size:
            flat += np.bincount(f1, weights=mrf.pairwise[p1, x[o1], :].ravel(), minlength=self._size)
        return out

    def forbidden(self, x: np.ndarray) -> np.ndarray:
        """(S, L) True where a label breaks a conflict with the others' labels ``x``."""
        mrf = self.mrf
        out = np.zeros(self._size, dtype=bool)
        p0, o0, f0, p1, o1, f1 = self._conf
        if p0.size:
            out[f0[mrf.conflict_mask[p0, :, x[o0]].ravel()]] = True
        if p1.size:
            out[f1[mrf.conflict_mask[p1, x[o1], :].ravel()]] = True
        return out.reshape(-1, mrf.max_labels)

    def feasible_costs(self, x: np.ndarray) -> np.ndarray:
        """:meth:`costs` with ``inf`` on forbidden labels."""
        c = self.costs(x)
        c[self.forbidden(x)] = np.inf
        return c


def colour_sweep(mrf: PairwiseMRF, seed: int = 0) -> list[LocalEnergy]:
    """One :class:`LocalEnergy` per colour class: a sweep updates them in this order."""
    return [LocalEnergy(mrf, c) for c in colour_classes(mrf, seed)]
