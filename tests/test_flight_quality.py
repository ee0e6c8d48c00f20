"""The flight-quality measures: the makespan's lower bound and the stop count."""

from __future__ import annotations

import itertools

import networkx as nx
import numpy as np
import pytest

from mrfswarm.discrete.goal_distance import goal_distance
from mrfswarm.flight_quality import (
    assignment_free_bound,
    count_stops,
    free_distances,
    free_move_counts,
    free_path_lengths,
    makespan_lower_bound,
)
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


def _doorway_config():
    """Five robots through a three-cell doorway in a wall (the flight-quality bench's doorway)."""
    from mrfswarm.config import from_dict
    from support.repository import EXPERIMENTS

    occ = np.zeros((30, 20), dtype=bool)
    occ[15, :] = True
    occ[15, 9:12] = False
    rows = ["".join("@" if occ[x, y] else "." for x in range(30)) for y in range(20)]
    scn = {"map": {"kind": "ascii", "rows": rows}, "start": {"center": [6, 10], "n_robots": 5, "sigma": 1.0, "seed": 0},
           "goal": [25, 10]}
    return from_dict({"scenario": scn, "interaction": {"k": 3}, "simulation": {"enabled": False}}, EXPERIMENTS)


def test_a_run_reports_its_makespan_over_the_lower_bound_and_its_stops():
    """result.json's flight_quality: the numbers of this module's functions on the run's own plan; a robot whose
    trajectory stops is counted; without a continuous plan there is none."""
    import dataclasses

    from mrfswarm.pipeline import plan

    r = plan(_doorway_config(), progress=False)
    c, P, scn = r.continuous, r.discrete.paths, r.scenario
    q = r.summary()["flight_quality"]
    lengths = free_path_lengths(scn.grid.free, P[0], P[-1], scn.grid.resolution)  # every robot searched
    bound = makespan_lower_bound(scn.grid.free, P[0], P[-1], scn.grid.resolution, r.config.smoothing.v_max)
    assert q["lower_bound_s"] == pytest.approx(bound, rel=1e-12) and bound > 0
    assert lengths[q["bound_robot"]] == pytest.approx(lengths.max(), rel=1e-12)
    assert q["makespan_over_bound"] == pytest.approx(c.makespan_s / bound, rel=1e-12) and q["makespan_over_bound"] > 1
    stops = count_stops(c.trajectories)
    assert q["stops"] == stops.per_robot.tolist() and q["stops_per_robot"] == stops.mean
    assert q["mean_speed_m_s"] == pytest.approx(stops.mean_speed.mean()) and q["stop_speed_m_s"] == 0.05

    stopping = dataclasses.replace(c, trajectories=[_line([1.0] * 4, [0.0, 1.0, 0.0, 1.0, 0.0])] + c.trajectories[1:])
    q2 = dataclasses.replace(r, continuous=stopping).summary()["flight_quality"]
    assert q2["stops"][0] == 1 and q2["stops"][1:] == q["stops"][1:] and q2["stops_max"] >= 1

    assert dataclasses.replace(r, continuous=None).summary()["flight_quality"] is None


def test_free_move_counts_count_a_diagonal_as_one_move_and_go_around_walls():
    free = np.ones((7, 5), dtype=bool)
    starts = np.array([[0, 0], [0, 0], [3, 2]])
    ends = np.array([[4, 4], [6, 0], [3, 2]])
    assert free_move_counts(free, starts, ends).tolist() == [4, 6, 0]
    free[3, :4] = False  # a wall with its gap at the top row: x = 3 only at y = 4
    walled = free_move_counts(free, np.array([[2, 0]]), np.array([[4, 0]]))[0]
    # up 4 to (2, 4), across the gap 2 to (4, 4) (the diagonals (2, 3) -> (3, 4) and (3, 4) -> (4, 3) would cut
    # the wall's corner at (3, 3)), down 4 to (4, 0)
    assert walled == 4 + 2 + 4
    blocked = free.copy()
    blocked[3, 4] = False
    assert free_move_counts(blocked, np.array([[2, 0]]), np.array([[4, 0]]))[0] == np.inf


def test_free_distances_hold_every_start_to_every_end():
    free = np.ones((7, 7), dtype=bool)
    free[3, 0:6] = False
    starts, ends = np.array([[0, 0], [5, 5], [1, 3]]), np.array([[6, 0], [1, 1]])
    d = free_distances(free, starts, ends)
    assert d.shape == (3, 2)
    for i, j in itertools.product(range(3), range(2)):
        assert d[i, j] == pytest.approx(free_path_lengths(free, starts[[i]], ends[[j]])[0])


def test_the_assignment_free_bound_is_the_best_assignments_longest_path():
    free = np.ones((12, 3), dtype=bool)
    starts = np.array([[0, 0], [1, 0], [2, 0]])
    ends = np.array([[11, 0], [5, 0], [6, 0]])
    # robot 0 -> 11 alone is 11 m; robot 2 -> 11 is 9 m, the best bottleneck: 2 -> 11, 1 -> 6 (5), 0 -> 5 (5)
    assert makespan_lower_bound(free, starts, ends, 1.0, 1.0) == 11.0
    assert assignment_free_bound(free, starts, ends, 1.0, 2.0) == 4.5
    # brute force over all assignments of random starts to random cells of a cluttered map
    rng = np.random.default_rng(3)
    free = rng.random((9, 8)) > 0.2
    cells = np.argwhere(free)
    for _ in range(5):
        pick = rng.choice(len(cells), 8, replace=False)
        s, e = cells[pick[:4]], cells[pick[4:]]
        d = free_distances(free, s, e, 0.5)
        best = min(max(d[i, p[i]] for i in range(4)) for p in itertools.permutations(range(4)))
        assert assignment_free_bound(free, s, e, 0.5, 1.0) == pytest.approx(best)


def test_the_assignment_free_bound_is_inf_without_an_assignment_and_refuses_too_few_cells():
    free = np.ones((5, 5), dtype=bool)
    free[2, :] = False  # two halves
    starts, ends = np.array([[0, 0], [0, 1]]), np.array([[1, 0], [4, 4]])
    assert assignment_free_bound(free, starts, ends, 1.0, 1.0) == float("inf")
    with pytest.raises(ValueError, match="2 robots and only 1 cells"):
        assignment_free_bound(free, starts, ends[:1], 1.0, 1.0)
