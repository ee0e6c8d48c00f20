"""The bio-inspired interaction graph (paper Section IV-A) and its clique factorization.

Each robot interacts with its k nearest robots (topological, not metric, neighbourhood,
after Ballerini et al. 2008); the graph is made symmetric (an edge where either robot
counts the other among its k nearest). The MRF factorizes over the graph's maximal
cliques, checked against ``networkx.find_cliques`` in tests.

Cliques. A k-NN graph is sparse and its cliques are small (at most a few more than k
robots), so the maximal cliques are enumerated level by level in whole-array operations:
every clique Q (members sorted) carries C(Q), the vertices adjacent to all of Q; the
cliques one larger are Q + c for c in C(Q) with c > max(Q), and
C(Q + c) = {c' in C(Q) : c' adjacent to c}; Q is maximal exactly when C(Q) is empty.
Each clique is generated once, from its sorted prefix, so the work is proportional to
the number of (clique, common neighbour) pairs. Dense graphs have exponentially many
non-maximal cliques; past a work budget proportional to the graph's size the
enumeration gives way to Bron–Kerbosch with pivoting, which lists maximal cliques only.

Pairwise reduction: a clique energy E_c = sum_{i in c} rho_S(x_i) + sum_{i<j in c}
rho_D(x_i, x_j) is a sum of unary and pairwise terms, so the swarm energy
sum_c E_c equals a pairwise MRF with unary weight w_i = number of maximal cliques that
contain i and pairwise weight w_ij = number that contain both i and j.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from mrfswarm.errors import ConfigError


def check_k(k: int, n_robots: int) -> None:
    """The paper's condition that no robot is without neighbours: 1 <= k < N.

    Raises
    ------
    ConfigError
        Naming k and N.
    """
    if n_robots < 2:
        raise ConfigError(f"a swarm needs at least 2 robots, got {n_robots}")
    if not 1 <= k < n_robots:
        raise ConfigError(f"interaction.k = {k}: must satisfy 1 <= k < N = {n_robots} (number of robots)")


def knn_edges(points: np.ndarray, k: int) -> np.ndarray:
    """Undirected edges of the symmetric k-nearest-neighbour graph.

    Parameters
    ----------
    points
        (N, d) robot positions (d = 2 or 3; Euclidean distance, not the downwash-scaled
        one: the graph couples the Morse interaction, which is Euclidean; safety is kept
        over all pairs by the step's hard conflicts, whatever the graph).
    k
        Neighbours per robot, 1 <= k < N. Ties in distance are broken by robot index
        (deterministic).

    Returns
    -------
    (E, 2) int array of pairs i < j, sorted lexicographically, without repeats.

    Raises
    ------
    ValueError
        ``points`` not (N, d), or a robot's position not finite (SciPy's tree said "data must be
        finite", naming no robot).
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2:
        raise ValueError(f"points must have shape (N, d), got {pts.shape}")
    bad = np.flatnonzero(~np.isfinite(pts).all(axis=1))
    if len(bad):
        raise ValueError(f"robot {int(bad[0])}'s position {pts[bad[0]].tolist()} is not finite")
    n = len(pts)
    check_k(k, n)
    tree = cKDTree(pts)
    nb = np.empty((n, k), dtype=np.intp)
    # Ask for a few neighbours more than needed; the rows whose k-th distance ties with the
    # last one returned may have more tied points, and are asked again with more, so that
    # ties at the k-th distance are broken by index, never by the tree's internal order.
    pending = np.arange(n)
    m = min(n, k + 5)
    while len(pending):
        dist, idx = tree.query(pts[pending], m)
        dist, idx = dist.reshape(len(pending), m), idx.reshape(len(pending), m)
        rd = np.round(dist, 9)
        done = (rd[:, k] < rd[:, m - 1]) if m < n else np.ones(len(pending), dtype=bool)
        rows, rd, idx = pending[done], rd[done], idx[done]
        order = np.lexsort((idx, rd), axis=1)
        idx = np.take_along_axis(idx, order, axis=1)
        # drop self (always at distance 0 and unique, since robots occupy distinct cells)
        rest = idx[idx != rows[:, None]].reshape(len(rows), m - 1)
        nb[rows] = rest[:, :k]
        pending = pending[~done]
        m = min(n, 2 * m + 8)
    a = np.repeat(np.arange(n), k)
    b = nb.ravel()
    keys = np.sort(np.minimum(a, b) * n + np.maximum(a, b))
    keys = keys[np.concatenate([[True], keys[1:] != keys[:-1]])]
    return np.stack([keys // n, keys % n], axis=1)


def graph_edges(n_nodes: int, edges: np.ndarray) -> np.ndarray:
    """``edges`` as an (E, 2) int64 array, or ValueError / TypeError naming the first bad edge.

    The enumeration reads edges as the docstring of :func:`maximal_clique_groups` states them
    (integer pairs i < j of vertices in 0..n_nodes - 1, each once); others gave wrong cliques
    without a word: a vertex beyond ``n_nodes`` a clique of its own, (1, 0) no clique with its
    third vertex, 0.5 read as 0 (a library tour).
    """
    a = np.asarray(edges)
    if a.size and a.dtype.kind not in "iu":
        raise TypeError(f"edges must be integer vertex pairs, got dtype {a.dtype}")
    if a.size % 2 or (a.ndim == 2 and a.shape[1] != 2) or a.ndim > 2:
        raise ValueError(f"edges must have shape (E, 2), got {a.shape}")
    e = a.astype(np.int64).reshape(-1, 2)
    bad = np.flatnonzero((e.min(axis=1) < 0) | (e.max(axis=1) >= n_nodes))
    if len(bad):
        raise ValueError(f"edge {e[bad[0]].tolist()} has a vertex outside 0..{n_nodes - 1}")
    bad = np.flatnonzero(e[:, 0] >= e[:, 1])
    if len(bad):
        raise ValueError(f"edge {e[bad[0]].tolist()}: edges must be pairs i < j")
    keys = np.sort(e[:, 0] * np.int64(n_nodes) + e[:, 1])
    repeated = np.flatnonzero(keys[1:] == keys[:-1])
    if len(repeated):
        k = int(keys[repeated[0]])
        raise ValueError(f"edge {[k // n_nodes, k % n_nodes]} is given more than once")
    return e


#: Work budget of the level-wise clique enumeration, in (clique, common neighbour) pairs
#: per node and edge of the graph; past it, Bron–Kerbosch takes over.
LEVEL_BUDGET = 64


class _EdgeSet:
    """Membership of vertex pairs in an edge set: sorted keys lo * n + hi and a binary search."""

    def __init__(self, n_nodes: int, edges: np.ndarray) -> None:
        self.n = np.int64(n_nodes)
        self.keys = np.sort(edges[:, 0].astype(np.int64) * self.n + edges[:, 1])

    def contains(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        q = np.minimum(a, b) * self.n + np.maximum(a, b)
        if not len(self.keys):
            return np.zeros(len(q), dtype=bool)
        pos = np.minimum(np.searchsorted(self.keys, q), len(self.keys) - 1)
        return self.keys[pos] == q


def _cliques_by_level(n_nodes: int, edges: np.ndarray, budget: int, seeds: int | None = None
                      ) -> dict[int, np.ndarray] | None:
    """Maximal cliques by size, enumerated level by level (module docstring); None past ``budget``.

    With ``seeds``, only the cliques whose smallest vertex is below ``seeds``.

    Returns {size: (M, size) int array}, each row sorted ascending, rows in lexicographic
    order.
    """
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    n = n_nodes
    m = n if seeds is None else seeds
    adjacent = _EdgeSet(n, edges)
    src = np.concatenate([edges[:, 0], edges[:, 1]])
    dst = np.concatenate([edges[:, 1], edges[:, 0]])
    keep = src < m
    src, dst = src[keep], dst[keep]
    order = np.argsort(src * n + dst, kind="stable")
    # C({v}) = N(v), as flat (owner, vertex) pairs sorted by owner, then vertex
    c_owner, c_vert = src[order], dst[order]
    c_count = np.bincount(c_owner, minlength=m)
    groups: dict[int, np.ndarray] = {}
    if np.any(c_count == 0):
        groups[1] = np.flatnonzero(c_count == 0).astype(np.int64)[:, None]
    members = np.arange(m, dtype=np.int64)[:, None]
    work = 0
    while len(c_owner):
        # children Q + c: c in C(Q) beyond Q's last member
        child = np.flatnonzero(c_vert > members[c_owner, -1])
        child_owner, child_vert = c_owner[child], c_vert[child]
        c_start = np.cumsum(c_count) - c_count
        reps = c_count[child_owner]
        total = int(reps.sum())
        work += total
        if work > budget:
            return None
        # every (child, c') with c' in C(owner): C(child) keeps the c' adjacent to c
        which = np.repeat(np.arange(len(child), dtype=np.int64), reps)
        at = np.arange(total, dtype=np.int64) + np.repeat(c_start[child_owner] - (np.cumsum(reps) - reps), reps)
        other = c_vert[at]
        cv = child_vert[which]
        keep = other != cv
        which, other, cv = which[keep], other[keep], cv[keep]
        keep = adjacent.contains(cv, other)
        members = np.concatenate([members[child_owner], child_vert[:, None]], axis=1)
        c_owner, c_vert = which[keep], other[keep]
        c_count = np.bincount(c_owner, minlength=len(child))
        maximal = c_count == 0
        if maximal.any():
            groups[members.shape[1]] = members[maximal]
    return groups


def _bron_kerbosch(n_nodes: int, edges: np.ndarray) -> list[list[int]]:
    """Maximal cliques by Bron–Kerbosch with Tomita pivoting (unsorted lists).

    The outer loop is Eppstein–Löffler–Strash's: for each vertex v (low degree first), the
    cliques whose earliest vertex is v, found with P = later neighbours and X = earlier
    ones. Vertex sets are Python ints used as bitsets. Isolated nodes are maximal cliques
    of size one.
    """
    nbr = [0] * n_nodes
    for a, b in np.asarray(edges).reshape(-1, 2).tolist():
        nbr[a] |= 1 << b
        nbr[b] |= 1 << a
    found: list[list[int]] = []

    def expand(R: list[int], P: int, X: int) -> None:
        if not P:
            if not X:
                found.append(R)
            return
        # pivot: the vertex of P | X with the most neighbours in P
        best, u, m = -1, 0, P | X
        while m:
            low = m & -m
            w = low.bit_length() - 1
            c = (P & nbr[w]).bit_count()
            if c > best:
                best, u = c, w
            m ^= low
        cand = P & ~nbr[u]
        while cand:
            low = cand & -cand
            v = low.bit_length() - 1
            cand ^= low
            expand(R + [v], P & nbr[v], X & nbr[v])
            P &= ~low
            X |= low

    later = (1 << n_nodes) - 1
    for v in sorted(range(n_nodes), key=lambda i: nbr[i].bit_count()):
        later &= ~(1 << v)
        expand([v], nbr[v] & later, nbr[v] & ~later)
    return found


def maximal_clique_groups(n_nodes: int, edges: np.ndarray, budget: int | None = None) -> dict[int, np.ndarray]:
    """Maximal cliques grouped by size (module docstring).

    Parameters
    ----------
    n_nodes
        Number of vertices.
    edges
        (E, 2) undirected edges i < j, without repeats.
    budget
        Work budget of the level-wise enumeration in (clique, common neighbour) pairs;
        default ``LEVEL_BUDGET * (n_nodes + E)``. Past it, Bron–Kerbosch is used.

    Returns
    -------
    {size: (M, size) int array}: each row a maximal clique sorted ascending, rows in
    lexicographic order.

    Raises
    ------
    ValueError, TypeError
        Edges that are not such pairs (:func:`graph_edges`).
    """
    edges = graph_edges(n_nodes, edges)
    if budget is None:
        budget = LEVEL_BUDGET * (n_nodes + len(edges))
    groups = _cliques_by_level(n_nodes, edges, budget)
    if groups is None:
        by_size: dict[int, list[list[int]]] = {}
        for c in _bron_kerbosch(n_nodes, edges):
            by_size.setdefault(len(c), []).append(sorted(c))
        groups = {}
        for size, rows in by_size.items():
            a = np.array(rows, dtype=np.int64).reshape(-1, size)
            groups[size] = a[np.lexsort(a.T[::-1])]
    return dict(sorted(groups.items()))


def _sorted_clique_list(groups: dict[int, np.ndarray]) -> list[np.ndarray]:
    """The cliques of all groups as one list, sorted as lists (a prefix before its extensions)."""
    if not groups:
        return []
    width = max(groups)
    rows = np.concatenate([np.pad(g, ((0, 0), (0, width - s)), constant_values=-1) for s, g in groups.items()])
    sizes = np.concatenate([np.full(len(g), s) for s, g in groups.items()])
    order = np.lexsort(rows.T[::-1])
    rows = rows[order].astype(np.intp)
    return [r[:s] for r, s in zip(rows, sizes[order].tolist())]


def maximal_cliques(n_nodes: int, edges: np.ndarray) -> list[np.ndarray]:
    """Maximal cliques, each a sorted int array; the list sorted (as lists).

    The same cliques as ``networkx.find_cliques`` (tested). Isolated nodes are maximal
    cliques of size one. See :func:`maximal_clique_groups` and the module docstring.
    """
    return _sorted_clique_list(maximal_clique_groups(n_nodes, edges))


@dataclass(frozen=True)
class CliqueWeights:
    """The pairwise reduction of the clique energy for one graph.

    Attributes
    ----------
    edges
        (E, 2) graph edges, i < j.
    node
        (N,) w_i = number of maximal cliques containing i.
    edge
        (E,) w_ij = number of maximal cliques containing both ends of the edge.
    cliques
        The maximal cliques themselves.
    groups
        The same cliques by size, {size: (M, size) array} (what
        :func:`update_clique_weights` starts from), or None.
    """

    edges: np.ndarray
    node: np.ndarray
    edge: np.ndarray
    cliques: list[np.ndarray]
    groups: dict[int, np.ndarray] | None = field(default=None, compare=False, repr=False)


def clique_weights(n_nodes: int, edges: np.ndarray, cliques: list[np.ndarray]) -> CliqueWeights:
    """Count, per node and per edge, the maximal cliques that contain it."""
    by_size: dict[int, list[np.ndarray]] = {}
    for c in cliques:
        by_size.setdefault(len(c), []).append(c)
    groups = {size: np.stack(group) for size, group in by_size.items()}
    return _weights_from_groups(n_nodes, edges, groups, cliques)


def _weights_from_groups(n_nodes: int, edges: np.ndarray, groups: dict[int, np.ndarray],
                         cliques: list[np.ndarray]) -> CliqueWeights:
    node = np.zeros(n_nodes, dtype=np.int64)
    pair_keys = []
    for size, members in groups.items():  # (n_cliques, size), rows sorted ascending
        node += np.bincount(members.ravel(), minlength=n_nodes)
        if size > 1:
            i, j = np.triu_indices(size, 1)
            pair_keys.append((members[:, i].astype(np.int64) * n_nodes + members[:, j]).ravel())
    edge_keys = edges[:, 0].astype(np.int64) * n_nodes + edges[:, 1]
    if pair_keys:
        keys = np.sort(np.concatenate(pair_keys))
        first = np.flatnonzero(np.concatenate([[True], keys[1:] != keys[:-1]]))
        keys, counts = keys[first], np.diff(np.append(first, len(keys)))
        pos = np.searchsorted(keys, edge_keys)
        pos = np.minimum(pos, len(keys) - 1)
        found = keys[pos] == edge_keys
        edge = np.where(found, counts[pos], 0)
    else:
        edge = np.zeros(len(edges), dtype=np.int64)
    if np.any(edge == 0):  # every edge lies in some maximal clique; anything else is a bug
        raise AssertionError("an edge lies in no maximal clique")
    return CliqueWeights(edges=edges, node=node, edge=edge, cliques=cliques, groups=groups)


def clique_weights_of_graph(n_nodes: int, edges: np.ndarray) -> CliqueWeights:
    """The maximal cliques of a graph and their pairwise reduction, in one pass."""
    groups = maximal_clique_groups(n_nodes, edges)
    return _weights_from_groups(n_nodes, edges, groups, _sorted_clique_list(groups))


def update_clique_weights(previous: CliqueWeights, n_nodes: int, edges: np.ndarray) -> CliqueWeights:
    """:func:`clique_weights_of_graph` of a graph that differs from ``previous``'s in a few places.

    A vertex is *changed* when its neighbours differ between the two graphs. A maximal
    clique without a changed vertex keeps its edges and its (empty) set of common
    neighbours, so it is maximal in both graphs, and conversely. The new cliques are
    therefore the previous ones without a changed vertex and the new graph's cliques
    that contain one; the latter are enumerated alone, by numbering the changed vertices
    first and seeding the enumeration with them only. The result equals the full
    computation (tested); along a crossing only a few percent of the robots change
    neighbours in a step.
    """
    edges = graph_edges(n_nodes, edges)
    if previous.groups is None or len(previous.node) != n_nodes:
        return clique_weights_of_graph(n_nodes, edges)
    n = np.int64(n_nodes)
    old_keys = previous.edges[:, 0].astype(np.int64) * n + previous.edges[:, 1]
    new_keys = edges[:, 0] * n + edges[:, 1]
    diff = np.setxor1d(old_keys, new_keys, assume_unique=True)
    changed = np.zeros(n_nodes, dtype=bool)
    changed[diff // n] = True
    changed[diff % n] = True
    m = int(changed.sum())
    if m == 0:
        return _weights_from_groups(n_nodes, edges, previous.groups, previous.cliques)
    order = np.concatenate([np.flatnonzero(changed), np.flatnonzero(~changed)])  # new number -> vertex
    rank = np.empty(n_nodes, dtype=np.int64)
    rank[order] = np.arange(n_nodes)
    relabelled = np.sort(rank[edges], axis=1)
    fresh = _cliques_by_level(n_nodes, relabelled, LEVEL_BUDGET * (n_nodes + len(edges)), seeds=m)
    if fresh is None:
        return clique_weights_of_graph(n_nodes, edges)
    merged: dict[int, list[np.ndarray]] = {}
    for size, g in previous.groups.items():
        merged.setdefault(size, []).append(g[~changed[g].any(axis=1)])
    for size, g in fresh.items():
        merged.setdefault(size, []).append(np.sort(order[g], axis=1))
    groups = {}
    for size in sorted(merged):
        g = np.concatenate(merged[size])
        if len(g):
            groups[size] = g[np.lexsort(g.T[::-1])]
    return _weights_from_groups(n_nodes, edges, groups, _sorted_clique_list(groups))


def interaction_graph(points: np.ndarray, k: int) -> CliqueWeights:
    """The k-NN graph of ``points``, its maximal cliques and their pairwise reduction."""
    return clique_weights_of_graph(len(points), knn_edges(points, k))


def swarm_energy_from_cliques(cliques: list[np.ndarray], positions: np.ndarray, static: np.ndarray,
                              rho_d, resolution: float = 1.0) -> float:
    """The swarm energy straight from its definition, sum over maximal cliques of E_c.

    E_c = sum_{i in c} rho_S(x_i) + sum_{i<j in c} rho_D(|x_i - x_j|). A slow reference for
    tests and figures; the planner uses the pairwise reduction.
    """
    total = 0.0
    for c in cliques:
        cells = positions[c]
        total += float(static[tuple(cells.T)].sum())
        for a in range(len(c)):
            for b in range(a + 1, len(c)):
                total += float(rho_d(np.linalg.norm(cells[a] - cells[b]) * resolution))
    return total
