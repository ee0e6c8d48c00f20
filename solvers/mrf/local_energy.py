"""Local energies of many nodes at once, and the colour classes that make that exact.

The local energy of node i given the labels x of the others is

.. math::

    \\ell_i(a \\mid x) = U_i(a) + \\sum_{e=(i,j)} W_e(a, x_j) + \\sum_{e=(j,i)} W_e(x_j, a),

and label a is *forbidden* for i if some conflict pair (i, j) or (j, i) forbids (a, x_j).
Changing x_i alone changes E(x) by exactly the change of \\ell_i, so single-site
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
    key = np.sort(src * N + dst)
    key = key[np.concatenate([[True], key[1:] != key[:-1]])]
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
    logarithmic on paths and grids). At most max degree + 1 colours. Each class is sorted
    by node index; the classes are ordered by colour.

    With ``mrf.priority`` a node of higher priority is coloured before its neighbours of
    lower priority, and each of them takes a colour above its own (the smallest free one
    above the colours of all its neighbours of higher priority), so a sweep updates it
    first: the colouring may then need more colours (at most the number of distinct
    priorities times max degree + 1).
    """
    N = mrf.n_nodes
    indptr, nbr = union_adjacency(mrf)
    if nbr.size == 0:
        return [np.arange(N, dtype=np.intp)]
    deg = np.diff(indptr)
    owner = np.repeat(np.arange(N, dtype=np.intp), deg)
    prio = deg + np.random.default_rng(seed).random(N)
    rank = np.zeros(N, dtype=np.intp)
    if mrf.priority is not None:  # its rank first: ranks apart by more than any degree plus the fraction
        rank = np.unique(mrf.priority, return_inverse=True)[1].reshape(N)
        prio = prio + rank * float(deg.max() + 2)
    colour = np.full(N, -1, dtype=np.intp)
    # entries (u, v) with v outranking u: u must wait for v while both are open
    wait_u, wait_v = owner[prio[nbr] > prio[owner]], nbr[prio[nbr] > prio[owner]]
    open_ = np.ones(N, dtype=bool)
    while open_.any():
        blocked = np.zeros(N, dtype=bool)
        blocked[wait_u] = True
        idx = np.flatnonzero(open_ & ~blocked)
        # colours already taken around each chosen node (its coloured neighbours), and below its floor: every
        # colour up to those of its neighbours of higher priority (all coloured by now)
        sub = np.repeat(np.arange(idx.size), deg[idx])
        nb = neighbours(indptr, nbr, idx)
        floor = np.zeros(idx.size, dtype=np.intp)
        above = rank[nb] > rank[idx[sub]]
        np.maximum.at(floor, sub[above], colour[nb[above]] + 1)
        # room for every colour taken so far and one beyond each floor's degree, and the spare column
        width = int(max(colour.max(), floor.max(initial=0) + deg.max())) + 2
        used = np.arange(width)[None, :] < floor[:, None]
        used[sub, colour[nb]] = True  # colour -1 (open) lands in the spare last column
        used[:, -1] = True
        colour[idx] = np.argmin(used, axis=1)
        open_[idx] = False
        keep = open_[wait_v]
        wait_u, wait_v = wait_u[keep], wait_v[keep]
    order = np.argsort(colour, kind="stable")
    counts = np.bincount(colour)
    return [c for c in np.split(order, np.cumsum(counts)[:-1]) if c.size]


def row_tables(mrf: PairwiseMRF) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """Pairwise costs and conflict masks as contiguous rows, for fast gathers.

    Returns ``((W0, W1), (F0, F1))``, each of shape (P L, L) for P pairs: row ``p*L + b``
    of ``W0`` is ``pairwise[p, :, b]`` (the first node's row given the second's label b;
    a transposed copy) and row ``p*L + a`` of ``W1`` is ``pairwise[p, a, :]`` (the second
    node's row given the first's a; a view). Likewise for the conflict masks.
    """
    L = mrf.max_labels

    def rows(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.ascontiguousarray(t.transpose(0, 2, 1)).reshape(-1, L), t.reshape(-1, L)

    return rows(mrf.pairwise), rows(mrf.conflict_mask)


def _gather(tables: tuple[np.ndarray, np.ndarray], recipe: tuple[np.ndarray, ...], x: np.ndarray) -> np.ndarray:
    """The (n, L) rows of a recipe given the labels ``x``: first ends from ``tables[0]``, then second ends."""
    other, base, _, n0 = recipe
    idx = base + x[other]
    if n0 == idx.size:
        return tables[0][idx]
    if n0 == 0:
        return tables[1][idx]
    return np.concatenate([tables[0][idx[:n0]], tables[1][idx[n0:]]])


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

    def __init__(self, mrf: PairwiseMRF, nodes: np.ndarray, _shared: tuple | None = None) -> None:
        self.mrf = mrf
        self.nodes = np.asarray(nodes, dtype=np.intp)
        N, L = mrf.n_nodes, mrf.max_labels
        S = self.nodes.size
        pos = np.full(N, -1, dtype=np.intp)
        pos[self.nodes] = np.arange(S)
        self._unary = mrf.unary[self.nodes]
        self._size = S * L
        if _shared is None:
            member = pos >= 0
            _shared = (_incident_ends(mrf.edges, member), _incident_ends(mrf.conflicts, member), row_tables(mrf))
        (ep, eend), (cp, cend), (self._pairwise, self._mask) = _shared
        self._edge = self._recipe(mrf.edges, ep, eend, pos, L)
        self._conf = self._recipe(mrf.conflicts, cp, cend, pos, L)

    @staticmethod
    def _recipe(pairs: np.ndarray, p: np.ndarray, end: np.ndarray, pos: np.ndarray, L: int) -> tuple:
        """Where the rows of the pair ends (p, end) in the set live in :func:`row_tables`.

        Returns the other node of each end, the row base (the row is ``base + x[other]``),
        the flat (S*L) scatter index of each row entry, and how many ends (listed first)
        are first ends.
        """
        lab = np.arange(L, dtype=np.intp)
        if not p.size:
            z = np.zeros(0, dtype=np.intp)
            return z, z, z, 0
        order = np.argsort(end, kind="stable")
        p, end = p[order], end[order]
        other = pairs[p, 1 - end]
        at = pos[pairs[p, end]]
        return other, p * L, (at[:, None] * L + lab).ravel(), int(np.count_nonzero(end == 0))

    def _subset(self, recipe: tuple, sel: np.ndarray | None) -> tuple[tuple, int]:
        """The recipe restricted to the rows of the nodes where ``sel`` (S,) is True, renumbered."""
        if sel is None:
            return recipe, self._size
        L = self.mrf.max_labels
        other, base, scatter, n0 = recipe
        at = scatter[::L] // L
        keep = sel[at]
        newpos = np.cumsum(sel) - 1
        lab = np.arange(L, dtype=np.intp)
        return ((other[keep], base[keep], (newpos[at[keep]][:, None] * L + lab).ravel(),
                 int(np.count_nonzero(keep[:n0]))), int(sel.sum()) * L)

    def costs(self, x: np.ndarray, sel: np.ndarray | None = None) -> np.ndarray:
        """(S, L) local energies given the others' labels ``x`` (padding stays ``inf``).

        With ``sel``, a (S,) boolean mask, only the rows of those nodes, in order.
        """
        out = self._unary.copy() if sel is None else self._unary[sel]
        recipe, size = self._subset(self._edge, sel)
        if recipe[0].size:
            rows = _gather(self._pairwise, recipe, x)
            out.reshape(-1)[:] += np.bincount(recipe[2], weights=rows.ravel(), minlength=size)
        return out

    def forbidden(self, x: np.ndarray, sel: np.ndarray | None = None) -> np.ndarray:
        """(S, L) True where a label breaks a conflict with the others' labels ``x`` (``sel`` as in :meth:`costs`)."""
        recipe, size = self._subset(self._conf, sel)
        out = np.zeros(size, dtype=bool)
        if recipe[0].size:
            out[recipe[2][_gather(self._mask, recipe, x).ravel()]] = True
        return out.reshape(-1, self.mrf.max_labels)

    def conflict_counts(self, x: np.ndarray) -> np.ndarray:
        """(S, L) how many conflicts each label breaks with the others' labels ``x``."""
        out = np.zeros(self._size)
        if self._conf[0].size:
            out += np.bincount(self._conf[2], weights=_gather(self._mask, self._conf, x).ravel(),
                               minlength=self._size)
        return out.reshape(-1, self.mrf.max_labels)

    def feasible_costs(self, x: np.ndarray, sel: np.ndarray | None = None) -> np.ndarray:
        """:meth:`costs` with ``inf`` on forbidden labels."""
        c = self.costs(x, sel)
        c[self.forbidden(x, sel)] = np.inf
        return c


def neighbours(indptr: np.ndarray, nbr: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """The neighbours of ``nodes`` in a CSR adjacency (with repeats)."""
    d = indptr[nodes + 1] - indptr[nodes]
    within = np.arange(d.sum()) - np.repeat(np.cumsum(d) - d, d)
    return nbr[np.repeat(indptr[nodes], d) + within]


def _incident_ends(pairs: np.ndarray, member: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(pair index, end 0/1) of every pair end that lies in the set ``member`` (bool mask)."""
    if not len(pairs):
        z = np.zeros(0, dtype=np.intp)
        return z, z
    p0, p1 = np.flatnonzero(member[pairs[:, 0]]), np.flatnonzero(member[pairs[:, 1]])
    return np.concatenate([p0, p1]), np.repeat(np.array([0, 1], dtype=np.intp), [p0.size, p1.size])


def _ends_by_class(pairs: np.ndarray, colour: np.ndarray, k: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`_incident_ends` for each of the k colour classes at once."""
    P = len(pairs)
    p = np.concatenate([np.arange(P), np.arange(P)])
    end = np.repeat(np.array([0, 1], dtype=np.intp), P)
    cls = colour[pairs[p, end]] if P else np.zeros(0, dtype=np.intp)
    order = np.argsort(cls, kind="stable")
    cut = np.searchsorted(cls[order], np.arange(k + 1))
    return [(p[order[a:b]], end[order[a:b]]) for a, b in zip(cut[:-1], cut[1:])]


def colour_sweep(mrf: PairwiseMRF, seed: int = 0) -> list[LocalEnergy]:
    """One :class:`LocalEnergy` per colour class: a sweep updates them in this order."""
    classes = colour_classes(mrf, seed)
    colour = np.empty(mrf.n_nodes, dtype=np.intp)
    for c, nodes in enumerate(classes):
        colour[nodes] = c
    e = _ends_by_class(mrf.edges, colour, len(classes))
    f = _ends_by_class(mrf.conflicts, colour, len(classes))
    tables = row_tables(mrf)
    return [LocalEnergy(mrf, nodes, (e[c], f[c], tables)) for c, nodes in enumerate(classes)]
