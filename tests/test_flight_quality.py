"""The flight-quality measures: the makespan's lower bound and the stop count."""

from __future__ import annotations

import itertools

import networkx as nx
import numpy as np
import pytest

from mrfswarm.discrete.goal_distance import goal_distance
from mrfswarm.flight_quality import count_stops, free_path_lengths, makespan_lower_bound
from mrfswarm.geometry import segment_clear
from mrfswarm.trajectory import PiecewisePolynomial


def test_free_path_lengths_go_around_a_wall_without_cutting_corners():
    free = np.ones((7, 7), dtype=bool)
    free[3, 0:6] = False  # a wall with its gap at the top (y = 6)
    starts, ends = np.array([[0, 0], [0, 0]]), np.array([[6, 0], [1, 1]])
    lengths = free_path_lengths(free, starts, ends)
    assert lengths[1] == np.sqrt(2)  # one diagonal move
    assert lengths[0] > 12.0  # the straight 6 m are blocked
    via = free_path_lengths(free, ends, np.array([[6, 0], [6, 0]]))
    assert makespan_lower_bound(free, starts, ends, 1.0, 2.0) == lengths.max() / 2.0
    # pruning by the bound through a common cell keeps the maximum
    d_goal = goal_distance(free, np.array([6, 0])).path
    assert makespan_lower_bound(free, starts, ends, 1.0, 2.0, via=d_goal) == lengths.max() / 2.0
    assert np.isfinite(via).all()


def _line(durations, speeds):
    """A 1-D flight along x: one cubic piece per duration, knot speeds given, in the (..., 2) layout."""
    pieces, x = [], 0.0
    for T, (v0, v1) in zip(durations, zip(speeds[:-1], speeds[1:])):
        # cubic Hermite with position x -> x + (v0 + v1) T / 2 (the trapezoid's distance)
        dx = (v0 + v1) * T / 2
        c = np.zeros((4, 2))
        c[0, 0], c[1, 0] = x, v0
        c[2, 0] = (3 * dx - (2 * v0 + v1) * T) / T**2
        c[3, 0] = (-2 * dx + (v0 + v1) * T) / T**3
        pieces.append(c)
        x += dx
    return PiecewisePolynomial(np.array(durations, float), np.stack(pieces))


def test_a_stop_inside_the_flight_counts_and_the_ends_do_not():
    go_stop_go = _line([1.0, 1.0, 1.0, 1.0], [0.0, 1.0, 0.0, 1.0, 0.0])
    cruise = _line([1.0, 1.0, 1.0], [0.0, 1.0, 1.0, 0.0])
    stops = count_stops([go_stop_go, cruise])
    assert stops.per_robot.tolist() == [1, 0]
    assert stops.mean == 0.5 and (stops.mean_speed > 0).all()



def test_the_3d_lower_bound_searches_the_26_connected_voxel_graph_without_cutting():
    rng = np.random.default_rng(2)
    free = rng.random((6, 5, 4)) > 0.25
    G = nx.DiGraph()
    for c in map(tuple, np.argwhere(free).tolist()):
        for m in itertools.product((-1, 0, 1), repeat=3):
            q = tuple(np.add(c, m))
            if any(m) and segment_clear(free, np.array(c, float), np.array(q, float)):
                G.add_edge(c, q, weight=float(np.linalg.norm(m)))
    cells = np.argwhere(free)
    starts, ends = cells[rng.choice(len(cells), 6)], cells[rng.choice(len(cells), 6)]
    got = free_path_lengths(free, starts, ends, resolution=0.5)
    for s, e, d in zip(starts, ends, got):
        if tuple(s) == tuple(e):
            expect = 0.0
        elif nx.has_path(G, tuple(s.tolist()), tuple(e.tolist())):
            expect = nx.dijkstra_path_length(G, tuple(s.tolist()), tuple(e.tolist())) * 0.5
        else:
            expect = np.inf
        assert d == pytest.approx(expect), (s, e)
    # space diagonals across an empty block: sqrt(3) per move, at v_max = 2
    open_ = np.ones((4, 4, 4), bool)
    assert makespan_lower_bound(open_, np.array([[0, 0, 0]]), np.array([[3, 3, 3]]), 1.0, 2.0) == \
        pytest.approx(3 * np.sqrt(3) / 2)
    # a floor at z = 2 with one hole: the way up goes through it, and the bound through the
    # hole (via its 26-connected distances) is exact
    walled = np.ones((4, 4, 5), bool)
    walled[:, :, 2] = False
    walled[3, 3, 2] = True
    via = goal_distance(walled, np.array([3, 3, 2]), order=3).path
    d = free_path_lengths(walled, np.array([[0, 0, 0]]), np.array([[0, 0, 4]]), via=via)[0]
    assert d == pytest.approx(via[0, 0, 0] + via[0, 0, 4])
