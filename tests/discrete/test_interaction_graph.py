"""k-NN graph, maximal cliques, and the pairwise reduction of the swarm energy."""

import itertools

import networkx as nx
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrfswarm.discrete.interaction_graph import (
    check_k,
    clique_weights,
    interaction_graph,
    knn_edges,
    maximal_cliques,
    swarm_energy_from_cliques,
)
from mrfswarm.discrete.label_sets import label_sets
from mrfswarm.discrete.potentials import Morse
from mrfswarm.discrete.step_mrf import step_mrf
from mrfswarm.errors import ConfigError


def random_cells(rng, n, span):
    cells = np.unique(rng.integers(0, span, size=(4 * n, 2)), axis=0)
    rng.shuffle(cells)
    return cells[:n]


@pytest.mark.parametrize("seed", range(5))
def test_knn_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    pts = random_cells(rng, 40, 15).astype(float)
    k = int(rng.integers(1, 8))
    edges = knn_edges(pts, k)
    D = np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1))
    expect = set()
    for i in range(len(pts)):
        order = sorted((j for j in range(len(pts)) if j != i), key=lambda j: (round(D[i, j], 9), j))
        for j in order[:k]:
            expect.add((min(i, j), max(i, j)))
    assert set(map(tuple, edges.tolist())) == expect
    deg = np.bincount(edges.ravel(), minlength=len(pts))
    assert np.all(deg >= k)  # symmetric union: at least k neighbours each, none isolated


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 30), st.floats(0.05, 0.9), st.integers(0, 2**32 - 1))
def test_maximal_cliques_match_networkx(n, p, seed):
    g = nx.gnp_random_graph(n, p, seed=seed)
    edges = np.array(sorted(tuple(sorted(e)) for e in g.edges()), dtype=np.intp).reshape(-1, 2)
    ours = sorted(tuple(c.tolist()) for c in maximal_cliques(n, edges))
    ref = sorted(tuple(sorted(c)) for c in nx.find_cliques(g))
    assert ours == ref


def test_clique_weights_count_cliques():
    rng = np.random.default_rng(3)
    pts = random_cells(rng, 30, 12)
    w = interaction_graph(pts.astype(float), 4)
    for i in range(30):
        assert w.node[i] == sum(i in set(c.tolist()) for c in w.cliques)
    for (i, j), we in zip(w.edges.tolist(), w.edge):
        assert we == sum(i in set(c.tolist()) and j in set(c.tolist()) for c in w.cliques) >= 1


def test_k_condition():
    for k, n in [(0, 5), (5, 5), (7, 3)]:
        with pytest.raises(ConfigError, match=f"interaction.k = {k}"):
            check_k(k, n)
    with pytest.raises(ConfigError, match="at least 2 robots"):
        check_k(1, 1)
    check_k(1, 2)


@pytest.mark.parametrize("seed", range(8))
def test_pairwise_reduction_equals_clique_definition(seed):
    """The step MRF's energy of any labelling equals sum_c E_c of the moved swarm (same graph)."""
    rng = np.random.default_rng(seed)
    W, H = 25, 25
    free = rng.random((W, H)) > 0.15
    cells = random_cells(rng, 30, 25)
    cells = cells[free[cells[:, 0], cells[:, 1]]][:12]
    k = int(rng.integers(1, len(cells)))
    static = rng.random((W, H)) * 5
    morse = Morse()
    w = clique_weights(len(cells), knn_edges(cells.astype(float), k), maximal_cliques(len(cells), knn_edges(cells.astype(float), k)))
    labels = label_sets(free, cells, order=int(rng.choice([1, 2, 4])))
    mrf = step_mrf(labels, w, static, morse, resolution=0.5)
    for _ in range(10):
        lab = rng.integers(0, labels.count)
        moved = labels.cells[np.arange(len(cells)), lab]
        direct = swarm_energy_from_cliques(w.cliques, moved, static, morse, resolution=0.5)
        assert mrf.energy(lab) == pytest.approx(direct, rel=1e-12)


def test_clique_factorization_of_a_known_graph():
    # a 4-cycle with one chord: cliques {0,1,2} and {0,2,3}
    edges = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]])
    c = maximal_cliques(4, edges)
    assert [x.tolist() for x in c] == [[0, 1, 2], [0, 2, 3]]
    w = clique_weights(4, edges, c)
    assert w.node.tolist() == [2, 1, 2, 1]
    assert dict(zip(map(tuple, edges.tolist()), w.edge.tolist())) == {(0, 1): 1, (0, 2): 2, (0, 3): 1, (1, 2): 1, (2, 3): 1}
    assert list(itertools.chain.from_iterable(x.tolist() for x in c)).count(0) == 2


@pytest.mark.parametrize("edges, error, match", [
    ([[0, 5]], ValueError, r"edge \[0, 5\] has a vertex outside 0..2"),  # was a clique [0, 5] of a 3-vertex graph
    ([[-1, 2]], ValueError, r"edge \[-1, 2\] has a vertex outside"),
    ([[1, 0], [2, 1], [2, 0]], ValueError, r"edge \[1, 0\]: edges must be pairs i < j"),  # was three 2-cliques
    ([[0, 0], [1, 2]], ValueError, r"edge \[0, 0\]"),  # vertex 0 was dropped
    ([[0, 1], [1, 2], [0, 2], [0, 1]], ValueError, r"edge \[0, 1\] is given more than once"),  # the triangle twice
    ([[0.5, 1.0]], TypeError, "integer vertex pairs, got dtype float64"),  # 0.5 was read as 0
    ([[0, 1, 2]], ValueError, r"shape \(E, 2\), got \(1, 3\)"),
])
def test_maximal_cliques_refuse_edges_outside_their_contract(edges, error, match):
    with pytest.raises(error, match=match):
        maximal_cliques(3, np.array(edges))


def test_maximal_cliques_of_no_edges_are_the_vertices():
    assert [c.tolist() for c in maximal_cliques(3, np.zeros((0, 2), np.intp))] == [[0], [1], [2]]
    assert [c.tolist() for c in maximal_cliques(2, [])] == [[0], [1]]


def test_knn_edges_name_the_robot_whose_position_is_not_finite():
    with pytest.raises(ValueError, match=r"robot 1's position \[nan, 1.0\] is not finite"):
        knn_edges(np.array([[0.0, 0.0], [np.nan, 1.0], [2.0, 2.0]]), 1)
    with pytest.raises(ValueError, match=r"robot 2's position \[2.0, inf\]"):
        knn_edges(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, np.inf]]), 1)
