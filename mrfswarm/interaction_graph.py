"""The bio-inspired interaction graph (paper Section IV-A) and its clique factorization.

Each robot interacts with its k nearest robots (topological, not metric, neighbourhood,
after Ballerini et al. 2008); the graph is made symmetric (an edge where either robot
counts the other among its k nearest). The MRF factorizes over the graph's maximal
cliques (Bron–Kerbosch with pivoting; checked against ``networkx.find_cliques`` in tests).

Pairwise reduction: a clique energy E_c = sum_{i in c} rho_S(x_i) + sum_{i<j in c}
rho_D(x_i, x_j) is a sum of unary and pairwise terms, so the swarm energy
sum_c E_c equals a pairwise MRF with unary weight w_i = number of maximal cliques that
contain i and pairwise weight w_ij = number that contain both i and j.
"""

from __future__ import annotations

from dataclasses import dataclass

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
        (N, 2) robot positions.
    k
        Neighbours per robot, 1 <= k < N. Ties in distance are broken by robot index
        (deterministic).

    Returns
    -------
    (E, 2) int array of pairs i < j, sorted lexicographically, without repeats.
    """
    pts = np.asarray(points, dtype=float)
    n = len(pts)
    check_k(k, n)
    # Ask for extra neighbours so that ties at the k-th distance are broken by index rather
    # than by the tree's internal order (a shell of equal distances on a grid holds <= 12).
    m = min(n, k + 1 + 12)
    dist, idx = cKDTree(pts).query(pts, m)
    order = np.lexsort((idx, np.round(dist, 9)), axis=1)
    idx = np.take_along_axis(idx, order, axis=1)
    nb = np.empty((n, k), dtype=np.intp)
    for_self = idx == np.arange(n)[:, None]
    # drop self (always at distance 0 and unique, since robots occupy distinct cells)
    rest = idx[~for_self].reshape(n, m - 1)
    nb[:] = rest[:, :k]
    a = np.repeat(np.arange(n), k)
    b = nb.ravel()
    pairs = np.sort(np.stack([a, b], axis=1), axis=1)
    keys = np.unique(pairs[:, 0] * n + pairs[:, 1])
    return np.stack([keys // n, keys % n], axis=1)


def maximal_cliques(n_nodes: int, edges: np.ndarray) -> list[np.ndarray]:
    """Maximal cliques by Bron–Kerbosch with Tomita pivoting, each a sorted int array.

    The outer loop is Eppstein–Löffler–Strash's: for each vertex v (low degree first), the
    cliques whose earliest vertex is v, found with P = later neighbours and X = earlier
    ones. Vertex sets are Python ints used as bitsets. Gives the same cliques as
    ``networkx.find_cliques`` (tested), a few times faster on k-NN graphs. Isolated
    nodes are maximal cliques of size one. The list is sorted.
    """
    nbr = [0] * n_nodes
    for a, b in edges.tolist():
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
    found = sorted(sorted(c) for c in found)
    return [np.array(c, dtype=np.intp) for c in found]


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
    """

    edges: np.ndarray
    node: np.ndarray
    edge: np.ndarray
    cliques: list[np.ndarray]


def clique_weights(n_nodes: int, edges: np.ndarray, cliques: list[np.ndarray]) -> CliqueWeights:
    """Count, per node and per edge, the maximal cliques that contain it."""
    node = np.zeros(n_nodes, dtype=np.int64)
    pair_keys = []
    by_size: dict[int, list[np.ndarray]] = {}
    for c in cliques:
        by_size.setdefault(len(c), []).append(c)
    for size, group in by_size.items():
        members = np.stack(group)  # (n_cliques, size), rows sorted ascending
        node += np.bincount(members.ravel(), minlength=n_nodes)
        if size > 1:
            i, j = np.triu_indices(size, 1)
            pair_keys.append((members[:, i] * n_nodes + members[:, j]).ravel())
    edge_keys = edges[:, 0] * n_nodes + edges[:, 1]
    if pair_keys:
        keys, counts = np.unique(np.concatenate(pair_keys), return_counts=True)
        pos = np.searchsorted(keys, edge_keys)
        pos = np.minimum(pos, len(keys) - 1)
        found = keys[pos] == edge_keys
        edge = np.where(found, counts[pos], 0)
    else:
        edge = np.zeros(len(edges), dtype=np.int64)
    if np.any(edge == 0):  # every edge lies in some maximal clique; anything else is a bug
        raise AssertionError("an edge lies in no maximal clique")
    return CliqueWeights(edges=edges, node=node, edge=edge, cliques=cliques)


def interaction_graph(points: np.ndarray, k: int) -> CliqueWeights:
    """The k-NN graph of ``points``, its maximal cliques and their pairwise reduction."""
    edges = knn_edges(points, k)
    cliques = maximal_cliques(len(points), edges)
    return clique_weights(len(points), edges, cliques)


def swarm_energy_from_cliques(cliques: list[np.ndarray], positions: np.ndarray, static: np.ndarray,
                              rho_d, resolution: float = 1.0) -> float:
    """The swarm energy straight from its definition, sum over maximal cliques of E_c.

    E_c = sum_{i in c} rho_S(x_i) + sum_{i<j in c} rho_D(|x_i - x_j|). A slow reference for
    tests and figures; the planner uses the pairwise reduction.
    """
    total = 0.0
    for c in cliques:
        cells = positions[c]
        total += float(static[cells[:, 0], cells[:, 1]].sum())
        for a in range(len(c)):
            for b in range(a + 1, len(c)):
                total += float(rho_d(np.hypot(*(cells[a] - cells[b])) * resolution))
    return total
