"""The step's graph, cliques and energy tables at scale: exact against slow references."""

import networkx as nx
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrfswarm.discrete.interaction_graph import (
    _bron_kerbosch,
    _cliques_by_level,
    clique_weights,
    clique_weights_of_graph,
    knn_edges,
    maximal_clique_groups,
    maximal_cliques,
    update_clique_weights,
)
from mrfswarm.discrete.label_sets import label_sets
from mrfswarm.discrete.potentials import Morse
from mrfswarm.discrete.step_mrf import _OFFSET_RADIUS, pairwise_tables
from solvers.errors import InvalidProblem
from solvers.mrf import PairwiseMRF


def brute_knn(pts, k):
    D = np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1))
    out = set()
    for i in range(len(pts)):
        order = sorted((j for j in range(len(pts)) if j != i), key=lambda j: (round(D[i, j], 9), j))
        out |= {(min(i, j), max(i, j)) for j in order[:k]}
    return out


def gaussian_swarm(rng, n, sigma):
    cells = np.unique(np.round(rng.normal(0, sigma, (3 * n, 2))).astype(int), axis=0)
    rng.shuffle(cells)
    return cells[:n]


@settings(max_examples=25, deadline=None)
@given(st.integers(8, 120), st.integers(1, 9), st.integers(0, 2**32 - 1))
def test_knn_cliques_equal_networkx_and_bron_kerbosch(n, k, seed):
    """Level-wise cliques of k-NN graphs (the planner's case) = networkx = Bron–Kerbosch."""
    rng = np.random.default_rng(seed)
    pts = gaussian_swarm(rng, n, 0.6 * np.sqrt(n)).astype(float)
    k = min(k, len(pts) - 1)
    edges = knn_edges(pts, k)
    ours = [c.tolist() for c in maximal_cliques(len(pts), edges)]
    g = nx.Graph()
    g.add_nodes_from(range(len(pts)))
    g.add_edges_from(edges.tolist())
    assert ours == sorted(sorted(c) for c in nx.find_cliques(g))
    assert ours == sorted(sorted(c) for c in _bron_kerbosch(len(pts), edges))
    levels = _cliques_by_level(len(pts), edges, budget=10**9)
    assert levels is not None  # within budget: the level-wise enumeration is what gave ``ours``
    assert sorted(c.tolist() for rows in levels.values() for c in rows) == ours


def test_dense_graph_falls_back_to_bron_kerbosch():
    """A complete graph has 2^n cliques: the level-wise enumeration stops at its budget."""
    n = 24
    edges = np.array([(i, j) for i in range(n) for j in range(i + 1, n)])
    assert _cliques_by_level(n, edges, budget=64 * (n + len(edges))) is None
    groups = maximal_clique_groups(n, edges)
    assert list(groups) == [n] and groups[n].tolist() == [list(range(n))]
    # the same graph with room in the budget: same answer by the level-wise path
    small = edges[(edges < 10).all(axis=1)]
    assert _cliques_by_level(10, small, budget=10**9)[10].tolist() == [list(range(10))]


def test_isolated_nodes_and_mixed_sizes_sorted_as_lists():
    # 0-1-2 triangle, 2-3 edge, 4 isolated, 5-6 edge: sorted as lists (prefix first)
    edges = np.array([[0, 1], [0, 2], [1, 2], [2, 3], [5, 6]])
    assert [c.tolist() for c in maximal_cliques(7, edges)] == [[0, 1, 2], [2, 3], [4], [5, 6]]
    w = clique_weights_of_graph(7, edges)
    ref = clique_weights(7, edges, maximal_cliques(7, edges))
    assert w.node.tolist() == ref.node.tolist() == [1, 1, 2, 1, 1, 1, 1]
    assert w.edge.tolist() == ref.edge.tolist()


def test_knn_ties_beyond_the_first_query_are_broken_by_index():
    """A robot whose k-th neighbour lies on a shell of 16 equidistant cells (x^2 + y^2 = 65)."""
    shell = [(x, y) for x in range(-8, 9) for y in range(-8, 9) if x * x + y * y == 65]
    assert len(shell) == 16
    rng = np.random.default_rng(0)
    pts = np.array([(0, 0), (1, 0), (0, 1)] + shell, dtype=float)
    perm = np.concatenate([[0], 1 + rng.permutation(len(pts) - 1)])
    pts = pts[perm]
    for k in (3, 7, 12):
        assert set(map(tuple, knn_edges(pts, k).tolist())) == brute_knn(pts, k)


def test_pairwise_tables_equal_direct_distances_near_and_far():
    """Tables gathered from the offset box and computed directly (edges longer than its radius) agree."""
    rng = np.random.default_rng(1)
    W, H = 120, 40
    free = rng.random((W, H)) > 0.1
    near = gaussian_swarm(rng, 25, 3) + [20, 20]
    far = np.array([[20 + _OFFSET_RADIUS + 30, 20], [20 + _OFFSET_RADIUS + 31, 21]])
    cells = np.concatenate([near, far])
    free[cells[:, 0], cells[:, 1]] = True
    labels = label_sets(free, cells, order=2)
    edges = knn_edges(cells.astype(float), 4)
    d0 = cells[edges[:, 0]] - cells[edges[:, 1]]
    assert np.any(np.abs(d0) > _OFFSET_RADIUS) and np.any(np.all(np.abs(d0) <= _OFFSET_RADIUS, axis=1))
    weights = rng.integers(1, 4, len(edges))
    morse = Morse()
    got = pairwise_tables(labels, edges, weights, morse, 0.5)
    c = labels.cells
    for e, (i, j) in enumerate(edges.tolist()):
        for a in range(labels.count[i]):
            for b in range(labels.count[j]):
                d = np.hypot(*(c[i, a] - c[j, b])) * 0.5
                assert got[e, a, b] == pytest.approx(weights[e] * morse(d), rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("pairs", [[[0, 1], [1, 0]], [[0, 2], [0, 2]]])
def test_mrf_rejects_repeated_pairs(pairs):
    N, L = 3, 2
    with pytest.raises(InvalidProblem, match="repeated pair"):
        PairwiseMRF(unary=np.zeros((N, L)), edges=np.array(pairs), pairwise=np.zeros((2, L, L)),
                    conflicts=np.zeros((0, 2)), conflict_mask=np.zeros((0, L, L), bool), initial=np.zeros(N, int))
    PairwiseMRF(unary=np.zeros((N, L)), edges=np.array([[0, 1], [1, 2]]), pairwise=np.zeros((2, L, L)),
                conflicts=np.zeros((0, 2)), conflict_mask=np.zeros((0, L, L), bool), initial=np.zeros(N, int))


@pytest.mark.parametrize("seed", range(4))
def test_incremental_cliques_equal_full_computation_along_a_plan(seed):
    """Cliques updated from the previous step's graph equal the full enumeration at every step."""
    from mrfswarm.discrete.planner import DiscreteProblem, plan_discrete

    rng = np.random.default_rng(seed)
    W, H = 50, 30
    free = rng.random((W, H)) > 0.05
    cells = gaussian_swarm(rng, 40, 3) + [10, 15]
    cells = cells[free[cells[:, 0], cells[:, 1]]]
    goal = np.array([42, 15])
    static = np.hypot(*(np.indices((W, H)) - goal[:, None, None]))
    plan = plan_discrete(DiscreteProblem(free=free, static=static, start=cells, goal=goal, morse=Morse(),
                                         k=int(rng.integers(3, 8)), order=2), max_steps=25)
    k = int(rng.integers(3, 8))
    prev = None
    changed_some = unchanged_some = False
    for p in plan.paths:
        edges = knn_edges(p.astype(float), k)
        full = clique_weights_of_graph(len(p), edges)
        got = full if prev is None else update_clique_weights(prev, len(p), edges)
        assert [c.tolist() for c in got.cliques] == [c.tolist() for c in full.cliques]
        assert got.node.tolist() == full.node.tolist() and got.edge.tolist() == full.edge.tolist()
        assert {s: g.tolist() for s, g in got.groups.items()} == {s: g.tolist() for s, g in full.groups.items()}
        if prev is not None:
            same = np.array_equal(prev.edges, edges)
            changed_some |= not same
            unchanged_some |= len(np.intersect1d(prev.edges[:, 0] * 1000 + prev.edges[:, 1],
                                                 edges[:, 0] * 1000 + edges[:, 1])) > 0 and not same
        prev = got
    assert changed_some and unchanged_some  # the partial update was exercised
