"""ICM and the colour-class machinery it runs on, against brute force and a plain loop."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from solvers import mrf
from solvers.mrf.icm import descend
from solvers.mrf.local_energy import LocalEnergy, colour_classes, colour_sweep
from solvers.mrf.synthetic import random_mrf


def reference_icm(m: mrf.PairwiseMRF, order: np.ndarray, tol: float, max_sweeps: int = 1000) -> np.ndarray:
    """Textbook sequential ICM: one node at a time, one label at a time, full energy."""
    x = m.initial.copy()
    for _ in range(max_sweeps):
        moved = False
        for i in order:
            cur = m.energy(x)
            best_a, best_e = x[i], cur
            for a in range(m.n_labels[i]):
                y = x.copy()
                y[i] = a
                if m.is_feasible(y) and m.energy(y) < best_e - tol and m.energy(y) < cur - tol:
                    best_a, best_e = a, m.energy(y)
            if best_a != x[i]:
                x[i] = best_a
                moved = True
        if not moved:
            break
    return x


@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 9), L=st.integers(1, 5))
@settings(max_examples=60, deadline=None)
def test_colouring_is_proper_partition(seed, N, L):
    m = random_mrf(np.random.default_rng(seed), N, L)
    classes = colour_classes(m)
    assert np.array_equal(np.sort(np.concatenate(classes)), np.arange(N))
    colour = np.empty(N, int)
    for c, nodes in enumerate(classes):
        colour[nodes] = c
    for pairs in (m.edges, m.conflicts):
        assert np.all(colour[pairs[:, 0]] != colour[pairs[:, 1]])


def test_colouring_of_a_long_path_uses_few_colours():
    N = 2000
    e = np.stack([np.arange(N - 1), np.arange(1, N)], 1)
    m = mrf.PairwiseMRF(np.zeros((N, 2)), e, np.zeros((N - 1, 2, 2)), np.zeros((0, 2)), np.zeros((0, 2, 2)),
                        np.zeros(N, int))
    assert len(colour_classes(m)) <= 3


@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 7), L=st.integers(1, 4))
@settings(max_examples=60, deadline=None)
def test_local_energy_is_the_energy_difference(seed, N, L):
    rng = np.random.default_rng(seed)
    m = random_mrf(rng, N, L)
    x = rng.integers(0, m.n_labels)
    le = LocalEnergy(m, np.arange(N))
    c, forb = le.costs(x), le.forbidden(x)
    for i in range(N):
        for a in range(m.n_labels[i]):
            y = x.copy()
            y[i] = a
            assert c[i, a] - c[i, x[i]] == pytest.approx(m.energy(y) - m.energy(x), abs=1e-9)
            others = np.setdiff1d(m.violated_conflicts(y), np.flatnonzero((m.conflicts != i).all(axis=1)))
            assert forb[i, a] == (others.size > 0)
        assert np.all(np.isinf(c[i, m.n_labels[i]:]))


@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 8), L=st.integers(1, 5))
@settings(max_examples=60, deadline=None)
def test_icm_is_monotone_feasible_and_a_local_minimum(seed, N, L):
    m = random_mrf(np.random.default_rng(seed), N, L)
    res = mrf.minimize(m, "icm")
    assert m.is_feasible(res.labels) and res.repaired == 0
    trace = res.energy_trace
    assert np.all(np.diff(trace) <= 1e-12)
    assert res.energy <= m.energy(m.initial) + 1e-12
    assert res.energy == pytest.approx(m.energy(res.labels))
    assert res.iterations == len(trace) and res.stats["converged"]
    # no single feasible relabelling improves by more than tol
    for i in range(N):
        for a in range(m.n_labels[i]):
            y = res.labels.copy()
            y[i] = a
            if m.is_feasible(y):
                assert m.energy(y) >= res.energy - 1e-9 - 1e-12


@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 7), L=st.integers(1, 4))
@settings(max_examples=40, deadline=None)
def test_vectorized_icm_equals_plain_sequential_icm_in_colour_order(seed, N, L):
    m = random_mrf(np.random.default_rng(seed), N, L)
    order = np.concatenate(colour_classes(m))
    ref = reference_icm(m, order, tol=1e-9)
    res = mrf.minimize(m, "icm")
    assert np.array_equal(res.labels, ref)


def test_icm_matches_exact_on_one_node():
    rng = np.random.default_rng(1)
    for _ in range(20):
        m = random_mrf(rng, 1, 6)
        assert mrf.minimize(m, "icm").energy == pytest.approx(mrf.minimize(m, "exact").energy)


@pytest.mark.parametrize("seed", range(10))
def test_icm_matches_exact_without_edges(seed):
    m0 = random_mrf(np.random.default_rng(seed), 6, 4, p_conf=0.0, edges=np.zeros((0, 2)))
    res = mrf.minimize(m0, "icm")
    assert res.energy == pytest.approx(mrf.minimize(m0, "exact").energy)
    assert res.iterations <= 2


@pytest.mark.parametrize("seed", range(10))
def test_icm_matches_exact_with_conflicts_that_never_bind(seed):
    rng = np.random.default_rng(seed)
    m0 = random_mrf(rng, 6, 4, p_conf=0.8, edges=np.zeros((0, 2)))
    best = np.argmin(m0.unary, axis=1)
    mask = m0.conflict_mask.copy()
    # forbid only pairs in which neither node takes its own best label
    mask[np.arange(len(mask)), best[m0.conflicts[:, 0]], :] = False
    mask[np.arange(len(mask)), :, best[m0.conflicts[:, 1]]] = False
    m = mrf.PairwiseMRF(m0.unary, m0.edges, m0.pairwise, m0.conflicts, mask, m0.initial)
    res = mrf.minimize(m, "icm")
    assert np.array_equal(res.labels, best)
    assert res.energy == pytest.approx(mrf.minimize(m, "exact").energy)


def test_icm_respects_a_binding_conflict():
    # both nodes want label 1, which they may not share; node 0 gains more, goes first
    unary = np.array([[0.0, -1.0], [0.0, -2.0]])
    mask = np.zeros((1, 2, 2), bool)
    mask[0, 1, 1] = True
    m = mrf.PairwiseMRF(unary, np.zeros((0, 2)), np.zeros((0, 2, 2)), [[0, 1]], mask, [0, 0])
    res = mrf.minimize(m, "icm")
    assert m.is_feasible(res.labels) and res.energy in (-1.0, -2.0)
    assert res.energy == pytest.approx(-2.0) or res.labels.tolist() == [1, 0]


def test_icm_stops_at_max_iter_and_tol_suppresses_small_moves():
    rng = np.random.default_rng(3)
    m = random_mrf(rng, 8, 4, p_conf=0.0)
    res = mrf.minimize(m, "icm", mrf.Options(max_iter=1))
    assert res.iterations == 1 and len(res.energy_trace) == 1
    big = mrf.minimize(m, "icm", mrf.Options(tol=1e6))
    assert np.array_equal(big.labels, m.initial) and big.stats["moves"] == [0]


def test_descend_from_a_given_labelling_keeps_it_if_already_optimal():
    rng = np.random.default_rng(4)
    m = random_mrf(rng, 6, 3)
    opt = mrf.minimize(m, "exact").labels
    x, trace, moves = descend(m, opt, colour_sweep(m), 10, 1e-9)
    assert np.array_equal(x, opt) and moves == [0]


@given(seed=st.integers(0, 2**32 - 1), N=st.integers(2, 9), L=st.integers(1, 4), levels=st.integers(1, 4))
@settings(max_examples=60, deadline=None)
def test_a_node_of_higher_priority_is_in_an_earlier_class_than_its_neighbours(seed, N, L, levels):
    rng = np.random.default_rng(seed)
    m = random_mrf(rng, N, L)
    m = mrf.PairwiseMRF(m.unary, m.edges, m.pairwise, m.conflicts, m.conflict_mask, m.initial,
                        priority=rng.integers(0, levels, N).astype(float))
    classes = colour_classes(m)
    colour = np.empty(N, int)
    for c, nodes in enumerate(classes):
        colour[nodes] = c
    for pairs in (m.edges, m.conflicts):
        i, j = pairs[:, 0], pairs[:, 1]
        assert np.all(colour[i] != colour[j])
        higher = m.priority[i] > m.priority[j]
        lower = m.priority[i] < m.priority[j]
        assert np.all(colour[i][higher] < colour[j][higher]) and np.all(colour[i][lower] > colour[j][lower])


def contested_pair(priority=None) -> mrf.PairwiseMRF:
    """Two nodes that both gain most from label 1, which they cannot both take; node 0 has more neighbours."""
    unary = np.array([[0.0, -1.0], [0.0, -1.0], [0.0, 0.0], [0.0, 0.0]])
    edges = np.array([[0, 2], [0, 3]])
    mask = np.zeros((1, 2, 2), dtype=bool)
    mask[0, 1, 1] = True
    return mrf.PairwiseMRF(unary, edges, np.zeros((2, 2, 2)), np.array([[0, 1]]), mask, np.zeros(4, int),
                           priority=priority)


@pytest.mark.parametrize("priority, winner", [(None, 0), ([0.0, 3.0, 0.0, 0.0], 1), ([3.0, 0.0, 0.0, 0.0], 0),
                                              ([1.0, 2.0, 5.0, 5.0], 1)])
def test_icm_gives_a_contested_label_to_the_node_it_visits_first(priority, winner):
    """Without a priority the node of higher degree is visited first; a priority overrides that."""
    x = mrf.minimize(contested_pair(priority), method="icm").labels
    assert x[winner] == 1 and x[1 - winner] == 0


@pytest.mark.parametrize("priority, why", [([1.0, 2.0], "shape"), ([0.0, np.nan, 0.0, 0.0], "non-finite")])
def test_a_priority_that_is_not_one_finite_number_per_node_is_refused(priority, why):
    with pytest.raises(mrf.InvalidProblem, match=why):
        contested_pair(np.array(priority))


def test_a_chain_of_priorities_colours_a_path_in_order():
    """Priorities falling along a path push each node's colour above its predecessor's: node 5 takes colour 5, and
    node 6, of node 5's priority and fewer neighbours, is coloured after it next to that high colour (which once
    overflowed the table of colours taken: an IndexError from ICM on a 200-robot swarm)."""
    N = 7
    e = np.stack([np.arange(N - 1), np.arange(1, N)], 1)
    m = mrf.PairwiseMRF(np.zeros((N, 2)), e, np.zeros((N - 1, 2, 2)), np.zeros((0, 2)), np.zeros((0, 2, 2)),
                        np.zeros(N, int), priority=np.array([5.0, 4, 3, 2, 1, 0, 0]))
    colour = np.empty(N, int)
    for c, nodes in enumerate(colour_classes(m)):
        colour[nodes] = c
    assert colour[:6].tolist() == [0, 1, 2, 3, 4, 5] and colour[6] == 0
